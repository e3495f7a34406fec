"""Dashboard benchmark (``python -m benchmarks ui``): Debian's full Chromium (Playwright) against a real
``quasitune serve`` with the simulated leg.

Figures, not assertions (the browser tests assert behaviour):

* ``proposal_view_ms``: from the moment ``POST /api/patients/{id}/proposals`` returns in the page to the proposal
  view being interactive — loops, curves, features, table, decision and push controls drawn and wired (the
  simulated preview arrives later, on its own). The target is ≤ 1000 ms.
* ``cold_proposal_page_ms``: a fresh page load of a proposal URL (navigation start → interactive), the case of a
  prosthetist opening a link.
* ``envelope_view_ms`` / ``envelope_from_request_ms``: the envelope page (8 maps of 25 nodes, decision, edit and
  push controls) interactive after ``POST /api/patients/{id}/envelopes`` returns / after the click that sends it
  (the server builds all 25 nodes in between). The target is ≤ 1000 ms after the request.
* ``adaptive_monitor_fps``: the live monitor with an envelope on the leg walking the ``mixed`` course (the map with
  the estimated task and its trail, the blended values and the state banner, on top of the charts); target ≥ 30.
* ``monitor_fps``: live-monitor redraws per second (charts and the side view of the leg) while telemetry streams
  (target ≥ 30), with the telemetry rate the page received and any sequence gaps; ``monitor_fps_with_3d_view``
  the same with the viser scene open (the benchmark's server runs ``--viewer3d``; WebGL, which headless Chromium
  here renders in software, SwiftShader, on the same CPU cores).
"""

from __future__ import annotations

import statistics
import time

from tests.helpers.browser import CHROMIUM_ARGS, chromium_path, sign_in
from tests.helpers.server import PASSWORD, sign_off, temporary_server

COLLEAGUE = "colleague"     # the second prosthetist of the bench gate's two-person override


def _pct(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, round(q * (len(ordered) - 1)))]


def _measure(base: str, repeats: int, monitor_s: float) -> dict:
    import httpx
    from playwright.sync_api import sync_playwright

    with httpx.Client(base_url=base, timeout=30) as c:
        while c.get("/api/health").json()["model"] != "ready":
            time.sleep(0.1)
        tok = c.post("/api/auth/token", data={"username": "bench", "password": PASSWORD}).json()["access_token"]
        h = {"Authorization": f"Bearer {tok}"}
        patient = c.post("/api/patients", headers=h, json={"code_name": "UI-1", "body_mass_kg": 75, "side": "left"}).json()
        c.put("/api/devices/sim-leg-1/assignment", headers=h, json={"patient_id": patient["id"]}).raise_for_status()
    view_ms, cold_ms = [], []
    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=chromium_path(full_browser=True), args=CHROMIUM_ARGS)
        page = browser.new_page(viewport={"width": 1366, "height": 900})
        sign_in(page, base, "bench")
        for i in range(repeats):
            page.goto(f"{base}/#/patients/{patient['id']}")
            page.wait_for_selector("#propose")
            page.evaluate("window.quasitune.proposalViewMs = undefined")
            page.fill("#propose input[name=speed_mps]", f"{0.9 + 0.05 * (i % 16):.2f}")
            page.click("#propose button[type=submit]")
            page.wait_for_function("() => window.quasitune.proposalViewMs !== undefined", timeout=30_000)
            view_ms.append(page.evaluate("window.quasitune.proposalViewMs"))
        url = page.url
        for _ in range(max(3, repeats // 4)):
            page.goto("about:blank")
            page.goto(url)
            page.wait_for_function("() => window.quasitune && window.quasitune.proposalInteractiveAt !== undefined",
                                   timeout=30_000)
            cold_ms.append(page.evaluate("window.quasitune.proposalInteractiveAt"))
        env_ms, env_request_ms = [], []
        for _ in range(3):
            page.goto(f"{base}/#/patients/{patient['id']}")
            page.wait_for_selector("#request-envelope")
            page.evaluate("window.quasitune.envelopeViewMs = undefined")
            page.click("#request-envelope button[type=submit]")
            page.wait_for_function("() => window.quasitune.envelopeViewMs !== undefined", timeout=30_000)
            env_ms.append(page.evaluate("window.quasitune.envelopeViewMs"))
            env_request_ms.append(page.evaluate("window.quasitune.envelopeFromRequestMs"))
            # its preview walked before the next request: the bench queues at most two walks per person and refuses
            # a third ("wait for them first"), which the page then shows instead of the preview
            page.wait_for_selector("#preview-segments", timeout=300_000)
        page.goto(f"{base}/#/monitor/sim-leg-1?patient={patient['id']}")
        page.fill("#session input[name=speed]", "1.2")
        page.click("#start-session")
        page.wait_for_selector("#stop-session")
        page.wait_for_function("() => window.quasitune.monitor && window.quasitune.monitor.samples > 100", timeout=20_000)
        before = page.evaluate("({...window.quasitune.monitor, now: performance.now()})")
        page.wait_for_timeout(monitor_s * 1000)
        after = page.evaluate("({...window.quasitune.monitor, now: performance.now()})")
        page.click("#viewer3d-toggle summary")          # the same with the viser 3D scene open
        page.frame_locator("#viewer3d iframe").locator("canvas").first.wait_for(timeout=20_000)
        page.wait_for_timeout(1000)
        before3d = page.evaluate("({...window.quasitune.monitor, now: performance.now()})")
        page.wait_for_timeout(monitor_s * 1000)
        after3d = page.evaluate("({...window.quasitune.monitor, now: performance.now()})")
        page.click("#viewer3d-toggle summary")
        page.click("#stop-session")
        page.click("#stop-dialog-confirm")              # stopping a session asks first
        page.wait_for_selector("#session-summary")
        adaptive = _adaptive_monitor(page, base, h, monitor_s)
        webgl = page.evaluate("""() => { const g = document.createElement('canvas').getContext('webgl');
            const i = g && g.getExtension('WEBGL_debug_renderer_info');
            return g ? (i ? g.getParameter(i.UNMASKED_RENDERER_WEBGL) : 'webgl') : 'none'; }""")
        browser.close()
    span_s = (after["now"] - before["now"]) / 1000
    span3d_s = (after3d["now"] - before3d["now"]) / 1000
    return {
        "proposal_view_ms_median": round(statistics.median(view_ms), 1),
        "proposal_view_ms_p95": round(_pct(view_ms, 0.95), 1),
        "proposal_view_ms_max": round(max(view_ms), 1), "proposal_views": len(view_ms),
        "cold_proposal_page_ms_median": round(statistics.median(cold_ms), 1),
        "monitor_fps": round((after["frames"] - before["frames"]) / span_s, 1),
        "monitor_telemetry_hz": round((after["samples"] - before["samples"]) / span_s, 1),
        "monitor_sequence_gaps": after3d["gaps"], "monitor_seconds": round(span_s, 2),
        "monitor_fps_with_3d_view": round((after3d["frames"] - before3d["frames"]) / span3d_s, 1),
        "webgl_renderer": webgl,
        "envelope_view_ms_median": round(statistics.median(env_ms), 1), "envelope_view_ms_max": round(max(env_ms), 1),
        "envelope_from_request_ms_median": round(statistics.median(env_request_ms), 1),
        "envelope_from_request_ms_max": round(max(env_request_ms), 1), "envelope_views": len(env_ms),
        **adaptive,
    }


def _adaptive_monitor(page, base: str, headers: dict, monitor_s: float) -> dict:
    """Approve and push the patient's newest envelope (over the API), then watch the course on the monitor."""
    import httpx

    with httpx.Client(base_url=base, timeout=60, headers=headers) as c:
        device = c.get("/api/devices/sim-leg-1").json()
        envelope = c.get(f"/api/patients/{device['patient']['patient_id']}/envelopes").json()[0]
        decision = {"comment": "benchmark"}
        if c.get(f"/api/envelopes/{envelope['id']}").json()["bench"]["status"] != "clean":
            # the default 5 x 5 envelope's node walks flag figures at its steepest tasks: approved as a clinic would,
            # two prosthetists signing off the findings (this measures the monitor, not the envelope)
            reason = "benchmark: the monitor is measured, not this envelope; its flagged nodes are not walked"
            sign_off(base, COLLEAGUE, "envelope", envelope["id"], reason)
            decision["override_reason"] = reason
        c.post(f"/api/envelopes/{envelope['id']}/approve", json=decision).raise_for_status()
        on_leg = device["active_table"]
        c.post(f"/api/envelopes/{envelope['id']}/push", json={
            "device_id": "sim-leg-1", "patient_ready": True,
            "replaces_proposal_id": on_leg and on_leg["proposal_id"],
            "replaces_envelope_id": on_leg and on_leg["envelope_id"],
            "override_reason": decision.get("override_reason")}).raise_for_status()
    page.goto(f"{base}/#/monitor/sim-leg-1")
    page.wait_for_selector("#adaptive:not([hidden]) #live-map")
    page.select_option("#session-walk", "mixed")
    page.click("#start-session")
    page.wait_for_selector("#live-map circle.task-point[visibility=visible]", timeout=30_000)
    before = page.evaluate("({...window.quasitune.monitor, now: performance.now()})")
    page.wait_for_timeout(monitor_s * 1000)
    after = page.evaluate("({...window.quasitune.monitor, now: performance.now()})")
    page.click("#stop-session")
    page.click("#stop-dialog-confirm")
    page.wait_for_selector("#session-summary")
    span_s = (after["now"] - before["now"]) / 1000
    return {"adaptive_monitor_fps": round((after["frames"] - before["frames"]) / span_s, 1),
            "adaptive_monitor_telemetry_hz": round((after["samples"] - before["samples"]) / span_s, 1),
            "adaptive_monitor_sequence_gaps": after["gaps"] - before["gaps"]}


def run(repeats: int = 20, monitor_s: float = 5.0) -> dict:
    # the 3D view is timed too; a colleague signs off the bench's findings where the envelope's preview flags any
    with temporary_server("quasitune-uibench-", device="sim", viewer3d=True, colleague=COLLEAGUE) as base:
        return _measure(base, repeats, monitor_s)
