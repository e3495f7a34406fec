"""Readiness while the model loads."""

from __future__ import annotations

import threading

from tests.helpers.api import make_api


def test_model_still_loading_gives_503_with_retry_after(tmp_path, model):
    gate = threading.Event()

    def slow_loader():
        gate.wait(10)
        return model

    api, client = make_api(tmp_path, slow_loader, model_wait_s=0.05)
    with client:
        patient = api.new_patient()
        assert client.get("/api/health").json()["model"] == "loading"
        r = client.post(f"/api/patients/{patient['id']}/proposals", headers=api.as_("prosthetist"),
                        json={"speed_mps": 1.0})
        assert r.status_code == 503 and r.headers["retry-after"] == "5" and "loading" in r.json()["detail"]
        gate.set()
        client.app.state.model._thread.join(5)
        assert client.get("/api/health").json()["model"] == "ready"
        assert api.propose(patient["id"])["status"] == "draft"
