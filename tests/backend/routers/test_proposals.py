"""Proposals: request, read, edit, diff, approve, reject."""

from __future__ import annotations

import asyncio
import threading

import httpx
import numpy as np
import pytest
from sqlalchemy.exc import IntegrityError

from backend.db import write_transaction
from backend.services import proposals as proposal_versions
from backend.store import versions
from backend.store.users import User
from tests.helpers.api import walk_preview
from tests.helpers.sql import drop_trigger, sql


# ------------------------------------------------------------- proposals
def test_proposal_carries_features_curves_table_units_and_provenance(api, model):
    patient = api.new_patient(mass=80.0)
    p = api.propose(patient["id"], speed=1.3, incline=2.0)
    assert p["status"] == "draft" and p["version"] == 1 and p["source"] == "model" and p["created_by"] == "prosthetist"
    assert p["task"] == {"speed_mps": 1.3, "incline_deg": 2.0, "body_mass_kg": 80.0}
    direct = model.propose(1.3, 2.0, 80.0)
    for row, ref in zip(p["table"], direct.table.rows, strict=True):
        assert row["k_Nm_per_rad"] == pytest.approx(ref.k_Nm_per_rad, abs=1e-3)
        assert row["k_Nm_per_deg"] == pytest.approx(ref.k_Nm_per_rad * 3.141592653589793 / 180, abs=1e-4)
        assert row["theta_e_deg"] == pytest.approx(ref.theta_e_deg, abs=5e-3)   # as run: to the wire's 0.01°
    assert len(p["curves"]["knee_angle_deg"]) == 101 and len(p["curves"]["knee_angle_deg_std"]) == 101
    assert {f["unit"] for f in p["features"]} >= {"deg", "N·m/kg"}
    assert p["safety"] == {"ok": True, "violations": []}
    assert p["model"]["version"] == model.model_version and len(p["model"]["data_sha256"]) == 64
    assert p["limits"]["k_Nm_per_rad"] == {"low": -1200.0, "high": 200.0}
    listed = api.client.get(f"/api/patients/{patient['id']}/proposals", headers=api.as_("viewer")).json()
    assert [x["id"] for x in listed] == [p["id"]] and "curves" not in listed[0]


def test_a_new_proposal_answer_is_exactly_its_schema_and_what_is_stored(api):
    from backend.schemas.versions import ProposalOut

    patient = api.new_patient()
    r = api.client.post(f"/api/patients/{patient['id']}/proposals", headers=api.as_("prosthetist"),
                        json={"speed_mps": 1.1, "incline_deg": 3.0})
    assert r.status_code == 201 and r.headers["content-type"] == "application/json"
    answer = r.json()
    assert answer == ProposalOut.model_validate(answer).model_dump(mode="json")     # no extra, none missing
    stored = api.client.get(f"/api/proposals/{answer['id']}", headers=api.as_("viewer")).json()
    assert answer == stored


def test_concurrent_proposals_are_each_stored_with_consecutive_versions(api):
    patient = api.new_patient()
    app = api.client.app

    async def main() -> list[httpx.Response]:
        async with httpx.AsyncClient(transport=httpx.ASGITransport(app=app), base_url="http://test") as client:
            return await asyncio.gather(*(
                client.post(f"/api/patients/{patient['id']}/proposals", headers=api.as_("prosthetist"),
                            json={"speed_mps": 0.8 + 0.1 * i}) for i in range(6)))

    answers = asyncio.run(main())
    assert [r.status_code for r in answers] == [201] * 6
    assert sorted(r.json()["version"] for r in answers) == [1, 2, 3, 4, 5, 6]
    stored = {r.json()["id"]: r.json()["task"]["speed_mps"] for r in answers}
    for pid, speed in stored.items():      # each answer is its own stored row
        assert api.client.get(f"/api/proposals/{pid}", headers=api.as_("viewer")).json()["task"]["speed_mps"] == speed
    actions = [e["action"] for e in api.client.get("/api/audit", headers=api.as_("prosthetist")).json()["items"]]
    assert actions.count("proposal.create") == 6


def test_task_outside_the_data_is_flagged_with_larger_std(api):
    patient = api.new_patient()
    inside = api.propose(patient["id"], speed=1.2)
    outside = api.propose(patient["id"], speed=2.2)   # beyond the data (1.95 m/s), within the margin
    assert inside["extrapolation"] is False and outside["extrapolation"] is True
    assert outside["extrapolation_reason"] is None
    sd_in = {f["name"]: f["std"] for f in inside["features"]}
    sd_out = {f["name"]: f["std"] for f in outside["features"]}
    assert sd_out["knee_swing_flexion_peak"] > sd_in["knee_swing_flexion_peak"]


@pytest.mark.parametrize(("body", "field"), [
    ({"speed_mps": 0}, "speed_mps"), ({"speed_mps": -1.2}, "speed_mps"), ({"speed_mps": 3.5}, "speed_mps"),
    ({"speed_mps": 1.2, "incline_deg": 25}, "incline_deg"), ({"incline_deg": 2}, "speed_mps"),
    ({"speed_mps": "fast"}, "speed_mps"), ({"speed_mps": 1e-320}, "speed_mps"), ({"speed_mps": 0.05}, "speed_mps"),
])
def test_bad_task_is_refused_and_nothing_stored(api, body, field):
    patient = api.new_patient()
    r = api.client.post(f"/api/patients/{patient['id']}/proposals", headers=api.as_("prosthetist"), json=body)
    words = {"speed_mps": "speed", "incline_deg": "incline"}[field]
    assert r.status_code == 422 and words in r.json()["detail"]                 # in words on the page
    assert field in [e["field"] for e in r.json()["errors"]]                     # by its code for scripts
    assert api.count("proposals") == 0


def test_edit_makes_a_new_version_and_diff_lists_the_cells(api):
    patient = api.new_patient()
    v1 = api.propose(patient["id"])
    r = api.client.post(f"/api/proposals/{v1['id']}/edits", headers=api.as_("prosthetist"), json={
        "rows": [{"joint": "knee", "subphase": "stance_flexion", "k_Nm_per_rad": -250.0},
                 {"joint": "ankle", "subphase": "swing_extension", "b_Nm_s_per_rad": 2.5}],
        "thresholds": {"we_to_sf_load_N": 150.0}, "comment": "patient felt the knee buckle"})
    assert r.status_code == 201, r.text
    v2 = r.json()
    assert v2["version"] == 2 and v2["parent_id"] == v1["id"] and v2["source"] == "edit" and v2["status"] == "draft"
    knee_sf = next(x for x in v2["table"] if x["joint"] == "knee" and x["subphase"] == "stance_flexion")
    assert knee_sf["k_Nm_per_rad"] == -250.0 and knee_sf["fit_method"] == "manual" and knee_sf["r2"] is None
    ankle_we = next(x for x in v2["table"] if x["joint"] == "ankle" and x["subphase"] == "swing_extension")
    assert ankle_we["b_Nm_s_per_rad"] == 2.5 and ankle_we["fit_method"] != "manual"   # damping only: still a fit
    assert v2["curves"] == v1["curves"] and v2["table_sha256"] != v1["table_sha256"]
    diff = api.client.get(f"/api/proposals/{v1['id']}/diff/{v2['id']}", headers=api.as_("viewer")).json()
    fields = {c["field"]: c for c in diff["changes"]}
    assert set(fields) == {"knee.stance_flexion.k_Nm_per_rad", "knee.stance_flexion.fit_method",
                           "ankle.swing_extension.b_Nm_s_per_rad", "thresholds.we_to_sf_load_N"}
    assert fields["knee.stance_flexion.k_Nm_per_rad"]["after"] == -250.0
    assert fields["knee.stance_flexion.k_Nm_per_rad"]["unit"] == "N·m/rad"
    # the parent is untouched
    again = api.client.get(f"/api/proposals/{v1['id']}", headers=api.as_("viewer")).json()
    assert again["table"] == v1["table"] and again["table_sha256"] == v1["table_sha256"]


def test_the_stumble_support_is_shown_with_its_limits_and_edited_like_any_threshold(api):
    patient = api.new_patient()
    v1 = api.propose(patient["id"])
    assert v1["thresholds"]["stumble_knee_margin_deg"] == 15.0 and v1["thresholds"]["fold_window_of_stance_pct"] == 50.0
    assert v1["limits"]["fold_knee_rate_deg_per_s"] == {"low": 60.0, "high": 300.0}
    assert v1["thresholds"]["early_landing_swing_pct"] == 80.0 and v1["thresholds"]["forefoot_landing_pct"] == 50.0
    assert v1["limits"]["early_landing_swing_pct"] == {"low": 50.0, "high": 95.0}
    r = api.client.post(f"/api/proposals/{v1['id']}/edits", headers=api.as_("prosthetist"), json={
        "thresholds": {"stumble_knee_margin_deg": 12.0, "fold_knee_rate_deg_per_s": 110.0,
                       "forefoot_landing_pct": 60.0},
        "comment": "catch a stalled knee sooner"})
    assert r.status_code == 201, r.text
    v2 = r.json()
    assert v2["thresholds"]["stumble_knee_margin_deg"] == 12.0 and v2["thresholds"]["fold_knee_rate_deg_per_s"] == 110.0
    assert v2["thresholds"]["forefoot_landing_pct"] == 60.0
    diff = api.client.get(f"/api/proposals/{v1['id']}/diff/{v2['id']}", headers=api.as_("viewer")).json()
    units = {c["field"]: c["unit"] for c in diff["changes"]}
    assert units == {"thresholds.stumble_knee_margin_deg": "deg", "thresholds.fold_knee_rate_deg_per_s": "deg/s",
                     "thresholds.forefoot_landing_pct": "%"}


@pytest.mark.parametrize(("edit", "words"), [
    ({"rows": [{"joint": "knee", "subphase": "stance_flexion", "k_Nm_per_rad": -5000}]},
     "knee.stance_flexion.k_Nm_per_rad = -5000 N·m/rad is outside [-1200, 0]"),
    ({"rows": [{"joint": "knee", "subphase": "stance_flexion", "k_Nm_per_rad": 150}]},
     "knee stance flexion: k = +150 N·m/rad pushes the joint instead of resisting it (the knee gives way"),
    # valid as typed, but the device runs millisecond state times: 1.49951 s becomes 1.500 s, equal to the maximum
    ({"thresholds": {"min_state_time_s": 1.49951, "max_state_time_s": 1.5}},
     "as the device will run it (rounded to the wire's precision): thresholds.min_state_time_s must be below"),
    ({"rows": [{"joint": "ankle", "subphase": "swing_flexion", "theta_e_deg": 45}]}, "is outside [-30, 30] deg"),
    ({"thresholds": {"min_state_time_s": 2.0}}, "must be below max_state_time_s"),
    ({"thresholds": {"fold_knee_rate_deg_per_s": 40.0}}, "fold_knee_rate_deg_per_s = 40 deg/s is outside [60, 300]"),
    ({"rows": [{"joint": "knee", "subphase": "stance_flexion", "b_Nm_s_per_rad": -1}]}, "b_Nm_s_per_rad = -1"),
    ({"rows": []}, "changes nothing"),
    ({"rows": [{"joint": "knee", "subphase": "stance_flexion", "k_Nm_per_rad": -100},
               {"joint": "knee", "subphase": "stance_flexion", "theta_e_deg": 5}]}, "edited twice"),
])
def test_unsafe_or_empty_edit_is_refused_and_nothing_stored(api, edit, words):
    patient = api.new_patient()
    v1 = api.propose(patient["id"])
    before = (api.count("proposals"), api.count("audit_log"))
    r = api.client.post(f"/api/proposals/{v1['id']}/edits", headers=api.as_("prosthetist"),
                        json={**edit, "comment": "try"})
    assert r.status_code == 422 and words in r.json()["detail"], r.json()
    assert (api.count("proposals"), api.count("audit_log")) == before


def test_approve_once_then_immutable(api):
    patient = api.new_patient()
    p = api.propose(patient["id"])
    walk_preview(api, p["id"])   # approval rests on the bench
    for body in ({}, {"comment": ""}, {"comment": "   "}):                   # a decision needs its reason
        r = api.client.post(f"/api/proposals/{p['id']}/approve", headers=api.as_("prosthetist"), json=body)
        assert r.status_code == 422 and "comment" in r.text
    assert api.client.get(f"/api/proposals/{p['id']}", headers=api.as_("viewer")).json()["status"] == "draft"
    walk_preview(api, p["id"])   # approval rests on the bench
    r = api.client.post(f"/api/proposals/{p['id']}/approve", headers=api.as_("prosthetist"),
                        json={"comment": "matches the gait lab"})
    assert r.status_code == 200
    d = r.json()["decision"]
    assert d["status"] == "approved" and d["by"] == "prosthetist" and d["comment"] == "matches the gait lab"
    for action in ("approve", "reject"):
        again = api.client.post(f"/api/proposals/{p['id']}/{action}", headers=api.as_("prosthetist"),
                                json={"comment": "again"})
        assert again.status_code == 409 and "already approved" in again.json()["detail"]
    conn = api.db()
    with pytest.raises(IntegrityError, match="immutable"):
        sql(conn, "UPDATE versions SET content_json = '{}' WHERE id = :id", id=p["id"])
    with pytest.raises(IntegrityError, match="already been approved"):
        sql(conn, "UPDATE versions SET status = 'draft' WHERE id = :id", id=p["id"])
    with pytest.raises(IntegrityError, match="never deleted"):
        sql(conn, "DELETE FROM versions")
    with pytest.raises(IntegrityError, match="append-only"):
        sql(conn, "DELETE FROM audit_log")
    with pytest.raises(IntegrityError, match="append-only"):
        sql(conn, "UPDATE audit_log SET actor_name = 'someone else'")
    conn.close()
    # editing an approved proposal derives a new draft; the approved one stays as it was
    v2 = api.client.post(f"/api/proposals/{p['id']}/edits", headers=api.as_("prosthetist"), json={
        "rows": [{"joint": "knee", "subphase": "swing_flexion", "b_Nm_s_per_rad": 1.0}], "comment": "more damping"})
    assert v2.status_code == 201 and v2.json()["status"] == "draft"
    assert api.client.get(f"/api/proposals/{p['id']}", headers=api.as_("viewer")).json()["status"] == "approved"


def test_reject_records_the_comment(api):
    p = api.propose(api.new_patient()["id"])
    r = api.client.post(f"/api/proposals/{p['id']}/reject", headers=api.as_("prosthetist"),
                        json={"comment": "swing too stiff"})
    assert r.status_code == 200 and r.json()["decision"]["status"] == "rejected"
    entry = api.client.get("/api/audit", headers=api.as_("prosthetist"), params={"entity": "proposal"}).json()["items"][0]
    assert entry["action"] == "proposal.reject" and entry["after"]["comment"] == "swing too stiff"


def test_approval_rechecks_the_limits_of_the_stored_table(api, model):
    """Layered safety: a draft whose table is outside the limits (stored here behind the API's back, as a
    corrupted or legacy row would be) cannot be approved."""
    patient = api.new_patient()
    proposal = model.propose(1.2, 0.0, 80.0)
    row = proposal.table.rows[0]
    bad_row = row.model_copy(update={"k_Nm_per_rad": -3000.0})
    bad_table = proposal.table.model_copy(update={"rows": [bad_row, *proposal.table.rows[1:]]})
    proposal.table = bad_table
    conn = api.db()
    stored = proposal_versions.create_from_model(conn, patient["id"], proposal, User(1, "prosthetist", "prosthetist"))
    conn.close()
    assert stored["safety"]["ok"] is False
    assert api.client.get(f"/api/proposals/{stored['id']}/preview", headers=api.as_("viewer")).status_code == 409
    r = api.client.post(f"/api/proposals/{stored['id']}/approve", headers=api.as_("prosthetist"),
                        json={"comment": "ok", "override_reason": "an override never passes a limit"})
    assert r.status_code == 409 and "outside the safety limits" in r.json()["detail"]
    assert r.json()["violations"][0]["field"] == "knee.stance_flexion.k_Nm_per_rad"
    assert api.client.get(f"/api/proposals/{stored['id']}", headers=api.as_("viewer")).json()["status"] == "draft"


def test_tampered_table_is_refused_at_approval(api):
    p = api.propose(api.new_patient()["id"])
    conn = api.db()
    with write_transaction(conn):   # simulate on-disk corruption: drop the trigger, change one byte
        drop_trigger(conn, "versions_content_immutable", "versions")
        sql(conn, "UPDATE versions SET content_json = replace(content_json, '\"knee\"', '\"knee\" ') WHERE id = :id",
            id=p["id"])
    conn.close()
    r = api.client.post(f"/api/proposals/{p['id']}/approve", headers=api.as_("prosthetist"), json={"comment": "ok"})
    assert r.status_code == 409 and "sha256" in r.json()["detail"]


def test_versions_stay_unique_under_concurrent_edits(api):
    p = api.propose(api.new_patient()["id"])
    errors: list[int] = []

    def edit(i: int) -> None:
        r = api.client.post(f"/api/proposals/{p['id']}/edits", headers=api.as_("prosthetist"), json={
            "rows": [{"joint": "knee", "subphase": "swing_flexion", "b_Nm_s_per_rad": 1.0 + i / 10}],
            "comment": f"edit {i}"})
        if r.status_code != 201:
            errors.append(r.status_code)

    threads = [threading.Thread(target=edit, args=(i,)) for i in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
    versions = [x["version"] for x in api.client.get(f"/api/patients/{p['patient_id']}/proposals",
                                                     headers=api.as_("viewer")).json()]
    assert sorted(versions) == list(range(1, 10))


def test_proposal_carries_its_via_points_on_its_curves(api):
    prop = api.propose(api.new_patient()["id"], speed=1.4, incline=0.0)
    vias = prop["via_points"]
    assert {v["joint"] for v in vias} == {"knee", "ankle"}
    curves = prop["curves"]
    for v in vias:
        # KMP passes through its via-points (within the tolerance of its grid and the features' SD)
        angle = np.interp(v["phase"], curves["phase"], curves[f"{v['joint']}_angle_deg"])
        assert abs(angle - v["angle_deg"]) < 3.0
    features = {(f["joint"], round(f["phase"], 3)) for f in prop["features"] if f["quantity"] in ("angle", "moment")}
    assert {(v["joint"], round(v["phase"], 3)) for v in vias} <= features


# ------------------------------------------------------------- exactly what runs
def test_a_value_within_half_a_wire_step_of_a_limit_is_stored_shown_and_approved_as_the_device_runs_it(api):
    """+0.000316 N·m/rad on a stance row rounds to 0 on the wire: it is stored and shown as 0.0, never as a value
    outside the limit that the preview then refuses to walk."""
    from device_bridge.envelope_wire import table_wire
    from tests.helpers.device import assert_same_as_device

    p = api.propose(api.new_patient()["id"], speed=1.2)
    r = api.client.post(f"/api/proposals/{p['id']}/edits", headers=api.as_("prosthetist"), json={
        "rows": [{"joint": "knee", "subphase": "stance_extension", "k_Nm_per_rad": 0.000316,
                  "theta_e_deg": 4.00049}],
        "thresholds": {"min_state_time_s": 0.0500004}, "comment": "rounding check"})
    assert r.status_code == 201, r.text
    v2 = r.json()
    row = next(x for x in v2["table"] if (x["joint"], x["subphase"]) == ("knee", "stance_extension"))
    assert row["k_Nm_per_rad"] == 0.0 and row["theta_e_deg"] == 4.0 and v2["thresholds"]["min_state_time_s"] == 0.05
    assert v2["safety"]["ok"]
    conn = api.db()
    try:
        stored = versions.stored_table(versions.get_row(conn, "proposal", v2["id"]))
    finally:
        conn.close()
    assert_same_as_device(stored, table_wire(stored).to_device().tables[0])
    assert api.client.get(f"/api/proposals/{v2['id']}/preview", headers=api.as_("viewer")).status_code == 200


@pytest.mark.parametrize("value", [1e306, 1.79e308, -1e306])
@pytest.mark.parametrize("where", ["row", "threshold"])
def test_a_huge_finite_value_is_refused_at_the_schema_naming_the_field(api, value, where):
    p = api.propose(api.new_patient()["id"], speed=1.2)
    body = ({"rows": [{"joint": "knee", "subphase": "swing_flexion", "b_Nm_s_per_rad": value}]} if where == "row"
            else {"thresholds": {"se_to_wf_load_N": value}})
    before = api.count("proposals")
    r = api.client.post(f"/api/proposals/{p['id']}/edits", headers=api.as_("prosthetist"),
                        json={**body, "comment": "overflow"})
    assert r.status_code == 422, r.text
    text = r.text
    assert ("b_Nm_s_per_rad" if where == "row" else "se_to_wf_load_N") in text and "10000" in text
    assert api.count("proposals") == before
    assert api.client.get("/api/health").status_code == 200   # the connection and the server carry on


def test_the_version_list_is_paged_summaries_with_the_total_and_a_cursor(api):
    patient = api.new_patient()
    ids = [api.propose(patient["id"], speed=0.9 + 0.1 * i)["id"] for i in range(5)]
    h = api.as_("viewer")
    r = api.client.get(f"/api/patients/{patient['id']}/proposals", headers=h, params={"limit": 2})
    assert r.status_code == 200 and r.headers["X-Total-Count"] == "5"
    page = r.json()
    assert [p["version"] for p in page] == [5, 4] and "curves" not in page[0] and "table" not in page[0]
    assert page[0]["safety_ok"] is True and page[0]["table_label"] == "P-001 · table v5"
    seen = [p["id"] for p in page]
    while "X-Next-Before-Version" in r.headers:
        r = api.client.get(f"/api/patients/{patient['id']}/proposals", headers=h,
                           params={"limit": 2, "before_version": r.headers["X-Next-Before-Version"]})
        seen += [p["id"] for p in r.json()]
    assert seen == ids[::-1]
    assert api.client.get(f"/api/patients/{patient['id']}/proposals", headers=h).headers["X-Total-Count"] == "5"
    assert api.client.get(f"/api/patients/{patient['id']}/proposals", headers=h,
                          params={"limit": 201}).status_code == 422


def test_a_server_on_a_heavier_leg_proposes_swing_rows_for_that_leg(tmp_path, model):
    from device_bridge.sim.leg_file import LEGS_DIR, load_leg
    from device_bridge.sim.swing_inertia import swing_inertia_ratio
    from tests.helpers.api import make_api

    api, client = make_api(tmp_path, lambda: model, bench_leg=LEGS_DIR / "heavy_foot.json")
    ratio = swing_inertia_ratio(load_leg("heavy_foot"))
    with client:
        patient = api.new_patient(mass=75.0)
        p = api.propose(patient["id"], speed=1.3, incline=0.0)
        r = client.post(f"/api/patients/{patient['id']}/envelopes", headers=api.as_("prosthetist"),
                        json={"speed_range_mps": [1.0, 1.4], "incline_range_deg": [-4, 4], "grid": [2, 2]})
        assert r.status_code == 201, r.text
    for_leg, plain = model.propose(1.3, 0.0, 75.0, swing_inertia_ratio=ratio).table, model.propose(1.3, 0.0, 75.0).table
    knee_swing = [i for i, row in enumerate(plain.rows) if (row.joint, row.subphase) == ("knee", "swing_extension")]
    for row, ref in zip(p["table"], for_leg.rows, strict=True):
        assert row["k_Nm_per_rad"] == pytest.approx(ref.k_Nm_per_rad, abs=1e-3)
        assert row["b_Nm_s_per_rad"] == pytest.approx(ref.b_Nm_s_per_rad, abs=5e-3)   # as run: to 0.01
    assert p["table"][knee_swing[0]]["k_Nm_per_rad"] < plain.rows[knee_swing[0]].k_Nm_per_rad - 10.0   # firmer
    assert p["swing_inertia"] == {"knee_ratio": round(ratio[0], 4), "ankle_ratio": round(ratio[1], 4),   # and says so
                                  "scaled_rows": ["knee.swing_extension", "ankle.swing_flexion", "ankle.swing_extension"]}
    envelope = model.propose_envelope([1.0, 1.4], [-4.0, 4.0], 75.0, swing_inertia_ratio=ratio)
    assert r.json()["swing_inertia"] == p["swing_inertia"]
    stored = [n["table"] for n in r.json()["nodes"]]                  # as the device runs it: to the wire's steps
    assert [t[knee_swing[0]]["b_Nm_s_per_rad"] for t in stored] == pytest.approx(
        [n.table.rows[knee_swing[0]].b_Nm_s_per_rad for n in envelope.nodes], abs=0.01)
