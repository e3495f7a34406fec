"""Several API instances on one database (``python -m benchmarks instances``): throughput, latency, and what survives a
killed instance.

Configurations, each a fresh database and real ``quasitune serve`` processes on loopback (no device: this measures the
store and the API):

* ``sqlite_1``: today's embedded default, one process on the SQLite file;
* ``postgresql_1``: one instance on PostgreSQL (a throwaway server, tests/helpers/postgres.py);
* ``postgresql_2``: two instances on that database, the clients split between them;
* ``postgresql_2_killed``: two instances for ``kill_seconds``, the second killed with SIGKILL at one third and two
  thirds of the run and restarted on its port at once.

``clients`` clients each run one request at a time, mixing reads (a version, a patient's list), new proposals, edits,
approvals (with a written override: the bench's verdict is not what is measured) and small envelopes over a few
patients. A client whose instance drops its connection moves to the other (what the proxy's ``proxy_next_upstream``
does; nginx is not started here) and the dropped request is counted as dropped, not as an answer.

Afterwards the database is checked: every acknowledged write (201 or 200) is there as answered, no version was
decided twice (at most one decision in the audit log per version, and at most one 200 per approval), versions are
numbered 1…n per patient, and every decided version has its decision in the audit log. Per configuration:
requests per second and p50/p95/p99 per endpoint class, 5xx answers, dropped connections, the checks.
"""

from __future__ import annotations

import asyncio
import os
import random
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

import numpy as np
from sqlalchemy import func, select

from backend.db import connect
from backend.migrate import migrate
from backend.settings import DB_FILE
from backend.store.tables import audit_log, versions
from backend.store.users import create_user

PASSWORD = "benchmark password"
OVERRIDE = "instances benchmark: measuring the store, not the bench's verdict"
PATIENTS = 4
WEIGHTS = {"read": 40, "propose": 25, "edit": 15, "approve": 15, "envelope": 5}


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Instance:
    """One ``quasitune serve`` on a fixed loopback port (so a restarted one is found where it was), serving ``device``
    (none: the store and the API alone), with ``env`` added to its environment."""

    def __init__(self, data_dir: Path, database_url: str | None, device: str = "none",
                 env: dict[str, str] | None = None) -> None:
        self.data_dir, self.port, self.proc, self.device = data_dir, _free_port(), None, device
        self.env = {**os.environ, "PYTHONUNBUFFERED": "1", "QUASITUNE_DEVICE": device, **(env or {})}
        if database_url:
            self.env["QUASITUNE_DATABASE_URL"] = database_url

    @property
    def base(self) -> str:
        return f"http://127.0.0.1:{self.port}"

    def start(self) -> None:
        self.spawn()
        self.ready()

    def spawn(self) -> None:
        """Start the process (several can start side by side before :meth:`ready`)."""
        cmd = [sys.executable, "-m", "backend.cli", "serve", "--port", str(self.port), "--data-dir",
               str(self.data_dir), "--device", self.device, "--no-bootstrap-user"]
        self.proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, env=self.env)

    def ready(self) -> None:
        """Wait for the process to say it listens."""
        line = self.proc.stdout.readline()
        if "listening on" not in line:
            raise RuntimeError(f"instance on port {self.port} did not start: {line!r}")

    def kill(self) -> None:
        self.proc.send_signal(signal.SIGKILL)
        self.proc.wait(10)

    def stop(self) -> None:
        if self.proc and self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(5)
            except subprocess.TimeoutExpired:
                self.kill()


class Load:
    """The mixed clients and what they saw."""

    def __init__(self, bases: list[str], token: str, patients: list[int], seed: int) -> None:
        self.bases, self.headers, self.patients = bases, {"Authorization": f"Bearer {token}"}, patients
        self.rng = random.Random(seed)
        self.latency: dict[str, list[float]] = defaultdict(list)
        self.status: dict[str, dict[int, int]] = defaultdict(lambda: defaultdict(int))
        self.dropped = 0
        self.proposals: dict[int, tuple[int, int]] = {}     # acknowledged: id -> (patient, version)
        self.envelopes: dict[int, tuple[int, int]] = {}
        self.drafts: list[int] = []
        self.approved_200: dict[int, int] = defaultdict(int)

    def _request(self, kind: str) -> tuple[str, str, str, dict | None]:
        """(class, method, path, body) of one request of ``kind``; a new proposal while there is nothing to read,
        edit or approve yet."""
        rng, pid = self.rng, self.rng.choice(self.patients)
        known = list(self.proposals)
        if kind == "read" and known:
            pick = rng.choice(known)
            return ("read", "GET", f"/api/proposals/{pick}", None) if rng.random() < 0.5 else \
                ("read", "GET", f"/api/patients/{self.proposals[pick][0]}/proposals", None)
        if kind == "edit" and self.drafts:
            return "edit", "POST", f"/api/proposals/{rng.choice(self.drafts)}/edits", {
                "rows": [{"joint": "knee", "subphase": "swing_flexion",
                          "theta_e_deg": round(rng.uniform(55, 62), 1)}], "comment": "benchmark edit"}
        if kind == "approve" and self.drafts:
            return "approve", "POST", f"/api/proposals/{rng.choice(self.drafts)}/approve", {
                "comment": "benchmark", "override_reason": OVERRIDE}
        if kind == "envelope":
            return "envelope", "POST", f"/api/patients/{pid}/envelopes", {
                "grid": [2, 2], "speed_range_mps": [0.8, 1.4], "incline_range_deg": [-5.0, 5.0]}
        return "propose", "POST", f"/api/patients/{pid}/proposals", {"speed_mps": round(rng.uniform(0.6, 1.8), 3),
                                                                     "incline_deg": round(rng.uniform(-8, 8), 2)}

    def _note(self, kind: str, path: str, status: int, body: dict) -> None:
        if kind in ("propose", "edit") and status == 201:
            self.proposals[body["id"]] = (body["patient_id"], body["version"])
            self.drafts.append(body["id"])
        elif kind == "envelope" and status == 201:
            self.envelopes[body["id"]] = (body["patient_id"], body["version"])
        elif kind == "approve" and status == 200:
            pid = int(path.split("/")[3])
            self.approved_200[pid] += 1
            if pid in self.drafts:
                self.drafts.remove(pid)

    async def client(self, index: int, deadline: float) -> None:
        import httpx

        home = index % len(self.bases)
        clients = [httpx.AsyncClient(base_url=b, headers=self.headers, timeout=60.0) for b in self.bases]
        kinds, weights = zip(*WEIGHTS.items(), strict=True)
        try:
            while time.perf_counter() < deadline:
                kind, method, path, body = self._request(self.rng.choices(kinds, weights)[0])
                t0 = time.perf_counter()
                try:
                    r = await clients[home].request(method, path, json=body)
                except httpx.TransportError:    # its instance died under it: the proxy would go to the other
                    self.dropped += 1
                    home = (home + 1) % len(self.bases)
                    await asyncio.sleep(0.05)
                    continue
                self.latency[kind].append(time.perf_counter() - t0)
                self.status[kind][r.status_code] += 1
                self._note(kind, path, r.status_code, r.json() if r.status_code in (200, 201) else {})
        finally:
            for c in clients:
                await c.aclose()


def _percentiles(values: list[float]) -> dict:
    ms = np.array(values) * 1e3
    return {"n": int(ms.size), **{f"p{q}_ms": round(float(np.percentile(ms, q)), 1) for q in (50, 95, 99)}}


def _checks(database: str | Path, load: Load) -> dict:
    """The database against what the clients were told."""
    conn = connect(database)
    try:
        v = versions
        stored = {r.id: (r.patient_id, r.version, r.status) for r in conn.execute(
            select(v.c.id, v.c.patient_id, v.c.version, v.c.status).where(v.c.kind == "table"))}
        stored_env = {r.id: (r.patient_id, r.version) for r in conn.execute(
            select(v.c.id, v.c.patient_id, v.c.version).where(v.c.kind == "envelope"))}
        decisions = dict(conn.execute(
            select(audit_log.c.entity_id, func.count()).where(
                audit_log.c.entity == "proposal", audit_log.c.action.in_(("proposal.approve", "proposal.reject")))
            .group_by(audit_log.c.entity_id)).all())
    finally:
        conn.close()
    lost = [i for i, (p, v) in load.proposals.items() if stored.get(i, (None, None))[:2] != (p, v)]
    lost += [i for i, pv in load.envelopes.items() if stored_env.get(i) != pv]
    by_patient: dict[int, list[int]] = defaultdict(list)
    for p, v, _ in stored.values():
        by_patient[p].append(v)
    numbering_ok = all(sorted(vs) == list(range(1, len(vs) + 1)) for vs in by_patient.values())
    decided_twice = [i for i, n in decisions.items() if n > 1] + [i for i, n in load.approved_200.items() if n > 1]
    undocumented = [i for i, (_, _, s) in stored.items() if (s != "draft") != (decisions.get(i, 0) == 1)]
    return {"acknowledged_writes": len(load.proposals) + len(load.envelopes), "acknowledged_writes_lost": len(lost),
            "decisions_taken_twice": len(decided_twice), "versions_numbered_1_to_n": numbering_ok,
            "decisions_without_their_audit_entry": len(undocumented)}


def _setup(database: str | Path) -> None:
    migrate(database)
    conn = connect(database)
    try:
        create_user(conn, "bench", "prosthetist", PASSWORD)
    finally:
        conn.close()


async def _drive(instances: list[Instance], clients: int, seconds: float, kill_at: list[float]) -> Load:
    import httpx

    async with httpx.AsyncClient(base_url=instances[0].base, timeout=60.0) as c:
        while (await c.get("/api/health")).json()["model"] != "ready":
            await asyncio.sleep(0.1)
        token = (await c.post("/api/auth/token", data={"username": "bench", "password": PASSWORD})).json()
        h = {"Authorization": f"Bearer {token['access_token']}"}
        patients = [(await c.post("/api/patients", headers=h, json={
            "code_name": f"INS-{i}", "body_mass_kg": 75.0, "side": "left"})).json()["id"] for i in range(PATIENTS)]
    for inst in instances[1:]:
        async with httpx.AsyncClient(base_url=inst.base, timeout=60.0) as c:
            while (await c.get("/api/health")).json()["model"] != "ready":
                await asyncio.sleep(0.1)
    load = Load([i.base for i in instances], token["access_token"], patients, seed=len(instances))
    t0 = time.perf_counter()

    async def killer() -> None:
        for at in kill_at:
            await asyncio.sleep(max(0.0, t0 + at - time.perf_counter()))
            instances[-1].kill()
            await asyncio.to_thread(instances[-1].start)

    await asyncio.gather(*(load.client(i, t0 + seconds) for i in range(clients)), killer())
    load.wall_s = time.perf_counter() - t0
    return load


def _configuration(tmp: Path, name: str, url: str | None, n: int, clients: int, seconds: float,
                   kills: int = 0) -> dict:
    """``n`` instances on PostgreSQL at ``url``, or on the SQLite file of their data directory (``url`` None)."""
    data_dir = tmp / name
    data_dir.mkdir()
    database = url or data_dir / DB_FILE
    _setup(database)
    instances = [Instance(data_dir, url) for _ in range(n)]
    try:
        for inst in instances:
            inst.start()
        load = asyncio.run(_drive(instances, clients, seconds, [seconds * (k + 1) / (kills + 1) for k in range(kills)]))
    finally:
        for inst in instances:
            inst.stop()
    answers = sum(len(v) for v in load.latency.values())
    server_errors = sum(c for k in load.status.values() for s, c in k.items() if s >= 500)
    return {"instances": n, "clients": clients, "seconds": round(load.wall_s, 1), "sigkills": kills,
            "requests_per_s": round(answers / load.wall_s, 1),
            "by_class": {k: {**_percentiles(v), "status": dict(sorted(load.status[k].items()))}
                         for k, v in sorted(load.latency.items())},
            "answers_5xx": server_errors, "dropped_connections": load.dropped, **_checks(database, load)}


def run(clients: int = 20, seconds: float = 20.0, kill_seconds: float = 60.0) -> dict:
    from tests.helpers.postgres import PostgresServer

    out: dict = {"note": "real quasitune serve processes on loopback, no device; clients mix reads, proposals, edits, "
                         "approvals with a written override and 2 x 2 envelopes over 4 patients"}
    with tempfile.TemporaryDirectory(prefix="quasitune-instances-") as tmp_name:
        tmp = Path(tmp_name)
        out["sqlite_1"] = _configuration(tmp, "sqlite_1", None, 1, clients, seconds)
        server = PostgresServer()
        try:
            server.start()
            for name, n, secs, kills in (("postgresql_1", 1, seconds, 0), ("postgresql_2", 2, seconds, 0),
                                         ("postgresql_2_killed", 2, kill_seconds, 2)):
                with server.new_database() as url:
                    out[name] = _configuration(tmp, name, url, n, clients, secs, kills)
        finally:
            server.stop()
    return out
