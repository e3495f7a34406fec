"""The API pieces the dashboard draws from: via-points, the measured reference, the simulated preview, the
session report PDF, the viser 3D view and the served page itself (in-process; the browser tests drive them)."""

from __future__ import annotations

import json
import time
import urllib.request

import numpy as np
import pytest

from tests.api_helpers import make_api
from tests.test_api_devices import DEVICE, approved_proposal, wait_for


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


def test_reference_lists_the_measured_conditions_with_citations(api, reference):
    r = api.client.get("/api/reference", headers=api.as_("viewer"))
    assert r.status_code == 200, r.text
    body = r.json()
    assert len(body["conditions"]) == len(reference.records)
    first = body["conditions"][0]
    assert "Bovi" in first["citation"] and first["speed_mps"] > 0
    rec = reference.records[0]
    assert first["knee_angle_deg"][50] == pytest.approx(np.degrees(rec.mean["knee_angle"][50]), abs=1e-3)
    assert api.client.get("/api/reference").status_code == 401


def test_preview_walks_the_table_and_the_fsmic_once_and_keeps_it(api):
    prop = api.propose(api.new_patient()["id"], speed=1.2)
    c, viewer = api.client, api.as_("viewer")
    r = c.get(f"/api/proposals/{prop['id']}/preview", headers=viewer)
    assert r.status_code == 200, r.text
    first = r.json()
    assert first["table_sha256"] == prop["table_sha256"]
    assert set(first["controllers"]) == {"table", "fsmic"}
    for run in first["controllers"].values():
        assert run["seconds"] == pytest.approx(10.0, abs=0.01)
        assert set(run["mean_curves"]) <= set(first["reference_curves"])
    assert first["controllers"]["fsmic"]["strides"] >= 3   # the benchmark walks at its nominal task
    # how sure: each RMSE has its interval over strides, and the table's difference from the FSMIC its verdict
    table = first["controllers"]["table"]
    lo, hi = table["knee_angle_rmse_ci95_deg"]
    assert lo <= table["knee_angle_rmse_deg"] <= hi
    vs = table["vs_fsmic"]
    assert vs["knee_angle_rmse_difference_deg"] == pytest.approx(
        table["knee_angle_rmse_deg"] - first["controllers"]["fsmic"]["knee_angle_rmse_deg"])
    assert vs["knee_angle_verdict"] in {"learned lower", "FSMIC lower", "not resolved"}
    assert table["heel_strikes_without_stance"] == 0 and table["heel_strike_to_stance_ms_median"] >= 20.0
    assert len(first["phase_grid"]) == 101
    again = c.get(f"/api/proposals/{prop['id']}/preview", headers=viewer).json()
    assert again == first   # stored, not re-simulated (same created_at)
    with api.db() as conn:
        assert conn.execute("SELECT count(*) FROM proposal_previews").fetchone()[0] == 1
    assert c.get("/api/proposals/999/preview", headers=viewer).status_code == 404


def test_preview_made_from_another_table_is_refused(api):
    prop = api.propose(api.new_patient()["id"], speed=1.2)
    c, viewer = api.client, api.as_("viewer")
    assert c.get(f"/api/proposals/{prop['id']}/preview", headers=viewer).status_code == 200
    with api.db() as conn:
        conn.execute("UPDATE proposal_previews SET table_sha256 = ?", ("0" * 64,))
        conn.commit()
    r = c.get(f"/api/proposals/{prop['id']}/preview", headers=viewer)
    assert r.status_code == 409 and "another table" in r.json()["detail"]


def test_dashboard_page_and_vendor_packages_are_served(api):
    page = api.client.get("/")
    assert page.status_code == 200 and '<script type="module"' in page.text
    js = api.client.get("/vendor/uplot/uPlot.esm.js")
    assert js.status_code == 200 and "uPlot" in js.text
    assert api.client.get("/app/main.js").status_code == 200


def test_a_missing_npm_package_is_said_not_hidden(tmp_path, model):
    frontend = tmp_path / "frontend"
    (frontend / "app").mkdir(parents=True)
    (frontend / "index.html").write_text("<!doctype html>")
    api, _ = make_api(tmp_path / "data", lambda: model, frontend_dir=frontend)
    r = api.client.get("/")
    assert r.status_code == 503 and "npm ci" in r.text and "npm package uplot not installed" in r.text
    assert api.client.get("/api/health").status_code == 200   # the API works regardless


def test_a_missing_dashboard_folder_is_said_and_the_api_still_serves(tmp_path, model):
    api, _ = make_api(tmp_path / "data", lambda: model, frontend_dir=tmp_path / "nowhere")
    r = api.client.get("/")
    assert r.status_code == 503 and "no dashboard files" in r.text and "QUASITUNE_FRONTEND_DIR" in r.text
    assert api.client.get("/api/patients", headers=api.as_("viewer")).status_code == 200


@pytest.fixture
def sim_api(tmp_path, model):
    api, _client = make_api(tmp_path, lambda: model, device="sim")
    yield api
    api.client.app.state.viewers.close()
    api.client.app.state.devices.close()


def test_viewer_binds_loopback_on_a_port_it_reads_back_and_follows_telemetry(sim_api):
    c, viewer = sim_api.client, sim_api.as_("viewer")
    r = c.get(f"/api/devices/{DEVICE}/viewer", headers=viewer)
    assert r.status_code == 200, r.text
    info = r.json()
    assert info["host"] == "127.0.0.1" and info["port"] > 0 and info["url"] == f"http://127.0.0.1:{info['port']}/"
    with urllib.request.urlopen(info["url"], timeout=5) as page:   # viser's own client page, on that port
        assert page.status == 200 and b"<html" in page.read().lower()
    assert c.get(f"/api/devices/{DEVICE}/viewer", headers=viewer).json()["port"] == info["port"]   # one per device
    patient = sim_api.new_patient()
    r = c.post(f"/api/patients/{patient['id']}/sessions", headers=viewer, json={"device_id": DEVICE, "speed_mps": 1.2})
    assert r.status_code == 201, r.text   # the simulated leg walks (and streams telemetry) during a session
    wait_for(lambda: c.get(f"/api/devices/{DEVICE}/viewer", headers=viewer).json(), lambda v: v["frames_drawn"] > 5)
    assert c.get("/api/devices/nope/viewer", headers=viewer).status_code == 404


def test_session_report_pdf(sim_api):
    api = sim_api
    c, pro = api.client, api.as_("prosthetist")
    prop = approved_proposal(api)
    assert c.post(f"/api/proposals/{prop['id']}/push", headers=pro, json={"device_id": DEVICE}).status_code == 201
    session = c.post(f"/api/patients/{prop['patient_id']}/sessions", headers=pro, json={"device_id": DEVICE}).json()
    early = c.get(f"/api/sessions/{session['id']}/report.pdf", headers=pro)
    assert early.status_code == 409 and "still recording" in early.json()["detail"]
    time.sleep(2.5)
    assert c.post(f"/api/sessions/{session['id']}/stop", headers=pro).status_code == 200
    r = c.get(f"/api/sessions/{session['id']}/report.pdf", headers=api.as_("viewer"))
    assert r.status_code == 200 and r.headers["content-type"] == "application/pdf"
    assert r.content.startswith(b"%PDF") and len(r.content) > 5000
    assert f"session-{session['id']}.pdf" in r.headers["content-disposition"]
    json.dumps(c.get(f"/api/sessions/{session['id']}", headers=pro).json())
