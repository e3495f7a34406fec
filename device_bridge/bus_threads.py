"""The life of a piece that runs threads over CAN buses: start them, stop them, shut its buses.

A node (the leg's firmware), a link (the server's side) and a gateway each run a few threads against their buses;
this is their one start/close and context-manager. Ours because it is four methods: subclasses set ``_threads``
and the buses they own, and their loops watch ``_stop``.
"""

from __future__ import annotations

import threading
from typing import Self

import can


class BusThreads:
    """Threads over buses. Subclasses call ``super().__init__(buses, join_timeout_s)`` and fill ``_threads``."""

    def __init__(self, buses: list[can.BusABC], join_timeout_s: float = 1.0) -> None:
        self._buses = buses
        self._join_timeout_s = join_timeout_s
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []

    def start(self) -> Self:
        for t in self._threads:
            t.start()
        return self

    def close(self) -> None:
        """Stop the threads (each given ``join_timeout_s`` to finish its round) and shut the buses."""
        self._stop.set()
        for t in self._threads:
            if t.is_alive():
                t.join(timeout=self._join_timeout_s)
        for bus in self._buses:
            bus.shutdown()

    def __enter__(self) -> Self:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()
