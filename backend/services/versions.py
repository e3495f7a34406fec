"""What a version is and where it stands, whichever kind it is: its stored content as the device will be sent it (a
table, or an envelope, read back and proved by its hash), and what its page shows beside it (where it runs, the
bench's verdict on exactly its content, a withdrawal). One place for the two kinds."""

from __future__ import annotations

from sqlalchemy import Connection, RowMapping

from backend.services import bench_verdict
from backend.store import pushes, versions, withdrawals
from backend.store.pushes import Pushed, PushedKind
from controller_core.envelope import Envelope
from controller_core.table import ParameterTable


def stored_content(conn: Connection, item: Pushed) -> tuple[RowMapping, ParameterTable | Envelope]:
    """The version's row and its content (raises NotFoundError for no such version, ConflictError where the stored
    content no longer matches its hash)."""
    row = versions.get_row(conn, *item)
    return row, versions.stored_content(row)


def with_state(conn: Connection, kind: PushedKind, shown: dict) -> dict:
    """The version's view ``shown`` (its ``id`` and content hash are read) and what the page shows beside it: where
    it runs, the bench's verdict on exactly its content, and its withdrawal if it was taken back."""
    return {**shown, "deployment": pushes.deployment_state(conn, (kind, shown["id"])),
            "bench": bench_verdict.verdict(conn, kind, shown), "withdrawal": withdrawals.withdrawal(conn, kind, shown["id"])}
