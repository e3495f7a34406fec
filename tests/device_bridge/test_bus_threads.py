"""The life of threads over buses: started once, stopped together, buses shut."""

from __future__ import annotations

import threading

import can

from device_bridge.bus_threads import BusThreads


class _Counter(BusThreads):
    def __init__(self, bus: can.BusABC) -> None:
        super().__init__([bus], join_timeout_s=2.0)
        self.rounds = 0
        self.started = threading.Event()
        self.worker = threading.Thread(target=self._loop, daemon=True)
        self._threads = [self.worker]

    def _loop(self) -> None:
        self.started.set()
        while not self._stop.wait(0.001):
            self.rounds += 1


def test_threads_run_until_closed_and_the_bus_is_shut():
    bus = can.Bus(interface="virtual", channel="bus-threads")
    with _Counter(bus) as c:
        assert c.started.wait(5.0)
    assert not c.worker.is_alive()                           # stopped by close, not left running
    try:
        bus.send(can.Message(arbitration_id=1, data=b"", is_extended_id=False))
        raised = False
    except can.CanOperationError:
        raised = True
    assert raised                                            # shut: the bus sends no more
