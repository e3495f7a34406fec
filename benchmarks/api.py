"""Load benchmark of ``POST /api/patients/{id}/proposals`` (``python -m benchmarks api``; figures, not a test).

Starts ``quasitune serve`` in a subprocess on a free loopback port with a temporary database and the simulated
leg walking, creates a prosthetist and a patient, warms up, then runs ``clients`` concurrent clients (each one
request at a time, back to back, over its own keep-alive connection) for ``seconds``. Tasks are drawn at random
over the model's range (speed 0.5–2.0 m/s, incline ±10°) so no two requests are alike. Reports proposals per
second and latency percentiles (any non-201 answer is counted), and, from a WebSocket client subscribed during
the measured window, the telemetry rate and its sequence gaps: the leg's stream must not suffer from the load.

The clients speak HTTP/1.1 directly over asyncio streams: the load generator shares the two cores with the
server, and a full HTTP client library spent as much CPU per request as the server did, which measured the
generator rather than the server. Setup and checks still go through httpx.
"""

from __future__ import annotations

import asyncio
import itertools
import json
import os
import random
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from tests.helpers.server import PASSWORD, temporary_server_process

DEVICE = "sim-leg-1"


async def _post(reader: asyncio.StreamReader, writer: asyncio.StreamWriter, host: str, path: str,
                authorization: str, body: bytes) -> int:
    """One keep-alive HTTP/1.1 POST of a JSON body; returns the status after reading the whole answer."""
    writer.write(f"POST {path} HTTP/1.1\r\nHost: {host}\r\nAuthorization: {authorization}\r\n"
                 f"Content-Type: application/json\r\nContent-Length: {len(body)}\r\n\r\n".encode() + body)
    await writer.drain()
    head = await reader.readuntil(b"\r\n\r\n")
    lines = head.decode("latin-1").split("\r\n")
    status = int(lines[0].split(" ", 2)[1])
    length = next((int(h.split(":", 1)[1]) for h in lines[1:] if h.lower().startswith("content-length:")), None)
    if length is None:
        raise RuntimeError(f"answer without Content-Length: {lines[0]}")
    await reader.readexactly(length)
    return status


async def _telemetry(ws_url: str, stop: asyncio.Event) -> dict:
    """Count the telemetry samples a WebSocket client receives until ``stop``, and the gaps in their ``seq``."""
    import websockets

    seqs: list[int] = []
    arrivals: list[float] = []
    async with websockets.connect(ws_url, max_queue=None) as ws:
        t0 = time.perf_counter()
        while not stop.is_set():
            try:
                msg = json.loads(await asyncio.wait_for(ws.recv(), 0.5))
            except TimeoutError:
                continue
            if msg["type"] == "telemetry":
                seqs.append(msg["seq"])
                arrivals.append(time.perf_counter())
        wall = time.perf_counter() - t0
    gaps = sum(1 for a, b in itertools.pairwise(seqs) if (b - a) % 65536 != 1)
    spans = [(b - a, a - t0) for a, b in itertools.pairwise(arrivals)] or [(wall, 0.0)]
    largest, at = max(spans)
    return {"telemetry_hz": round(len(seqs) / wall, 1), "telemetry_sequence_gaps": gaps,
            "telemetry_largest_gap_ms": round(largest * 1e3, 1), "telemetry_largest_gap_at_s": round(at, 2),
            "telemetry_gaps_over_100ms": sum(1 for g, _ in spans if g > 0.1)}


async def _reads(base: str, headers: dict, paths: list[str], clients: int, seconds: float, ws_url: str) -> dict:
    """``clients`` clients reading ``paths`` in turn for ``seconds`` while one WebSocket client takes the telemetry:
    what a clinic's list pages cost the live stream."""
    import httpx

    latencies: list[float] = []
    codes: dict[int, int] = {}

    async def reader(c: httpx.AsyncClient, i: int, deadline: float) -> None:
        n = i
        while time.perf_counter() < deadline:
            t0 = time.perf_counter()
            r = await c.get(paths[n % len(paths)])
            latencies.append(time.perf_counter() - t0)
            codes[r.status_code] = codes.get(r.status_code, 0) + 1
            n += 1

    # the clients are made before the stream is measured: making one builds an SSL context (tens of ms of this
    # process's own event loop, where the telemetry is received), which would read as a gap in the server's stream
    readers = [httpx.AsyncClient(base_url=base, headers=headers, timeout=30.0) for _ in range(clients)]
    stop = asyncio.Event()
    telemetry = asyncio.create_task(_telemetry(ws_url, stop))
    await asyncio.sleep(0.5)
    t_start = time.perf_counter()
    await asyncio.gather(*(reader(c, i, t_start + seconds) for i, c in enumerate(readers)))
    stop.set()
    stream = await telemetry
    for c in readers:
        await c.aclose()
    lat = np.array(latencies) * 1e3
    return {"read_requests": int(lat.size), "read_p50_ms": round(float(np.percentile(lat, 50)), 2),
            "read_p99_ms": round(float(np.percentile(lat, 99)), 2), "read_non_200": sum(v for k, v in codes.items()
                                                                                     if k != 200),
            **{f"reads_{k}": v for k, v in stream.items()}}


async def _run(base: str, clients: int, seconds: float, server_cpu_s: Callable[[], float | None]) -> dict:
    import httpx

    async with httpx.AsyncClient(base_url=base, timeout=30.0) as setup:
        while (await setup.get("/api/health")).json()["model"] != "ready":
            await asyncio.sleep(0.1)
        token = (await setup.post("/api/auth/token", data={"username": "bench", "password": PASSWORD})).json()
        headers = {"Authorization": f"Bearer {token['access_token']}"}
        patient = (await setup.post("/api/patients", headers=headers,
                                    json={"code_name": "LOAD-1", "body_mass_kg": 75.0, "side": "left"})).json()
        while not (await setup.get(f"/api/devices/{DEVICE}", headers=headers)).json()["online"]:
            await asyncio.sleep(0.05)
        await setup.put(f"/api/devices/{DEVICE}/assignment", headers=headers, json={"patient_id": patient["id"]})
        session = (await setup.post(f"/api/patients/{patient['id']}/sessions", headers=headers,
                                    json={"device_id": DEVICE, "speed_mps": 1.2})).json()
    url = f"/api/patients/{patient['id']}/proposals"
    host, port = base.removeprefix("http://").rsplit(":", 1)
    latencies: list[float] = []
    statuses: dict[int, int] = {}
    rng = random.Random(0)
    finished: list[float] = []                   # when each measured client's last request came back

    async def client(deadline: float, record: bool) -> None:
        reader, writer = await asyncio.open_connection(host, int(port))
        try:
            while time.perf_counter() < deadline:
                body = json.dumps({"speed_mps": round(rng.uniform(0.5, 2.0), 3),
                                   "incline_deg": round(rng.uniform(-10, 10), 2)}).encode()
                t0 = time.perf_counter()
                status = await _post(reader, writer, host, url, headers["Authorization"], body)
                dt = time.perf_counter() - t0
                if record:
                    latencies.append(dt)
                    statuses[status] = statuses.get(status, 0) + 1
            if record:
                finished.append(time.perf_counter())
        finally:
            writer.close()

    await asyncio.gather(*(client(time.perf_counter() + 2.0, False) for _ in range(clients)))   # warm-up
    stop = asyncio.Event()
    ws_url = base.replace("http://", "ws://") + f"/api/devices/{DEVICE}/telemetry?token={token['access_token']}"
    telemetry = asyncio.create_task(_telemetry(ws_url, stop))
    await asyncio.sleep(0.5)
    t_start, cpu_start = time.perf_counter(), server_cpu_s()
    await asyncio.gather(*(client(t_start + seconds, True) for _ in range(clients)))
    cpu_end = server_cpu_s()
    stop.set()
    stream = await telemetry
    wall = max(finished) - t_start
    envelope = (await httpx.AsyncClient(base_url=base, headers=headers, timeout=60.0).post(
        f"/api/patients/{patient['id']}/envelopes", json={"grid": [5, 5]})).json()
    reads = await _reads(base, headers, [url, f"/api/patients/{patient['id']}/envelopes", f"/api/envelopes/"
                                         f"{envelope['id']}", f"/api/patients/{patient['id']}/sessions"],
                         clients, seconds, ws_url)
    async with httpx.AsyncClient(base_url=base, timeout=30.0) as c:
        summary = (await c.post(f"/api/sessions/{session['id']}/stop", headers=headers)).json()["summary"]
    lat = np.array(latencies) * 1e3
    return {"clients": clients, "seconds": round(wall, 2), "requests": int(lat.size),
            "proposals_per_s": round(statuses.get(201, 0) / wall, 1),
            "p50_ms": round(float(np.percentile(lat, 50)), 2), "p95_ms": round(float(np.percentile(lat, 95)), 2),
            "p99_ms": round(float(np.percentile(lat, 99)), 2), "max_ms": round(float(lat.max()), 2),
            "server_cpu_ms_per_proposal": None if cpu_start is None or cpu_end is None or not statuses.get(201) else
            round((cpu_end - cpu_start) * 1e3 / statuses[201], 2),
            "non_201": sum(v for k, v in statuses.items() if k != 201), **stream, **reads,
            "session_missing_samples": summary["missing_samples"]}


def _cpu_s(pid: int) -> float | None:
    """A process's CPU time so far (user + system, s), from /proc (None where there is none)."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return None
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def run(clients: int = 20, seconds: float = 10.0) -> dict:
    """Run the benchmark against a fresh single-process server; the load generator shares the machine with it.
    Also the server's CPU time per proposal over the proposals' window (``server_cpu_ms_per_proposal``): steadier
    from run to run than the rate, which moves with whatever else the two cores do."""
    with temporary_server_process("quasitune-loadbench-", device="sim") as (proc, base):
        result = asyncio.run(_run(base, clients, seconds, lambda: _cpu_s(proc.pid)))
    return {**result, "cpu_count": os.cpu_count()}
