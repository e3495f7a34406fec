"""Domain errors raised below the HTTP layer; ``backend.app`` maps each to its status code.

Every message says what was wrong in words a person understands (which field, which value, which range).
"""

from __future__ import annotations


class DomainError(Exception):
    """Base class: ``status`` is the HTTP status the API answers with; ``extra`` is merged into the body."""

    status = 400

    def __init__(self, message: str, **extra: object) -> None:
        super().__init__(message)
        self.message = message
        self.extra = extra


class NotFoundError(DomainError):
    status = 404


class MovedError(DomainError):
    """An envelope named by its id from before one version (revision 0021): answered with a permanent redirect to the
    same path under its version id (``moved_from`` → ``moved_to``)."""

    status = 308

    def __init__(self, message: str, moved_from: int, moved_to: int) -> None:
        super().__init__(message, moved_to=moved_to)
        self.moved_from = moved_from


class ForbiddenError(DomainError):
    """The signed-in user may not do this to this item (someone else's)."""

    status = 403


class ConflictError(DomainError):
    """The request is well-formed but clashes with the stored state (duplicate name, already decided …)."""

    status = 409


class InvalidError(DomainError):
    """A value is out of range or inconsistent (beyond what the request schema can express)."""

    status = 422


class ServiceUnavailableError(DomainError):
    status = 503


class TooManyError(DomainError):
    """One user asked for more of a shared, bounded resource than their share (the bench's queue)."""

    status = 429


class DeviceError(DomainError):
    """The device did not do what was asked (no acknowledgement, refused): the body carries the record."""

    status = 502
