"""A draft is decided once; an approval rests on the stored content's check and the bench."""

from __future__ import annotations

import pytest

from backend.db import connect, write_transaction
from backend.errors import ConflictError
from backend.services.decisions import decide_once
from backend.store import audit, signoffs, versions
from controller_core.table import LimitViolation

REASON = "walked with the patient in the parallel bars"


def _signed(conn, pid, colleague):
    """The colleague's sign-off on the draft's content (it has no preview walked): the approver's is then the second."""
    with write_transaction(conn):
        signoffs.sign(conn, "proposal", pid, versions.get_row(conn, "proposal", pid)["content_sha256"], colleague, REASON)


def _decide(conn, pid, actor, status, recheck=list, override=REASON):
    with write_transaction(conn):
        decide_once(conn, "proposal", versions.get_row(conn, "proposal", pid), status, "looked at it", actor, recheck,
                    "the safety limits", {"note": 1}, override)


def test_a_draft_is_decided_once_and_audited(conn, prosthetist, colleague, draft):
    pid = draft()
    _signed(conn, pid, colleague)
    _decide(conn, pid, prosthetist, "approved")
    row = versions.get_row(conn, "proposal", pid)
    assert (row["status"], row["decided_by_name"], row["decision_override"]) == ("approved", "pat",
                                                                                 f"kim: {REASON}; pat: {REASON}")
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
    assert versions.get_row(conn, "proposal", pid)["status"] == "draft"
    _decide(conn, pid, prosthetist, "rejected", recheck=lambda: bad)   # a rejection needs no check
    assert versions.get_row(conn, "proposal", pid)["status"] == "rejected"
    with pytest.raises(ValueError, match="approved' or 'rejected"):
        _decide(conn, draft(), prosthetist, "maybe")



def test_a_decision_made_on_a_row_read_before_another_server_decided_it_writes_nothing(conn, database, prosthetist,
                                                                                      colleague, draft):
    """Two instances read the same draft; the other one's decision commits first. The second's update, made only
    while the version is still a draft, changes nothing, and it is refused: no second decision, no second audit."""
    pid = draft()
    _signed(conn, pid, colleague)
    stale = versions.get_row(conn, "proposal", pid)            # read while still a draft
    other = connect(database)
    try:
        _decide(other, pid, prosthetist, "rejected")
    finally:
        other.close()
    with pytest.raises(ConflictError, match="decided by someone else a moment ago"), write_transaction(conn):
        decide_once(conn, "proposal", stale, "approved", "me too", prosthetist, list, "the safety limits", {},
                    REASON)
    assert versions.get_row(conn, "proposal", pid)["status"] == "rejected"
    decisions = [e["action"] for e in audit.list_entries(conn, entity="proposal", entity_id=pid)]
    assert decisions == ["proposal.reject", "proposal.gate_signoff"]          # the approver's sign-off was not kept
    assert [s["by"] for s in signoffs.signoffs(conn, "proposal", pid, stale["content_sha256"])] == ["kim"]
