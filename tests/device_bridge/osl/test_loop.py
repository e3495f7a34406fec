"""The leg's control loop on a scripted clock: ticks on time, overruns counted, safe after enough in a row."""

from __future__ import annotations

import pytest

from device_bridge.osl.loop import ControlLoop


class ScriptedClock:
    """A monotonic clock that moves only when slept on or when a tick takes time."""

    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now

    def sleep(self, s: float) -> None:
        self.now += s


def test_ticks_come_every_period_and_a_slow_tick_is_an_overrun_that_does_not_make_the_loop_race():
    clock = ScriptedClock()
    started = []
    work = {5: 0.0065}          # the sixth tick takes 6.5 ms: the next two slots are missed

    def tick(now: float) -> None:
        started.append(now)
        clock.now += work.get(len(started) - 1, 0.0002)

    loop = ControlLoop(0.002, tick, overruns_to_safe=3, clock=clock, sleep=clock.sleep, keep_lateness=True)
    stats = loop.run(max_ticks=12)
    assert stats.ticks == 12 and stats.overruns == 1 and stats.overruns_in_row == 0
    assert started[:6] == pytest.approx([0.0, 0.002, 0.004, 0.006, 0.008, 0.010])
    assert started[6] == pytest.approx(0.0165) and started[7] == pytest.approx(0.0185)   # on from the late tick
    assert stats.longest_late_s == pytest.approx(0.0045)


def test_overruns_in_a_row_call_for_safe_mode_once():
    clock = ScriptedClock()
    called = []

    def tick(now: float) -> None:
        clock.now += 0.0045         # every tick longer than two periods: every slot after the first is missed

    loop = ControlLoop(0.002, tick, overruns_to_safe=4, on_overruns=called.append, clock=clock, sleep=clock.sleep)
    stats = loop.run(max_ticks=10)
    assert called == [4] and stats.overruns >= 8


def test_nonsense_settings_are_refused():
    with pytest.raises(ValueError, match="period_s"):
        ControlLoop(0.0, lambda now: None)
    with pytest.raises(ValueError, match="overruns_to_safe"):
        ControlLoop(0.002, lambda now: None, overruns_to_safe=0)
