"""Least-connections accepting (backend/balancer.py) on a real listening socket, in one process: the shared
counts array stands in for the other worker's slot."""

from __future__ import annotations

import asyncio
import socket

from backend.balancer import LeastConnectionsAcceptor

TICK_S = 0.2             # a time scale long enough that a slow test machine keeps "at once" apart from "later"
PENDING_RECHECK_S = 0.01
TAKEOVER_S = 0.2


def _listener() -> socket.socket:
    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    sock.listen(16)
    return sock


def _started(counts: list[int]) -> tuple[socket.socket, list[socket.socket], LeastConnectionsAcceptor]:
    """A listening socket and a started acceptor in slot 0 of ``counts`` (call from a running loop)."""
    listener = _listener()
    accepted: list[socket.socket] = []
    acceptor = LeastConnectionsAcceptor(listener, counts, 0, accepted.append, PENDING_RECHECK_S, TAKEOVER_S)
    acceptor.start()
    return listener, accepted, acceptor


async def _run(counts: list[int], connect: int, wait_s: float) -> tuple[list[socket.socket], list[int]]:
    listener, accepted, acceptor = _started(counts)
    clients = [socket.create_connection(listener.getsockname()) for _ in range(connect)]
    await asyncio.sleep(wait_s)
    acceptor.stop()
    for s in clients + accepted:
        s.close()
    listener.close()
    return accepted, counts


def test_the_least_loaded_process_accepts_until_it_holds_more_than_another():
    # the other process (slot 1) holds 3: we take three to catch up and one more at the tie (3 vs 3), then
    # hold 4 and leave the fifth to it for now
    accepted, counts = asyncio.run(_run([0, 3], connect=5, wait_s=TICK_S / 4))
    assert len(accepted) == 4
    assert counts[0] == 0     # stop() clears the slot


def test_a_connection_the_least_loaded_process_does_not_take_is_taken_after_the_takeover_time():
    # slot 1 claims fewer connections but never accepts (busy or stuck): no client waits for ever
    accepted, _ = asyncio.run(_run([0, 3], connect=5, wait_s=TAKEOVER_S * 3))
    assert len(accepted) == 5


def test_a_process_that_becomes_least_loaded_takes_a_waiting_connection_at_once():
    async def scenario() -> list[int]:
        counts = [0, 0]
        listener, accepted, acceptor = _started(counts)
        first = socket.create_connection(listener.getsockname())
        await asyncio.sleep(TICK_S / 8)
        seen = [len(accepted)]                   # 1: now 1 vs 0, it leaves the next one to the other process
        second = socket.create_connection(listener.getsockname())
        await asyncio.sleep(TICK_S / 8)
        seen.append(len(accepted))               # still 1
        counts[1] = 1                            # the other process accepted one elsewhere: a tie
        await asyncio.sleep(TICK_S / 8)          # well before the takeover time
        seen.append(len(accepted))
        acceptor.stop()
        for s in (first, second, *accepted, listener):
            s.close()
        return seen
    assert asyncio.run(scenario()) == [1, 1, 2]


def test_closing_connections_makes_a_process_least_loaded_again():
    async def scenario() -> int:
        counts = [0, 1]
        listener, accepted, acceptor = _started(counts)
        first = socket.create_connection(listener.getsockname())
        await asyncio.sleep(TICK_S / 4)
        assert len(accepted) == 1 and counts[0] == 1        # 1 vs 1: still least loaded (ties accept)
        counts[1] = 0                                        # the other process lost its connection
        second = socket.create_connection(listener.getsockname())
        await asyncio.sleep(TICK_S / 4)
        assert len(accepted) == 1                            # 1 vs 0: leave it to the other
        accepted[0].close()
        acceptor.closed()                                    # ours closed: 0 vs 0
        await asyncio.sleep(TICK_S / 4)
        n = len(accepted)
        acceptor.stop()
        for s in (first, second, *accepted, listener):
            s.close()
        return n
    assert asyncio.run(scenario()) == 2


class _OutOfDescriptors:
    """A listening socket whose accept() fails as when the process has no file descriptors left."""

    def __init__(self, real: socket.socket) -> None:
        self.real = real
        self.accept_calls = 0

    def fileno(self) -> int:
        return self.real.fileno()

    def setblocking(self, flag: bool) -> None:
        self.real.setblocking(flag)

    def accept(self):
        self.accept_calls += 1
        raise OSError(24, "Too many open files")


def test_an_accept_error_pauses_accepting_instead_of_spinning_on_the_readable_socket(caplog):
    async def scenario() -> tuple[int, int]:
        listener = _listener()
        failing = _OutOfDescriptors(listener)
        acceptor = LeastConnectionsAcceptor(failing, [0, 0], 0, lambda s: None, retry_s=0.3)
        acceptor.start()
        client = socket.create_connection(listener.getsockname())   # the socket stays readable
        await asyncio.sleep(0.15)
        during_pause = failing.accept_calls
        await asyncio.sleep(0.3)                                     # retried once the pause is over
        after_pause = failing.accept_calls
        acceptor.stop()
        client.close()
        listener.close()
        return during_pause, after_pause
    during_pause, after_pause = asyncio.run(scenario())
    assert during_pause == 1 and 2 <= after_pause <= 3
    assert "Too many open files" in caplog.text and "not accepting for 0.3 s" in caplog.text


def test_closing_connections_after_stop_does_not_start_accepting_again():
    async def scenario() -> int:
        listener = _listener()
        accepted: list[socket.socket] = []
        acceptor = LeastConnectionsAcceptor(listener, [0, 5], 0, accepted.append, PENDING_RECHECK_S, TAKEOVER_S)
        acceptor.start()
        first = socket.create_connection(listener.getsockname())
        await asyncio.sleep(TICK_S / 4)
        acceptor.stop()                          # graceful shutdown: connections drain after this
        second = socket.create_connection(listener.getsockname())
        acceptor.closed()                        # the first one closes while draining
        await asyncio.sleep(TICK_S * 3)
        for s in (first, second, *accepted, listener):
            s.close()
        return len(accepted)
    assert asyncio.run(scenario()) == 1
