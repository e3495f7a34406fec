"""Least-connections accepting (backend/balancer.py) on a real listening socket, in one process: the shared
counts array stands in for the other worker's slot."""

from __future__ import annotations

import asyncio
import socket

from backend.balancer import LeastConnectionsAcceptor

RECHECK_S = 0.2     # long, so that a slow test machine does not turn "at once" into "after two re-checks"


def _listener() -> socket.socket:
    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    sock.listen(16)
    return sock


async def _run(counts: list[int], connect: int, wait_s: float) -> tuple[list[socket.socket], list[int]]:
    listener = _listener()
    accepted: list[socket.socket] = []
    acceptor = LeastConnectionsAcceptor(listener, counts, 0, accepted.append, RECHECK_S)
    acceptor.start()
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
    accepted, counts = asyncio.run(_run([0, 3], connect=5, wait_s=RECHECK_S / 4))
    assert len(accepted) == 4
    assert counts[0] == 0     # stop() clears the slot


def test_a_connection_the_least_loaded_process_does_not_take_is_taken_after_two_rechecks():
    # slot 1 claims fewer connections but never accepts (busy or stuck): no client waits for ever
    accepted, _ = asyncio.run(_run([0, 3], connect=5, wait_s=RECHECK_S * 4))
    assert len(accepted) == 5


def test_closing_connections_makes_a_process_least_loaded_again():
    async def scenario() -> int:
        listener = _listener()
        accepted: list[socket.socket] = []
        counts = [0, 1]
        acceptor = LeastConnectionsAcceptor(listener, counts, 0, accepted.append, RECHECK_S)
        acceptor.start()
        first = socket.create_connection(listener.getsockname())
        await asyncio.sleep(RECHECK_S / 4)
        assert len(accepted) == 1 and counts[0] == 1        # 1 vs 1: still least loaded (ties accept)
        counts[1] = 0                                        # the other process lost its connection
        second = socket.create_connection(listener.getsockname())
        await asyncio.sleep(RECHECK_S / 4)
        assert len(accepted) == 1                            # 1 vs 0: leave it to the other
        accepted[0].close()
        acceptor.closed()                                    # ours closed: 0 vs 0
        await asyncio.sleep(RECHECK_S / 4)
        n = len(accepted)
        acceptor.stop()
        for s in (first, second, *accepted, listener):
            s.close()
        return n
    assert asyncio.run(scenario()) == 2
