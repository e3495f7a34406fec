"""Serving the dashboard: ``/`` is the single page, ``/app/`` its modules and styles, ``/vendor/`` the npm packages
installed into ``frontend/node_modules`` by the set-up command (never committed). None of it needs a token: the
page signs in through the API, and every piece of data comes from the API with the bearer token."""

from __future__ import annotations

from pathlib import Path

from fastapi import FastAPI
from fastapi.responses import FileResponse, HTMLResponse
from fastapi.staticfiles import StaticFiles

from backend.clinical_words import WORDS_PATH

# npm package → the folder of it the browser may load
VENDOR = {"uplot": "uplot/dist", "swagger-ui": "swagger-ui-dist"}

_MISSING = """<!doctype html><meta charset="utf-8"><title>QuasiTune</title>
<p>The dashboard cannot be shown: {missing}.
Run <code>bash scripts/run.sh</code>, which installs the npm packages with <code>npm ci</code> in <code>frontend/</code>,
or point <code>QUASITUNE_FRONTEND_DIR</code> at the repository's <code>frontend/</code>. The API works regardless.</p>"""


def mount_frontend(app: FastAPI, frontend_dir: Path) -> None:
    """Add the dashboard routes; if an npm package is missing, ``/`` says so instead of a broken page."""
    index = frontend_dir / "index.html"
    if not (index.is_file() and (frontend_dir / "app").is_dir()):
        problems = [f"no dashboard files in {frontend_dir}"]
    else:
        problems = [f"npm package {name} not installed" for name, sub in VENDOR.items()
                    if not (frontend_dir / "node_modules" / sub).is_dir()]

    @app.get("/", include_in_schema=False, response_model=None)
    def dashboard() -> FileResponse | HTMLResponse:
        if problems:
            return HTMLResponse(_MISSING.format(missing="; ".join(problems)), status_code=503)
        return FileResponse(index, headers={"Cache-Control": "no-cache"})

    @app.get("/clinical_words.json", include_in_schema=False)
    def clinical_words() -> FileResponse:
        """The settings' names in a prosthetist's words: the server's own copy, which the dashboard imports."""
        return FileResponse(WORDS_PATH, media_type="application/json", headers={"Cache-Control": "no-cache"})

    if (frontend_dir / "app").is_dir():
        app.mount("/app", StaticFiles(directory=frontend_dir / "app"), name="app")
    for name, sub in VENDOR.items():
        if (frontend_dir / "node_modules" / sub).is_dir():
            app.mount(f"/vendor/{name}", StaticFiles(directory=frontend_dir / "node_modules" / sub),
                      name=f"vendor-{name}")
