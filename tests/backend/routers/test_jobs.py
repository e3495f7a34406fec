"""Bench walks are jobs: anyone sees the queue, with each walk's progress and the time left; its owner (or an admin)
cancels it, the request that asked for it answers 409 and nothing is stored."""

from __future__ import annotations

import threading
import time


def _walking(api, path: str, deadline_s: float = 60.0) -> dict:
    """The job walking ``path``, once it has walked a simulated second (polled as a viewer)."""
    end = time.monotonic() + deadline_s
    while time.monotonic() < end:
        for job in api.client.get("/api/jobs", headers=api.as_("viewer")).json():
            if job["path"] == path and job["state"] == "walking" and job["walked_s"] > 0:
                return job
        time.sleep(0.02)
    raise AssertionError(f"no job walked {path}")


def test_a_preview_walks_as_a_job_its_owner_watches_and_cancels(api):
    from backend.bench.preview import BenchmarkWalks

    api.client.app.state.benchmark_walks = BenchmarkWalks()   # none of this process's kept walks: this one walks
    prop = api.propose(api.new_patient()["id"], speed=1.2)
    path = f"/api/proposals/{prop['id']}"
    answer: dict = {}
    asker = threading.Thread(target=lambda: answer.update(
        r=api.client.get(f"{path}/preview", headers=api.as_("prosthetist"))))
    asker.start()
    try:
        job = _walking(api, path)
        assert job["kind"] == "table preview" and job["user"] == "prosthetist" and job["target"] == f"table {prop['id']}"
        assert 0 < job["fraction"] < 1 and job["seconds_left_s"] > 0 and job["words"].startswith("walking, ")
        assert job["expected_s"] >= job["walked_s"] and job["ahead"] == 0 and "table preview" in job["estimate_basis"]
        r = api.client.delete(f"/api/jobs/{job['id']}", headers=api.as_("viewer"))
        assert r.status_code == 403 and "prosthetist's" in r.json()["detail"]        # not theirs
        r = api.client.delete(f"/api/jobs/{job['id']}", headers=api.as_("prosthetist"))
        assert r.status_code == 200 and r.json()["cancelled_by"] == "prosthetist"
    finally:
        asker.join(60)
    r = answer["r"]
    assert r.status_code == 409 and r.json()["detail"] == (f"the table preview of table {prop['id']} was cancelled by "
                                                           "prosthetist; nothing was stored")
    assert api.count("previews") == 0
    after = api.client.get(f"/api/jobs/{job['id']}", headers=api.as_("viewer")).json()
    assert after["state"] == "cancelled" and after["words"] == "cancelled by prosthetist; nothing was stored"
    assert after["seconds_left_s"] == 0
    assert api.client.delete(f"/api/jobs/{job['id']}", headers=api.as_("prosthetist")).status_code == 409
    assert api.client.get("/api/jobs/999999", headers=api.as_("viewer")).status_code == 404
    r = api.client.get(f"{path}/preview", headers=api.as_("viewer"))        # asked again: walked whole, stored
    assert r.status_code == 200 and api.count("previews") == 1
    done = next(j for j in api.client.get("/api/jobs", headers=api.as_("viewer")).json() if j["state"] == "done")
    assert done["fraction"] == 1.0 and done["user"] == "viewer" and done["words"] == "done"
