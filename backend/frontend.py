"""Serving the dashboard: ``/`` is the single page, ``/app/`` its modules and styles, ``/vendor/`` the npm packages
installed into ``frontend/node_modules`` by the set-up command (never committed). None of it needs a token: the
page signs in through the API, and every piece of data comes from the API with the bearer token."""

from __future__ import annotations

from pathlib import Path

from fastapi import FastAPI
from fastapi.responses import FileResponse, HTMLResponse
from fastapi.staticfiles import StaticFiles

# npm package → the folder of it the browser may load
VENDOR = {"uplot": "uplot/dist"}

_MISSING = """<!doctype html><meta charset="utf-8"><title>QuasiTune</title>
<p style="font:16px sans-serif;margin:2em">The dashboard's npm packages are not installed ({missing}).
Run <code>bash scripts/run.sh</code>, which installs them with <code>npm ci</code> in <code>frontend/</code>.</p>"""


def mount_frontend(app: FastAPI, frontend_dir: Path) -> None:
    """Add the dashboard routes; if an npm package is missing, ``/`` says so instead of a broken page."""
    missing = [name for name, sub in VENDOR.items() if not (frontend_dir / "node_modules" / sub).is_dir()]
    index = frontend_dir / "index.html"

    @app.get("/", include_in_schema=False, response_model=None)
    def dashboard() -> FileResponse | HTMLResponse:
        if missing:
            return HTMLResponse(_MISSING.format(missing=", ".join(missing)), status_code=503)
        return FileResponse(index, headers={"Cache-Control": "no-cache"})

    app.mount("/app", StaticFiles(directory=frontend_dir / "app"), name="app")
    for name, sub in VENDOR.items():
        if name not in missing:
            app.mount(f"/vendor/{name}", StaticFiles(directory=frontend_dir / "node_modules" / sub),
                      name=f"vendor-{name}")
