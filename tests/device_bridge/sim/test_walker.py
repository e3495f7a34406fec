"""The simulated leg walking behind the device node."""

from __future__ import annotations

import threading

from controller_core.walking_reference import level_walking_reference
from device_bridge.host import TelemetrySample
from device_bridge.protocol import Mode
from device_bridge.sim.walker import SimWalker
from tests.helpers.device import pair, until


def test_the_walking_simulated_leg_streams_telemetry_without_gaps(tables):
    walker = SimWalker()
    got: list[TelemetrySample] = []
    lock = threading.Lock()

    def on_telemetry(sample: TelemetrySample) -> None:
        with lock:
            got.append(sample)

    node, link = pair(leg=walker, on_telemetry=on_telemetry)
    try:
        link.push(tables[0], version=3)
        walker.start(level_walking_reference(1.2), 75.0)
        until(lambda: len(got) >= 150, timeout_s=10.0)
    finally:
        link.close()
        node.close()
    seqs = [s.seq for s in got]
    assert seqs == list(range(seqs[0], seqs[0] + len(seqs)))
    knee = [s.knee_angle_rad for s in got]
    assert max(knee) - min(knee) > 0.2   # the knee moves (about 11° or more of swing in 1.5 s of walking)
    assert {s.mode for s in got} == {Mode.ACTIVE} and {s.fsm_state for s in got} >= {0, 1}
