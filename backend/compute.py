"""A lane for CPU-bound work (the model's ``propose``) — one request at a time per process, in a worker thread.

Forty threads all running NumPy-heavy Python fight over the GIL: under 20 concurrent proposal requests that
contention cost about as much as the proposals themselves (load benchmark: 186 → 245 proposals/s on one
process when the work was queued into one lane). The event loop stays free for light requests meanwhile.
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
