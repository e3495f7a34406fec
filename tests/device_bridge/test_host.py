"""The host's side of the link against the device node on a virtual bus."""

from __future__ import annotations

import can
import pytest

from device_bridge.clock import SteppedClock
from device_bridge.envelope_wire import table_wire
from device_bridge.firmware import FirmwareConfig
from device_bridge.host import DeviceLink, PushError
from device_bridge.protocol import Command, Mode
from tests.helpers.device import pair, until


def test_a_push_returns_the_crc_the_device_then_reports_active(tables):
    node, link = pair()
    try:
        result = link.push(tables[0], version=42)
        assert result.crc32 == table_wire(tables[0]).crc32() and result.version == 42
        until(lambda: link.status is not None and link.status.active_crc32 == result.crc32, clock=link.clock)
        assert link.status.mode == Mode.ACTIVE and link.status.active_version == 42
        assert node.snapshot().active.crc32 == result.crc32
    finally:
        link.close()
        node.close()


def test_a_table_the_device_finds_unsafe_is_refused_and_the_old_one_stays(tables):
    node, link = pair()
    try:
        old = link.push(tables[0], version=1).crc32
        until(lambda: node.snapshot().active is not None, clock=link.clock)   # a leg at rest switches at its next tick
        row = tables[1].rows[0]
        unsafe = tables[1].model_copy(update={"rows": [row.model_copy(update={"k_Nm_per_rad": 900.0}),
                                                       *tables[1].rows[1:]]})   # fits the wire; injects energy
        with pytest.raises(PushError, match="outside its own safety limits") as err:
            link.push(unsafe, version=2)
        assert err.value.reason == "safety_limit"
        assert node.snapshot().active.crc32 == old and node.snapshot().staged is None
    finally:
        link.close()
        node.close()


def test_a_push_to_a_silent_bus_times_out_with_a_reason(tables):
    link = DeviceLink(can.Bus(interface="virtual", channel="test-link-silent"), clock=SteppedClock())
    try:
        with pytest.raises(PushError, match="unconfirmed: the device's next status tells") as err:
            link.push(tables[0], version=1, timeout_s=0.3)
        assert err.value.reason == "timeout"
    finally:
        link.close()


def test_heartbeat_loss_is_reported_as_safe_mode_and_a_command_resumes(tables):
    node, link = pair(FirmwareConfig(heartbeat_timeout_s=0.1))
    try:
        link.push(tables[0], version=1)
        until(lambda: link.status is not None and link.status.mode == Mode.ACTIVE, clock=link.clock)
        link.pause_heartbeat(True)
        until(lambda: link.status.mode == Mode.SAFE, clock=link.clock)
        entered = node.snapshot().safe_mode_entered_s
        assert entered - node.snapshot().last_heartbeat_s == pytest.approx(0.1, abs=0.02)
        link.pause_heartbeat(False)
        until(lambda: node.snapshot().last_heartbeat_s > entered, clock=link.clock)    # heard again: the leg stays safe
        assert node.snapshot().mode == Mode.SAFE and link.status.mode == Mode.SAFE
        link.command(Command.LEAVE_SAFE_MODE)
        until(lambda: link.status.mode == Mode.ACTIVE, clock=link.clock)
    finally:
        link.close()
        node.close()


def test_a_failing_callback_does_not_stop_the_link(tables):
    def broken(_status) -> None:
        raise RuntimeError("dashboard bug")

    node, link = pair(on_status=broken)
    try:
        until(lambda: link.callback_errors > 0, clock=link.clock)
        assert link.push(tables[0], version=5).crc32 == table_wire(tables[0]).crc32()
    finally:
        link.close()
        node.close()


def test_every_status_after_an_acknowledgement_says_what_the_device_has_staged(tables):
    """A status is read with the health frame the device sent with it: one made after a push was staged says so.
    (A status joined with the health of the cycle before said "nothing staged" for one status period after the
    acknowledgement, and a second push confirming the old table could then pass the one-push-per-device check.)"""
    import queue
    from dataclasses import replace

    from device_bridge.rig import Rig
    from tests.device_bridge.test_device_node import StandingLeg

    class OneStep(StandingLeg):
        """The person stands, takes one step (the leg lifted 0.25–0.3 s in, the knee bending) and stands loaded
        again: one heel strike, none after it."""

        def __init__(self, clock) -> None:
            super().__init__(clock)
            self.t0 = clock.monotonic()

        def sample(self):
            x = super().sample()
            return replace(x, load_N=0.0, knee_velocity_rad_s=1.0) if 0.25 < x.time_s - self.t0 <= 0.3 else x

    # after its one heel strike the leg is walking for a minute: a staged table stays staged
    rig = Rig(config=FirmwareConfig(idle_switch_s=60.0))
    node, link = rig.node, rig.link
    node.leg = OneStep(rig.clock)
    acked: list[float] = []

    class NotedAcks(queue.Queue):
        def put(self, item, block=True, timeout=None):
            acked.append(link.clock.monotonic())
            super().put(item, block, timeout)

    seen: list = []
    link.on_status = seen.append
    try:
        link.push(tables[0], version=1)
        until(lambda: link.status is not None and link.status.active_version == 1, clock=link.clock)
        until(lambda: node.firmware.controller_ is not None and node.firmware.controller_.state_ == 0,   # stance
              clock=link.clock)
        link._acks = NotedAcks()
        link.push(tables[1], version=2)
        ack_s = acked[-1]
        until(lambda: sum(s.received_monotonic_s > ack_s for s in seen) >= 3, clock=link.clock)
        after = [s for s in seen if s.received_monotonic_s > ack_s and s.active_version == 1]
        assert after and all(s.pending_version == 2 for s in after), [s.pending_version for s in after]
    finally:
        link.close()
        node.close()


def _sample_frames(seq16: int) -> list[tuple[str, dict[str, int]]]:
    from device_bridge.protocol import decode, encode

    return [decode(encode(name, {"seq": seq16}))
            for name in ("TELEMETRY_GAIT", "TELEMETRY_KNEE", "TELEMETRY_ANKLE")]


def _join(joiner, seq16: int, **kwargs):
    kwargs.setdefault("at_unix_s", 0.0)
    out = None
    for name, raw in _sample_frames(seq16):
        out = joiner.add(name, raw, **kwargs)
    return out


def test_sequence_numbers_unwrap_through_repeats_wraps_and_late_samples():
    """The 16-bit sequence made whole: forward through a wrap, a repeat (QoS 1 delivers at least once) just behind the
    newest instead of a wrap ahead, and a late sample near where its time puts it."""
    from device_bridge.host import _TelemetryJoiner

    live = _TelemetryJoiner()
    assert [_join(live, s).seq for s in (65534, 65535, 0, 1)] == [65534, 65535, 65536, 65537]
    assert _join(live, 65535).seq == 65535                 # a repeat, not 131071
    assert _join(live, 2).seq == 65538
    late = _TelemetryJoiner()
    sample = _join(late, 40000, near=65538 - 6000, at_unix_s=123.0)   # made a minute before the newest live one
    assert sample.seq == 40000 and sample.received_unix_s == 123.0
    assert _join(late, 1000, near=65538 + 1000).seq == 65536 + 1000


class _PushingBus(can.BusABC):
    """A bus that hands its frames to the link (as the broker link's shared connection does) and keeps what is sent."""

    delivers_frames = True

    def __init__(self) -> None:
        super().__init__(channel="pushing")
        self.on_frames = None
        self.sent: list[can.Message] = []

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        self.sent.append(msg)

    def _recv_internal(self, timeout: float | None):
        raise AssertionError("a link on a bus that delivers its frames must not read it")


def _telemetry(seq16: int) -> list[can.Message]:
    from device_bridge.protocol import encode

    return [encode(name, {"seq": seq16}) for name in ("TELEMETRY_GAIT", "TELEMETRY_KNEE", "TELEMETRY_ANKLE")]


def test_a_bus_that_delivers_its_frames_feeds_the_link_and_gaps_are_counted_until_filled():
    """No receive thread on such a bus; a skipped sample is missing until it arrives (overtaken on the way), a repeat
    is no gap."""
    bus = _PushingBus()
    samples = []
    link = DeviceLink(bus, on_telemetry=samples.append).start()
    try:
        assert [t.name for t in link._threads] == ["can-heartbeat"]
        for seq in (0, 1, 4):
            bus.on_frames(_telemetry(seq))
        assert [s.seq for s in samples] == [0, 1, 4]
        assert (link.telemetry_received, link.telemetry_missing) == (3, 2)
        bus.on_frames(_telemetry(2))          # overtaken, not lost
        bus.on_frames(_telemetry(4))          # a repeat (QoS 1): no gap, nothing filled
        assert (link.telemetry_received, link.telemetry_missing) == (5, 1)
    finally:
        link.close()


def test_one_clock_beats_for_several_links_and_skips_a_paused_one():
    from device_bridge.host import HeartbeatClock
    from device_bridge.protocol import frame_id

    stepped = SteppedClock()
    clock = HeartbeatClock(0.01, clock=stepped)   # not started: the stepped clock runs its round
    stepped.add(lambda now: clock.beat() if stepped.steps % 10 == 0 else None)   # what its thread does at 0.01 s
    buses = [_PushingBus() for _ in range(3)]
    links = [DeviceLink(bus, heartbeat_clock=clock, clock=stepped).start() for bus in buses]
    beats = lambda bus: sum(f.arbitration_id == frame_id("HOST_HEARTBEAT") for f in bus.sent)  # noqa: E731
    try:
        assert all(t.name != "can-heartbeat" for link in links for t in link._threads)
        links[1].pause_heartbeat()
        paused_at = beats(buses[1])
        until(lambda: beats(buses[0]) >= 5 and beats(buses[2]) >= 5, clock=stepped)
        assert beats(buses[1]) <= paused_at + 1       # at most the beat under way when it was paused
        links[0].close()
        closed_at = beats(buses[0])
        until(lambda: beats(buses[2]) >= closed_at + 5, clock=stepped)
        assert beats(buses[0]) <= closed_at + 1
    finally:
        for link in links[1:]:
            link.close()
        clock.close()
    with pytest.raises(ValueError, match="period_s"):
        HeartbeatClock(0.0)


def _status_frame(mode: Mode, made_unix_s: float) -> can.Message:
    from device_bridge.protocol import encode

    f = encode("DEVICE_STATUS", {"counter": 1, "mode": int(mode), "fsm_state": 15})
    f.timestamp = made_unix_s
    return f


def test_a_status_that_was_in_flight_when_the_link_broke_is_history_not_the_legs_state():
    """What the broker link delivers first after a cut was made before it: a status much later than the link's usual
    delay is counted, not taken as the leg's state; fresh ones are."""
    import time

    bus = _PushingBus()
    link = DeviceLink(bus).start()
    try:
        now = time.time()
        bus.on_frames([_status_frame(Mode.ACTIVE, now - 0.02)])
        assert link.status.mode == Mode.ACTIVE
        telemetry = _telemetry(0)
        for f in telemetry:
            f.timestamp = time.time() - 0.02          # the link's usual delay: 20 ms
        bus.on_frames(telemetry)
        bus.on_frames([_status_frame(Mode.SAFE, time.time() - 0.03)])
        assert link.status.mode == Mode.SAFE
        bus.on_frames([_status_frame(Mode.ACTIVE, time.time() - 3.0)])   # made 3 s ago, before the cut
        assert link.status.mode == Mode.SAFE and link.stale_statuses == 1
        bus.on_frames([_status_frame(Mode.SAFE, time.time() - 0.02)])
        assert link.status.mode == Mode.SAFE and link.stale_statuses == 1
    finally:
        link.close()


def test_a_bridge_clock_step_either_way_is_learned_and_the_leg_is_heard_again():
    """The leg's clock (its bridge's) set forward: its statuses are current at once. Set back 10 s: every status looks
    10 s late; once every frame has been late for RELEARN_S the delay is learned again and the leg is heard, instead
    of 100 s per second of the step (990 s here) before."""
    from device_bridge.clock import SteppedClock
    from device_bridge.host import RELEARN_S

    clock = SteppedClock()
    link = DeviceLink(_PushingBus(), clock=clock)    # its receive path alone: no thread of its own moves the time

    def status(mode: Mode, lag_s: float) -> Mode:
        link.receive([_status_frame(mode, clock.time() - lag_s)])
        return link.status.mode

    try:
        assert status(Mode.ACTIVE, 0.02) == Mode.ACTIVE
        assert status(Mode.SAFE, -0.4) == Mode.SAFE                         # its clock 0.42 s ahead: current
        clock.advance(0.1)
        assert status(Mode.ACTIVE, -0.38) == Mode.ACTIVE
        late_since = clock.time()                                            # its clock set back by 10 s
        heard = None
        while clock.time() - late_since < 2 * RELEARN_S:
            clock.advance(0.1)
            mode = Mode.SAFE if heard is None else Mode.ACTIVE
            if status(mode, 9.62) == mode and heard is None:
                heard = clock.time() - late_since
        assert heard is not None and RELEARN_S - 0.2 <= heard <= RELEARN_S + 0.2, heard
        assert link.status.mode == Mode.ACTIVE and link.relearned_delays == 1
        assert link.stale_statuses >= 40                                     # the first 5 s counted as history
    finally:
        link.close()
