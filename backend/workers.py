"""``quasitune serve --workers N``: N server processes sharing one listening socket, least-connections first.

Keep-alive clients stay with the process that accepted them, so the split of connections is the split of the
work. uvicorn's own ``--workers`` share a socket and whichever process is awake first accepts every waiting
connection (20/0, 20/0, 15/5 in three load-benchmark runs, one core idle); ``SO_REUSEPORT`` sockets, which we
used next, leave it to a hash of the address pair (10/10 … 16/4). Now a process accepts only while it holds no
more connections than any other (:mod:`backend.balancer`), which gives 10/10.

The parent binds and listens, starts the workers, waits until each one accepts, and only then announces the
address, so the "listening on" line is true when printed (a client that connects earlier waits in the backlog).
A worker that dies takes the server down (the others are stopped, exit status 1): a loud failure for the
supervisor (systemd, docker) to restart, instead of a server quietly running short of a process. Workers die
with the parent (``PR_SET_PDEATHSIG``), also when it is killed with SIGKILL. Linux only (``prctl``).
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
from typing import Any

from backend.settings import Settings

READY_TIMEOUT_S = 120.0
STOP_TIMEOUT_S = 10.0
_PR_SET_PDEATHSIG = 1


def supported() -> bool:
    return sys.platform.startswith("linux")


def _die_with_parent(parent_pid: int) -> None:
    libc = ctypes.CDLL(None, use_errno=True)
    if libc.prctl(_PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0) != 0:
        raise OSError(ctypes.get_errno(), "prctl(PR_SET_PDEATHSIG) failed")
    if os.getppid() != parent_pid:      # the parent died before the request took effect
        os._exit(1)


def _worker_main(settings: Settings, listener: socket.socket, counts: Any, index: int, log_level: str,
                 ready: multiprocessing.Queue, parent_pid: int) -> None:
    import uvicorn

    from backend.app import create_app
    from backend.balancer import BalancedServer
    from backend.serve import one_blas_thread

    _die_with_parent(parent_pid)
    one_blas_thread()

    class AnnouncingServer(BalancedServer):
        async def startup(self, sockets: list[socket.socket] | None = None) -> None:
            await super().startup(sockets)
            if not self.should_exit:
                ready.put(os.getpid())        # accepting from here

    config = uvicorn.Config(create_app(settings), log_level=log_level, access_log=False, lifespan="on")
    AnnouncingServer(config, listener, counts, index).run()


def _report_dead(procs: list[multiprocessing.Process]) -> bool:
    dead = [p for p in procs if p.exitcode is not None]
    if dead:
        print("quasitune: worker " + ", ".join(f"{p.name} (pid {p.pid}, exit status {p.exitcode})" for p in dead)
              + " stopped; stopping the server", file=sys.stderr, flush=True)
    return bool(dead)


def run_workers(settings: Settings, listener: socket.socket, workers: int, log_level: str,
                announce: Callable[[], None]) -> int:
    """Start ``workers`` processes accepting from ``listener`` (a listening socket), call ``announce`` once all
    accept, and supervise until SIGTERM/SIGINT (exit status 0) or a worker's death (1)."""
    ctx = multiprocessing.get_context("spawn")
    ready = ctx.Queue()
    counts = ctx.RawArray("i", workers)       # open connections per worker, for least-connections accepting
    procs = [ctx.Process(target=_worker_main,
                         args=(settings, listener, counts, i, log_level, ready, os.getpid()),
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
