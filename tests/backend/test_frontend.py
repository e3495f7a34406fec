"""The dashboard's files served by the backend."""

from __future__ import annotations

from tests.helpers.api import make_api


def test_dashboard_page_and_vendor_packages_are_served(api):
    page = api.client.get("/")
    assert page.status_code == 200 and '<script type="module"' in page.text
    js = api.client.get("/vendor/uplot/uPlot.esm.js")
    assert js.status_code == 200 and "uPlot" in js.text
    assert api.client.get("/app/main.js").status_code == 200


def test_a_missing_npm_package_is_said_not_hidden(tmp_path, model):
    frontend = tmp_path / "frontend"
    (frontend / "app").mkdir(parents=True)
    (frontend / "index.html").write_text("<!doctype html>")
    api, _ = make_api(tmp_path / "data", lambda: model, frontend_dir=frontend)
    r = api.client.get("/")
    assert r.status_code == 503 and "npm ci" in r.text and "npm package uplot not installed" in r.text
    assert api.client.get("/api/health").status_code == 200   # the API works regardless


def test_a_missing_dashboard_folder_is_said_and_the_api_still_serves(tmp_path, model):
    api, _ = make_api(tmp_path / "data", lambda: model, frontend_dir=tmp_path / "nowhere")
    r = api.client.get("/")
    assert r.status_code == 503 and "no dashboard files" in r.text and "QUASITUNE_FRONTEND_DIR" in r.text
    assert api.client.get("/api/patients", headers=api.as_("viewer")).status_code == 200
