"""``quasitune serve --workers 2``: two real worker processes behind one port, supervised by the parent."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import httpx
import pytest

from backend.loadbench import PASSWORD, add_user, connection_split, start_server

pytestmark = pytest.mark.skipif(not os.path.exists("/proc/self/task"), reason="reads process trees from /proc")


def _workers(parent_pid: int) -> list[int]:
    """Pids of the parent's worker processes (multiprocessing's spawned children, not its resource tracker)."""
    pids = []
    for task in Path(f"/proc/{parent_pid}/task").iterdir():
        for pid in (task / "children").read_text().split():
            try:
                cmdline = Path(f"/proc/{pid}/cmdline").read_bytes()
            except FileNotFoundError:
                continue
            if b"spawn_main" in cmdline:
                pids.append(int(pid))
    return sorted(pids)


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except FileNotFoundError:
        return False
    return state != "Z"


def _wait_gone(pids: list[int], timeout_s: float = 15.0) -> None:
    deadline = time.monotonic() + timeout_s
    while any(_alive(p) for p in pids):
        assert time.monotonic() < deadline, f"still running: {[p for p in pids if _alive(p)]}"
        time.sleep(0.05)


@pytest.fixture
def two_workers(tmp_path):
    add_user(tmp_path, "pat", "prosthetist")
    proc, base = start_server(tmp_path, workers=2)
    try:
        yield proc, base
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.wait(timeout=15)


def test_two_workers_listen_before_the_address_is_announced_and_serve_proposals(two_workers):
    proc, base = two_workers
    workers = _workers(proc.pid)
    assert len(workers) == 2
    # both processes listen when the line is printed: no connection is refused from the first moment
    token = httpx.post(f"{base}/api/auth/token", data={"username": "pat", "password": PASSWORD}, timeout=60).json()
    h = {"Authorization": f"Bearer {token['access_token']}"}
    patient = httpx.post(f"{base}/api/patients", headers=h,
                         json={"code_name": "W-1", "body_mass_kg": 70.0, "side": "left"}).json()
    ids = set()
    for i in range(12):   # a fresh connection each
        r = httpx.post(f"{base}/api/patients/{patient['id']}/proposals", headers=h,
                       json={"speed_mps": 0.9 + 0.05 * i, "incline_deg": 0.0}, timeout=60)
        assert r.status_code == 201, r.text
        ids.add(r.json()["id"])
    versions = httpx.get(f"{base}/api/patients/{patient['id']}/proposals", headers=h).json()
    assert sorted(v["version"] for v in versions) == list(range(1, 13)) and len(ids) == 12
    proc.send_signal(signal.SIGTERM)
    assert proc.wait(timeout=20) == 0
    _wait_gone(workers)


def test_keep_alive_connections_are_spread_evenly_over_the_workers(two_workers):
    """Least-connections accepting: 20 clients that stay connected end up 10 and 10 (the SO_REUSEPORT hash
    split them anywhere from 10/10 to 16/4)."""
    _proc, base = two_workers
    host, port = base.removeprefix("http://").rsplit(":", 1)
    clients = []
    try:
        for _ in range(20):
            sock = socket.create_connection((host, int(port)), timeout=30)
            clients.append(sock)
            sock.sendall(f"GET /api/health HTTP/1.1\r\nHost: {host}\r\n\r\n".encode())
            assert sock.recv(65536).startswith(b"HTTP/1.1 200")     # accepted and answered, still open
        split = connection_split(int(port), [s.getsockname()[1] for s in clients])
        assert split == [10, 10]
    finally:
        for sock in clients:
            sock.close()


def test_a_worker_that_dies_stops_the_server_loudly(two_workers, tmp_path):
    proc, _base = two_workers
    first, second = _workers(proc.pid)
    os.kill(first, signal.SIGKILL)
    assert proc.wait(timeout=20) == 1
    _wait_gone([second])
    assert f"pid {first}, exit status -9" in (tmp_path / "serve.stderr.log").read_text()


def test_workers_die_with_a_parent_killed_by_sigkill(two_workers):
    proc, _base = two_workers
    workers = _workers(proc.pid)
    assert len(workers) == 2
    proc.kill()
    proc.wait(timeout=10)
    _wait_gone(workers)


def test_cli_refuses_several_workers_with_a_device(tmp_path):
    r = subprocess.run([sys.executable, "-m", "backend.cli", "serve", "--workers", "2", "--device", "sim",
                        "--data-dir", str(tmp_path)], capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and "--workers 1" in r.stderr
