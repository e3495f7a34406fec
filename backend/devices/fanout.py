"""Live telemetry to WebSocket clients: items published from the CAN receive thread reach each subscriber's
asyncio queue through its own event loop. A client too slow to keep up loses its oldest items; the bus never waits."""

from __future__ import annotations

import asyncio
import threading


class TelemetryFanout:
    def __init__(self) -> None:
        self._subscribers: dict[asyncio.Queue, asyncio.AbstractEventLoop] = {}
        self._lock = threading.Lock()

    def __bool__(self) -> bool:
        return bool(self._subscribers)

    def subscribe(self, queue: asyncio.Queue, loop: asyncio.AbstractEventLoop) -> None:
        with self._lock:
            self._subscribers[queue] = loop

    def unsubscribe(self, queue: asyncio.Queue) -> None:
        with self._lock:
            self._subscribers.pop(queue, None)

    def publish(self, item: dict) -> None:
        """Offer ``item`` to every subscriber (from any thread)."""
        with self._lock:
            targets = list(self._subscribers.items())
        for queue, loop in targets:
            try:
                loop.call_soon_threadsafe(self._offer, queue, item)
            except RuntimeError:   # the subscriber's loop has closed
                self.unsubscribe(queue)

    @staticmethod
    def _offer(queue: asyncio.Queue, item: dict) -> None:
        if queue.full():
            queue.get_nowait()
        queue.put_nowait(item)
