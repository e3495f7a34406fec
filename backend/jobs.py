"""Bench walks as jobs: queued, walking, done, failed or cancelled, with their progress and the time left.

Every walk on the simulated bench (a preview, a refinement's step checks) runs as a :class:`BenchJob` on the bench's
one queue (``backend.threads.run_bench``). The walk reports each simulated second it walks
(``device_bridge.sim.progress``); the job turns that into a fraction and the seconds left, from what jobs of its kind
walked before (their simulated seconds, and the wall seconds this one takes per simulated second). Anyone may cancel
their own job (an admin anyone's): a queued job leaves the queue at once, a walking one stops at its next simulated
second, and nothing it would have stored is stored.

Jobs are this instance's, in memory: a job of another instance is not listed here (each instance walks its own
bench). A finished job is listed for :data:`KEEP_FINISHED_S`.
"""

from __future__ import annotations

import itertools
import threading
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Literal

import anyio

JobState = Literal["queued", "walking", "done", "failed", "cancelled"]
KEEP_FINISHED_S = 600.0
KEEP_FINISHED = 50
# simulated seconds a job of each kind walks, until one has been measured on this instance: a table's preview walks
# the table and the FSMIC 10 s each; an envelope's the mixed course twice; a refinement the step checks of its nodes
FIRST_GUESS_S = {"table preview": 20.0, "envelope preview": 100.0, "refinement": 60.0}
FIRST_GUESS_WALL_PER_SIM = 0.5      # wall seconds per simulated second before any was measured (this machine: 0.3–0.6)


class JobCancelled(BaseException):
    """Raised inside a walk whose job was cancelled (a BaseException: no ``except Exception`` in a walk swallows it)."""

    def __init__(self, by: str) -> None:
        super().__init__(f"cancelled by {by}")
        self.by = by


@dataclass
class BenchJob:
    """One walk (see the module); times in Unix seconds, walked and expected in simulated seconds."""

    id: int
    kind: str                      # "table preview", "envelope preview", "refinement"
    target: str                    # what it walks, in the page's words ("envelope 12")
    path: str                      # … as the API names it ("/api/envelopes/12")
    user: str
    expected_s: float
    wall_per_sim: float
    basis: str                     # where expected_s comes from, in words
    queued_at: float = field(default_factory=time.time)
    state: JobState = "queued"
    started_at: float | None = None
    ended_at: float | None = None
    walked_s: float = 0.0
    error: str | None = None
    cancelled_by: str | None = None
    _cancel: threading.Event = field(default_factory=threading.Event, repr=False)
    _scope: anyio.CancelScope | None = field(default=None, repr=False)

    def tick(self, simulated_s: float) -> None:
        """The walk's report (its thread): ``simulated_s`` more walked; stops the walk if the job was cancelled."""
        self.walked_s += simulated_s
        if self.started_at is not None and self.walked_s > 0:
            self.wall_per_sim = (time.time() - self.started_at) / self.walked_s
        if self._cancel.is_set():
            raise JobCancelled(self.cancelled_by or "someone")

    def fraction(self) -> float:
        """How far it has come, 0–1 (never 1 before it is done: the expectation is an estimate)."""
        if self.state == "done":
            return 1.0
        return min(self.walked_s / self.expected_s, 0.99) if self.expected_s > 0 else 0.0

    def seconds_left(self) -> float:
        """Wall seconds until this job is done, walking its own remaining expectation (0 once finished)."""
        if self.state not in ("queued", "walking"):
            return 0.0
        return max(self.expected_s - self.walked_s, 0.0) * self.wall_per_sim


class JobBoard:
    """This instance's bench jobs: the queue in order, and those finished lately."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._ids = itertools.count(1)
        self._live: dict[int, BenchJob] = {}
        self._finished: deque[BenchJob] = deque(maxlen=KEEP_FINISHED)
        self._measured: dict[str, tuple[float, float]] = {}    # kind -> (simulated s, wall s per simulated s)

    def expectation(self, kind: str) -> tuple[float, float, str]:
        """What a job of ``kind`` is expected to walk (simulated s), at what pace (wall s per simulated s), and where
        that comes from: the last one done on this instance, or a first guess."""
        if kind in self._measured:
            return (*self._measured[kind], f"the last {kind} on this server")
        return (FIRST_GUESS_S.get(kind, 30.0), FIRST_GUESS_WALL_PER_SIM,
                f"a first guess: no {kind} has been walked on this server yet")

    def new(self, kind: str, target: str, path: str, user: str) -> BenchJob:
        with self._lock:
            job = BenchJob(next(self._ids), kind, target, path, user, *self.expectation(kind))
            self._live[job.id] = job
            return job

    def started(self, job: BenchJob) -> None:
        job.state, job.started_at = "walking", time.time()

    def finished(self, job: BenchJob, state: JobState, error: str | None = None) -> None:
        with self._lock:
            job.state, job.ended_at, job.error = state, time.time(), error
            self._live.pop(job.id, None)
            self._finished.append(job)
            if state == "done" and job.walked_s > 0:         # what the next job of its kind expects
                self._measured[job.kind] = (job.walked_s, job.wall_per_sim)

    def get(self, job_id: int) -> BenchJob | None:
        with self._lock:
            return self._live.get(job_id) or next((j for j in self._finished if j.id == job_id), None)

    def jobs(self) -> list[BenchJob]:
        """The queue in order (walking first), then the finished ones, newest first."""
        cutoff = time.time() - KEEP_FINISHED_S
        with self._lock:
            live = sorted(self._live.values(), key=lambda j: (j.state != "walking", j.id))
            return live + [j for j in reversed(self._finished) if (j.ended_at or 0) >= cutoff]

    def ahead_of(self, job: BenchJob) -> list[BenchJob]:
        """The jobs that will walk before ``job`` (the one walking, and those queued before it)."""
        with self._lock:
            return [j for j in self._live.values() if j.id != job.id and (j.state == "walking" or j.id < job.id)]

    def cancel(self, job: BenchJob, by: str) -> None:
        """Cancel ``job`` (see the module): from the event loop's thread (a request handler)."""
        job.cancelled_by = by
        job._cancel.set()
        if job.state == "queued" and job._scope is not None:
            job._scope.cancel()


BOARD = JobBoard()
