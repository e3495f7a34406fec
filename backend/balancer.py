"""Least-connections accepting for ``quasitune serve --workers N``: one shared listening socket, and a process
accepts a new connection only while it holds no more open connections than any other process.

Why: keep-alive clients stay with the process that accepted them for as long as they are connected, so how the
connections are split decides how the work is split. The kernel's ``SO_REUSEPORT`` hash split 20 load-benchmark
clients 10/10 … 16/4 from run to run, and a process holding 16 queues 16 requests on one core while the other
core idles between its 4. Counting connections and letting the least-loaded process take the next one is what
load balancers call least-connections (nginx ``least_conn``).

How: each process publishes its open-connection count in a shared array (one slot per process), and every
process watches the shared socket. The least-loaded ones accept (ties: every tied process may; the kernel gives
the connection to one, the others see ``EAGAIN``). A process that is not the least loaded, woken by a waiting
connection, stops watching (the socket stays readable until someone accepts, so watching would spin) and looks
again every :data:`PENDING_RECHECK_S` (0.5 ms) until the connection is gone, or until it has itself become the
least loaded (another process accepted meanwhile), when it accepts. A connection that has waited
:data:`TAKEOVER_S` (50 ms) for a busy or stuck least-loaded process is taken by whichever process looks.
(An earlier version looked again every 25 ms whatever happened: a burst of 20 connections then took 250 ms to
accept, the process that had become least loaded sleeping out its interval after each accept.)
"""

from __future__ import annotations

import asyncio
import functools
import logging
import select
import socket
from collections.abc import Callable
from typing import Any

import uvicorn

PENDING_RECHECK_S = 0.0005
TAKEOVER_S = 0.05
ACCEPT_RETRY_S = 1.0       # after running out of descriptors or memory, as asyncio's own servers do

logger = logging.getLogger("quasitune.balancer")


class LeastConnectionsAcceptor:
    """Accept connections from ``listener`` into ``serve(sock)`` while this process is the least loaded.

    ``counts`` is shared between the processes (``multiprocessing`` ``RawArray('i', N)``); this process owns
    ``counts[index]``: the connections it accepted and has not yet seen closed (call :meth:`closed` for each).
    """

    def __init__(self, listener: socket.socket, counts: Any, index: int,
                 serve: Callable[[socket.socket], None], pending_recheck_s: float = PENDING_RECHECK_S,
                 takeover_s: float = TAKEOVER_S, retry_s: float = ACCEPT_RETRY_S) -> None:
        self.listener = listener
        self.counts = counts
        self.index = index
        self.serve = serve
        self.pending_recheck_s = pending_recheck_s
        self.takeover_s = takeover_s
        self.retry_s = retry_s
        self.open = 0
        self._loop: asyncio.AbstractEventLoop | None = None
        self._watching = False
        self._active = False          # between start() and stop(), and not paused after an accept error
        self._stopped = False
        self._waiting_since: float | None = None   # when a waiting connection woke us while not least loaded
        self._timer: asyncio.TimerHandle | None = None
        self._poll = select.poll()
        self._poll.register(listener.fileno(), select.POLLIN)

    def start(self) -> None:
        self.listener.setblocking(False)
        self._loop = asyncio.get_running_loop()
        self.counts[self.index] = self.open
        self._active = True
        self._watch()

    def stop(self) -> None:
        """Stop accepting (the connections already accepted are not touched); this slot reads 0."""
        self._stopped = True
        self._halt()
        self.counts[self.index] = 0

    def closed(self) -> None:
        """One of this process's connections has closed."""
        self.open -= 1
        if self._active:
            self.counts[self.index] = self.open

    def least_loaded(self) -> bool:
        mine = self.counts[self.index]
        return all(mine <= c for c in self.counts)

    def _watch(self) -> None:
        if not self._watching:
            self._loop.add_reader(self.listener.fileno(), self._on_readable)
            self._watching = True

    def _halt(self) -> None:
        self._active = False
        if self._watching and self._loop is not None:
            self._loop.remove_reader(self.listener.fileno())
        self._watching = False
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None
        self._waiting_since = None

    def _resume(self) -> None:
        if not self._stopped and not self._active:
            self._active = True
            self._watch()

    def _accept_one(self) -> bool:
        try:
            sock, _ = self.listener.accept()
        except (BlockingIOError, InterruptedError, ConnectionAbortedError):
            return False        # another process took it, or the client gave up first
        except OSError as exc:  # out of descriptors or memory: the socket stays readable, so do not spin on it
            logger.error("cannot accept a connection (%s); not accepting for %g s", exc, self.retry_s)
            self._halt()
            self._loop.call_later(self.retry_s, self._resume)
            return False
        self.open += 1
        self.counts[self.index] = self.open
        self.serve(sock)
        return True

    def _on_readable(self) -> None:
        while self._active and self.least_loaded() and self._accept_one():
            pass
        if self._active and not self.least_loaded():     # one may still be waiting for the least loaded
            self._loop.remove_reader(self.listener.fileno())
            self._watching = False
            self._waiting_since = self._loop.time()
            self._timer = self._loop.call_later(self.pending_recheck_s, self._recheck)

    def _recheck(self) -> None:
        self._timer = None
        if not self._active:
            return
        if not self._poll.poll(0) or self.least_loaded():   # taken by another process, or ours to take now
            self._waiting_since = None
            self._watch()                                    # fires at once if one is still waiting
            return
        if self._loop.time() - self._waiting_since >= self.takeover_s:
            self._accept_one()                               # the least-loaded process has not taken it
            if self._active:
                self._waiting_since = None
                self._watch()
            return
        self._timer = self._loop.call_later(self.pending_recheck_s, self._recheck)


class BalancedServer(uvicorn.Server):
    """uvicorn's server, fed by a :class:`LeastConnectionsAcceptor` on a shared socket instead of its own
    listener. Everything else (lifespan, graceful shutdown, connection bookkeeping) is uvicorn's."""

    def __init__(self, config: uvicorn.Config, listener: socket.socket, counts: Any, index: int) -> None:
        super().__init__(config)
        self._listener = listener
        self._counts = counts
        self._index = index
        self.acceptor: LeastConnectionsAcceptor | None = None
        self._tasks: set[asyncio.Task] = set()

    async def startup(self, sockets: list[socket.socket] | None = None) -> None:
        await super().startup(sockets=[])          # lifespan (model, storage) without a listener of its own
        if self.should_exit:
            return
        loop = asyncio.get_running_loop()
        acceptor: LeastConnectionsAcceptor

        class CountedProtocol(self.config.http_protocol_class):     # type: ignore[misc, name-defined]
            def connection_lost(self, exc: Exception | None) -> None:
                super().connection_lost(exc)
                acceptor.closed()

        factory = functools.partial(CountedProtocol, config=self.config, server_state=self.server_state,
                                    app_state=self.lifespan.state)

        async def connect(sock: socket.socket) -> None:
            try:
                await loop.connect_accepted_socket(factory, sock)
            except OSError:              # the client went away before the transport was set up
                sock.close()
                acceptor.closed()

        def serve(sock: socket.socket) -> None:
            self._tasks.add(task := loop.create_task(connect(sock)))
            task.add_done_callback(self._tasks.discard)

        acceptor = self.acceptor = LeastConnectionsAcceptor(self._listener, self._counts, self._index, serve)
        acceptor.start()

    async def shutdown(self, sockets: list[socket.socket] | None = None) -> None:
        if self.acceptor is not None:
            self.acceptor.stop()
        await super().shutdown(sockets=None)
