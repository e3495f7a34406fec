"""Browser fixtures: one real server with the simulated leg per test module, one Debian Chromium per test module
(each test has a browser context of its own; Playwright's sync API holds the thread's event loop while it runs, so a
browser kept for the whole run would break any later test of that process that runs asyncio), a page that fails its
test on any console error the test did not provoke."""

from __future__ import annotations

import pytest

from backend.app import prepare_storage
from backend.settings import Settings
from tests.helpers.browser import CHROMIUM_ARGS, chromium_path, watch_errors
from tests.helpers.server import add_user, start_server, stop_server

playwright_api = pytest.importorskip("playwright.sync_api", reason="playwright is a dev dependency")


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    data = tmp_path_factory.mktemp("browser-server")
    prepare_storage(Settings(data_dir=data))
    add_user(data, "dana", "prosthetist")
    add_user(data, "eli", "prosthetist")      # the second prosthetist: the bench gate's override takes two
    add_user(data, "vic", "viewer")
    add_user(data, "ada", "admin")
    proc, base = start_server(data, device="sim")
    yield base
    stop_server(proc)


@pytest.fixture(scope="module")
def browser():
    with playwright_api.sync_playwright() as pw:
        b = pw.chromium.launch(executable_path=chromium_path(), args=CHROMIUM_ARGS)
        yield b
        b.close()


@pytest.fixture
def page(browser):
    context = browser.new_context(viewport={"width": 1366, "height": 900}, accept_downloads=True)
    p = context.new_page()
    errors = watch_errors(p)
    p.errors = errors
    yield p
    context.close()
    assert not errors, f"the page logged errors: {errors}"
