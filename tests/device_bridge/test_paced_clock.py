"""The paced clock: the server's simulated leg and its link on one clock that keeps up with the wall clock. A stalled
process stalls the whole simulated world, so the leg never misses a heartbeat its host sent on time (on separate
threads, a starved heartbeat thread put a supervised leg in safe mode on a loaded CI machine)."""

from __future__ import annotations

import time

import pytest

from controller_core.walking_reference import level_walking_reference
from device_bridge.clock import PacedClock
from device_bridge.protocol import Fault, Mode
from device_bridge.rig import Rig
from device_bridge.sim.walker import SimWalker
from tests.helpers.device import until

pytestmark = [pytest.mark.wallclock]


def test_a_paced_clock_moves_on_its_own_and_slips_after_a_stall():
    clock = PacedClock(max_behind_s=0.05).start()
    stalled = []

    def stall(_now: float) -> None:           # one step that holds the whole simulated world (the process starved)
        if clock.steps == 100 and not stalled:
            stalled.append(True)
            time.sleep(0.3)

    clock.add(stall)
    try:
        until(lambda: clock.steps >= 200)      # nobody waits on it: its own thread steps it
        assert stalled and clock.slipped_s > 0.0 and clock.time() >= clock.start_unix_s + clock.monotonic()
    finally:
        clock.close()
    steps = clock.steps
    time.sleep(0.05)                           # closed: it stays where it is (not a wait for anything)
    assert clock.steps == steps


def test_a_stall_of_the_process_never_costs_the_leg_its_host(tables):
    """Walking with a table, the process stalls 0.4 s (twice the heartbeat timeout) inside a step: the leg, its
    firmware and the host's heartbeat all stood still together, and the leg walks on, supervised, with no fault."""
    clock = PacedClock()
    walker = SimWalker()
    with Rig(leg=walker, clock=clock) as rig:
        clock.start()
        try:
            rig.link.push(tables[0], version=3)
            walker.start(level_walking_reference(1.2), 75.0)
            stalls: list[float] = []

            def stall(_now: float) -> None:
                if len(stalls) < 2 and clock.monotonic() > 1.0 + 0.5 * len(stalls):
                    stalls.append(clock.monotonic())
                    time.sleep(0.4)

            clock.add(stall)
            until(lambda: clock.monotonic() > 2.5, timeout_s=30.0)
            snap = rig.node.snapshot()
            assert len(stalls) == 2 and snap.mode == Mode.ACTIVE
            assert not Fault.HEARTBEAT_LOST & rig.node.firmware.faults_
        finally:
            clock.close()
