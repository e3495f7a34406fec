"""Every page a prosthetist or clinician uses, at the three screen sizes the clinic has (1280 × 800 laptop, 1024 × 700
small laptop, 768 × 1024 tablet): no page wider than the screen, no script error, and a screenshot of each to look
at (artifacts/browser/screens/, with ``QUASITUNE_SCREENSHOTS=1``)."""

from __future__ import annotations

import re

import pytest

from tests.helpers.browser import api_call, create_patient_and_propose, next_frames, shot, sign_in, watch_errors
from tests.helpers.device import until

SIZES = [(1280, 800), (1024, 700), (768, 1024)]


@pytest.fixture(scope="module")
def pages(server, browser) -> dict[str, str]:
    """One patient with a walked, approved, pushed table, an envelope, and a stopped session: the pages to show."""
    context = browser.new_context(viewport={"width": 1280, "height": 800})
    page = context.new_page()
    try:
        sign_in(page, server, "dana")
        pid = create_patient_and_propose(page, "P-SCR")
        patient_id = api_call(page, "GET", f"/api/proposals/{pid}")["body"]["patient_id"]
        assert api_call(page, "GET", f"/api/proposals/{pid}/preview")["status"] == 200
        assert api_call(page, "POST", f"/api/proposals/{pid}/approve", {"comment": "reviewed"})["status"] == 200
        assert api_call(page, "PUT", "/api/devices/sim-leg-1/assignment", {"patient_id": patient_id})["status"] == 200
        body = {"device_id": "sim-leg-1", "patient_ready": True, "replaces_proposal_id": None, "replaces_envelope_id": None}
        pushed = api_call(page, "POST", f"/api/proposals/{pid}/push", body)
        assert pushed["status"] == 201, pushed
        envelope = api_call(page, "POST", f"/api/patients/{patient_id}/envelopes", {"grid": [3, 3]})["body"]
        until(lambda: api_call(page, "GET", "/api/devices/sim-leg-1")["body"]["active_crc32"] == pushed["body"]["crc32"],
              20.0, poll_s=0.2)
        session = api_call(page, "POST", f"/api/patients/{patient_id}/sessions", {"device_id": "sim-leg-1"})["body"]
        until(lambda: api_call(page, "GET", f"/api/sessions/{session['id']}/samples?every=10")["body"]["count"] >= 30,
              30.0, poll_s=0.2)                                  # 3 s of the device's samples
        assert api_call(page, "POST", f"/api/sessions/{session['id']}/stop")["status"] == 200
    finally:
        context.close()
    return {"patients": "#/patients", "patient": f"#/patients/{patient_id}", "proposal": f"#/proposals/{pid}",
            "envelope": f"#/envelopes/{envelope['id']}", "envelope-node": f"#/envelopes/{envelope['id']}/nodes/1/1",
            "monitor": "#/monitor/sim-leg-1", "report": f"#/sessions/{session['id']}/report", "audit": "#/audit"}


READY = {"patients": "#patients, table", "patient": "#propose", "proposal": "#param-table", "envelope": "#envelope-maps svg",
         "envelope-node": "#param-table", "monitor": "#monitor-actions", "report": "#report-facts", "audit": "#audit-table"}


@pytest.mark.parametrize(("width", "height"), SIZES)
def test_every_page_fits_the_screen_without_script_errors(server, browser, pages, width, height):
    context = browser.new_context(viewport={"width": width, "height": height}, has_touch=width < 1000)
    page = context.new_page()
    errors = watch_errors(page)
    try:
        sign_in(page, server, "dana")
        for name, route in pages.items():
            page.goto(f"{server}/{route}")
            page.wait_for_selector(READY[name], timeout=30_000)
            next_frames(page)   # charts draw on the next frames
            overflow = page.evaluate("document.documentElement.scrollWidth - window.innerWidth")
            assert overflow <= 0, f"{name} is {overflow}px wider than a {width} × {height} screen"
            body = page.inner_text("body")
            leaked = [body[max(m.start() - 60, 0):m.end() + 20] for m in re.finditer(r"\b(?:null|undefined|NaN)\b", body)]
            assert not leaked, f"{name} shows a programming value to people: {leaked}"
            if name in ("report", "monitor"):      # the simulated leg's walk never passes for a person's
                assert "SIMULATED" in page.inner_text("h1" if name == "report" else "#device-status"), name
            shot(page, f"screens/{name}-{width}x{height}")
        assert not errors, errors
    finally:
        context.close()
