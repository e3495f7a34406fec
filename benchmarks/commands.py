"""Commands to a leg while the bench is busy (``python -m benchmarks commands``): a real ``quasitune serve`` with the
simulated leg, driven over loopback HTTP.

Five prosthetists ask at once for the bench walks of ten new envelopes (two each: the queue takes eight, the rest are
refused 503 with a Retry-After); meanwhile safe mode is entered and left on the leg every half second, the leg's
acknowledgement included, and the device list read. The same commands are timed first with the bench idle. Ten
concurrent refinements made entering safe mode take 42.4 s when bench walks ran in the request threads; the target
is ≤ 200 ms. Prints figures; asserts nothing.
"""

from __future__ import annotations

import asyncio
import statistics
import tempfile
import time
from pathlib import Path

from tests.helpers.server import PASSWORD, add_user, start_server, stop_server

USERS = [f"pt{i}" for i in range(5)]


def _figures(ms: list[float]) -> dict:
    ms = sorted(ms)
    return {"n": len(ms), "p50_ms": round(statistics.median(ms), 1),
            "p99_ms": round(ms[min(len(ms) - 1, round(0.99 * (len(ms) - 1)))], 1), "max_ms": round(ms[-1], 1)}


async def _commands(c, h: dict, seconds: float) -> dict:
    """Safe mode entered and left every half second for ``seconds`` (each until the leg confirms), and the device list
    read between: their latencies."""
    safe, listed, end = [], [], time.perf_counter() + seconds
    while time.perf_counter() < end:
        for command in ("enter_safe_mode", "leave_safe_mode"):
            t0 = time.perf_counter()
            r = await c.post("/api/devices/sim-leg-1/commands", headers=h, json={"command": command})
            if command == "enter_safe_mode":
                safe.append((time.perf_counter() - t0) * 1e3)
            if r.status_code >= 300:
                raise RuntimeError(f"{command}: {r.status_code} {r.text}")
            t0 = time.perf_counter()
            await c.get("/api/devices", headers=h)
            listed.append((time.perf_counter() - t0) * 1e3)
            await asyncio.sleep(0.25)
    return {"enter_safe_mode": _figures(safe), "get_devices": _figures(listed)}


async def _run(base: str, seconds: float) -> dict:
    import httpx

    async with httpx.AsyncClient(base_url=base, timeout=120.0) as c:
        while (await c.get("/api/health")).json()["model"] != "ready":
            await asyncio.sleep(0.1)
        tokens = {u: (await c.post("/api/auth/token", data={"username": u, "password": PASSWORD})).json()[
            "access_token"] for u in USERS}
        hs = {u: {"Authorization": f"Bearer {t}"} for u, t in tokens.items()}
        h = hs[USERS[0]]
        patient = (await c.post("/api/patients", headers=h,
                                json={"code_name": "CMD-1", "body_mass_kg": 75.0, "side": "left"})).json()
        while not (await c.get("/api/devices/sim-leg-1", headers=h)).json()["online"]:
            await asyncio.sleep(0.05)
        await c.put("/api/devices/sim-leg-1/assignment", headers=h, json={"patient_id": patient["id"]})
        envelopes = []
        for i in range(10):
            r = await c.post(f"/api/patients/{patient['id']}/envelopes", headers=h,
                             json={"speed_range_mps": [0.7 + 0.02 * i, 1.5], "incline_range_deg": [-8.0, 8.0],
                                   "grid": [3, 3]})
            r.raise_for_status()
            envelopes.append(r.json()["id"])
        idle = await _commands(c, h, seconds)

        async def walk(user: str, envelope_id: int) -> int:
            r = await c.get(f"/api/envelopes/{envelope_id}/preview", headers=hs[user])
            return r.status_code

        walks = [asyncio.create_task(walk(USERS[k % len(USERS)], e)) for k, e in enumerate(envelopes)]
        await asyncio.sleep(1.0)                                   # queued and walking
        queue = (await c.get("/api/jobs", headers=h)).json()
        busy = await _commands(c, h, seconds)
        still = len([j for j in (await c.get("/api/jobs", headers=h)).json() if j["state"] in ("queued", "walking")])
        statuses = await asyncio.gather(*walks)
    return {"idle": idle, "bench_busy": busy,
            "bench_jobs_at_start": {"walking": sum(j["state"] == "walking" for j in queue),
                                    "queued": sum(j["state"] == "queued" for j in queue)},
            "bench_jobs_left_at_end": still,
            "preview_answers": {str(s): statuses.count(s) for s in sorted(set(statuses))},
            "target_enter_safe_mode_ms": 200}


def run(seconds: float) -> dict:
    with tempfile.TemporaryDirectory(prefix="quasitune-commands-") as tmp:
        data_dir = Path(tmp)
        for user in USERS:
            add_user(data_dir, user, "prosthetist")
        proc, base = start_server(data_dir, device="sim")
        try:
            return asyncio.run(_run(base, seconds))
        finally:
            stop_server(proc)
