"""The tasks a request may name: the limits of any walking task, and the narrower range the model knows.

A task beyond the known range (:mod:`controller_core.known_range`) is refused unless the prosthetist asks to
extrapolate and writes why; the reason is stored with the version (never changed) and audited.
"""

from __future__ import annotations

from collections.abc import Sequence

from backend.errors import InvalidError
from controller_core.known_range import known_range
from controller_core.model import QuasiStiffnessModel


def extrapolation_reason(model: QuasiStiffnessModel, tasks: Sequence[tuple[float, float]], extrapolate: bool,
                         reason: str | None) -> str | None:
    """The reason to store with a version over ``tasks`` (speed m/s, incline deg): None when every task is within
    what the model knows; the written reason when one lies beyond and ``extrapolate`` is set.

    Raises:
        InvalidError: a task beyond the known range without ``extrapolate`` (422, saying the range the model knows).
    """
    known = known_range(model)
    beyond = [why for s, g in tasks if (why := known.beyond(s, g)) is not None]
    if not beyond:
        return None
    if extrapolate and reason is not None:
        return reason
    raise InvalidError(f"refused, nothing stored: {beyond[0]}. To request it anyway, send \"extrapolate\": true with "
                       "a \"reason\" (at least 20 characters), which is audited and shown with the version",
                       known_range=known.to_json())
