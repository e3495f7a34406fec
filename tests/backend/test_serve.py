"""A real quasitune serve subprocess on a loopback port with a temporary database."""

from __future__ import annotations

import os
import signal
import subprocess
import threading

import httpx
import pytest

from tests.helpers.device import until
from tests.helpers.server import PASSWORD, add_user, start_server

pytestmark = pytest.mark.wallclock


def _wait_ready(base: str, timeout_s: float = 60.0) -> None:
    until(lambda: httpx.get(f"{base}/api/health").json()["model"] == "ready", timeout_s, poll_s=0.1)


def _login(base: str, name: str, password: str = PASSWORD) -> dict[str, str]:
    r = httpx.post(f"{base}/api/auth/token", data={"username": name, "password": password})
    assert r.status_code == 200, r.text
    return {"Authorization": f"Bearer {r.json()['access_token']}"}


def _stop(proc: subprocess.Popen) -> None:
    proc.send_signal(signal.SIGINT)
    try:
        proc.wait(timeout=15)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


def test_first_start_prints_a_password_once_and_a_restart_keeps_everything(tmp_path):
    proc, base = start_server(tmp_path, bootstrap=True)
    try:
        assert base.startswith("http://127.0.0.1:")
        assert "dashboard: http://127.0.0.1:" in proc.stdout.readline()
        assert "database:" in proc.stdout.readline()
        assert "first start" in proc.stdout.readline()
        printed = {}
        for _ in range(2):            # an admin who manages accounts in the dashboard, and a prosthetist
            line = proc.stdout.readline()
            name = line.split("user '", 1)[1].split("'", 1)[0]
            printed[name] = line.rsplit("password ", 1)[1].strip()
        assert set(printed) == {"admin", "prosthetist"}
        _wait_ready(base)
        admin = _login(base, "admin", printed["admin"])
        assert httpx.get(f"{base}/api/users", headers=admin).status_code == 403     # one-time: its own password first
        assert httpx.post(f"{base}/api/auth/password", headers=admin, json={
            "current_password": printed["admin"], "new_password": "the clinic's admin passphrase"}).status_code == 200
        added = httpx.post(f"{base}/api/users", headers=admin,
                           json={"username": "kim", "role": "prosthetist", "password": "a first password for kim"})
        assert added.status_code == 201, added.text                       # the first account manages users
        password = printed["prosthetist"]
        h = _login(base, "prosthetist", password)
        # the printed password is one-time: nothing but changing it works
        assert httpx.get(f"{base}/api/patients", headers=h).status_code == 403
        assert httpx.get(f"{base}/api/auth/me", headers=h).json()["must_change_password"]
        changed = httpx.post(f"{base}/api/auth/password", headers=h,
                             json={"current_password": password, "new_password": "my own long password"})
        assert changed.status_code == 200 and not changed.json()["must_change_password"]
        password = "my own long password"
        patient = httpx.post(f"{base}/api/patients", headers=h,
                             json={"code_name": "SRV-1", "body_mass_kg": 71.0, "side": "right"}).json()
        proposal = httpx.post(f"{base}/api/patients/{patient['id']}/proposals", headers=h,
                              json={"speed_mps": 1.1, "incline_deg": 0.0}).json()
        assert httpx.get(f"{base}/api/proposals/{proposal['id']}/preview", headers=h,
                         timeout=60).status_code == 200   # approval rests on the bench
        approved = httpx.post(f"{base}/api/proposals/{proposal['id']}/approve", headers=h,
                              json={"comment": "looks right"}).json()
        assert approved["status"] == "approved"
    finally:
        _stop(proc)
    assert proc.returncode in (0, -signal.SIGINT)    # shut down on the interrupt, not killed (-9) or crashed
    proc, base2 = start_server(tmp_path, bootstrap=True)   # users exist now: nothing created, nothing printed
    try:
        h = _login(base2, "prosthetist", password)
        again = httpx.get(f"{base2}/api/proposals/{proposal['id']}", headers=h).json()
        assert again["status"] == "approved" and again["decision"]["comment"] == "looks right"
        assert again["table"] == approved["table"] and again["table_sha256"] == approved["table_sha256"]
        assert httpx.get(f"{base2}/api/patients/{patient['id']}", headers=h).json()["code_name"] == "SRV-1"
        actions = [e["action"] for e in httpx.get(f"{base2}/api/audit", headers=h).json()["items"]]
        assert {"patient.create", "proposal.create", "proposal.approve"} <= set(actions)
    finally:
        _stop(proc)
    assert "created user" not in proc.stdout.read()


def test_sigkill_mid_load_loses_no_acknowledged_write(tmp_path):
    add_user(tmp_path, "pat", "prosthetist")
    proc, base = start_server(tmp_path)
    _wait_ready(base)
    h = _login(base, "pat")
    patient = httpx.post(f"{base}/api/patients", headers=h,
                         json={"code_name": "KILL-1", "body_mass_kg": 75.0, "side": "left"}).json()
    acknowledged: list[int] = []
    patients_acked: list[str] = []
    stop = threading.Event()

    def writer(i: int) -> None:
        with httpx.Client(base_url=base, headers=h, timeout=10) as c:
            n = 0
            while not stop.is_set():
                n += 1
                try:
                    if n % 3:
                        r = c.post(f"/api/patients/{patient['id']}/proposals", json={"speed_mps": 0.8 + (n % 10) / 10})
                        if r.status_code == 201:
                            acknowledged.append(r.json()["id"])
                    else:
                        code = f"K-{i}-{n}"
                        r = c.post("/api/patients", json={"code_name": code, "body_mass_kg": 70.0, "side": "left"})
                        if r.status_code == 201:
                            patients_acked.append(code)
                except httpx.HTTPError:
                    return   # the server is gone

    threads = [threading.Thread(target=writer, args=(i,)) for i in range(6)]
    for t in threads:
        t.start()
    until(lambda: len(acknowledged) > 20, 60.0, poll_s=0.05)   # the load under way, by what the server acknowledged
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    stop.set()
    for t in threads:
        t.join(15)
    assert len(acknowledged) > 20, "the load did not get going before the kill"
    proc, base = start_server(tmp_path)
    try:
        h = _login(base, "pat")
        stored: set[int] = set()
        params: dict = {"limit": 200}
        while True:   # every page of the version list
            r = httpx.get(f"{base}/api/patients/{patient['id']}/proposals", headers=h, params=params)
            stored |= {p["id"] for p in r.json()}
            if "X-Next-Before-Version" not in r.headers:
                break
            params["before_version"] = r.headers["X-Next-Before-Version"]
        assert len(stored) == int(r.headers["X-Total-Count"])
        assert set(acknowledged) <= stored
        codes = {p["code_name"] for p in httpx.get(f"{base}/api/patients", headers=h).json()}
        assert set(patients_acked) <= codes
        # every stored proposal is whole: its table re-validates against its sha256 and has its audit entry
        audited = {e["entity_id"] for e in httpx.get(f"{base}/api/audit", headers=h,
                                                      params={"entity": "proposal", "limit": 1000}).json()["items"]}
        assert stored <= audited
        for pid in list(stored)[:: max(1, len(stored) // 10)]:
            assert httpx.get(f"{base}/api/proposals/{pid}", headers=h).status_code == 200
    finally:
        _stop(proc)
