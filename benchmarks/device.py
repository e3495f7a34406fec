"""Device-loop benchmark (``python -m benchmarks device``): a real ``quasitune serve`` with the simulated leg, driven
over loopback HTTP and WebSocket.

Approve a proposal, push it through the API (push latency as the prosthetist sees it, CRC read-back included),
start a walking session, then count the telemetry reaching a WebSocket client for ``seconds``: samples per second
and gaps in the sequence numbers. Prints figures; asserts nothing (the tests do the asserting).
"""

from __future__ import annotations

import asyncio
import itertools
import json
import statistics
import time

from tests.helpers.server import PASSWORD, temporary_server

# what is measured is the link, not the bench's verdict on each table (approval and push rest on it otherwise)
OVERRIDE = "device benchmark: push latency is measured, not the bench's verdict on the table"


async def _run(base: str, seconds: float, pushes: int) -> dict:
    import httpx
    import websockets

    async with httpx.AsyncClient(base_url=base, timeout=30.0) as c:
        while (await c.get("/api/health")).json()["model"] != "ready":
            await asyncio.sleep(0.1)
        token = (await c.post("/api/auth/token", data={"username": "bench", "password": PASSWORD})).json()["access_token"]
        h = {"Authorization": f"Bearer {token}"}
        patient = (await c.post("/api/patients", headers=h,
                                json={"code_name": "DEV-1", "body_mass_kg": 75.0, "side": "left"})).json()
        while not (await c.get("/api/devices/sim-leg-1", headers=h)).json()["online"]:
            await asyncio.sleep(0.05)
        await c.put("/api/devices/sim-leg-1/assignment", headers=h, json={"patient_id": patient["id"]})
        push_ms = []
        replaces = None
        for i in range(pushes):
            prop = (await c.post(f"/api/patients/{patient['id']}/proposals", headers=h,
                                 json={"speed_mps": 1.0 + 0.05 * (i % 10), "incline_deg": 0.0})).json()
            r = await c.get(f"/api/proposals/{prop['id']}/preview", headers=h)   # the gate approves a walked one
            if r.status_code != 200:
                raise RuntimeError(f"preview refused: {r.text}")
            r = await c.post(f"/api/proposals/{prop['id']}/approve", headers=h,
                             json={"comment": "bench", "override_reason": OVERRIDE})
            if r.status_code != 200:
                raise RuntimeError(f"approval refused: {r.text}")
            t0 = time.perf_counter()
            r = await c.post(f"/api/proposals/{prop['id']}/push", headers=h,
                             json={"device_id": "sim-leg-1", "replaces_proposal_id": replaces, "patient_ready": True,
                                   "override_reason": OVERRIDE})
            push_ms.append((time.perf_counter() - t0) * 1e3)
            if r.status_code != 201:
                raise RuntimeError(f"push failed: {r.text}")
            replaces = prop["id"]
        session = (await c.post(f"/api/patients/{patient['id']}/sessions", headers=h,
                                json={"device_id": "sim-leg-1"})).json()
        ws_url = base.replace("http://", "ws://") + f"/api/devices/sim-leg-1/telemetry?token={token}"
        seqs: list[int] = []
        async with websockets.connect(ws_url) as ws:
            t_end = time.perf_counter() + 1.0    # let the stream settle, then measure
            while time.perf_counter() < t_end:
                await ws.recv()
            t0 = time.perf_counter()
            while (now := time.perf_counter()) < t0 + seconds:
                msg = json.loads(await ws.recv())
                if msg["type"] == "telemetry":
                    seqs.append(msg["seq"])
            wall = now - t0
        stop = (await c.post(f"/api/sessions/{session['id']}/stop", headers=h)).json()
    gaps = sum(1 for a, b in itertools.pairwise(seqs) if b != a + 1)
    ordered = sorted(push_ms)
    return {"api_push_ms_median": round(statistics.median(ordered), 2),
            "api_push_ms_p99": round(ordered[min(len(ordered) - 1, int(0.99 * len(ordered)))], 2),
            "pushes": pushes, "telemetry_seconds": round(wall, 2), "telemetry_samples": len(seqs),
            "telemetry_hz": round(len(seqs) / wall, 1), "sequence_gaps": gaps,
            "session_strides": stop["summary"]["strides"],
            "session_missing_samples": stop["summary"]["missing_samples"]}


def run(seconds: float = 10.0, pushes: int = 50) -> dict:
    with temporary_server("quasitune-devicebench-", device="sim") as base:
        return asyncio.run(_run(base, seconds, pushes))
