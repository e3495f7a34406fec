"""A draft is decided once; an approval rests on the stored content's check and the bench."""

from __future__ import annotations

import pytest

from backend.errors import ConflictError
from backend.store import audit, proposals
from backend.store.decisions import decide_once, summary_select, version_page
from controller_core.table import LimitViolation

REASON = "walked with the patient in the parallel bars"


def _decide(conn, pid, actor, status, recheck=list, override=REASON):
    with conn:
        decide_once(conn, "proposal", proposals.get_row(conn, pid), status, "looked at it", actor, recheck,
                    "the safety limits", {"note": 1}, override)


def test_a_draft_is_decided_once_and_audited(conn, prosthetist, draft):
    pid = draft()
    _decide(conn, pid, prosthetist, "approved")
    row = proposals.get_row(conn, pid)
    assert (row["status"], row["decided_by_name"], row["decision_override"]) == ("approved", "pat", REASON)
    entry = audit.list_entries(conn, entity="proposal", entity_id=pid)[0]
    assert entry["action"] == "proposal.approve" and entry["after"]["bench"] == "not_walked"
    with pytest.raises(ConflictError, match="already approved by pat"):
        _decide(conn, pid, prosthetist, "rejected")


def test_an_approval_whose_content_fails_its_check_writes_nothing(conn, prosthetist, draft):
    pid = draft()
    bad = [LimitViolation(field="knee.stance_flexion.k_Nm_per_rad", value=10.0, low=-1200.0, high=0.0,
                          message="knee stance flexion k 10 is outside [-1200, 0]")]
    with pytest.raises(ConflictError, match="cannot be approved: 1 value"):
        _decide(conn, pid, prosthetist, "approved", recheck=lambda: bad)
    assert proposals.get_row(conn, pid)["status"] == "draft"
    _decide(conn, pid, prosthetist, "rejected", recheck=lambda: bad)   # a rejection needs no check
    assert proposals.get_row(conn, pid)["status"] == "rejected"
    with pytest.raises(ValueError, match="approved' or 'rejected"):
        _decide(conn, draft(), prosthetist, "maybe")


def test_versions_page_newest_first_and_read_only_their_summary_columns(conn, patient, draft):
    for _ in range(5):
        draft()
    select = summary_select("SELECT p.*, 0 AS unused FROM proposals p", "p", "p.speed_mps")
    rows, total = version_page(conn, "proposal", select, "p", patient["id"], 2, None)
    assert total == 5 and [r["version"] for r in rows] == [5, 4]
    rows, _ = version_page(conn, "proposal", select, "p", patient["id"], 2, 4)
    assert [r["version"] for r in rows] == [3, 2]
    columns = list(rows[0].keys())          # a sqlite3.Row's `in` looks at values, not names
    assert "table_json" not in columns and "speed_mps" in columns
