"""Telemetry storage benchmark (``python -m benchmarks storage``): what an hour of walking costs on each database.

1. A real ``quasitune serve`` with the simulated leg records ``record_s`` seconds of a walking session (its table
   approved with a written override: the figure here is storage, not the bench's verdict); the samples it stored are
   read back from its database.
2. That recording, repeated with its sequence numbers and times moved on, makes ``hours`` of walking (said in the
   output). It is written to a fresh SQLite file and to a fresh PostgreSQL database (a throwaway server,
   tests/helpers/postgres.py) the way the recorder writes it: each second of walking once it is complete.
3. Per database: bytes of the samples' table per walking hour (SQLite's ``dbstat``; PostgreSQL's
   ``pg_total_relation_size``: table, TOAST and key index), the same hour stored a row per sample (the layout before
   revision 0014) for comparison, the write time, and the time to read the hour back for a report (checked equal).
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from sqlalchemy import Column, Connection, Double, Integer, MetaData, PrimaryKeyConstraint, Table, Text, insert, text

from backend.db import connect, write_transaction
from backend.migrate import migrate
from backend.settings import DB_FILE
from backend.store import sessions
from backend.store.sample_pack import COLUMNS, SAMPLES_PER_ROW
from tests.helpers.server import PASSWORD, add_user, start_server, stop_server

OVERRIDE = "storage benchmark: the table is walked to record telemetry, not to judge it"
BATCH = 100   # the recorder writes each second of walking once it is complete


def _record(data_dir: Path, seconds: float) -> int:
    """Walk ``seconds`` on a real server's simulated leg in a recorded session; its id."""
    import httpx

    add_user(data_dir, "bench", "prosthetist")
    proc, base = start_server(data_dir, device="sim")
    try:
        with httpx.Client(base_url=base, timeout=60.0) as c:
            while c.get("/api/health").json()["model"] != "ready":
                time.sleep(0.1)
            token = c.post("/api/auth/token", data={"username": "bench", "password": PASSWORD}).json()["access_token"]
            c.headers["Authorization"] = f"Bearer {token}"
            patient = c.post("/api/patients", json={"code_name": "STO-1", "body_mass_kg": 75.0, "side": "left"}).json()
            while not c.get("/api/devices/sim-leg-1").json()["online"]:
                time.sleep(0.05)
            c.put("/api/devices/sim-leg-1/assignment", json={"patient_id": patient["id"]}).raise_for_status()
            prop = c.post(f"/api/patients/{patient['id']}/proposals", json={"speed_mps": 1.2, "incline_deg": 0.0}).json()
            c.post(f"/api/proposals/{prop['id']}/approve",
                   json={"comment": "bench", "override_reason": OVERRIDE}).raise_for_status()
            c.post(f"/api/proposals/{prop['id']}/push", json={"device_id": "sim-leg-1", "patient_ready": True,
                                                              "replaces_proposal_id": None,
                                                              "override_reason": OVERRIDE}).raise_for_status()
            deadline = time.monotonic() + 30
            while (r := c.post(f"/api/patients/{patient['id']}/sessions", json={"device_id": "sim-leg-1"})
                   ).status_code == 409 and time.monotonic() < deadline:
                time.sleep(0.2)      # the pushed table runs from the leg's next heel strike
            r.raise_for_status()
            session_id = r.json()["id"]
            time.sleep(seconds)
            c.post(f"/api/sessions/{session_id}/stop").raise_for_status()
    finally:
        stop_server(proc)
    return session_id


def _hour(recorded: list[tuple], hours: float) -> list[tuple]:
    """The recording repeated to ``hours`` of samples, sequence numbers and times moved on."""
    n = int(hours * 3600 * 100)
    span_s = recorded[-1][1] - recorded[0][1] + 0.01
    out, k = [], 0
    while len(out) < n:
        for r in recorded:
            if len(out) == n:
                break
            out.append((len(out), r[1] + k * span_s, *r[2:]))
        k += 1
    return out


def _rowwise_table() -> Table:
    """The layout before revision 0014: a row per sample, keyed by (session, sequence)."""
    types = {"seq": Integer, "mode": Integer, "fsm_state": Integer, "adaptive_mode": Text}
    return Table("samples_a_row_each", MetaData(), Column("session_id", Integer, nullable=False),
                 *(Column(c, types.get(c, Double)) for c in COLUMNS), PrimaryKeyConstraint("session_id", "seq"),
                 sqlite_with_rowid=False)


def _bytes(conn: Connection, table: str) -> int:
    if conn.dialect.name == "sqlite":
        return int(conn.execute(text("SELECT sum(pgsize) FROM dbstat WHERE name = :t"),
                                {"t": table}).scalar() or 0)
    conn.exec_driver_sql("VACUUM ANALYZE")
    return int(conn.execute(text("SELECT pg_total_relation_size(:t)"), {"t": table}).scalar())


def _measure(database: str | Path, samples: list[tuple], hours: float) -> dict:
    migrate(database)
    conn = connect(database)
    try:
        with write_transaction(conn):
            conn.exec_driver_sql("INSERT INTO users (username, role, password_hash, created_at) VALUES "
                                 "('b', 'prosthetist', 'x', 't')")
            conn.exec_driver_sql("INSERT INTO patients (code_name, body_mass_kg, side, created_by, created_at, "
                                 "updated_at) VALUES ('B-1', 75, 'left', 1, 't', 't')")
            conn.exec_driver_sql("INSERT INTO devices (id, kind, interface, channel, registered_at) VALUES "
                                 "('leg', 'simulated', 'virtual', 'a', 't')")
            conn.exec_driver_sql("INSERT INTO walking_sessions (patient_id, device_id, speed_mps, incline_deg, "
                                 "body_mass_kg, status, started_by, started_at) VALUES (1, 'leg', 1.2, 0, 75, "
                                 "'recording', 1, 't')")
        t0 = time.perf_counter()
        for i in range(0, len(samples), BATCH):
            sessions.add_samples(conn, 1, samples[i:i + BATCH])
        write_s = time.perf_counter() - t0
        t0 = time.perf_counter()
        back = sessions.samples(conn, 1)
        read_s = time.perf_counter() - t0
        if [tuple(back[c][i] for c in COLUMNS) for i in range(len(back["seq"]))] != samples:
            raise AssertionError("the hour did not read back as written")
        packed = _bytes(conn, "session_sample_seconds")
        old = _rowwise_table()
        old.create(conn)
        rows = [{"session_id": 1, **dict(zip(COLUMNS, s, strict=True))} for s in samples]
        with write_transaction(conn):
            for i in range(0, len(rows), 5000):
                conn.execute(insert(old), rows[i:i + 5000])
        rowwise = _bytes(conn, old.name)
    finally:
        conn.close()
    return {"bytes_per_walking_hour": round(packed / hours), "row_per_sample_bytes_per_walking_hour":
            round(rowwise / hours), "bytes_per_sample": round(packed / len(samples), 1),
            "write_s_per_walking_hour": round(write_s / hours, 2), "read_back_s_per_walking_hour": round(read_s / hours, 3)}


def run(record_s: float = 60.0, hours: float = 1.0) -> dict:
    with tempfile.TemporaryDirectory(prefix="quasitune-storagebench-") as tmp:
        server_dir = Path(tmp) / "server"
        server_dir.mkdir()
        session_id = _record(server_dir, record_s)
        conn = connect(server_dir / DB_FILE)
        try:
            cols = sessions.samples(conn, session_id)
        finally:
            conn.close()
        recorded = [tuple(cols[c][i] for c in COLUMNS) for i in range(len(cols["seq"]))]
        samples = _hour(recorded, hours)
        out = {"recorded_s": round(len(recorded) / 100, 1), "walking_hours_written": hours,
               "how": f"{len(recorded)} samples recorded by a server with the simulated leg, repeated to "
                      f"{len(samples)} ({SAMPLES_PER_ROW} per stored row)",
               "sqlite": _measure(Path(tmp) / "hour.sqlite", samples, hours)}
        from tests.helpers.postgres import PostgresServer

        server = PostgresServer()
        try:
            server.start()
            with server.new_database() as url:
                out["postgresql"] = _measure(url, samples, hours)
        finally:
            server.stop()
    return out
