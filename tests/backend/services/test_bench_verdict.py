"""The bench's verdict on a version, and the gate approval and push rest on: every figure beyond its bound gates, and
going ahead anyway takes two prosthetists' sign-offs on exactly that content."""

from __future__ import annotations

import pytest

from backend.db import write_transaction
from backend.errors import ConflictError
from backend.services import bench_verdict
from backend.services import envelopes as envelope_versions
from backend.store import previews, signoffs, versions
from tests.backend.conftest import CLEAN_WALK

WHY = "seated in the bars, every row checked by hand"


def _walked(conn, pid, mine):
    row = versions.get_row(conn, "proposal", pid)
    previews.store_preview(conn, "proposal", pid, row["content_sha256"], {"seconds": 10.0, "controllers": {
        "table": mine, "fsmic": CLEAN_WALK}})
    return versions.get_row(conn, "proposal", pid)


def test_a_clean_walk_passes_alone(conn, draft, prosthetist):
    row = _walked(conn, draft(), CLEAN_WALK)
    v, kept = bench_verdict.require_bench(conn, "proposal", row, None, "pushed", prosthetist)
    assert v["status"] == "clean" and kept is None and v["words"] == "bench preview clean"
    assert [f["figure"] for f in v["figures"]][:2] == ["falls", "toe_catches"]


@pytest.mark.parametrize("figure, value", [("heel_strike_to_stance_ms_max", 80.0), ("hip_sink_max_mm", 87.0),
                                           ("stance_knee_flexion_peak_max_deg", 44.0), ("loaded_swing_ms_max_stride", 30.0),
                                           ("support_deficit_max_bw", 1.8), ("falls", 3)])
def test_every_figure_beyond_its_bound_gates_as_a_fall_does(conn, draft, prosthetist, figure, value):
    row = _walked(conn, draft(), {**CLEAN_WALK, figure: value})
    with pytest.raises(ConflictError, match="not approved: its bench preview shows") as caught:
        bench_verdict.require_bench(conn, "proposal", row, WHY, "approved", prosthetist)   # one person's reason
    assert caught.value.extra["bench"]["status"] == "unsafe"
    assert [f["figure"] for f in caught.value.extra["bench"]["flags"]] == [figure]
    assert "2 prosthetists' sign-offs" in caught.value.message and "nobody has signed off yet" in caught.value.message


def test_the_override_takes_two_accounts_each_with_its_reason_on_exactly_this_content(conn, draft, prosthetist,
                                                                                      colleague):
    row = _walked(conn, draft(), {**CLEAN_WALK, "falls": 2})
    with write_transaction(conn):
        signoffs.sign(conn, "proposal", row["id"], row["content_sha256"], prosthetist, WHY)
    with pytest.raises(ConflictError, match="already signed off"), write_transaction(conn):
        signoffs.sign(conn, "proposal", row["id"], row["content_sha256"], prosthetist, WHY + " again")
    with pytest.raises(ConflictError, match="signed off so far by pat"):    # the signer cannot be the second as well
        bench_verdict.require_bench(conn, "proposal", row, WHY, "approved", prosthetist)
    with write_transaction(conn):      # the colleague approves: their reason is the second sign-off, kept with it
        _, kept = bench_verdict.require_bench(conn, "proposal", row, "the falls are on the first step only", "approved",
                                              colleague)
    assert kept == f"pat: {WHY}; kim: the falls are on the first step only"
    assert [s["by"] for s in bench_verdict.verdict(conn, "proposal", row)["signoffs"]] == ["pat", "kim"]
    # a push of it still needs the pusher's own reason
    with pytest.raises(ConflictError, match="give override_reason"):
        bench_verdict.require_bench(conn, "proposal", row, None, "pushed", prosthetist)
    assert bench_verdict.require_bench(conn, "proposal", row, WHY, "pushed", prosthetist)[1] == kept
    # sign-offs on other content never count
    other = _walked(conn, draft('{"rows": [1]}'), {**CLEAN_WALK, "falls": 2})
    assert bench_verdict.verdict(conn, "proposal", other)["signoffs"] == []


def test_not_walked_is_refused_with_the_way_to_walk_it(conn, draft, prosthetist):
    row = versions.get_row(conn, "proposal", draft())
    assert bench_verdict.verdict(conn, "proposal", row)["status"] == "not_walked"
    with pytest.raises(ConflictError, match=r"not approved: its bench preview has not been walked.*GET /api/proposals"):
        bench_verdict.require_bench(conn, "proposal", row, None, "approved", prosthetist)


def test_a_version_worse_than_its_parent_on_the_bench_says_in_which_figures(conn, draft, prosthetist):
    """A refinement or an edit that the bench finds worse is not offered as an improvement: each figure it makes
    worse than its parent's, beyond the bench's resolution (any count; 10 ms, 5 mm, 1°), even within its bound."""
    parent = _walked(conn, draft('{"rows": [1]}'), {**CLEAN_WALK, "toe_catches": 0, "hip_sink_max_mm": 20.0})
    child_id = draft('{"rows": [2]}', parent_id=parent["id"])
    assert bench_verdict.verdict(conn, "proposal", versions.get_row(conn, "proposal", child_id))["worse_than_parent"] is None
    child = _walked(conn, child_id, {**CLEAN_WALK, "toe_catches": 1, "hip_sink_max_mm": 24.0,
                                     "heel_strike_to_stance_ms_max": CLEAN_WALK["heel_strike_to_stance_ms_max"] + 25})
    worse = bench_verdict.verdict(conn, "proposal", child)["worse_than_parent"]
    assert worse["walked"] and worse["parent_version"] == parent["version"]
    assert {f["figure"]: (f["parent_value"], f["value"]) for f in worse["figures"]} == {
        "toe_catches": (0, 1),
        "heel_strike_to_stance_ms_max": (CLEAN_WALK["heel_strike_to_stance_ms_max"],
                                         CLEAN_WALK["heel_strike_to_stance_ms_max"] + 25)}   # 4 mm: within resolution
    # better or equal everywhere: nothing said; a parent not walked yet: said so, nothing compared
    assert bench_verdict.verdict(conn, "proposal", parent)["worse_than_parent"] is None      # no parent of its own
    orphan = draft('{"rows": [3]}', parent_id=draft('{"rows": [4]}'))
    unwalked = bench_verdict.verdict(conn, "proposal", _walked(conn, orphan, CLEAN_WALK))["worse_than_parent"]
    assert unwalked["walked"] is False and unwalked["figures"] == []


def _envelope_walked(conn, model, patient, prosthetist, nodes):
    """An envelope whose stored preview walked the course clean, with these node walks (None: none, as stored before
    nodes were walked alone)."""
    created = envelope_versions.create_from_model(conn, patient["id"], model.propose_envelope([0.8, 1.4], [-5.0, 5.0], 80.0),
                                          prosthetist)
    row = versions.get_row(conn, "envelope", created["id"])
    result = {"course": {"name": "mixed"}, "controllers": {"envelope": CLEAN_WALK, "fsmic": CLEAN_WALK}}
    previews.store_preview(conn, "envelope", row["id"], row["content_sha256"],
                                    result if nodes is None else {**result, "nodes": nodes})
    return versions.get_row(conn, "envelope", row["id"])


def test_an_envelope_node_beyond_a_bound_gates_the_envelope_and_is_named(conn, model, patient, prosthetist):
    fall = {"figure": "falls", "severity": "bad", "value": 2, "fsmic_value": None, "unit": "falls",
            "message": "from standing: the leg gave way 2 time(s) on the simulated bench", "start": "standing"}
    nodes = [{"speed_mps": v, "incline_deg": g, "walks": {}, "flags": [fall] if (v, g) == (0.8, -5.0) else []}
             for v in (0.8, 1.4) for g in (-5.0, 5.0)]
    row = _envelope_walked(conn, model, patient, prosthetist, nodes)
    v = bench_verdict.verdict(conn, "envelope", row)
    assert v["status"] == "unsafe" and len(v["flags"]) == 1
    flag = v["flags"][0]
    assert (flag["node_speed_mps"], flag["node_incline_deg"], flag["start"]) == (0.8, -5.0, "standing")
    assert flag["message"] == "at 0.8 m/s, −5°, from standing: the leg gave way 2 time(s) on the simulated bench"
    assert {f["figure"]: f["value"] for f in v["figures"]}["nodes_beyond_bounds"] == 1
    with pytest.raises(ConflictError, match=r"at 0\.8 m/s, −5°, from standing: the leg gave way"):
        bench_verdict.require_bench(conn, "envelope", row, WHY, "approved", prosthetist)
    clean = _envelope_walked(conn, model, patient, prosthetist, [{**n, "flags": []} for n in nodes])
    assert bench_verdict.verdict(conn, "envelope", clean)["status"] == "clean"


def test_an_envelope_preview_without_node_walks_is_not_clean(conn, model, patient, prosthetist):
    """A preview stored before the nodes were walked alone judged part of the envelope: it gates until walked again."""
    row = _envelope_walked(conn, model, patient, prosthetist, None)
    v = bench_verdict.verdict(conn, "envelope", row)
    assert v["status"] == "unsafe" and [f["figure"] for f in v["flags"]] == ["nodes_walked"]
    assert "walk the preview again" in v["flags"][0]["message"]
