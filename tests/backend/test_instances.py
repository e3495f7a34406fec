"""Two API instances on one database (the deployment with several servers): what one decides, the other cannot decide
again; what one counts, the other sees. On SQLite (two processes' worth of connections to one file) and PostgreSQL."""

from __future__ import annotations

import threading
import time

import pytest
from fastapi.testclient import TestClient

from backend.app import create_app
from backend.settings import Settings
from tests.helpers.api import FIXTURE_OVERRIDE, cosign, make_api


@pytest.fixture
def two(tmp_path, model, api_storage):
    """(first instance's Api, a second instance's TestClient): two apps, one database, the same signed-in users."""
    api, first = make_api(tmp_path, lambda: model, **api_storage)
    shared = {k: v for k, v in api_storage.items() if k == "database_url"}      # SQLite: the first's file in data_dir
    second = TestClient(create_app(Settings(data_dir=tmp_path, **shared), model_loader=lambda: model))
    with first, second:
        yield api, second


def _at_once(calls) -> list:
    """Run the calls at the same moment (a barrier before each), their responses in order."""
    barrier, out = threading.Barrier(len(calls)), [None] * len(calls)

    def run(i: int, call) -> None:
        barrier.wait()
        out[i] = call()

    threads = [threading.Thread(target=run, args=(i, c)) for i, c in enumerate(calls)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return out


@pytest.mark.parametrize("round_", range(2))
def test_two_instances_approving_one_version_at_once_decide_it_once(two, round_, monkeypatch):
    """Both read the draft before either writes (the bench's verdict, read between, is slowed to make sure of it):
    exactly one approval is taken and audited, the other is refused."""
    from backend.services import decisions

    real = decisions.require_bench

    def slow_bench(*args, **kwargs):
        time.sleep(0.3)        # widens the race window (not a wait for anything): the other approval comes meanwhile
        return real(*args, **kwargs)

    monkeypatch.setattr(decisions, "require_bench", slow_bench)
    api, second = two
    proposal = api.propose(api.new_patient(code=f"P-{round_}")["id"])
    cosign(api, "proposal", proposal["id"])        # not walked: the approver's sign-off is the second
    body = {"comment": "looked at it", "override_reason": FIXTURE_OVERRIDE}
    url = f"/api/proposals/{proposal['id']}/approve"
    headers = api.as_("prosthetist")
    answers = _at_once([lambda: api.client.post(url, headers=headers, json=body),
                        lambda: second.post(url, headers=headers, json=body)])
    assert sorted(r.status_code for r in answers) == [200, 409], [r.text for r in answers]
    audit = api.client.get("/api/audit", headers=api.as_("admin"),
                           params={"entity": "proposal", "entity_id": proposal["id"]}).json()["items"]
    assert [e["action"] for e in audit].count("proposal.approve") == 1


def test_two_instances_numbering_one_patients_versions_at_once_never_collide(two):
    api, second = two
    patient = api.new_patient()
    url, headers = f"/api/patients/{patient['id']}/proposals", api.as_("prosthetist")
    calls = [lambda c=c, s=s: c.post(url, headers=headers, json={"speed_mps": s, "incline_deg": 0.0})
             for c, s in ((api.client, 1.0), (second, 1.1), (api.client, 1.2), (second, 1.3))]
    answers = _at_once(calls)
    assert [r.status_code for r in answers] == [201] * 4, [r.text for r in answers]
    assert sorted(r.json()["version"] for r in answers) == [1, 2, 3, 4]


def test_a_lock_out_earned_at_one_instance_holds_at_the_other(two):
    api, second = two
    for _ in range(5):
        r = api.client.post("/api/auth/token", data={"username": "viewer", "password": "wrong password"})
        assert r.status_code == 401
    refused = second.post("/api/auth/token", data={"username": "viewer", "password": "wrong password"})
    assert refused.status_code == 429 and int(refused.headers["Retry-After"]) > 0
