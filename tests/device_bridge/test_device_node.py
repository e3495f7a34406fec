"""The simulated device on its bus, with its two threads on the wall clock (their timing is the subject): it keeps
hearing the host even when its physics runs slower than real time, and its frames leave in the order made."""

from __future__ import annotations

import time

import pytest

from controller_core.fsm import SensorSample
from device_bridge.clock import WALL_CLOCK, Clock
from device_bridge.protocol import Fault, Mode
from tests.helpers.device import until, wall_pair

pytestmark = [pytest.mark.wallclock, pytest.mark.live]


class SlowLeg:
    """A standing leg whose physics step takes 1.3 ms of wall time per 1 ms tick (as a MuJoCo leg does when other
    threads of a busy server hold the interpreter): the node falls behind a little more every batch of ticks."""

    def __init__(self, clock: Clock = WALL_CLOCK) -> None:
        self.steps = 0
        self.clock = clock

    def sample(self) -> SensorSample:
        return SensorSample(time_s=self.clock.monotonic(), knee_angle_rad=0.1, knee_velocity_rad_s=0.0, ankle_angle_rad=0.0,
                            ankle_velocity_rad_s=0.0, load_N=700.0, ankle_moment_Nm=0.0)

    def step(self, knee_torque_Nm: float, ankle_torque_Nm: float) -> None:
        self.steps += 1
        end = time.perf_counter() + 0.0013
        while time.perf_counter() < end:
            pass


def test_a_node_running_behind_still_hears_the_heartbeat(tables):
    leg = SlowLeg()
    node, link = wall_pair(leg=leg)
    try:
        until(lambda: link.status is not None)
        until(lambda: leg.steps >= 1500, timeout_s=60)   # 1.5 s of ticks: well past the 200 ms watchdog, all late
        assert node.snapshot().mode != Mode.SAFE and not Fault.HEARTBEAT_LOST & node.firmware.faults_, \
            "the device lost a host that kept sending its heartbeat"
    finally:
        link.close()
        node.close()



class StandingLeg(SlowLeg):
    """A standing leg whose physics costs nothing: the node streams telemetry and status as on a patient."""

    def step(self, knee_torque_Nm: float, ankle_torque_Nm: float) -> None:
        self.steps += 1


class SlowSendBus:
    """A virtual bus whose every send first waits half a millisecond for its transmit mailbox: wide windows for two
    threads' frames to cross. Notes each frame as it goes onto the bus."""

    def __init__(self, bus) -> None:
        self.bus, self.sent = bus, []

    def send(self, msg, timeout=None) -> None:
        time.sleep(0.0005)            # the controller's transmit path, waiting for its mailbox (other threads run)
        self.sent.append(msg)
        self.bus.send(msg, timeout)

    def __getattr__(self, name):
        return getattr(self.bus, name)


def test_frames_leave_in_the_order_the_firmware_made_them(tables):
    """A status built before a push was staged must not reach the host after that push's acknowledgement (the host
    would take the stale status as the device's word and record the push as lost): the control loop's frames and
    the receive loop's answers leave in the order the firmware produced them, as from a firmware's one thread."""
    import can

    from device_bridge.device_node import DeviceNode
    from device_bridge.host import DeviceLink

    channel = "test-frame-order"
    bus = SlowSendBus(can.Bus(interface="virtual", channel=channel))
    node = DeviceNode(bus, leg=StandingLeg())
    made = []
    tick, receive = node.firmware.tick, node.firmware.receive

    def noted_tick(*args):
        knee, ankle, frames = tick(*args)
        made.extend(frames)
        return knee, ankle, frames

    def noted_receive(*args):
        frames = receive(*args)
        made.extend(frames)
        return frames

    node.firmware.tick, node.firmware.receive = noted_tick, noted_receive     # both run holding the firmware
    node.start()
    link = DeviceLink(can.Bus(interface="virtual", channel=channel)).start()
    try:
        until(lambda: link.status is not None)
        for version, table in enumerate(tables * 3, start=1):                # answers crossing the status stream
            link.push(table, version=version)
    finally:
        link.close()
        node.close()
    assert len(bus.sent) > 12 and len(bus.sent) >= len(made) - 5      # six read-backs among the periodic frames
    assert [id(m) for m in bus.sent] == [id(m) for m in made[:len(bus.sent)]], "frames left out of the firmware's order"
