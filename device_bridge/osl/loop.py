"""The leg's control loop: one tick every period on the leg's monotonic clock, its lateness measured.

A tick is **late** by how long after its due time it began; it is an **overrun** when that is more than one period
(the slot was missed: the tick before took too long, or the machine did not wake the loop). ``overruns_to_safe``
overruns in a row call ``on_overruns`` once (the leg goes to safe mode: a controller that cannot keep its rate is not
controlling). After a stall the loop does not race to catch up: the next tick is due a period after the late one.
The loop runs in the thread that calls :meth:`ControlLoop.run` (the main thread on the leg); the clinic's link runs in
its own threads beside it and never takes the loop's time.

Our own: the SDK's ``SoftRealtimeLoop`` installs signal handlers (main thread only) and reports no overruns.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field


@dataclass
class LoopStats:
    """What the loop measured (s)."""

    ticks: int = 0
    overruns: int = 0
    overruns_in_row: int = 0
    longest_late_s: float = 0.0
    late_s: list[float] = field(default_factory=list)   # every tick's lateness, when kept (benchmarks)


class ControlLoop:
    """Call ``tick(now_s)`` every ``period_s`` (module docstring).

    Args:
        period_s: the control period (s): 0.002 for 500 Hz.
        tick: one control period's work, given the time it began (s, the loop's clock).
        overruns_to_safe: overruns in a row that call ``on_overruns`` (once per run of them).
        on_overruns: called with the number in a row.
        clock, sleep: the leg's monotonic clock and sleep (s).
        keep_lateness: keep every tick's lateness in :attr:`stats` (benchmarks).
    """

    def __init__(self, period_s: float, tick: Callable[[float], None], overruns_to_safe: int = 5,
                 on_overruns: Callable[[int], None] | None = None, clock: Callable[[], float] = time.monotonic,
                 sleep: Callable[[float], None] = time.sleep, keep_lateness: bool = False) -> None:
        if not (0.0001 <= period_s <= 0.1):
            raise ValueError(f"period_s must be 0.1 ms to 100 ms, got {period_s!r}")
        if overruns_to_safe < 1:
            raise ValueError(f"overruns_to_safe must be at least 1, got {overruns_to_safe!r}")
        self.period_s, self.tick, self.overruns_to_safe = period_s, tick, overruns_to_safe
        self.on_overruns = on_overruns
        self.clock, self.sleep = clock, sleep
        self.keep_lateness = keep_lateness
        self.stats = LoopStats()
        self.stop_event = threading.Event()

    def run(self, max_ticks: int | None = None) -> LoopStats:
        """Tick until :attr:`stop_event` is set (or ``max_ticks`` ticks); the stats."""
        st, period = self.stats, self.period_s
        due = self.clock()
        while not self.stop_event.is_set() and (max_ticks is None or st.ticks < max_ticks):
            now = self.clock()
            if now < due:
                self.sleep(due - now)
                now = self.clock()
            late = max(now - due, 0.0)
            st.longest_late_s = max(st.longest_late_s, late)
            if self.keep_lateness:
                st.late_s.append(late)
            if late > period:
                st.overruns += 1
                st.overruns_in_row += 1
                if st.overruns_in_row == self.overruns_to_safe and self.on_overruns is not None:
                    self.on_overruns(st.overruns_in_row)
            else:
                st.overruns_in_row = 0
            self.tick(now)
            st.ticks += 1
            due = due + period if late <= period else now + period   # after a stall: on from now, no racing
        return st
