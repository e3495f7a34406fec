"""A whole envelope over CAN: all or nothing, re-checked by the device, run by the adaptive controller."""

from __future__ import annotations

import math
import random

import pytest

from controller_core.adaptive import AdaptiveController
from controller_core.envelope import Envelope
from controller_core.fsm import GaitState, SensorSample, StateMachineController
from device_bridge.envelope_wire import (
    WireEnvelope,
    check_envelope_as_run,
    envelope_begin_frame,
    envelope_commit_frame,
    table_wire,
)
from device_bridge.firmware import DeviceFirmware
from device_bridge.protocol import AckResult, Mode, ProtocolError, decode, physical
from device_bridge.soak import soak
from tests.device_bridge.test_firmware import feed, heartbeat, install
from tests.helpers.device import frames_of

SPEEDS = [0.8, 1.2, 1.6]
INCLINES = [-8.0, 0.0, 8.0]


@pytest.fixture(scope="module")
def envelopes(model) -> list[Envelope]:
    return [model.propose_envelope(SPEEDS, INCLINES, m) for m in (70.0, 85.0)]


def with_node_table(env: Envelope, index: int, **row_update) -> Envelope:
    """The envelope with the knee's stance-flexion row of one node changed (its JSON validation bypassed)."""
    node = env.nodes[index]
    rows = [r.model_copy(update=row_update) if (r.joint, r.subphase) == ("knee", "stance_flexion") else r
            for r in node.table.rows]
    nodes = list(env.nodes)
    nodes[index] = node.model_copy(update={"table": node.table.model_copy(update={"rows": rows})})
    return env.model_copy(update={"nodes": nodes})


def test_an_envelope_is_staged_whole_and_runs_on_the_adaptive_controller(envelopes):
    fw = DeviceFirmware()
    begin, data, commit, crc = frames_of(envelopes[0], 5, 300)
    assert len(data) == 3 + 3 + 2 + 1 + 1 + 9 * 13   # axes, nominal, body mass, axes check; 9 nodes of 12 and a check
    [ack] = feed(fw, [begin, *data, commit], 0.0)
    assert ack["result"] == AckResult.STAGED and ack["crc32"] == crc
    fw.tick(None, 0.001)
    assert fw.active_.crc32 == crc and fw.active_.envelope is not None and fw.active_.table is None
    assert isinstance(fw.controller_, AdaptiveController) and fw.mode_ == Mode.ACTIVE
    held = fw.active_.envelope
    assert held.speeds_mps == pytest.approx(SPEEDS) and held.inclines_deg == pytest.approx(INCLINES)
    assert held.nominal == pytest.approx((1.2, 0.0))


def test_lost_reordered_and_corrupted_frames_never_stage_a_mixed_envelope(envelopes):
    fw = DeviceFirmware()
    begin, data, commit, crc = frames_of(envelopes[0], 2, 7)
    rng = random.Random(4)
    kept = [f for f in data if rng.random() > 0.15]            # 15 % lost
    rng.shuffle(kept)                                          # and in any order
    bad = kept[10]
    flipped = bytearray(bad.data)
    flipped[5] ^= 0x10                                         # one corrupted frame
    kept[10] = type(bad)(arbitration_id=bad.arbitration_id, data=bytes(flipped), is_extended_id=False)
    [ack] = feed(fw, [begin, *kept, commit], 0.0)
    assert ack["result"] == AckResult.MISSING_ROWS and ack["missing_rows"] > 0 and fw.staged_ is None
    for attempt in range(3):                                   # the host sends the data again until none is missing
        [ack] = feed(fw, [*data, commit], 0.01 * (attempt + 1))
        if ack["result"] != AckResult.MISSING_ROWS:
            break
        assert fw.staged_ is None
    assert ack["result"] == AckResult.STAGED and ack["crc32"] == crc
    fw.tick(None, 0.05)
    assert fw.active_.envelope == WireEnvelope.from_envelope(envelopes[0]).to_device()


def test_the_device_refuses_an_unsafe_node_or_a_broken_neighbour_rule_and_keeps_its_table(envelopes, tables):
    fw = DeviceFirmware()
    old = install(fw, tables[0], 1)
    for bad in (with_node_table(envelopes[0], 4, k_Nm_per_rad=40.0),        # a stance row that injects energy
                with_node_table(envelopes[0], 0, k_Nm_per_rad=-1100.0)):    # safe alone, a jump from its neighbours
        assert check_envelope_as_run(bad)                                  # the server would not approve it either
        begin, data, commit, _ = frames_of(bad, 3, 9)
        [ack] = feed(fw, [begin, *data, commit], 0.1)
        assert ack["result"] == AckResult.SAFETY_LIMIT and ack["crc32"] == 0
        assert fw.staged_ is None and fw.active_.crc32 == old
    assert check_envelope_as_run(envelopes[0]) == []


def test_a_wrong_envelope_crc_is_refused(envelopes):
    fw = DeviceFirmware()
    wire = WireEnvelope.from_envelope(envelopes[0])
    crc = wire.crc32() ^ 1
    [ack] = feed(fw, [envelope_begin_frame(1, 3, crc, wire.shape), *wire.frames(1),
                      envelope_commit_frame(1, 3, crc, wire.shape)], 0.0)
    assert ack["result"] == AckResult.CRC_MISMATCH and fw.staged_ is None


def test_an_envelope_too_large_for_the_link_is_refused_before_sending(model):
    env = model.propose_envelope([0.6 + 0.1 * i for i in range(9)], [-8.0 + 2.0 * j for j in range(9)], 75.0)
    with pytest.raises(ProtocolError, match="64 nodes"):
        WireEnvelope.from_envelope(env)


def test_a_staged_envelope_switches_in_at_heel_strike_and_reports_the_task(envelopes, tables):
    fw = DeviceFirmware()
    install(fw, tables[0], 1)
    th = fw.active_.table.thresholds
    t = 0.0
    loaded = th.we_to_sf_load_N + 50

    def step(load: float, moment: float = 0.0, knee: float = 0.3, knee_velocity: float = 0.0) -> list:
        nonlocal t
        t = round(t + 0.001, 6)
        heartbeat(fw, t)
        return fw.tick(SensorSample(t, knee, knee_velocity, 0.0, 0.0, load, moment, 0.2, 0.0), t)[2]

    for _ in range(100):      # the table came to a leg under a standing person: it stands
        step(loaded)
    for _ in range(50):       # the first step: lifted with the knee bending, then landed (stance flexion)
        step(0.0, knee_velocity=1.0)
    for _ in range(100):
        step(loaded)
    begin, data, commit, crc = frames_of(envelopes[1], 4, 12)
    [ack] = feed(fw, [begin, *data, commit], t)
    assert ack["result"] == AckResult.STAGED and isinstance(fw.controller_, StateMachineController)
    for load, moment, knee, velocity in [(loaded, th.sf_to_se_ankle_moment_Nm - 1, 0.3, 0.0)] * 100 + \
            [(0.0, 0.0, 0.3, 1.0)] * 100 + [(0.0, 0.0, math.radians(th.wf_to_we_knee_angle_deg) + 0.1, -2.0)] * 100:
        step(load, moment, knee, velocity)
        assert fw.active_.table is not None            # nothing switches in mid-stride
    out = []
    for _ in range(20):
        out += step(loaded)
    assert fw.active_.crc32 == crc and isinstance(fw.controller_, AdaptiveController)
    assert fw.controller_.state_ == GaitState.STANCE_FLEXION      # the leg carries on in stance
    task = [physical(*decode(m)) for m in out if decode(m)[0] == "TELEMETRY_TASK"]
    assert task and task[-1]["adaptive_mode"] == 1 and task[-1]["running_speed"] == pytest.approx(1.2, abs=0.004)


def test_envelope_pushes_through_a_faulty_bus_are_whole_or_not_at_all(envelopes, tables):
    out = soak([*envelopes, tables[0]], 15, drop=0.1, corrupt=0.05, reorder=0.05, seed=3, push_timeout_s=4.0)
    assert out["mixed"] == 0 and out["crc_mismatch"] == 0
    assert out["committed"] >= 13
    assert out["frames"]["host"]["corrupted"] > 0 and out["frames"]["host"]["dropped"] > 0


def test_a_walking_leg_adapts_to_a_ramp_and_streams_its_estimate_to_the_host(envelopes):
    """The simulated leg walks up an 8° ramp in real time with a pushed envelope: the host hears the estimate."""
    from controller_core.walking_reference import sloped_walking_reference
    from device_bridge.sim.walker import SimWalker
    from tests.helpers.device import pair, until

    samples = []
    walker = SimWalker()
    node, link = pair(leg=walker, on_telemetry=samples.append)
    try:
        result = link.push(envelopes[0], version=21)
        assert result.crc32 == WireEnvelope.from_envelope(envelopes[0]).crc32()
        until(lambda: link.status is not None and link.status.active_crc32 == result.crc32, clock=link.clock)
        walker.start(sloped_walking_reference(1.2, 8.0), 70.0)
        until(lambda: any(s.task is not None and s.task.adaptive_mode == "adaptive" for s in samples), timeout_s=20.0,
              clock=link.clock)
        last = next(s for s in reversed(samples) if s.task is not None)
        assert last.task.estimated_incline_deg == pytest.approx(8.0, abs=1.5)
        assert last.task.estimated_speed_mps == pytest.approx(1.2, abs=0.1)
        assert last.to_json()["adaptive_mode"] in ("adaptive", "partial")
        assert node.snapshot().mode == Mode.ACTIVE
    finally:
        walker.stop()
        link.close()
        node.close()


def test_a_table_pushed_after_an_envelope_replaces_it_at_heel_strike(envelopes, tables):
    fw = DeviceFirmware()
    begin, data, commit, env_crc = frames_of(envelopes[0], 1, 40)
    feed(fw, [begin, *data, commit], 0.0)
    fw.tick(None, 0.001)
    assert isinstance(fw.controller_, AdaptiveController) and fw.active_.crc32 == env_crc
    th = fw.active_.envelope.tables[4].thresholds
    loaded = th.we_to_sf_load_N + 50
    t = 0.001

    def step(load: float, moment: float = 0.0, knee: float = 0.3, knee_velocity: float = 0.0) -> None:
        nonlocal t
        t = round(t + 0.001, 6)
        heartbeat(fw, t)
        fw.tick(SensorSample(t, knee, knee_velocity, 0.0, 0.0, load, moment, 0.2, 0.0), t)

    for _ in range(100):      # the table came to a leg under a standing person: it stands
        step(loaded)
    for _ in range(50):       # the first step: lifted with the knee bending, then landed (stance flexion)
        step(0.0, knee_velocity=1.0)
    for _ in range(100):
        step(loaded)
    wire = table_wire(tables[1])       # the envelope of one node
    [ack] = feed(fw, [envelope_begin_frame(2, 41, wire.crc32(), (1, 1)), *wire.frames(2),
                      envelope_commit_frame(2, 41, wire.crc32(), (1, 1))], t)
    assert ack["result"] == AckResult.STAGED and fw.active_.crc32 == env_crc
    for load, moment, knee, velocity in [(loaded, th.sf_to_se_ankle_moment_Nm - 1, 0.3, 0.0)] * 100 + \
            [(0.0, 0.0, 0.3, 1.0)] * 100 + [(0.0, 0.0, math.radians(th.wf_to_we_knee_angle_deg) + 0.1, -2.0)] * 100:
        step(load, moment, knee, velocity)
        assert fw.active_.crc32 == env_crc              # the envelope runs to the end of its stride
    for _ in range(20):
        step(loaded)
    assert fw.active_.crc32 == wire.crc32() and isinstance(fw.controller_, StateMachineController)
    assert fw.controller_.state_ == GaitState.STANCE_FLEXION and fw.active_.blender is None   # run as a table
    assert fw.active_.table == wire.to_device().tables[0]


def test_a_commit_is_checked_before_the_firmware_is_taken_so_a_push_never_holds_up_a_control_tick(envelopes):
    """The node verifies an envelope (CRC, every node's limits, the neighbour rule, the blender: milliseconds on a
    leg's small computer) before it takes the firmware for the commit, and once; a transfer the control loop timed out
    in between is not staged from that verification."""
    import can

    from device_bridge.device_node import DeviceNode

    node = DeviceNode(can.Bus(interface="virtual", channel="prepare-test"), leg=None)
    fw = node.firmware
    checked = []
    verify = fw._verify

    def spy(rx):
        checked.append(node.ticking.locked())
        return verify(rx)

    fw._verify = spy
    begin, data, commit, crc = frames_of(envelopes[0], 2, 5)
    for f in [begin, *data, commit]:
        node.handle(f, 0.0)
    assert checked == [False] and fw.staged_ is not None and fw.staged_.crc32 == crc
    node.close()

    fw2 = DeviceFirmware()
    begin, data, commit, _ = frames_of(envelopes[0], 3, 6)
    for f in [begin, *data]:
        fw2.receive(f, 0.0)
    prepared = fw2.prepare(commit)
    assert prepared is not None and prepared.rx is not None
    fw2.tick(None, 10.0)                                   # the transfer times out meanwhile
    [ack] = [decode(m)[1] for m in fw2.receive(commit, 10.0, prepared) if decode(m)[0] == "TABLE_ACK"]
    assert ack["result"] == AckResult.UNKNOWN_TRANSFER and fw2.staged_ is None
