"""The app: validation errors that name the field, methods a path allows, storage prepared before serving."""

from __future__ import annotations

from backend.app import prepare_storage
from backend.db import connect
from backend.migrate import schema_version
from backend.settings import Settings


def test_a_validation_error_names_the_field_and_what_was_wrong(api):
    r = api.client.post("/api/patients", headers=api.as_("prosthetist"),
                        json={"code_name": "P-9", "body_mass_kg": -3.0, "side": "left", "height_m": 1.8, "k_level": 3})
    assert r.status_code == 422
    body = r.json()
    assert "body mass must be at least 20 kg" in body["detail"]                 # in words on the page
    assert [(e["field"], e["type"]) for e in body["errors"]] == [("body_mass_kg", "greater_than_equal")]   # scripts


def test_a_wrong_method_is_405_with_the_methods_allowed(api):
    r = api.client.delete("/api/patients", headers=api.as_("prosthetist"))
    assert r.status_code == 405 and set(r.headers["Allow"].split(", ")) >= {"GET", "POST"}


def test_storage_is_created_and_migrated_before_serving(tmp_path):
    settings = Settings(data_dir=tmp_path / "new")
    prepare_storage(settings)
    conn = connect(settings.db_path)
    try:
        assert schema_version(conn) >= 11
    finally:
        conn.close()


def test_the_openapi_schema_lists_every_router(api):
    paths = api.client.get("/openapi.json").json()["paths"]
    for path in ("/api/patients", "/api/proposals/{proposal_id}", "/api/envelopes/{envelope_id}",
                 "/api/devices", "/api/sessions/{session_id}", "/api/task-range", "/api/audit"):
        assert path in paths


_WITHOUT_FITTING_LIBRARIES = """
import importlib.abc, sys
BLOCKED = {"sklearn", "matplotlib", "pandas"}
class Blocker(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path, target=None):
        if name.split(".")[0] in BLOCKED:
            raise ImportError(f"imported {name} at start-up")
sys.meta_path.insert(0, Blocker())
import backend.app, backend.cli
from controller_core.model_io import load_model
model = load_model(sys.argv[1])
proposal = model.propose(1.2, 0.0, 75.0)
print(repr(proposal.table.row("knee", "stance_flexion").k_Nm_per_rad))
"""


def test_a_server_starts_and_a_saved_model_proposes_without_scikit_learn_matplotlib_or_pandas(model, tmp_path):
    """What a server or a CLI command loads at start: the app, the commands and a saved model, which then proposes.
    scikit-learn fits, matplotlib prints reports and pandas reads tables, each imported when that is done (together
    half of a server's start-up time when they were imported at start)."""
    import subprocess
    import sys

    from controller_core.model_io import save_model

    save_model(model, tmp_path / "model")
    r = subprocess.run([sys.executable, "-c", _WITHOUT_FITTING_LIBRARIES, str(tmp_path / "model")], capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
    assert float(r.stdout) == model.propose(1.2, 0.0, 75.0).table.row("knee", "stance_flexion").k_Nm_per_rad
