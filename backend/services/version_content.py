"""A version's stored content as the device will be sent it: a proposal's table or an envelope, read back and proved
by its hash (:mod:`backend.store.proposals`, :mod:`backend.store.envelopes`). One place for what a push and a
send-back take from storage, whichever kind the version is."""

from __future__ import annotations

from typing import Literal

from sqlalchemy import Connection, RowMapping

from backend.store import envelopes, proposals
from controller_core.envelope import Envelope
from controller_core.table import ParameterTable

Item = tuple[Literal["proposal", "envelope"], int]


def stored_content(conn: Connection, item: Item) -> tuple[RowMapping, ParameterTable | Envelope]:
    """The version's row and its content (raises NotFoundError for no such version, ConflictError where the stored
    content no longer matches its hash)."""
    kind, version_id = item
    if kind == "proposal":
        row = proposals.get_row(conn, version_id)
        return row, proposals.stored_table(row)
    row = envelopes.get_row(conn, version_id)
    return row, envelopes.stored_envelope(row)
