"""The bench gate as two prosthetists click it, and a withdrawal: a table whose bench preview breaks a bound (at 1.6 m/s
the hip sinks under the body) is signed off by one and approved by the other, each with their
reason; then it is withdrawn and the page says it is never pushed again. At 1280 × 800 and 768 × 1024."""

from __future__ import annotations

import pytest

from tests.helpers.browser import create_patient_and_propose, shot, sign_in, watch_errors

SIZES = {"1280x800": (1280, 800), "768x1024": (768, 1024)}


@pytest.mark.parametrize("size", list(SIZES))
def test_an_unsafe_table_takes_two_prosthetists_and_a_withdrawn_one_is_never_pushed(server, browser, size):
    width, height = SIZES[size]
    contexts = [browser.new_context(viewport={"width": width, "height": height}) for _ in range(2)]
    dana, eli = (c.new_page() for c in contexts)
    errors = [watch_errors(dana), watch_errors(eli)]
    try:
        sign_in(dana, server, "dana")
        pid = create_patient_and_propose(dana, f"P-GATE-{size}", speed="1.6")
        dana.wait_for_selector("#decision-bench:has-text('beyond their bounds')", timeout=60_000)
        assert "two prosthetists' sign-offs" in dana.inner_text("#bench-gate")
        assert dana.locator("#decision textarea, #decision input").count() == 1   # one reason box on the card
        assert dana.is_hidden("#approve")                                         # alone, nobody goes ahead
        dana.fill("#decision-reason", "reviewed the bench")
        assert dana.is_disabled("#signoff")                                       # a sign-off's reason: 20 characters
        dana.fill("#decision-reason", "seated trial only; the knee flexion is watched by hand")
        dana.click("#signoff")
        dana.wait_for_selector("#signoff-wait")
        assert dana.is_hidden("#approve") and "dana" in dana.inner_text("#signoffs")
        shot(dana, f"gate-{size}-01-first-signoff")

        sign_in(eli, server, "eli")
        eli.goto(f"{server}/#/proposals/{pid}")
        eli.wait_for_selector("#signoffs:has-text('dana')")
        eli.wait_for_selector("#decision-bench:has-text('beyond their bounds')")   # the card drawn for good first
        assert eli.is_hidden("#signoff")                                          # eli's sign-off is the second
        assert "the second of two" in eli.inner_text("#decision label")
        eli.fill("#decision-reason", "with dana")
        assert eli.is_disabled("#approve")                                        # the second sign-off: 20 characters
        eli.fill("#decision-reason", "agreed: seated trial, the flexion is within what the patient controls")
        eli.click("#approve")
        eli.wait_for_selector("#decision:has-text('approved by eli')")
        override = eli.inner_text("#decision-override")
        assert "dana: seated trial only" in override and "eli: agreed" in override
        shot(eli, f"gate-{size}-02-approved-by-two")

        eli.click("#withdraw")
        eli.wait_for_selector("#withdraw-dialog")
        assert eli.is_disabled("#withdraw-dialog-confirm")                        # says why first
        eli.fill("#withdraw-dialog-reason", "the patient felt the knee give at the first steps")
        eli.click("#withdraw-dialog-confirm")
        eli.wait_for_selector("#withdrawn:has-text('the patient felt the knee give')")
        assert "WITHDRAWN" in eli.inner_text("#withdrawn-chip")
        eli.wait_for_selector("#push:has-text('never pushed again')")
        assert eli.locator("#push-button").count() == 0
        shot(eli, f"gate-{size}-03-withdrawn")
    finally:
        for c in contexts:
            c.close()
    assert not any(errors), errors
