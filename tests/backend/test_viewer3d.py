"""The viser 3D view of the leg."""

from __future__ import annotations

import urllib.request

from tests.helpers.api import DEVICE, assign, wait_for


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
    assign(sim_api, patient["id"])
    r = c.post(f"/api/patients/{patient['id']}/sessions", headers=sim_api.as_("prosthetist"),
               json={"device_id": DEVICE, "speed_mps": 1.2})
    assert r.status_code == 201, r.text   # the simulated leg walks (and streams telemetry) during a session
    wait_for(lambda: c.get(f"/api/devices/{DEVICE}/viewer", headers=viewer).json(), lambda v: v["frames_drawn"] > 5,
             clock=sim_api.clock)
    assert c.get("/api/devices/nope/viewer", headers=viewer).status_code == 404


def test_the_3d_view_is_off_unless_the_server_was_started_with_it(tmp_path, model):
    from device_bridge.clock import SteppedClock
    from tests.helpers.api import make_api

    api, client = make_api(tmp_path, lambda: model, device="sim", clock=SteppedClock())   # as quasitune serve runs
    try:
        r = client.get("/api/devices/sim-leg-1/viewer", headers=api.as_("viewer"))
        assert r.status_code == 409 and "no login" in r.json()["detail"] and "--viewer3d" in r.json()["detail"]
        assert client.get("/api/devices/other/viewer", headers=api.as_("viewer")).status_code == 404
    finally:
        client.app.state.devices.close()


def test_asked_for_without_viser_installed_the_server_refuses_to_start_and_says_what_to_install(monkeypatch):
    """viser is an optional extra (``quasitune[view3d]``): a server started with the 3D view but without viser stops
    at once, loudly, instead of answering 500 when someone opens the view."""
    import importlib.util

    import pytest

    from backend.viewer3d import ViewerRegistry

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "viser" else real(name, *a))
    with pytest.raises(RuntimeError, match=r"quasitune\[view3d\]"):
        ViewerRegistry(devices=None)   # type: ignore[arg-type]
