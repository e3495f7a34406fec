"""The bench's verdict on a version, and the gate approval and push rest on."""

from __future__ import annotations

import pytest

from backend.errors import ConflictError
from backend.store import bench_verdict, previews, proposals
from tests.backend.store.conftest import CLEAN_WALK


def _walked(conn, pid, mine):
    row = proposals.get_row(conn, pid)
    previews.store_preview(conn, pid, row["table_sha256"], {"seconds": 10.0, "controllers": {
        "table": mine, "fsmic": CLEAN_WALK}})
    return proposals.get_row(conn, pid)


def test_not_walked_is_refused_with_the_way_to_walk_it_unless_a_reason_is_written(conn, draft):
    row = proposals.get_row(conn, draft())
    assert bench_verdict.verdict(conn, "proposal", row)["status"] == "not_walked"
    with pytest.raises(ConflictError, match=r"not approved: its bench preview has not been walked.*override_reason"):
        bench_verdict.require_bench(conn, "proposal", row, None, "approved")
    v, kept = bench_verdict.require_bench(conn, "proposal", row, "seated in the bars, checked by hand", "approved")
    assert v["status"] == "not_walked" and kept == "seated in the bars, checked by hand"


def test_a_clean_walk_passes_alone_and_a_warning_never_stops_a_decision(conn, draft):
    row = _walked(conn, draft(), CLEAN_WALK)
    v, kept = bench_verdict.require_bench(conn, "proposal", row, None, "pushed")
    assert v["status"] == "clean" and kept is None and v["words"] == "bench preview clean"
    assert [f["figure"] for f in v["figures"]][:2] == ["falls", "toe_catches"]
    slow = _walked(conn, draft(), {**CLEAN_WALK, "heel_strike_to_stance_ms_max": 80.0})
    v, kept = bench_verdict.require_bench(conn, "proposal", slow, None, "approved")
    assert v["status"] == "warnings" and kept is None


def test_a_fall_makes_the_version_unsafe_and_names_it(conn, draft):
    row = _walked(conn, draft(), {**CLEAN_WALK, "falls": 3})
    with pytest.raises(ConflictError, match="the leg gave way 3 time") as caught:
        bench_verdict.require_bench(conn, "proposal", row, None, "approved")
    assert caught.value.extra["bench"]["status"] == "unsafe"
