"""Several processes migrating one database at the same moment, as API instances (or a migration service beside one)
starting together would."""

from __future__ import annotations

import multiprocessing

from backend.migrate import migrate


def _migrate_in_child(target: str, barrier) -> None:
    barrier.wait()
    migrate(target)


def migrate_at_once(target: str, processes: int = 3, timeout_s: float = 60.0) -> list[int | None]:
    """Start ``processes`` fresh interpreters that each migrate ``target`` once all are ready; their exit codes."""
    ctx = multiprocessing.get_context("spawn")
    barrier = ctx.Barrier(processes)
    procs = [ctx.Process(target=_migrate_in_child, args=(target, barrier)) for _ in range(processes)]
    for p in procs:
        p.start()
    for p in procs:
        p.join(timeout_s)
    return [p.exitcode for p in procs]
