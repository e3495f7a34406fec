"""Helpers for the browser tests and the dashboard benchmark: Debian's Chromium, signing in, screenshots (under
``artifacts/browser/``, or ``$QUASITUNE_ARTIFACTS/browser``, when ``QUASITUNE_SCREENSHOTS=1``) and a check that a
canvas has something drawn on it."""

from __future__ import annotations

import os
import re
import shutil
from pathlib import Path

from tests.helpers.server import PASSWORD

# SwiftShader gives headless Chromium WebGL for the viser view; no sandbox: CI runs as root in a container
CHROMIUM_ARGS = ["--no-sandbox", "--enable-unsafe-swiftshader"]

# The tests drive Debian's chromium-headless-shell: the same Chromium source and release as the `chromium` package
# (Blink, V8, the same pages and scripts), without the desktop browser's window layer, and what Playwright itself
# uses for headless runs; the whole browser test set took 75 CPU-s with it against 125 with the full browser (docs/
# results.md). `benchmarks ui`, whose frame rates and view times stand for a clinic's browser, drives the full one.
HEADLESS_SHELL, FULL_BROWSER = "/usr/bin/chromium-headless-shell", "/usr/bin/chromium"


def chromium_path(full_browser: bool = False) -> str:
    """Debian's Chromium: ``$QUASITUNE_CHROMIUM`` if set, else the headless shell (tests) or the full browser
    (``full_browser``, benchmarks), installed by scripts/test.sh; a clear error naming the Debian package if it is
    missing (``playwright install`` is never used)."""
    wanted = os.environ.get("QUASITUNE_CHROMIUM", FULL_BROWSER if full_browser else HEADLESS_SHELL)
    path = shutil.which(wanted) or (wanted if Path(wanted).exists() else None)
    if path is None:
        package = Path(wanted).name if Path(wanted).name.startswith("chromium") else "chromium"
        raise RuntimeError(f"Chromium not found at {wanted}: install Debian's {package} package (apt-get install "
                           f"{package}; 'bash scripts/test.sh' installs the headless shell the tests use)")
    return path


# refusals the tests provoke (401/403/409/422) are shown on the page; anything else the console reports is an error
_EXPECTED = re.compile(r"Failed to load resource: the server responded with a status of (401|403|409|422)")


def watch_errors(page) -> list[str]:
    """Collect the page's uncaught errors and unexpected console errors (the list grows as they happen)."""
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" and not _EXPECTED.search(m.text) else None)
    return errors


def sign_in(page, base: str, username: str, password: str = PASSWORD) -> None:
    """Sign in through the dashboard's login form and wait for the patient list."""
    page.goto(base + "/")
    page.fill("input[name=username]", username)
    page.fill("input[name=password]", password)
    page.click("#login-form button[type=submit]")
    page.wait_for_selector("h1:has-text('Patients')")


def sign_in_one_time(page, base: str, username: str, given: str) -> None:
    """Sign in with a password someone else chose: the page asks for one's own before anything else."""
    page.goto(base + "/")
    page.fill("input[name=username]", username)
    page.fill("input[name=password]", given)
    page.click("#login-form button[type=submit]")
    page.wait_for_selector("h1:has-text('Choose your own password')")


def choose_own_password(page, given: str, own: str) -> None:
    """On the password page: replace ``given`` by ``own``; waits for the page to say it is changed."""
    page.fill("#password-form input[name=current_password]", given)
    page.fill("#password-form input[name=new_password]", own)
    page.fill("#password-form input[name=again]", own)
    page.click("#password-form button[type=submit]")
    page.wait_for_selector("#password-changed:has-text('Password changed')")


ARTIFACTS = Path(os.environ.get("QUASITUNE_ARTIFACTS", Path(__file__).resolve().parents[2] / "artifacts")) / "browser"


# screenshots are for people to look at, not checks: about 0.5 s of Chromium's time each, 80 of them a third of a
# 2-core machine's minute, so the suite takes them only when asked (`QUASITUNE_SCREENSHOTS=1 bash scripts/test.sh
# tests/frontend`)
SCREENSHOTS = os.environ.get("QUASITUNE_SCREENSHOTS", "") == "1"


def shot(page, name: str, full_page: bool = True) -> Path | None:
    """A screenshot of the page as ``ARTIFACTS/name.png`` when screenshots are asked for (``SCREENSHOTS``)."""
    if not SCREENSHOTS:
        return None
    path = ARTIFACTS / f"{name}.png"
    path.parent.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=str(path), full_page=full_page)
    return path


def canvas_ink(page, selector: str) -> list[int]:
    """Number of non-transparent pixels in each canvas matching ``selector`` (0 = nothing drawn)."""
    return page.evaluate("""(sel) => [...document.querySelectorAll(sel)].map((c) => {
        const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
        let n = 0; for (let i = 3; i < d.length; i += 4) if (d[i] > 0) n++; return n; })""", selector)


def create_patient(page, code: str, mass_kg: str = "78") -> None:
    """From the patient list: a new patient, through the form; waits for their page."""
    page.fill("#new-patient input[name=code_name]", code)
    page.fill("#new-patient input[name=body_mass_kg]", mass_kg)
    page.click("#new-patient button[type=submit]")
    page.wait_for_selector("#propose")


def create_patient_and_propose(page, code: str, speed: str = "1.25", incline: str = "0") -> int:
    """From the patient list: a new 78 kg patient and a proposal at the task; returns the proposal id."""
    create_patient(page, code)
    page.fill("#propose input[name=speed_mps]", speed)
    page.fill("#propose input[name=incline_deg]", incline)
    page.click("#propose button[type=submit]")
    page.wait_for_selector("#param-table")
    return int(re.search(r"#/proposals/(\d+)", page.url).group(1))




_FETCH = """async ([method, path, body]) => {
  const r = await fetch(path, {method, headers: {'Content-Type': 'application/json',
    Authorization: 'Bearer ' + sessionStorage.getItem('quasitune.token')}, body: body ? JSON.stringify(body) : undefined});
  return {status: r.status, body: await r.json().catch(() => null)}; }"""


def api_call(page, method: str, path: str, body: dict | None = None) -> dict:
    """The API as the signed-in page's user (what a script with the same token could do): status and JSON body."""
    return page.evaluate(_FETCH, [method, path, body])


def next_frames(page, frames: int = 2) -> None:
    """Wait for the page's next animation frames (charts and sticky layouts settle on them): an event, not a clock."""
    page.evaluate("(n) => new Promise((done) => { const step = (k) => (k ? requestAnimationFrame(() => step(k - 1)) "
                  ": done()); step(n); })", frames)
