"""Least-connections accepting for ``quasitune serve --workers N``: one shared listening socket, and a process
accepts a new connection only while it holds no more open connections than any other process.

Why: keep-alive clients stay with the process that accepted them for as long as they are connected, so how the
connections are split decides how the work is split. The kernel's ``SO_REUSEPORT`` hash split 20 load-benchmark
clients 10/10 … 16/4 from run to run, and a process holding 16 queues 16 requests on one core while the other
core idles between its 4. Counting connections and letting the least-loaded process take the next one is what
load balancers call least-connections (nginx ``least_conn``).

How: each process publishes its open-connection count in a shared array (one slot per process). A process
watches the shared socket only while its count is the smallest (ties: every tied process may accept; the kernel
gives the connection to one, the others see ``EAGAIN``). A process that is not the least loaded looks again
every :data:`RECHECK_S` (25 ms); if a connection has been waiting on two looks in a row (the least-loaded process is
busy or stuck), it takes it anyway: balance never costs a client more than about two re-check intervals.
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

RECHECK_S = 0.025
ACCEPT_RETRY_S = 1.0       # after running out of descriptors or memory, as asyncio's own servers do

logger = logging.getLogger("quasitune.balancer")


class LeastConnectionsAcceptor:
    """Accept connections from ``listener`` into ``serve(sock)`` while this process is the least loaded.

    ``counts`` is shared between the processes (``multiprocessing`` ``RawArray('i', N)``); this process owns
    ``counts[index]``: the connections it accepted and has not yet seen closed (call :meth:`closed` for each).
    """

    def __init__(self, listener: socket.socket, counts: Any, index: int,
                 serve: Callable[[socket.socket], None], recheck_s: float = RECHECK_S,
                 retry_s: float = ACCEPT_RETRY_S) -> None:
        self.listener = listener
        self.recheck_s = recheck_s
        self.retry_s = retry_s
        self.counts = counts
        self.index = index
        self.serve = serve
        self.open = 0
        self._loop: asyncio.AbstractEventLoop | None = None
        self._reading = False
        self._active = False          # between start() and stop(), and not paused after an accept error
        self._stopped = False
        self._waiting_seen = False
        self._timer: asyncio.TimerHandle | None = None
        self._poll = select.poll()
        self._poll.register(listener.fileno(), select.POLLIN)

    def start(self) -> None:
        self.listener.setblocking(False)
        self._loop = asyncio.get_running_loop()
        self.counts[self.index] = self.open
        self._active = True
        self._update()

    def stop(self) -> None:
        """Stop accepting (the connections already accepted are not touched); this slot reads 0."""
        self._stopped = True
        self._halt()
        self.counts[self.index] = 0

    def _halt(self) -> None:
        self._active = False
        if self._reading and self._loop is not None:
            self._loop.remove_reader(self.listener.fileno())
        self._reading = False
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None

    def closed(self) -> None:
        """One of this process's connections has closed."""
        self.open -= 1
        if self._active:
            self.counts[self.index] = self.open
            self._update()

    def least_loaded(self) -> bool:
        mine = self.counts[self.index]
        return all(mine <= c for c in self.counts)

    def _update(self) -> None:
        """Watch the socket when least loaded; otherwise stop watching and look again later."""
        want = self.least_loaded()
        if want and not self._reading:
            self._loop.add_reader(self.listener.fileno(), self._on_readable)
        elif not want and self._reading:
            self._loop.remove_reader(self.listener.fileno())
        self._reading = want
        if not want and self._timer is None:
            self._timer = self._loop.call_later(self.recheck_s, self._recheck)

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

    def _resume(self) -> None:
        if not self._stopped and not self._active:
            self._active = True
            self._update()

    def _on_readable(self) -> None:
        while self._active and self.least_loaded() and self._accept_one():
            pass
        if self._active:
            self._update()

    def _recheck(self) -> None:
        self._timer = None
        if not self._active:
            return
        if not self.least_loaded():
            waiting = bool(self._poll.poll(0))
            if waiting and self._waiting_seen:       # the least-loaded process has not taken it: we do
                self._accept_one()
                waiting = False
            self._waiting_seen = waiting
        if self._active:
            self._update()


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
