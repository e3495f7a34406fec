"""The append-only audit log: newest first, filtered, paged, never changed."""

from __future__ import annotations

import pytest
from sqlalchemy.exc import IntegrityError

from backend.store import audit
from tests.helpers.sql import sql


def test_entries_are_listed_newest_first_filtered_and_paged(conn):
    ids = [audit.record(conn, None, "cli", f"thing.{i}", "thing", i % 2, before={"i": i}, after=None)
           for i in range(5)]
    entries = audit.list_entries(conn)
    assert [e["id"] for e in entries] == ids[::-1] and entries[0]["before"] == {"i": 4} and entries[0]["after"] is None
    assert [e["entity_id"] for e in audit.list_entries(conn, entity="thing", entity_id=1)] == [1, 1]
    assert [e["id"] for e in audit.list_entries(conn, before_id=ids[2], limit=1)] == [ids[1]]
    assert audit.list_entries(conn, actor="someone else") == []


def test_the_log_refuses_changes_and_deletions(conn):
    audit.record(conn, None, "cli", "thing.made", "thing", 1)
    with pytest.raises(IntegrityError, match="append-only"):
        sql(conn, "UPDATE audit_log SET action = 'thing.unmade'")
    with pytest.raises(IntegrityError, match="append-only"):
        sql(conn, "DELETE FROM audit_log")
