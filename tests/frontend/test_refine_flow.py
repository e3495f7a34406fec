"""Refine from walking in the browser: the patient's session on an approved table → a refined draft with its
evidence, reviewed on its own page. The session is recorded offline (tests/helpers/sessions.py) into the server's
database: the bench walks the approved table, and the recorded knee angle is scaled down after toe-off so that the
swing knee flexes consistently short (a synthetic change, said here)."""

from __future__ import annotations

import re

import pytest

from backend.app import prepare_storage
from backend.settings import Settings
from tests.helpers.browser import api_call, create_patient_and_propose, shot, sign_in
from tests.helpers.device import until
from tests.helpers.server import add_user, sign_off, start_server, stop_server
from tests.helpers.sessions import record_offline

pytestmark = [pytest.mark.browser, pytest.mark.wallclock]

playwright_api = pytest.importorskip("playwright.sync_api", reason="playwright is a dev dependency")
expect = playwright_api.expect


@pytest.fixture(scope="module")
def server_and_data(tmp_path_factory):
    data = tmp_path_factory.mktemp("refine-server")
    prepare_storage(Settings(data_dir=data))
    add_user(data, "dana", "prosthetist")
    add_user(data, "eli", "prosthetist")
    proc, base = start_server(data)
    yield base, data
    stop_server(proc)


def test_a_prosthetist_refines_a_table_from_a_session_and_reviews_the_draft(server_and_data, page, model):
    base, data = server_and_data
    sign_in(page, base, "dana")
    pid = create_patient_and_propose(page, "P-REF", speed="1.2")
    assert api_call(page, "GET", f"/api/proposals/{pid}/preview")["status"] == 200   # walked (or its walk waited for)
    prop = api_call(page, "GET", f"/api/proposals/{pid}")["body"]
    if prop["bench"]["status"] != "clean":      # the gate's override takes a colleague's sign-off first
        sign_off(base, "eli", "proposal", pid, "test: the refinement, not the bench gate")
    r = api_call(page, "POST", f"/api/proposals/{pid}/approve",
                 {"comment": "ok", "override_reason": "test: the refinement, not the bench gate"})
    assert r["status"] == 200, r
    patient = api_call(page, "GET", f"/api/patients/{prop['patient_id']}")["body"]
    sid = record_offline(data / "quasitune.sqlite", model, patient, pid, 25.0, swing_scale=0.85)
    assert api_call(page, "POST", f"/api/sessions/{sid}/stop")["status"] == 200

    page.reload()          # the page was drawn while the table was a draft
    page.wait_for_selector("#refine-form")
    expect(page.locator("#refine-form input[name=session]")).to_have_count(1)
    versions = len(api_call(page, "GET", f"/api/patients/{prop['patient_id']}/proposals")["body"])
    # the refinement walks the bench as a job: its progress with the time left, and Cancel, which stores nothing. An
    # envelope's preview walks first (asked for by a request the page does not wait on), so the refinement waits behind
    # it and is cancelled while it waits (a table's refinement alone walks for about a second: too short to click)
    env = api_call(page, "POST", f"/api/patients/{prop['patient_id']}/envelopes", {"grid": [2, 2]})["body"]
    page.evaluate("(path) => { fetch(path, {headers: {Authorization: 'Bearer ' + "
                  "sessionStorage.getItem('quasitune.token')}}); }", f"/api/envelopes/{env['id']}/preview")
    until(lambda: any(j["path"] == f"/api/envelopes/{env['id']}" and j["state"] == "walking"
                      for j in api_call(page, "GET", "/api/jobs")["body"]), timeout_s=30.0, poll_s=0.1)
    page.fill("#refine-comment", "started by mistake")
    page.click("#refine-form button[type=submit]")
    page.wait_for_selector("#bench-progress-words:has-text('s left')", timeout=30_000)
    assert re.search(r"queued behind \d+ walks?: about \d+ s left", page.inner_text("#bench-progress-words"))
    page.click("#bench-cancel")
    page.wait_for_selector("#refine-error:has-text('cancelled by dana')", timeout=30_000)
    expect(page.locator("#refined-link")).to_have_count(0)
    assert len(api_call(page, "GET", f"/api/patients/{prop['patient_id']}/proposals")["body"]) == versions
    assert api_call(page, "GET", f"/api/envelopes/{env['id']}/preview")["status"] == 200   # walked (or waited for)
    page.fill("#refine-comment", "the knee swings short on the bench session")
    page.click("#refine-form button[type=submit]")
    page.wait_for_selector("#refined-link", timeout=60_000)
    changes = page.inner_text("#refine-changes")
    assert re.search(r"knee swing-flexion.*→.*swing knee flexion [\d.]+° short", changes, re.S | re.I), changes
    node = page.locator("details.refine-node").first
    assert "acted on" in node.inner_text() and "Bench: change" in node.inner_text()
    # the bias (what the rows move) with its interval, and beside it the spread from stride to stride (what no row moves)
    assert "Bias: mean error [95 % interval]" in node.inner_text() and re.search(r"±\d+\.\d°", node.inner_text())
    assert "The bench walked the nominal bench leg" in page.inner_text("#refinement")     # which leg, said
    shot(page, "refine-01-evidence")

    page.click("#refined-link")
    page.wait_for_selector("#refined-from")
    assert "Made by a refinement from walking" in page.inner_text("#refined-from")
    decision = page.inner_text("#decision")
    assert "draft" in page.inner_text("#proposal-chips") and "Reject" in decision
    assert "Approve" in decision or "Sign off (first of two)" in decision          # as the bench allows it
    assert "refined from the patient's own strides" in page.inner_text("#param-table")
    shot(page, "refine-02-draft")
