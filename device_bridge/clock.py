"""The time the leg side runs on: the wall clock on a server or a leg, a stepped clock in a rig.

Every piece of the device stack that reads the time or waits (the device node, the host link, the heartbeat, the
session recorder, the gateway) does so through a :class:`Clock` it is given, never through :mod:`time` itself. The
server and the bridge give them :data:`WALL_CLOCK` (nothing changes for a user); a rig
(:mod:`device_bridge.rig`) gives them a :class:`SteppedClock`, whose time moves only when the rig steps it, so the
whole loop runs in simulated seconds, as fast as the CPU allows, and the same inputs give the same frames.

A wait on a stepped clock is what moves it: the thread that waits runs the clock's steps (the firmware's ticks, the
frames' hand-over, the heartbeats) until what it waits for happens or its time is up. So a push waiting for its
acknowledgement, or a test waiting for a status, drives the simulation itself, on one thread.
"""

from __future__ import annotations

import contextlib
import queue
import threading
import time
from collections.abc import Callable, Iterator
from typing import Protocol, TypeVar

T = TypeVar("T")


class Clock(Protocol):
    """What the device stack asks of time: monotonic and Unix seconds, and two ways to wait."""

    def monotonic(self) -> float:
        """Seconds on a clock that never steps back (for periods, timeouts, ages)."""
        ...

    def time(self) -> float:
        """Unix seconds (for stamps stored or sent: a sample's time, a frame's)."""
        ...

    def wait(self, stop: threading.Event, timeout_s: float) -> bool:
        """Wait until ``stop`` is set or ``timeout_s`` passed; whether ``stop`` is set."""
        ...

    def get(self, items: queue.Queue[T], timeout_s: float) -> T:
        """The next item of ``items``, waiting at most ``timeout_s``; :class:`queue.Empty` when none came."""
        ...

    def until(self, done: Callable[[], bool], timeout_s: float, poll_s: float = 0.005) -> bool:
        """Wait until ``done()`` holds or ``timeout_s`` passed (asking every ``poll_s`` where time runs on its own);
        whether it holds."""
        ...


class WallClock:
    """The real clocks, and waits that block the calling thread."""

    def monotonic(self) -> float:
        return time.monotonic()

    def time(self) -> float:
        return time.time()

    def wait(self, stop: threading.Event, timeout_s: float) -> bool:
        return stop.wait(max(0.0, timeout_s))

    def get(self, items: queue.Queue[T], timeout_s: float) -> T:
        return items.get(timeout=max(0.0, timeout_s))

    def until(self, done: Callable[[], bool], timeout_s: float, poll_s: float = 0.005) -> bool:
        deadline = time.monotonic() + timeout_s
        while not done():
            left = deadline - time.monotonic()
            if left <= 0:
                return False
            time.sleep(min(poll_s, left))
        return True


WALL_CLOCK = WallClock()


class SteppedClock:
    """Simulated time in whole steps of ``step_s`` (s), starting at monotonic 0 and Unix ``start_unix_s``.

    :meth:`step` advances the time one step and then runs every stepper added (:meth:`add`) with the new time, in
    the order they were added; :meth:`advance` and every wait run steps. Time is kept as a step count, so it never
    drifts and two runs see the same floats. Several threads may wait at once (a test and a request it made): one
    step at a time, each waiter checking its own condition between steps. A wait from inside a step would never end:
    it raises instead.
    """

    def __init__(self, step_s: float = 0.001, start_unix_s: float = 1_800_000_000.0) -> None:
        if not (0.0 < step_s <= 0.1):
            raise ValueError(f"step_s must be in (0, 0.1] s, got {step_s!r}")
        self.step_s = step_s
        self.start_unix_s = start_unix_s
        self.steps = 0
        self._steppers: list[Callable[[float], None]] = []
        self._lock = threading.Lock()
        self._stepping: int | None = None     # the thread running a step

    def monotonic(self) -> float:
        return self.steps * self.step_s

    def time(self) -> float:
        return self.start_unix_s + self.steps * self.step_s

    def add(self, stepper: Callable[[float], None]) -> None:
        """Run ``stepper(now_s)`` at every step from now on (after those added before it)."""
        self._steppers.append(stepper)

    def remove(self, stepper: Callable[[float], None]) -> None:
        self._steppers = [s for s in self._steppers if s is not stepper]

    def step(self) -> None:
        """One step: the time moves on by ``step_s``, then every stepper runs at the new time."""
        me = threading.get_ident()
        if self._stepping == me:
            raise RuntimeError("a stepped clock was waited on from inside one of its own steps: it would never move")
        with self._lock:
            self._stepping = me
            try:
                self.steps += 1
                now = self.monotonic()
                for stepper in list(self._steppers):
                    stepper(now)
            finally:
                self._stepping = None

    @contextlib.contextmanager
    def between_steps(self) -> Iterator[None]:
        """Hold the clock between two steps: change what its steppers step (a simulated patient set walking) without a
        step running meanwhile on another thread. Not from inside a step."""
        with self._lock:
            yield

    def advance(self, seconds: float) -> None:
        """Run the steps of ``seconds`` of simulated time."""
        for _ in range(max(0, round(seconds / self.step_s))):
            self.step()

    def until(self, done: Callable[[], bool], timeout_s: float, poll_s: float = 0.0) -> bool:
        """Step until ``done()`` holds (checked before each step) or ``timeout_s`` of simulated time passed; whether
        it holds (``poll_s`` is the wall clock's: here every step is a look)."""
        deadline = self.steps + max(0, round(timeout_s / self.step_s))
        while not done():
            if self.steps >= deadline:
                return False
            self.step()
        return True

    def wait(self, stop: threading.Event, timeout_s: float) -> bool:
        return self.until(stop.is_set, timeout_s)

    def get(self, items: queue.Queue[T], timeout_s: float) -> T:
        if not self.until(lambda: not items.empty(), timeout_s):
            raise queue.Empty
        return items.get_nowait()


class PacedClock(SteppedClock):
    """A stepped clock kept in step with the wall clock by a thread of its own: the server's simulated leg.

    The leg, its firmware and the host's side of its link (heartbeat included) all run on this one clock, so a starved
    server runs the whole simulated world late, never one end of the link without the other: a busy machine can slow
    the simulated patient down, but cannot make the simulated leg miss a heartbeat that its host sent on time. A
    thread that waits on it steps it too (a push waiting for its acknowledgement runs ahead of the wall clock; the
    pacer then waits for the wall clock to catch up). Behind by more than ``max_behind_s`` (a stalled process), it
    slips rather than racing to catch up, as the device node does.
    """

    def __init__(self, step_s: float = 0.001, max_behind_s: float = 0.5, wake_s: float = 0.005) -> None:
        super().__init__(step_s, start_unix_s=time.time())
        self.max_behind_s = max_behind_s
        self.wake_s = wake_s
        self.slipped_s = 0.0            # simulated time given up to a stalled process
        self._origin = time.monotonic()
        self._closed = threading.Event()
        self._pacer = threading.Thread(target=self._run, name="paced-clock", daemon=True)

    def start(self) -> PacedClock:
        self._origin = time.monotonic() - self.monotonic()
        self._pacer.start()
        return self

    def time(self) -> float:
        return self.start_unix_s + self.monotonic() + self.slipped_s

    def _due(self) -> int:
        """The step the wall clock says is due now."""
        return round((time.monotonic() - self._origin) / self.step_s)

    def _run(self) -> None:
        behind_max = round(self.max_behind_s / self.step_s)
        while not self._closed.is_set():
            due = self._due()
            if due - self.steps > behind_max:                   # stalled: slip, keep the steps already due
                lost = due - self.steps - behind_max
                self._origin += lost * self.step_s
                self.slipped_s += lost * self.step_s
                due -= lost
            while self.steps < due and not self._closed.is_set():
                self.step()
            self._closed.wait(self.wake_s)

    def close(self) -> None:
        self._closed.set()
        if self._pacer.is_alive() and self._pacer is not threading.current_thread():
            self._pacer.join(timeout=2.0)
