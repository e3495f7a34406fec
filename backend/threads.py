"""Where a request's blocking work runs.

Request handlers run in a small pool of worker threads (``Settings.request_threads``, anyio's default limiter): the
process is bound by one interpreter lock, so more threads add no throughput and make the event loop, which streams
live telemetry, queue behind every one of them. Work that mostly *waits* (a push waiting for the device's
acknowledgement, a walk on the simulated bench, the model still loading) would then hold a request thread for
seconds; it runs on threads of its own instead (:func:`run_waiting`), so it never makes other requests queue.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import TypeVar

import anyio
import anyio.to_thread

T = TypeVar("T")
WAITING_THREADS = 16
_waiting: anyio.CapacityLimiter | None = None


def _limiter() -> anyio.CapacityLimiter:
    global _waiting
    if _waiting is None:
        _waiting = anyio.CapacityLimiter(WAITING_THREADS)
    return _waiting


async def run_waiting(fn: Callable[..., T], *args: object, **kwargs: object) -> T:
    """``fn(*args, **kwargs)`` on a thread for waiting work, outside the request threads."""
    return await anyio.to_thread.run_sync(functools.partial(fn, *args, **kwargs), limiter=_limiter())
