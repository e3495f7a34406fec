"""Guided calibration from the monitor, in Chromium: a real leg (a stand with a reversed, offset knee sensor and a
reversed, offset load cell: tests/helpers/stand.py) on a CAN bus, a real server on a thread of this process (the bus is
python-can's in-process ``virtual`` one), the prosthetist following the page's prompts while the test holds the poses
they ask for. A refused step shows the leg's reason and is measured again; kept, the leg says it is calibrated."""

from __future__ import annotations

import threading

import can
import httpx
import pytest
import uvicorn

from backend.serve import bind
from device_bridge.device_node import DeviceNode
from tests.helpers.api import make_api
from tests.helpers.browser import shot, sign_in
from tests.helpers.device import until
from tests.helpers.stand import Stand

CHANNEL = "quasitune-calibration-flow"
DEVICE = f"virtual-{CHANNEL}"
MASS_KG = 72.0


@pytest.fixture
def leg_and_server(tmp_path, model, migrated_sqlite):
    stand = Stand()
    node = DeviceNode(can.Bus(interface="virtual", channel=CHANNEL), leg=stand, calibration=stand.port(50)).start()
    api, _client = make_api(tmp_path, lambda: model, template=migrated_sqlite, device=f"virtual:{CHANNEL}")
    listener = bind("127.0.0.1", 0)
    server = uvicorn.Server(uvicorn.Config(api.client.app, log_level="warning"))
    thread = threading.Thread(target=server.run, kwargs={"sockets": [listener]}, daemon=True)
    thread.start()
    try:
        until(lambda: server.started, 20.0, poll_s=0.05)
        base = "http://{}:{}".format(*listener.getsockname()[:2])
        with httpx.Client(base_url=base, headers=api.as_("prosthetist"), timeout=30) as c:
            patient = c.post("/api/patients", json={"code_name": "P-CAL", "body_mass_kg": MASS_KG, "side": "left",
                                                    "height_m": 1.75, "k_level": 3}).json()
            assert c.put(f"/api/devices/{DEVICE}/assignment", json={"patient_id": patient["id"]}).status_code == 200
        yield stand, base
    finally:
        server.should_exit = True
        thread.join(10)
        listener.close()
        node.close()


def _measure(page, step: str) -> None:
    page.click("#calibration-measure")
    page.wait_for_selector(f"#calibration-{step} .chip")


def test_the_prosthetist_calibrates_a_mismounted_leg_from_the_monitor(leg_and_server, page):
    stand, base = leg_and_server
    sign_in(page, base, "prosthetist")
    page.goto(f"{base}/#/monitor/{DEVICE}")
    page.wait_for_selector("#calibration:not([hidden])")
    page.wait_for_selector("#calibration-state:has-text('not calibrated: knee, ankle, load cell')")

    page.click("#calibration-start")
    page.check("#calibration-dialog-ready")
    page.click("#calibration-dialog-confirm")
    page.wait_for_selector("#calibration-joint_zero .prompt:has-text('Hold the knee straight')")
    page.wait_for_selector("#device-status:has-text('CALIBRATING')")

    stand.pose(0.0, 0.0)
    stand.jitter_rad = 0.03                          # the knee not held still: refused, with the leg's reason
    _measure(page, "joint_zero")
    zero = page.locator("#calibration-joint_zero")
    assert "refused" in zero.inner_text() and "hold the joint still" in zero.inner_text()
    assert page.inner_text("#calibration-measure") == "Measure joint zero again"
    stand.jitter_rad = 0.0
    page.click("#calibration-measure")
    page.wait_for_selector("#calibration-joint_zero:has-text('accepted')")
    assert "knee reads +29.79° at its zero" in zero.inner_text()

    page.wait_for_selector("#calibration-direction .prompt:has-text('Bend the knee')")
    stand.pose(30.0, 10.0)
    _measure(page, "direction")
    assert "sensor reversed: the sensor reads flexion as negative" in page.inner_text("#calibration-direction")
    stand.pose(0.0, 0.0)
    _measure(page, "loadcell_zero")
    assert "unloaded: -140.0 N axial" in page.inner_text("#calibration-loadcell_zero")
    stand.pose(0.0, 0.0, load_N=0.5 * MASS_KG * 9.81)
    _measure(page, "loadcell_sign")
    sign = page.inner_text("#calibration-loadcell_sign")
    assert "reversed: compression reads negative" in sign and "72.0 kg" in sign
    shot(page, "calibration-monitor")

    page.click("#calibration-keep")
    page.wait_for_selector("#calibration-state:has-text('knee, ankle and load cell calibrated')")
    page.wait_for_selector("#calibration-running[hidden]", state="attached")
    assert len(stand.kept) == 1 and stand.kept[0].knee.sign == -1 and stand.kept[0].loadcell.fz_sign == -1
    page.wait_for_selector("#leg-hardware:has-text('calibrated')")
    # audited with the leg's answers
    with httpx.Client(base_url=base, timeout=30) as c:
        token = c.post("/api/auth/token", data={"username": "admin", "password": "correct-horse-battery"}).json()
        entries = c.get("/api/audit", params={"limit": 50},
                        headers={"Authorization": f"Bearer {token['access_token']}"}).json()
    actions = [e["action"] for e in (entries["items"] if isinstance(entries, dict) else entries)]
    assert "device.calibration.keep" in actions and actions.count("device.calibration.measure") == 5
