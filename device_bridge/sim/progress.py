"""Where a bench walk tells its caller how far it has come, and where the caller can stop it.

The 1 kHz loop (:func:`~device_bridge.sim.simulate.walk_loop`) calls :func:`walked` once per simulated second; a
caller that runs walks (the server's bench queue, ``backend.jobs``) sets a hook with :func:`reporting` around them.
The hook gets the simulated seconds walked since the last call and may raise (a cancelled job) to stop the walk
where it is: nothing the walk would have stored is stored. Without a hook, nothing happens. A context variable, so a
walk on one thread never reports to another's hook.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar

Hook = Callable[[float], None]
_hook: ContextVar[Hook | None] = ContextVar("bench_walk_progress", default=None)


@contextmanager
def reporting(hook: Hook) -> Iterator[None]:
    """Walks in this block call ``hook(simulated_s)`` as they go (see the module)."""
    token = _hook.set(hook)
    try:
        yield
    finally:
        _hook.reset(token)


def walked(simulated_s: float) -> None:
    """``simulated_s`` more seconds walked (the loop's call); the hook may raise to stop the walk."""
    hook = _hook.get()
    if hook is not None:
        hook(simulated_s)
