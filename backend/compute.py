"""A lane: work run in a worker thread, at most ``width`` calls at once per process (the dashboard's
simulated walking previews, seconds of MuJoCo each, use one so they queue instead of piling up).

Not for the proposal request: there 1-2 ms of NumPy-heavy Python only contended for the GIL with the event
loop (see ``backend/routers/proposals.py``). History: forty request threads fighting over the GIL first
became one lane (186 → 245 proposals/s on one process), then no thread at all.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TypeVar

import anyio
import anyio.to_thread

T = TypeVar("T")


class ComputeLane:
    def __init__(self, width: int = 1) -> None:
        self.width = width
        self._limiter: anyio.CapacityLimiter | None = None

    async def run(self, fn: Callable[..., T], *args: object) -> T:
        """Run ``fn(*args)`` in a worker thread, at most ``width`` at once."""
        if self._limiter is None:    # created on first use, inside the running event loop
            self._limiter = anyio.CapacityLimiter(self.width)
        return await anyio.to_thread.run_sync(fn, *args, limiter=self._limiter)
