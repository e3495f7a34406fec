"""Load benchmark of ``POST /api/patients/{id}/proposals`` (a command that prints figures, not a test).

Starts ``quasitune serve`` in a subprocess on a free loopback port with a temporary database, creates a
prosthetist and a patient, warms up, then runs ``clients`` concurrent clients (each one request at a time,
back to back, over its own keep-alive connection) for ``seconds``. Tasks are drawn at random over the model's
range (speed 0.5–2.0 m/s, incline ±10°) so no two requests are alike. Reports proposals per second and
latency percentiles, and how the clients' connections are split over the server processes (see
:func:`connection_split`); any non-201 answer is counted and reported.

The clients speak HTTP/1.1 directly over asyncio streams: the load generator shares the two cores with the
server, and a full HTTP client library spent as much CPU per request as the server did, which measured the
generator rather than the server. Setup and checks still go through httpx.
"""

from __future__ import annotations

import asyncio
import json
import os
import random
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

PASSWORD = "load-bench-password"


def start_server(data_dir: Path, workers: int = 1, bootstrap: bool = False,
                 device: str = "none") -> tuple[subprocess.Popen, str]:
    """``quasitune serve --port 0`` in a subprocess; returns (process, base URL) once it listens (its further
    stdout lines are left unread in ``process.stdout``). No device by default: the benchmark measures the API."""
    cmd = [sys.executable, "-m", "backend.cli", "serve", "--port", "0", "--data-dir", str(data_dir), "--device", device]
    if not bootstrap:
        cmd.append("--no-bootstrap-user")
    if workers > 1:
        cmd += ["--workers", str(workers)]
    err_path = data_dir / "serve.stderr.log"    # a file, not a pipe nobody drains
    with err_path.open("a") as err:
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=err, text=True,
                                env={**os.environ, "PYTHONUNBUFFERED": "1"})
    line = proc.stdout.readline()
    if "listening on" not in line:
        proc.kill()
        raise RuntimeError(f"server did not start: {line!r} {err_path.read_text()[-2000:]}")
    return proc, line.rsplit(" ", 1)[-1].strip()


@contextmanager
def bench_server(prefix: str, workers: int = 1, device: str = "none") -> Iterator[str]:
    """A fresh server on a temporary database with the prosthetist ``bench`` (password :data:`PASSWORD`); yields
    its base URL and stops it afterwards. Shared by the load, device and dashboard benchmarks."""
    with tempfile.TemporaryDirectory(prefix=prefix) as tmp:
        data_dir = Path(tmp)
        add_user(data_dir, "bench", "prosthetist")
        proc, base = start_server(data_dir, workers, device=device)
        try:
            yield base
        finally:
            proc.terminate()
            proc.wait(timeout=10)


def add_user(data_dir: Path, name: str, role: str, password: str = PASSWORD) -> None:
    subprocess.run([sys.executable, "-m", "backend.cli", "users", "add", name, "--role", role,
                    "--data-dir", str(data_dir)], input=password + "\n", text=True, check=True,
                   capture_output=True)


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


def connection_split(server_port: int, client_ports: list[int]) -> list[int] | None:
    """How many of the clients' connections each server process holds, largest first (Linux /proc; None
    elsewhere). Keep-alive clients stay with the process that accepted them, so this split, not only the
    code, sets the latency: a process holding 14 of 20 clients queues 14 requests on its core."""
    server_side: dict[str, int] = {}            # socket inode → client port, for connections to the server
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        try:
            lines = Path(table).read_text().splitlines()[1:]
        except OSError:
            continue
        for line in lines:
            f = line.split()
            local_port, remote_port = int(f[1].rsplit(":", 1)[1], 16), int(f[2].rsplit(":", 1)[1], 16)
            if local_port == server_port and remote_port in client_ports:
                server_side[f[9]] = remote_port
    if not server_side:
        return None
    owners: dict[int, int] = {}
    for fd_dir in Path("/proc").glob("[0-9]*/fd"):
        try:
            links = [os.readlink(fd) for fd in fd_dir.iterdir()]
        except OSError:
            continue
        held = sum(1 for link in links if link.startswith("socket:[") and link[8:-1] in server_side)
        if held:
            owners[int(fd_dir.parent.name)] = held
    return sorted(owners.values(), reverse=True)


async def _run(base: str, clients: int, seconds: float) -> dict:
    import httpx

    async with httpx.AsyncClient(base_url=base, timeout=30.0) as setup:
        while (await setup.get("/api/health")).json()["model"] != "ready":
            await asyncio.sleep(0.1)
        token = (await setup.post("/api/auth/token", data={"username": "bench", "password": PASSWORD})).json()
        headers = {"Authorization": f"Bearer {token['access_token']}"}
        patient = (await setup.post("/api/patients", headers=headers,
                                    json={"code_name": "LOAD-1", "body_mass_kg": 75.0, "side": "left"})).json()
    url = f"/api/patients/{patient['id']}/proposals"
    host, port = base.removeprefix("http://").rsplit(":", 1)
    latencies: list[float] = []
    statuses: dict[int, int] = {}
    rng = random.Random(0)

    ports: list[int] = []
    split: list[list[int] | None] = []
    finished: list[float] = []                   # when each measured client's last request came back
    all_finished, counted = asyncio.Event(), asyncio.Event()

    async def client(deadline: float, record: bool) -> None:
        reader, writer = await asyncio.open_connection(host, int(port))
        if record:
            ports.append(writer.get_extra_info("sockname")[1])
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
            if record:                           # stay connected until the split has been read
                finished.append(time.perf_counter())
                if len(finished) == clients:
                    all_finished.set()
                await counted.wait()
        finally:
            writer.close()

    async def count_connections() -> None:
        # after the measured window: reading /proc holds this process's GIL for tens of milliseconds, which
        # would have shown up as client-side latency had it run during the window
        await all_finished.wait()
        split.append(await asyncio.to_thread(connection_split, int(port), ports))
        counted.set()

    await asyncio.gather(*(client(time.perf_counter() + 2.0, False) for _ in range(clients)))   # warm-up
    await asyncio.sleep(0.2)   # let the server see the warm-up connections close before the measured ones open
    t_start = time.perf_counter()
    await asyncio.gather(count_connections(), *(client(t_start + seconds, True) for _ in range(clients)))
    wall = max(finished) - t_start
    lat = np.array(latencies) * 1e3
    return {"clients": clients, "seconds": round(wall, 2), "requests": int(lat.size),
            "proposals_per_s": round(statuses.get(201, 0) / wall, 1),
            "p50_ms": round(float(np.percentile(lat, 50)), 2), "p95_ms": round(float(np.percentile(lat, 95)), 2),
            "p99_ms": round(float(np.percentile(lat, 99)), 2), "max_ms": round(float(lat.max()), 2),
            "non_201": sum(v for k, v in statuses.items() if k != 201),
            "connections_per_process": "/".join(map(str, split[0])) if split and split[0] else "unknown"}


def run_load_bench(clients: int = 20, seconds: float = 10.0, workers: int = 1) -> dict:
    """Run the benchmark against a fresh server; the load generator shares the machine with it."""
    with bench_server("quasitune-loadbench-", workers) as base:
        result = asyncio.run(_run(base, clients, seconds))
    return {**result, "server_workers": workers, "cpu_count": os.cpu_count()}
