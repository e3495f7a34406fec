"""Clinical safety in the browser, as a prosthetist new to the app would meet it: a knee setting that would give way,
limits checked while typing, clinical words with the engineering view one click away, and a monitor that says when
there is no data and what safe mode means."""

from __future__ import annotations

from playwright.sync_api import expect

from tests.helpers.browser import api_call as call
from tests.helpers.browser import create_patient, create_patient_and_propose, next_frames, shot, sign_in


def test_a_knee_that_would_give_way_is_refused_as_typed_and_by_the_server(server, page):
    sign_in(page, server, "dana")
    pid = create_patient_and_propose(page, "P-400")
    k_cell = "#param-table input[data-field='knee.stance_flexion.k_Nm_per_rad']"
    original = page.input_value(k_cell)
    page.fill("#edit-form input[name=comment]", "try a springy knee")
    page.fill(k_cell, "-150")                       # a negative resistance pushes: the knee collapses into flexion
    live = page.inner_text("#edit-live")
    assert "pushes the joint instead of resisting it" in live and "knee gives way into flexion" in live, live
    expect(page.locator("td[data-cell='knee.stance_flexion.k_Nm_per_rad'].out")).to_have_count(1)   # the cell touched
    expect(page.locator("#param-table td.out")).to_have_count(1)
    assert page.is_disabled("#edit-form button[type=submit]")
    shot(page, "09-live-limit")
    page.fill(k_cell, original)                     # back within the limits: the mark and the message go
    expect(page.locator("#param-table td.out")).to_have_count(0)
    assert page.inner_text("#edit-live") == ""
    assert not page.is_disabled("#edit-form button[type=submit]")
    # the stumble support's trigger is part of the table: its own section, in words, with units and limits; a fold
    # speed at which every downhill stance would be held stiff is marked as typed
    section = page.inner_text("#stumble-support")
    assert "stumble: loaded knee folding in early stance faster than" in section and "deg/s" in section, section
    assert "60 … 300" in section and "20 … 70" in section and "%" in section, section
    assert "early landing: on the toe when the weight lands this far along the forefoot" in section, section
    expect(page.locator("#stumble-support tbody tr")).to_have_count(6)
    fold = "#stumble-support input[data-field='thresholds.fold_knee_rate_deg_per_s']"
    assert float(page.input_value(fold)) == 90.0
    page.fill(fold, "40")
    expect(page.locator("td[data-cell='thresholds.fold_knee_rate_deg_per_s'].out")).to_have_count(1)
    assert "outside" in page.inner_text("#edit-live") and page.is_disabled("#edit-form button[type=submit]")
    shot(page, "09b-stumble-support-limit")
    page.fill(fold, "90")
    expect(page.locator("#edit-live li")).to_have_count(0)

    # a script skipping the page meets the same rule, and nothing is stored
    before = len(call(page, "GET", "/api/patients/{}/proposals".format(
        call(page, "GET", f"/api/proposals/{pid}")["body"]["patient_id"]))["body"])
    refused = call(page, "POST", f"/api/proposals/{pid}/edits", {"comment": "springy", "rows": [
        {"joint": "knee", "subphase": "stance_flexion", "k_Nm_per_rad": 150.0}]})
    assert refused["status"] == 422, refused
    assert "knee gives way" in refused["body"]["detail"]
    patient_id = call(page, "GET", f"/api/proposals/{pid}")["body"]["patient_id"]
    assert len(call(page, "GET", f"/api/patients/{patient_id}/proposals")["body"]) == before


def test_clinical_words_by_default_and_the_engineering_view_one_click_away(server, page):
    sign_in(page, server, "dana")
    create_patient_and_propose(page, "P-410")
    table_text = page.inner_text("#table-card")
    assert "stance flexion resistance" in table_text and "terminal swing" in table_text
    for code in ("stance_flexion", "least_squares", "swing_target", "_load_N", "k_Nm_per_rad"):
        assert code not in table_text, code
    assert "% body weight" in page.inner_text("#thresholds")                 # loads as clinicians read them
    swing_r2 = [page.inner_text(f"#param-table tbody tr:nth-child({i}) td:nth-child(6)") for i in (3, 4, 7, 8)]
    assert swing_r2 == ["—"] * 4, swing_r2                                  # a swing target is not a fit
    page.check("#k-unit input[value=deg]")                                  # b follows k's unit
    heads = page.inner_text("#param-table thead")
    assert "N·m/deg" in heads and "N·m·s/deg" in heads
    page.check("#table-view input[value=engineering]")
    table_text = page.inner_text("#table-card")
    assert "stance_flexion" in table_text and "least_squares" in table_text
    assert "\tN\t" in page.inner_text("#thresholds")                        # loads in newtons for the engineers
    shot(page, "10-engineering-view")


def test_monitor_says_when_there_is_no_data_and_what_safe_mode_means(server, page):
    sign_in(page, server, "dana")
    pid = create_patient_and_propose(page, "P-420", speed="1.2")
    assert call(page, "GET", f"/api/proposals/{pid}/preview")["status"] == 200     # approval rests on the bench
    assert call(page, "POST", f"/api/proposals/{pid}/approve", {"comment": "reviewed"})["status"] == 200
    patient_id = call(page, "GET", f"/api/proposals/{pid}")["body"]["patient_id"]
    assert call(page, "PUT", "/api/devices/sim-leg-1/assignment", {"patient_id": patient_id})["status"] == 200
    device = call(page, "GET", "/api/devices/sim-leg-1")["body"]
    current = (device["pending_table"] or device["active_table"] or {}).get("proposal_id")
    pushed = call(page, "POST", f"/api/proposals/{pid}/push", {"device_id": "sim-leg-1",
                                                               "replaces_proposal_id": current, "patient_ready": True})
    assert pushed["status"] == 201, pushed
    page.goto(f"{server}/#/monitor/sim-leg-1")

    # the assigned patient stands on the leg between walks: live signals, and the monitor says they stand
    page.wait_for_selector("#telemetry-state:has-text('the patient stands')", timeout=20_000)
    assert "% body weight" in page.inner_text("#load")                       # the stance load, as read
    # nobody wears it: the monitor says "no data" and why, instead of blank charts
    assert call(page, "DELETE", "/api/devices/sim-leg-1/assignment")["status"] == 200
    page.wait_for_selector("#telemetry-state:has-text('no data')", timeout=10_000)
    assert "nobody wears the simulated leg" in page.inner_text("#telemetry-state")
    assert call(page, "PUT", "/api/devices/sim-leg-1/assignment", {"patient_id": patient_id})["status"] == 200
    page.reload()
    page.wait_for_selector("#telemetry-state:has-text('the patient stands')", timeout=20_000)
    # the safe-mode buttons only where they change something; entering it is a caution, not a green "done"
    page.wait_for_function("() => !document.querySelector('#enter-safe').disabled")
    assert page.is_disabled("#leave-safe")
    page.click("#enter-safe")
    page.wait_for_selector("#notice.warn:has-text('Safe mode requested')")
    assert page.get_attribute("#notice", "class").split() == ["notice", "warn"]
    page.wait_for_function("() => document.querySelector('#enter-safe').disabled && "
                           "!document.querySelector('#leave-safe').disabled")

    # a session in safe mode: live data, and the chip says the strides are not scored
    page.click("#start-session")
    page.wait_for_selector("#telemetry-state:has-text('live')", timeout=20_000)
    page.wait_for_selector("#recording-chip .chip.bad:has-text('SAFE MODE')")
    assert "not scored" in page.inner_text("#recording-chip")
    assert "SAFE MODE" in page.inner_text("#sample-mode")
    page.wait_for_selector("#walk-state .chip.bad:has-text('SAFE MODE')")        # never "walking" alone over safe mode
    assert "(the simulated leg: “nominal”)" in page.inner_text("#walk-state")   # and which leg the bench walks
    shot(page, "11-monitor-safe-mode")
    # Stop and Safe mode stay beside the charts on a small laptop and a tablet; each value sits under its label
    for width, height in ((1024, 700), (768, 1024)):
        page.set_viewport_size({"width": width, "height": height})
        page.locator(".chart").last.scroll_into_view_if_needed()
        next_frames(page)   # the sticky bar settles
        for button in ("#stop-session", "#enter-safe", "#leave-safe"):
            box = page.locator(button).bounding_box()
            assert box is not None and box["y"] >= 0 and box["y"] + box["height"] <= height, (width, button, box)
        chart = page.locator(".chart").last.bounding_box()
        assert chart["y"] < height, (width, chart)                        # the charts are on screen with them
        pairs = page.evaluate("""[...document.querySelectorAll('#readout .readout-item')].map((d) => {
            const a = d.querySelector('dt').getBoundingClientRect(), b = d.querySelector('dd').getBoundingClientRect();
            return [a.left, b.left, a.bottom <= b.top + 1]; })""")
        assert pairs and all(abs(a - b) < 1 and below for a, b, below in pairs), pairs
        assert page.evaluate("document.documentElement.scrollWidth - window.innerWidth") <= 0
        shot(page, f"16-monitor-{width}x{height}", full_page=False)   # the window, as scrolled
    page.set_viewport_size({"width": 1366, "height": 900})
    page.click("#leave-safe")                                # the table runs again under the patient: asked first
    page.wait_for_selector("#leave-safe-dialog")
    assert "runs this table again" in page.inner_text("#leave-safe-dialog")
    assert page.is_disabled("#leave-safe-dialog-confirm")
    page.check("#leave-safe-dialog-ready")
    page.click("#leave-safe-dialog-confirm")
    page.wait_for_selector("#recording-chip .chip.ok:has-text('recording')", timeout=10_000)
    page.click("#stop-session")
    page.click("#stop-dialog-confirm")
    page.wait_for_selector("#session-summary")
    expect(page.locator("#off-table")).to_have_count(1)                          # the summary says it, before errors


def test_a_knee_too_soft_to_carry_the_patient_is_refused_as_typed_and_by_the_server(server, page):
    """The stance support floor: 1.2 N·m/rad per kg × 78 kg = 93.6 N·m/rad of resistance at least for the knee's stance
    flexion (k ≤ −93.6 in the API), stated with the limits; a softer value is marked as typed and refused by the
    server."""
    sign_in(page, server, "dana")
    pid = create_patient_and_propose(page, "P-430")
    floor_text = page.inner_text("#support-floor")
    assert "at least 93.6 N·m/rad" in floor_text and "1.2 N·m/rad per kg × 78.0 kg" in floor_text, floor_text
    k_cell = "#param-table input[data-field='knee.stance_flexion.k_Nm_per_rad']"
    page.fill("#edit-form input[name=comment]", "softer knee on the ramp")
    page.fill(k_cell, "40")                         # 40 N·m/rad of resistance: softer than the floor
    live = page.inner_text("#edit-live")
    assert "softer than the stance support floor" in live and "buckle" in live, live
    assert page.is_disabled("#edit-form button[type=submit]")
    refused = call(page, "POST", f"/api/proposals/{pid}/edits", {"comment": "softer knee", "rows": [
        {"joint": "knee", "subphase": "stance_flexion", "k_Nm_per_rad": -40.0}]})
    assert refused["status"] == 422 and "support floor" in refused["body"]["detail"], refused


def test_a_task_far_outside_the_data_needs_a_written_reason_and_says_so_everywhere(server, page):
    sign_in(page, server, "dana")
    create_patient(page, "P-440")
    known = page.inner_text("#propose #known-range")
    assert "The model knows 0.49–2.30 m/s" in known and "0.84–1.95 m/s" in known, known
    assert page.get_attribute("#propose input[name=speed_mps]", "max") == "3"   # the server's bounds
    assert page.is_hidden("#propose fieldset.extrapolate")
    page.fill("#propose input[name=speed_mps]", "0.3")
    assert page.is_visible("#propose fieldset.extrapolate")
    page.click("#propose button[type=submit]")                    # not ticked: the server refuses, nothing stored
    page.wait_for_selector("#propose .error:not(:empty)")
    assert "beyond what the model knows" in page.inner_text("#propose .error")
    page.check("#propose input[name=extrapolate]")
    page.fill("#propose textarea[name=reason]", "the patient walks this slowly at home")
    page.click("#propose button[type=submit]")
    page.wait_for_selector("#param-table")
    assert "extrapolated beyond the data" in page.inner_text("#proposal-chips")
    assert "the patient walks this slowly at home" in page.inner_text("#extrapolation-reason")
    shot(page, "14-extrapolated-on-purpose")


_MAP_JS = """(id) => {
  const svg = document.getElementById(id);
  const cells = [...svg.querySelectorAll('g.node')].map((g) => {
    const [i, j] = g.dataset.node.split(',').map(Number);
    return {i, j, fill: g.querySelector('rect').getAttribute('fill')};
  });
  const order = [...svg.children].map((c) => c.tagName + (c.getAttribute('class') ? '.' + c.getAttribute('class') : ''));
  return {cells, order, key: svg.querySelector('.key-words')?.textContent,
          lo: svg.querySelector('.key-lo')?.textContent, hi: svg.querySelector('.key-hi')?.textContent,
          held: svg.querySelectorAll('.held-mark').length, weak: svg.querySelectorAll('.weak-mark').length};
}"""


def _lightness(fill: str) -> float:
    return float(fill.rsplit(",", 1)[1].strip(" %)"))


def test_every_map_has_a_key_with_its_unit_darker_is_firmer_and_dots_never_hide_a_value(server, page):
    """The default 5 × 5 envelope for a 70 kg patient: the knee's stance flexion holds the support floor at the slow
    uphill corner and the neighbour rule moves others; both are marked, and every map says its range and unit."""
    sign_in(page, server, "dana")
    create_patient(page, "P-450", "70")
    page.click("#request-envelope button[type=submit]")
    page.wait_for_selector("#map-knee-stance_flexion")
    page.click("#bench-cancel")          # its 25 nodes' walks are not what this test looks at
    env = call(page, "GET", "/api/envelopes/" + page.url.split("/envelopes/")[1].split("?")[0])["body"]
    values = {(round(n["speed_mps"], 2), round(n["incline_deg"], 1)): n["table"][0]["k_Nm_per_rad"] for n in env["nodes"]}
    m = page.evaluate(_MAP_JS, "map-knee-stance_flexion")
    assert m["key"] == "N·m/rad · darker = firmer" and float(m["lo"]) < float(m["hi"])
    # darker is firmer: the most negative k is the darkest cell
    by_node = {(c["i"], c["j"]): _lightness(c["fill"]) for c in m["cells"]}
    speeds, inclines = env["speeds_mps"], env["inclines_deg"]
    k = {(i, j): values[(round(v, 2), round(g, 1))] for i, v in enumerate(speeds) for j, g in enumerate(inclines)}
    assert min(by_node, key=by_node.get) == min(k, key=k.get)
    assert max(by_node, key=by_node.get) == max(k, key=k.get)
    # the measured-condition dots come before the values, which are drawn last, over them
    first_value = next(n for n, tag in enumerate(m["order"]) if tag.startswith("text.cell-value"))
    last_dot = max(n for n, tag in enumerate(m["order"]) if tag == "circle.measured")
    assert last_dot < first_value
    assert m["held"] >= 1                                          # the support floor at 0.6 m/s, +10°, at least
    for q, words in (("theta_e_deg", "deg · darker = more flexed"), ("b_Nm_s_per_rad", "N·m·s/rad · darker = firmer")):
        page.check(f"input[name=quantity][value={q}]")
        assert page.evaluate(_MAP_JS, "map-knee-stance_flexion")["key"] == words
    expect(page.locator("svg.envelope-map .colour-key")).to_have_count(8)
    shot(page, "15-envelope-map-keys")
    # the node's table: held values flagged, the support floor named, damping said to be a default
    page.check("input[name=quantity][value=k_Nm_per_rad]")
    page.click("#map-knee-stance_flexion g.node[data-node='0,4']")          # 0.6 m/s, +10°
    page.wait_for_selector("#param-table")
    assert "held at the stance support floor" in page.inner_text("#param-table")
    assert page.locator("#param-table td.held").count() >= 2              # its k and θe
    assert "a default per kg, not fitted" in page.inner_text("#param-table thead")


def test_one_moment_unit_per_page_chosen_once_and_kept(server, page):
    sign_in(page, server, "dana")
    create_patient_and_propose(page, "P-460")
    page.evaluate("localStorage.removeItem('quasitune.momentUnit')")
    page.reload()
    page.wait_for_selector("#loop-knee svg")

    def units_shown() -> set[str]:
        labels = page.locator("#loop-knee .axis-label, #loop-ankle .axis-label").all_text_contents()
        titles = page.locator("#curves .u-title").all_text_contents()
        features = page.inner_text("#features")
        found = {m for text in labels + titles for m in ("N·m/kg", "N·m)") if m in text}
        return found | ({"features N·m/kg"} if "N·m/kg" in features else set())

    assert units_shown() == {"N·m)"}                                    # the patient's N·m everywhere by default
    page.check("#moment-unit input[value=Nm_per_kg]")
    page.wait_for_selector("#reference-note:has-text('Moments on this page in N·m/kg')")
    page.wait_for_selector("#curves .u-title")
    assert units_shown() == {"N·m/kg", "features N·m/kg"}
    page.reload()                                                      # kept across visits
    page.wait_for_selector("#reference-note:has-text('Moments on this page in N·m/kg')")
    page.check("#moment-unit input[value=Nm]")
    page.wait_for_selector("#reference-note:has-text('Moments on this page in N·m:')")
    page.wait_for_selector("#curves .u-title")
    assert units_shown() == {"N·m)"}
