"""Walking sessions and their report."""

from __future__ import annotations

import json

from backend.report import report_facts
from tests.helpers.api import DEVICE, approved_proposal, push_to_leg, wait_for, wait_recorded


def _walking(api) -> tuple[dict, dict]:
    """An approved table pushed to the simulated leg and a session started on it: (the proposal, the session)."""
    prop = approved_proposal(api)
    assert push_to_leg(api, prop).status_code == 201
    started = api.client.post(f"/api/patients/{prop['patient_id']}/sessions", headers=api.as_("prosthetist"),
                              json={"device_id": DEVICE})
    assert started.status_code == 201, started.text
    return prop, started.json()


def test_session_report_pdf(sim_api):
    api = sim_api
    c, pro = api.client, api.as_("prosthetist")
    prop, session = _walking(api)
    early = c.get(f"/api/sessions/{session['id']}/report.pdf", headers=pro)
    assert early.status_code == 409 and "still recording" in early.json()["detail"]
    wait_recorded(api, session["id"], 2.5)
    assert c.post(f"/api/sessions/{session['id']}/stop", headers=pro).status_code == 200
    r = c.get(f"/api/sessions/{session['id']}/report.pdf", headers=api.as_("viewer"))
    assert r.status_code == 200 and r.headers["content-type"] == "application/pdf"
    assert r.content.startswith(b"%PDF") and len(r.content) > 5000
    assert f"session-{session['id']}.pdf" in r.headers["content-disposition"]
    stopped = c.get(f"/api/sessions/{session['id']}", headers=pro).json()
    assert json.loads(json.dumps(stopped, allow_nan=False)) == stopped      # plain JSON, no NaN, round-trips
    # 2.5 s is two strides or so: the headline says so instead of showing a figure to trust, here and in the PDF
    head = stopped["summary"]["headline"]
    assert head["strides_scored"] < 5 and not head["enough_strides"] and head["against"] == "the session's task"
    facts = dict(report_facts(stopped, c.get(f"/api/patients/{prop['patient_id']}", headers=pro).json()))
    assert facts["Angle error per stride"].startswith("too few strides to judge")
    assert facts["Task"].startswith(stopped["task_words"]) and stopped["task_words"] == "1.20 m/s, incline +0.0°"


def test_the_raw_telemetry_exports_as_csv_and_parquet_sample_for_sample(sim_api):
    import csv
    import io

    import pyarrow.parquet as pq

    api = sim_api
    c, pro = api.client, api.as_("prosthetist")
    _prop, session = _walking(api)
    wait_recorded(api, session["id"], 1.0)
    assert c.post(f"/api/sessions/{session['id']}/stop", headers=pro).status_code == 200
    cols = c.get(f"/api/sessions/{session['id']}/samples", headers=pro).json()["columns"]
    r = c.get(f"/api/sessions/{session['id']}/samples.csv", headers=api.as_("viewer"))
    assert r.status_code == 200 and r.headers["content-type"].startswith("text/csv")
    assert f"quasitune-session-{session['id']}-samples.csv" in r.headers["content-disposition"]
    rows = list(csv.reader(io.StringIO(r.text)))
    assert rows[0] == list(cols) and "knee_angle_deg" in rows[0] and len(rows) - 1 == len(cols["seq"]) >= 100
    knee = rows[0].index("knee_angle_deg")
    assert [float(x[knee]) for x in rows[1:]] == cols["knee_angle_deg"]          # the same numbers, in degrees
    p = c.get(f"/api/sessions/{session['id']}/samples.parquet", headers=pro)
    assert p.status_code == 200 and p.content.startswith(b"PAR1")
    table = pq.read_table(io.BytesIO(p.content))
    assert table.column_names == list(cols) and table.column("seq").to_pylist() == cols["seq"]
    assert table.column("mode").to_pylist() == cols["mode"]
    meta = {k.decode(): v.decode() for k, v in table.schema.metadata.items() if k.startswith(b"quasitune.")}
    assert meta["quasitune.session_id"] == str(session["id"]) and meta["quasitune.simulated"] == "True"
    assert c.get(f"/api/sessions/{session['id']}/samples.xlsx", headers=pro).status_code == 422   # said, not guessed
    assert c.get("/api/sessions/999999/samples.csv", headers=pro).status_code == 404


def test_strides_in_safe_mode_are_marked_and_left_out_of_the_errors(sim_api):
    api = sim_api
    c, pro = api.client, api.as_("prosthetist")
    _prop, session = _walking(api)
    modes = lambda: c.get(f"/api/sessions/{session['id']}/samples", headers=pro).json()["columns"]["mode"]  # noqa: E731
    wait_for(modes, lambda m: m.count("active") >= 250, 30, clock=api.clock)   # 2.5 s of walking, by the device's clock
    assert c.post(f"/api/devices/{DEVICE}/commands", headers=pro, json={"command": "enter_safe_mode"}).status_code == 202
    wait_for(modes, lambda m: m.count("safe") >= 150, 30, clock=api.clock)                   # 1.5 s in safe mode
    c.post(f"/api/devices/{DEVICE}/commands", headers=pro, json={"command": "leave_safe_mode"})
    safe_when_left = wait_for(lambda: c.get(f"/api/devices/{DEVICE}", headers=pro).json(),
                              lambda d: d["mode"] == "active", clock=api.clock)
    safe_seen = modes().count("safe")
    assert safe_when_left["mode"] == "active"
    wait_for(modes, lambda m: len(m) - m.index("safe") - m.count("safe") >= 250, 30, clock=api.clock)   # 2.5 s walking again
    summary = c.post(f"/api/sessions/{session['id']}/stop", headers=pro).json()["summary"]
    period = summary["sample_period_s"]
    # what the device reported, not a clock; the stored samples trail the live ones by one recorder flush (25)
    assert 1.5 <= summary["mode_s"]["safe"] <= (safe_seen + 60) * period
    assert summary["off_table_s"] >= summary["mode_s"]["safe"]
    assert summary["strides_off_table"] >= 1 and summary["strides_scored"] == summary["strides"] - summary[
        "strides_off_table"] >= 1
    cols = c.get(f"/api/sessions/{session['id']}/samples", headers=pro).json()["columns"]
    assert "safe" in cols["mode"] and "active" in cols["mode"]                   # every sample says its mode
    pdf = c.get(f"/api/sessions/{session['id']}/report.pdf", headers=pro)
    assert pdf.status_code == 200 and pdf.content.startswith(b"%PDF")


def test_a_viewer_watches_but_neither_starts_nor_stops_a_session(sim_api):
    """Starting a session sets the simulated patient walking: the prosthetist's, as stopping is."""
    api = sim_api
    prop = approved_proposal(api)
    assert push_to_leg(api, prop).status_code == 201
    url = f"/api/patients/{prop['patient_id']}/sessions"
    r = api.client.post(url, headers=api.as_("viewer"), json={"device_id": DEVICE})
    assert r.status_code == 403 and "prosthetist" in r.json()["detail"]
    assert api.count("walking_sessions") == 0
    session = api.client.post(url, headers=api.as_("prosthetist"), json={"device_id": DEVICE}).json()
    assert session["simulated"] is True                     # the simulated leg's walk says so, wherever it is shown
    assert api.client.post(f"/api/sessions/{session['id']}/stop", headers=api.as_("viewer")).status_code == 403
    assert api.client.get(f"/api/sessions/{session['id']}", headers=api.as_("viewer")).json()["status"] == "recording"
