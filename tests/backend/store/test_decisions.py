"""The versions table's shared queries: a page of a patient's versions reads only the summary columns."""

from __future__ import annotations

from sqlalchemy import literal, select

from backend.store.decisions import summary_columns, version_page
from backend.store.tables import versions as versions_table


def test_versions_page_newest_first_and_read_only_their_summary_columns(conn, patient, draft):
    for _ in range(5):
        draft()
    query = select(*summary_columns(versions_table), versions_table.c.speed_mps, literal(0).label("unused"))
    rows, total = version_page(conn, "table", query, patient["id"], 2, None)
    assert total == 5 and [r["version"] for r in rows] == [5, 4]
    rows, _ = version_page(conn, "table", query, patient["id"], 2, 4)
    assert [r["version"] for r in rows] == [3, 2]
    columns = list(rows[0].keys())
    assert "content_json" not in columns and "speed_mps" in columns
