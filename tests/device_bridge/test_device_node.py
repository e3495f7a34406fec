"""The simulated device on its bus: it keeps hearing the host even when its physics runs slower than real time."""

from __future__ import annotations

import time

from controller_core.fsm import SensorSample
from device_bridge.protocol import Fault, Mode
from tests.helpers.device import pair, until


class SlowLeg:
    """A standing leg whose physics step takes 1.3 ms of wall time per 1 ms tick (as a MuJoCo leg does when other
    threads of a busy server hold the interpreter): the node falls behind a little more every batch of ticks."""

    def __init__(self) -> None:
        self.steps = 0

    def sample(self) -> SensorSample:
        return SensorSample(time_s=time.monotonic(), knee_angle_rad=0.1, knee_velocity_rad_s=0.0, ankle_angle_rad=0.0,
                            ankle_velocity_rad_s=0.0, load_N=700.0, ankle_moment_Nm=0.0)

    def step(self, knee_torque_Nm: float, ankle_torque_Nm: float) -> None:
        self.steps += 1
        end = time.perf_counter() + 0.0013
        while time.perf_counter() < end:
            pass


def test_a_node_running_behind_still_hears_the_heartbeat(tables):
    leg = SlowLeg()
    node, link = pair(leg=leg)
    try:
        until(lambda: link.status is not None)
        until(lambda: leg.steps >= 1500, timeout_s=60)   # 1.5 s of ticks: well past the 200 ms watchdog, all late
        assert node.snapshot().mode != Mode.SAFE and not Fault.HEARTBEAT_LOST & node.firmware.faults_, \
            "the device lost a host that kept sending its heartbeat"
    finally:
        link.close()
        node.close()
