"""``quasitune serve --workers N``: N server processes, each accepting on its own ``SO_REUSEPORT`` socket.

Why not uvicorn's own ``--workers``: there the processes share one listening socket, and whichever process is
awake first accepts every connection waiting (the event loop accepts up to the backlog per wake-up).
Keep-alive clients stay with the process that accepted them, so 20 clients mostly landed on one process: the
connection split seen under the load benchmark was 20/0, 20/0 and 15/5, with one core idle. With a socket per
process in one ``SO_REUSEPORT`` group, the kernel spreads new connections over the processes by a hash of
the address pair.

The parent reserves the port (bound but not listening, so no connection is ever queued on it), starts the
workers, waits until each one listens, and only then announces the address, so the "listening on" line is
true when printed. A worker that dies takes the server down (the others are stopped, exit status 1): a loud
failure for the supervisor (systemd, docker) to restart, instead of a server quietly running short of a
process. Workers die with the parent (``PR_SET_PDEATHSIG``), also when it is killed with SIGKILL.
Linux only (``SO_REUSEPORT`` load balancing, ``prctl``).
"""

from __future__ import annotations

import ctypes
import multiprocessing
import multiprocessing.connection
import os
import queue
import signal
import socket
import sys
import time
from collections.abc import Callable

from backend.settings import Settings

READY_TIMEOUT_S = 120.0
STOP_TIMEOUT_S = 10.0
_PR_SET_PDEATHSIG = 1


def supported() -> bool:
    return sys.platform.startswith("linux") and hasattr(socket, "SO_REUSEPORT")


def _socket(host: str, port: int) -> socket.socket:
    sock = socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEPORT, 1)
    return sock


def reserve_port(host: str, port: int) -> socket.socket:
    """A bound, not listening, ``SO_REUSEPORT`` socket holding ``port`` (0 = any free port) for the workers
    (ValueError with the reason when the address cannot be used)."""
    sock = _socket(host, port)
    try:
        sock.bind((host, port))
    except OSError as exc:
        sock.close()
        raise ValueError(f"cannot listen on {host}:{port}: {exc.strerror or exc}") from None
    return sock


def _die_with_parent(parent_pid: int) -> None:
    libc = ctypes.CDLL(None, use_errno=True)
    if libc.prctl(_PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0) != 0:
        raise OSError(ctypes.get_errno(), "prctl(PR_SET_PDEATHSIG) failed")
    if os.getppid() != parent_pid:      # the parent died before the request took effect
        os._exit(1)


def _worker_main(settings: Settings, host: str, port: int, log_level: str, ready: multiprocessing.Queue,
                 parent_pid: int) -> None:
    import uvicorn

    from backend.app import create_app
    from backend.serve import one_blas_thread

    _die_with_parent(parent_pid)
    one_blas_thread()
    sock = _socket(host, port)
    sock.bind((host, port))
    sock.listen(2048)        # from here connections queue on this process's socket
    ready.put(os.getpid())
    config = uvicorn.Config(create_app(settings), log_level=log_level, access_log=False, lifespan="on")
    uvicorn.Server(config).run(sockets=[sock])


def _report_dead(procs: list[multiprocessing.Process]) -> bool:
    dead = [p for p in procs if p.exitcode is not None]
    if dead:
        print("quasitune: worker " + ", ".join(f"{p.name} (pid {p.pid}, exit status {p.exitcode})" for p in dead)
              + " stopped; stopping the server", file=sys.stderr, flush=True)
    return bool(dead)


def run_workers(settings: Settings, host: str, port: int, workers: int, log_level: str,
                announce: Callable[[], None]) -> int:
    """Start ``workers`` processes serving on ``host:port`` (a port held by :func:`reserve_port`), call
    ``announce`` once all listen, and supervise until SIGTERM/SIGINT (exit status 0) or a worker's death (1)."""
    ctx = multiprocessing.get_context("spawn")
    ready = ctx.Queue()
    procs = [ctx.Process(target=_worker_main, args=(settings, host, port, log_level, ready, os.getpid()),
                         name=f"quasitune-worker-{i + 1}") for i in range(workers)]
    stop = {"signal": None}

    def on_signal(signum: int, _frame: object) -> None:
        stop["signal"] = signum

    previous = {s: signal.signal(s, on_signal) for s in (signal.SIGTERM, signal.SIGINT)}
    try:
        for p in procs:
            p.start()
        listening, deadline = 0, time.monotonic() + READY_TIMEOUT_S
        while listening < workers:
            try:
                ready.get(timeout=0.2)
                listening += 1
            except queue.Empty:
                if _report_dead(procs) or stop["signal"] is not None:
                    return 1
                if time.monotonic() > deadline:
                    print(f"quasitune: a worker did not start listening within {READY_TIMEOUT_S:g} s",
                          file=sys.stderr, flush=True)
                    return 1
        announce()
        while stop["signal"] is None:
            if multiprocessing.connection.wait([p.sentinel for p in procs], timeout=0.5) and _report_dead(procs):
                return 1
        return 0
    finally:
        for p in procs:
            if p.is_alive():
                p.terminate()
        for p in procs:
            p.join(STOP_TIMEOUT_S)
            if p.is_alive():
                p.kill()
                p.join()
        for s, handler in previous.items():
            signal.signal(s, handler)
