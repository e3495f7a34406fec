"""The leg's firmware, fed frames and ticks: transfers, refusals, safe mode, the switch at heel strike."""

from __future__ import annotations

import dataclasses
import math
import random

import can
import pytest

from controller_core.fsm import GaitState, SensorSample
from controller_core.table import ParameterTable
from device_bridge.envelope_wire import (
    LANDING_ROW,
    STUMBLE_ROW,
    envelope_begin_frame,
    envelope_commit_frame,
    table_wire,
)
from device_bridge.firmware import DeviceFirmware, FirmwareConfig
from device_bridge.protocol import (
    AckResult,
    Command,
    Fault,
    LinkMode,
    Mode,
    decode,
    encode,
    physical,
)

BODY = 4   # a table's transfer: the axis frames (speed, incline, the nominal task's two, the body mass) and their check,
NODE = 6   # then its one node's twelve frames (eight rows, two threshold frames, the stumble and landing triggers)


def commit_frame(tid: int, version: int, crc: int) -> can.Message:
    return envelope_commit_frame(tid, version, crc, (1, 1))


def transfer(table: ParameterTable, tid: int, version: int) -> tuple[can.Message, list[can.Message], can.Message, int]:
    """A table's transfer: the envelope of its one node (begin, data frames, commit) and its CRC."""
    wire = table_wire(table)
    crc = wire.crc32()
    return envelope_begin_frame(tid, version, crc, (1, 1)), wire.frames(tid), commit_frame(tid, version, crc), crc


def feed(fw: DeviceFirmware, frames: list[can.Message], now: float) -> list[dict]:
    """Frames in; the decoded TABLE_ACKs out."""
    out = []
    for f in frames:
        out += fw.receive(f, now)
    return [decode(m)[1] for m in out if decode(m)[0] == "TABLE_ACK"]


def heartbeat(fw: DeviceFirmware, now: float) -> None:
    fw.receive(encode("HOST_HEARTBEAT", {"counter": 1}), now)


def install(fw: DeviceFirmware, table: ParameterTable, version: int, now: float = 0.0) -> int:
    begin, rows, commit, crc = transfer(table, version % 16, version)
    [ack] = feed(fw, [begin, *rows, commit], now)
    assert ack["result"] == AckResult.STAGED and ack["crc32"] == crc
    fw.tick(None, now + 0.001)
    assert fw.active_ is not None and fw.active_.crc32 == crc
    return crc


def status(frames: list[can.Message]) -> dict:
    return next(decode(m)[1] for m in reversed(frames) if decode(m)[0] == "DEVICE_STATUS")


def standing(t: float, knee_velocity: float = 0.5) -> SensorSample:
    return SensorSample(time_s=t, knee_angle_rad=0.3, knee_velocity_rad_s=knee_velocity, ankle_angle_rad=0.05,
                        ankle_velocity_rad_s=-0.2, load_N=700.0, ankle_moment_Nm=-20.0)


def test_a_clean_transfer_is_acknowledged_with_its_crc_and_becomes_active(tables):
    fw = DeviceFirmware()
    begin, rows, commit, crc = transfer(tables[0], 3, 17)
    [ack] = feed(fw, [begin, *rows, commit], 0.0)
    assert ack == {"transfer_id": 3, "result": AckResult.STAGED, "missing_rows": 0, "crc32": crc, "version_low": 17}
    assert fw.staged_.crc32 == crc and fw.active_ is None
    _, _, out = fw.tick(None, 0.001)   # no sensors: not walking, so it switches at once
    st = status(out)
    assert (st["mode"], st["active_version"], st["active_crc32"]) == (Mode.ACTIVE, 17, crc)
    assert fw.staged_ is None


def test_reordered_rows_still_make_the_table(tables):
    fw = DeviceFirmware()
    begin, rows, commit, crc = transfer(tables[0], 1, 2)
    shuffled = rows[:]
    random.Random(4).shuffle(shuffled)
    [ack] = feed(fw, [begin, *shuffled, commit], 0.0)
    assert ack["result"] == AckResult.STAGED and ack["crc32"] == crc


def test_a_lost_row_is_counted_resent_and_then_accepted(tables):
    fw = DeviceFirmware()
    old = install(fw, tables[0], 1)
    begin, rows, commit, crc = transfer(tables[1], 2, 2)
    lost = NODE + 4
    [nack] = feed(fw, [begin, *rows[:lost], *rows[lost + 1:], commit], 0.1)
    assert nack["result"] == AckResult.MISSING_ROWS and nack["missing_rows"] == 1 and nack["crc32"] == 0
    assert fw.active_.crc32 == old and fw.staged_ is None
    [ack] = feed(fw, [rows[lost], commit], 0.11)
    assert ack["result"] == AckResult.STAGED and ack["crc32"] == crc


def test_a_corrupted_row_fails_its_check_and_the_old_table_stays_until_clean_copies_come(tables):
    fw = DeviceFirmware()
    old = install(fw, tables[0], 1)
    begin, rows, commit, crc = transfer(tables[1], 2, 2)
    clean = list(rows)
    bad = bytearray(rows[NODE + 6].data)
    bad[3] ^= 0x10   # one bit of the ankle swing-flexion stiffness
    rows[NODE + 6] = can.Message(arbitration_id=rows[NODE + 6].arbitration_id, data=bytes(bad), is_extended_id=False)
    [nack] = feed(fw, [begin, *rows, commit], 0.1)
    assert nack["result"] == AckResult.MISSING_ROWS and nack["missing_rows"] == 13   # the node's frames and check
    fw.tick(None, 0.2)
    assert fw.active_.crc32 == old and fw.staged_ is None
    [ack] = feed(fw, [*clean, commit], 0.21)
    assert ack["result"] == AckResult.STAGED and ack["crc32"] == crc


def test_rows_of_another_transfer_are_not_mixed_in(tables):
    fw = DeviceFirmware()
    begin, rows, commit, _ = transfer(tables[0], 5, 1)
    _, other_rows, _, _ = transfer(tables[1], 6, 2)
    [nack] = feed(fw, [begin, *rows[:9], other_rows[9], *rows[10:], commit], 0.0)
    assert nack["result"] == AckResult.MISSING_ROWS and nack["missing_rows"] == 1


def test_begin_and_commit_must_agree(tables):
    fw = DeviceFirmware()
    begin, rows, _, crc = transfer(tables[0], 5, 1)
    [nack] = feed(fw, [begin, *rows, commit_frame(5, 1, crc ^ 1)], 0.0)
    assert nack["result"] == AckResult.MALFORMED and fw.staged_ is None


def test_a_transfer_that_stalls_times_out_and_keeps_the_old_table(tables):
    fw = DeviceFirmware(FirmwareConfig(transfer_timeout_s=0.5))
    old = install(fw, tables[0], 1)
    heartbeat(fw, 0.1)
    begin, rows, commit, _ = transfer(tables[1], 2, 2)
    feed(fw, [begin, *rows[:3]], 0.1)
    _, _, out = fw.tick(None, 0.59)
    assert not [m for m in out if decode(m)[0] == "TABLE_ACK"]
    heartbeat(fw, 0.59)
    _, _, out = fw.tick(None, 0.61)
    [ack] = [decode(m)[1] for m in out if decode(m)[0] == "TABLE_ACK"]
    assert ack["result"] == AckResult.TIMEOUT
    [late] = feed(fw, [*rows[3:], commit], 0.62)   # the rest arrives too late: that transfer is gone
    assert late["result"] == AckResult.UNKNOWN_TRANSFER and fw.active_.crc32 == old


def test_the_device_refuses_an_unsafe_table_itself(tables):
    fw = DeviceFirmware()
    old = install(fw, tables[0], 1)
    row = tables[1].rows[0]
    unsafe = tables[1].model_copy(update={"rows": [row.model_copy(update={"k_Nm_per_rad": 900.0}), *tables[1].rows[1:]]})
    begin, rows, commit, _ = transfer(unsafe, 2, 2)   # fits the wire, but +900 N·m/rad injects energy
    [nack] = feed(fw, [begin, *rows, commit], 0.1)
    assert nack["result"] == AckResult.SAFETY_LIMIT and nack["crc32"] == 0
    assert fw.active_.crc32 == old and fw.staged_ is None


def test_the_device_holds_the_stance_support_floor_for_the_mass_on_the_wire(tables):
    """The body mass travels in the transfer (an axis frame, under the CRC): the same rows pass for the 75 kg they were
    built for and are refused for 180 kg, whose floor (−216 N·m/rad) the knee's stance flexion is softer than."""
    fw = DeviceFirmware()
    table = tables[0]
    k = table.row("knee", "stance_flexion").k_Nm_per_rad
    assert -1.2 * 180.0 < k <= -1.2 * 75.0
    install(fw, table, 1)
    heavier = table.model_copy(update={"provenance": table.provenance.model_copy(update={"patient_mass_kg": 180.0})})
    begin, rows, commit, _ = transfer(heavier, 2, 2)
    [nack] = feed(fw, [begin, *rows, commit], 0.1)
    assert nack["result"] == AckResult.SAFETY_LIMIT and fw.staged_ is None


@pytest.mark.parametrize("index", [BODY, NODE + STUMBLE_ROW, NODE + LANDING_ROW])
def test_the_body_mass_stumble_and_landing_frames_are_part_of_the_transfer(tables, index):
    begin, rows, commit, crc = transfer(tables[0], 3, 3)
    fw = DeviceFirmware()
    [nack] = feed(fw, [begin, *rows[:index], *rows[index + 1:], commit], 0.0)   # that frame lost
    assert nack["result"] == AckResult.MISSING_ROWS and nack["missing_rows"] == 1
    [ack] = feed(fw, [rows[index], commit], 0.1)
    assert ack["result"] == AckResult.STAGED and ack["crc32"] == crc


def test_the_device_runs_the_stumble_support_it_was_sent_and_refuses_one_out_of_its_limits(tables):
    """The stumble and early-landing triggers travel in the transfer (ENVELOPE_STUMBLE, ENVELOPE_LANDING, under the CRC):
    the leg's state machine runs the values sent, and the device refuses a fold speed at which every downhill stance
    would be held stiff, and an early-landing share that ordinary stride-to-stride variation would trip."""
    fw = DeviceFirmware()
    th = tables[0].thresholds
    firmer = tables[0].model_copy(update={"thresholds": th.model_copy(update={
        "stumble_knee_margin_deg": 12.5, "fold_knee_rate_deg_per_s": 120.0, "fold_window_of_stance_pct": 40.0,
        "early_landing_swing_pct": 70.0, "forefoot_landing_pct": 60.0})})
    install(fw, firmer, 1)
    sch = fw.controller_.schedule
    assert sch.stumble_knee_margin_rad == pytest.approx(math.radians(12.5))
    assert sch.fold_knee_rate_rad_s == pytest.approx(math.radians(120.0)) and sch.fold_window_of_stance == 0.4
    assert sch.early_landing_fraction == 0.7 and sch.forefoot_landing_fraction == 0.6
    for update in ({"fold_knee_rate_deg_per_s": 40.0}, {"early_landing_swing_pct": 98.0}):
        slack = tables[0].model_copy(update={"thresholds": th.model_copy(update=update)})
        begin, rows, commit, _ = transfer(slack, 2, 2)      # fits the wire, outside its limits
        [nack] = feed(fw, [begin, *rows, commit], 0.1)
        assert nack["result"] == AckResult.SAFETY_LIMIT and fw.staged_ is None, update


def test_a_lost_acknowledgement_is_answered_again(tables):
    fw = DeviceFirmware()
    begin, rows, commit, crc = transfer(tables[0], 7, 9)
    feed(fw, [begin, *rows, commit], 0.0)
    [again] = feed(fw, [commit], 0.01)
    assert again["result"] == AckResult.STAGED and again["crc32"] == crc
    [stranger] = feed(fw, [commit_frame(8, 9, crc)], 0.02)
    assert stranger["result"] == AckResult.UNKNOWN_TRANSFER


def test_a_truncated_frame_is_counted_and_harms_nothing(tables):
    fw = DeviceFirmware()
    begin, rows, commit, crc = transfer(tables[0], 1, 1)
    short = can.Message(arbitration_id=rows[2].arbitration_id, data=rows[2].data[:3], is_extended_id=False)
    [ack] = feed(fw, [begin, short, *rows, commit], 0.0)
    assert ack["result"] == AckResult.STAGED and ack["crc32"] == crc
    assert fw.rx_errors_ == 1 and Fault.MALFORMED_FRAME in fw.faults_


def test_a_table_whose_nominal_task_is_not_its_node_is_refused_and_one_runs_as_a_table(tables):
    """One node is a table: the leg runs it on the state machine alone (nothing to blend, no task telemetry), and a
    one-node transfer whose nominal task is elsewhere is no table the host can have built."""
    fw = DeviceFirmware()
    install(fw, tables[0], 1)
    assert fw.active_.blender is None and fw.active_.table is not None
    assert type(fw.controller_).__name__ == "StateMachineController"
    _, _, out = fw.tick(standing(0.01), 0.01)
    assert not [m for m in out if decode(m)[0] == "TELEMETRY_TASK"]
    wire = table_wire(tables[1])
    odd = dataclasses.replace(wire, nominal=(wire.nominal[0] + 100, wire.nominal[1]))
    crc = odd.crc32()
    [nack] = feed(fw, [envelope_begin_frame(2, 2, crc, (1, 1)), *odd.frames(2), commit_frame(2, 2, crc)], 0.1)
    assert nack["result"] == AckResult.MALFORMED and fw.staged_ is None


@pytest.mark.parametrize("shape", [(1, 2), (2, 1), (0, 1), (8, 9)])
def test_a_transfer_is_one_node_or_a_grid_the_leg_can_hold(shape):
    """A table is one node (1 × 1), a range of tasks at least 2 × 2 and at most 64 nodes: anything else is refused at
    its begin."""
    fw = DeviceFirmware()
    [nack] = feed(fw, [envelope_begin_frame(1, 1, 5, shape)], 0.0)
    assert nack["result"] == AckResult.MALFORMED


def test_heartbeat_loss_enters_safe_mode_on_the_first_tick_past_the_timeout(tables):
    cfg = FirmwareConfig(heartbeat_timeout_s=0.2)
    fw = DeviceFirmware(cfg)
    install(fw, tables[0], 1)
    heartbeat(fw, 1.0)
    t = 1.0
    while t < 1.2:
        fw.tick(standing(t), t)
        assert fw.mode_ == Mode.ACTIVE
        t = round(t + 0.001, 6)
    _, _, out = fw.tick(standing(1.201), 1.201)
    assert fw.mode_ == Mode.SAFE and fw.safe_mode_entered_s_ == pytest.approx(1.201)
    assert status(out)["mode"] == Mode.SAFE and Fault.HEARTBEAT_LOST in fw.faults_
    knee, ankle, _ = fw.tick(standing(1.202), 1.202)   # safe mode's: the loaded, flexing knee is resisted
    p = cfg.safe_mode
    assert knee == pytest.approx(-p.knee_flexion_b_Nm_s_per_rad * 0.5)            # held where the load found it
    assert ankle == pytest.approx(-p.ankle_k_Nm_per_rad * 0.05 + p.ankle_b_Nm_s_per_rad * 0.2)   # toward neutral


def test_fitting_a_new_leg_in_safe_mode_keeps_the_loaded_knee_held(tables):
    """A simulated leg fitted to a patient's leg while it stands in safe mode (the server does it between walks): the
    knee a light load holds (between the loaded and unloaded thresholds, the hysteresis band) stays held, the new
    drive's limits taken at once. A fresh safe mode forgot that the leg was loaded and gave that knee the swing's
    extension assist."""
    cfg = FirmwareConfig(heartbeat_timeout_s=0.2)
    fw = DeviceFirmware(cfg)
    install(fw, tables[0], 1)
    heartbeat(fw, 1.0)
    fw.tick(standing(1.3), 1.3)
    assert fw.mode_ == Mode.SAFE
    p = cfg.safe_mode
    light = (p.loaded_off_N + p.loaded_on_N) / 2.0
    def lightly(t: float) -> SensorSample:
        return SensorSample(time_s=t, knee_angle_rad=0.35, knee_velocity_rad_s=0.5, ankle_angle_rad=0.05,
                            ankle_velocity_rad_s=0.0, load_N=light, ankle_moment_Nm=-5.0)
    fw.tick(lightly(1.301), 1.301)             # still loaded: held at 0.3 rad, where the load found it
    held = -p.knee_hold_k_Nm_per_rad * 0.05 - p.knee_flexion_b_Nm_s_per_rad * 0.5
    knee, _, _ = fw.tick(lightly(1.302), 1.302)
    assert knee == pytest.approx(held)
    weaker = dataclasses.replace(cfg.actuator, knee_torque_Nm=40.0)
    fw.fit_leg(dataclasses.replace(cfg, shank_length_m=cfg.shank_length_m + 0.03, actuator=weaker))
    knee, _, _ = fw.tick(lightly(1.303), 1.303)
    assert fw.mode_ == Mode.SAFE and knee == pytest.approx(-40.0)      # held, within the new drive's limit


def test_a_table_given_to_a_leg_under_a_standing_person_holds_the_knee_where_it_stands(tables):
    """A first table (or one after safe mode) reaches a leg that is not walking: the machine starts standing, the
    knee held where it is. On stance flexion's walking row it met a knee standing at 3° with flexion torque (the
    row's equilibrium lies near 10°) until standing was noticed half a second later."""
    fw = DeviceFirmware()
    begin, rows, commit, _ = transfer(tables[0], 1, 1)
    feed(fw, [begin, *rows, commit], 0.0)
    knees = []
    for i in range(1, 200):
        t = 0.001 * i
        heartbeat(fw, t)
        knee, _, _ = fw.tick(SensorSample(t, 0.05, 0.0, 0.0, 0.0, 600.0, -2.0), t)
        knees.append(knee)
    assert fw.controller_.standing_ and max(abs(k) for k in knees) < 1e-6
    row = fw.active_.table.row("knee", "stance_flexion")
    assert row.k_Nm_per_rad * (0.05 - math.radians(row.theta_e_deg)) > 10.0   # what the walking row would have given


def test_safe_mode_left_while_walking_walks_on_and_left_while_standing_stands(tables):
    """Leaving safe mode, the machine stands only if the person is not walking: safe mode counts a foot loaded again as
    a heel strike, so a leg that walked on through safe mode starts on its rows (its first state, about to touch
    down), and one stood on for longer than ``idle_switch_s`` starts standing."""
    def safe_fw() -> tuple[DeviceFirmware, float]:
        fw = DeviceFirmware()
        install(fw, tables[0], 1)
        fw.receive(encode("DEVICE_COMMAND", {"command": int(Command.ENTER_SAFE_MODE)}), 0.01)
        return fw, 0.01

    def sample(t: float, load: float) -> SensorSample:
        return SensorSample(t, 0.1, 0.0, 0.0, 0.0, load, 0.0)

    walking, t = safe_fw()
    for i in range(3000):                        # 3 s of strides: 0.6 s loaded, 0.4 s in the air
        t = round(0.01 + 0.001 * (i + 1), 6)
        heartbeat(walking, t)
        walking.tick(sample(t, 700.0 if (i % 1000) < 600 else 0.0), t)
    assert walking.mode_ == Mode.SAFE
    walking.receive(encode("DEVICE_COMMAND", {"command": int(Command.LEAVE_SAFE_MODE)}), t)
    walking.tick(sample(t + 0.001, 700.0), t + 0.001)
    assert walking.mode_ == Mode.ACTIVE and not walking.controller_.standing_

    standing, t = safe_fw()
    for i in range(3000):                        # 3 s stood on
        t = round(0.01 + 0.001 * (i + 1), 6)
        heartbeat(standing, t)
        standing.tick(sample(t, 700.0), t)
    standing.receive(encode("DEVICE_COMMAND", {"command": int(Command.LEAVE_SAFE_MODE)}), t)
    standing.tick(sample(t + 0.001, 700.0), t + 0.001)
    assert standing.mode_ == Mode.ACTIVE and standing.controller_.standing_


def test_a_leg_fitted_while_the_person_stands_on_it_goes_on_standing(tables):
    """The server fits its simulated leg to the patient while they stand on it between walks: the machine that takes
    over stands as the one it replaces did (a fresh one started on stance flexion's walking row, which bends a
    standing knee toward its equilibrium until standing is noticed again, half a second later)."""
    fw = DeviceFirmware()
    install(fw, tables[0], 1)
    t = 0.0
    for _ in range(900):                      # loaded and still: the machine takes it for standing
        t = round(t + 0.001, 6)
        heartbeat(fw, t)
        fw.tick(SensorSample(t, 0.05, 0.0, 0.0, 0.0, 600.0, -2.0), t)
    assert fw.controller_.standing_
    held = fw.controller_.standing_knee_rad_
    fw.fit_leg(dataclasses.replace(fw.config, shank_length_m=fw.config.shank_length_m + 0.03))
    t = round(t + 0.001, 6)
    knee, _, _ = fw.tick(SensorSample(t, 0.05, 0.0, 0.0, 0.0, 600.0, -2.0), t)
    assert fw.controller_.standing_ and fw.controller_.standing_knee_rad_ == pytest.approx(held)
    assert knee == pytest.approx(0.0, abs=1e-9)   # held where it stands: no torque toward a walking row's equilibrium


def health(frames: list[can.Message]) -> dict:
    return next(decode(m)[1] for m in reversed(frames) if decode(m)[0] == "DEVICE_HEALTH")


def link_mode(fw: DeviceFirmware, mode: LinkMode, now: float) -> list[can.Message]:
    command = Command.LINK_AUTONOMOUS if mode == LinkMode.AUTONOMOUS else Command.LINK_SUPERVISED
    return fw.receive(encode("DEVICE_COMMAND", {"command": int(command)}), now)


def test_a_device_starts_supervised_and_reports_the_link_mode_it_is_given(tables):
    fw = DeviceFirmware()
    assert fw.link_mode_ == LinkMode.SUPERVISED
    assert health(link_mode(fw, LinkMode.AUTONOMOUS, 0.0))["link_mode"] == LinkMode.AUTONOMOUS
    assert health(link_mode(fw, LinkMode.SUPERVISED, 0.01))["link_mode"] == LinkMode.SUPERVISED


def test_an_autonomous_leg_runs_on_through_a_lost_link_and_clears_the_fault_when_it_returns(tables):
    cfg = FirmwareConfig(heartbeat_timeout_s=0.2)
    fw = DeviceFirmware(cfg)
    install(fw, tables[0], 1)
    heartbeat(fw, 0.5)
    link_mode(fw, LinkMode.AUTONOMOUS, 0.5)
    t, reported = 0.5, []
    while t < 60.0:                        # a minute with no host at all
        knee, _, out = fw.tick(standing(t), t)
        assert fw.mode_ == Mode.ACTIVE and knee != pytest.approx(-cfg.safe_mode.knee_flexion_b_Nm_s_per_rad * 0.5)
        reported += [health(out)] if any(decode(m)[0] == "DEVICE_HEALTH" for m in out) else []
        t = round(t + 0.01, 6)
    assert Fault.HEARTBEAT_LOST in fw.faults_ and fw.active_.version == 1
    assert reported[-1]["fault_flags"] & Fault.HEARTBEAT_LOST and reported[-1]["link_mode"] == LinkMode.AUTONOMOUS
    heartbeat(fw, 60.0)
    _, _, out = fw.tick(standing(60.001), 60.001)
    assert Fault.HEARTBEAT_LOST not in fw.faults_ and fw.mode_ == Mode.ACTIVE
    assert not health(out)["fault_flags"] & Fault.HEARTBEAT_LOST


def test_a_table_staged_before_the_link_was_lost_does_not_end_the_safe_mode_when_it_returns(tables):
    """A copy staged just before the cut (a retried transfer over a slow link) waits for the host's word like the
    table it replaces: the link coming back alone never takes a supervised leg out of safe mode."""
    fw = DeviceFirmware(FirmwareConfig(heartbeat_timeout_s=0.2))
    install(fw, tables[0], 1)
    heartbeat(fw, 0.1)
    begin, rows, commit, crc = transfer(tables[1], 2, 2)
    [ack] = feed(fw, [begin, *rows, commit], 0.15)
    assert ack["result"] == AckResult.STAGED
    fw.tick(standing(0.40), 0.40)          # lost before the next heel strike
    assert fw.mode_ == Mode.SAFE and fw.staged_ is None and fw.active_.crc32 == crc
    for t in (1.0, 1.1, 1.2):              # the host is back
        heartbeat(fw, t)
        fw.tick(standing(t + 0.001), t + 0.001)
    assert fw.mode_ == Mode.SAFE
    fw.receive(encode("DEVICE_COMMAND", {"command": int(Command.LEAVE_SAFE_MODE)}), 1.3)
    assert fw.mode_ == Mode.ACTIVE and fw.active_.crc32 == crc


def test_an_autonomous_leg_still_waits_for_the_host_to_switch_a_staged_table(tables):
    fw = DeviceFirmware(FirmwareConfig(heartbeat_timeout_s=0.2))
    first = install(fw, tables[0], 1)
    heartbeat(fw, 0.1)
    link_mode(fw, LinkMode.AUTONOMOUS, 0.1)
    begin, rows, commit, _ = transfer(tables[1], 2, 2)
    [ack] = feed(fw, [begin, *rows, commit], 0.15)
    assert ack["result"] == AckResult.STAGED
    fw.tick(None, 0.5)                     # the link is gone before the switch
    assert fw.mode_ == Mode.ACTIVE and fw.active_.crc32 == first and fw.staged_ is not None


def test_a_supervised_leg_goes_safe_on_a_lost_link_and_back_only_when_the_host_says_so(tables):
    fw = DeviceFirmware(FirmwareConfig(heartbeat_timeout_s=0.2))
    install(fw, tables[0], 1)
    heartbeat(fw, 0.5)
    link_mode(fw, LinkMode.AUTONOMOUS, 0.5)
    link_mode(fw, LinkMode.SUPERVISED, 0.6)    # the prosthetist's choice changed back
    fw.tick(standing(0.81), 0.81)
    assert fw.mode_ == Mode.SAFE and Fault.HEARTBEAT_LOST in fw.faults_
    heartbeat(fw, 2.0)
    fw.tick(standing(2.001), 2.001)
    assert fw.mode_ == Mode.SAFE               # the link alone does not end it
    fw.receive(encode("DEVICE_COMMAND", {"command": int(Command.LEAVE_SAFE_MODE)}), 2.002)
    assert fw.mode_ == Mode.ACTIVE and Fault.HEARTBEAT_LOST not in fw.faults_


def test_safe_mode_is_left_only_by_command_or_a_new_table(tables):
    fw = DeviceFirmware(FirmwareConfig(heartbeat_timeout_s=0.2))
    install(fw, tables[0], 1)
    fw.tick(None, 0.5)
    assert fw.mode_ == Mode.SAFE
    for t in (0.6, 0.7, 0.8):   # the host comes back: that alone does not leave safe mode
        heartbeat(fw, t)
        fw.tick(None, t + 0.001)
    assert fw.mode_ == Mode.SAFE
    fw.receive(encode("DEVICE_COMMAND", {"command": int(Command.LEAVE_SAFE_MODE)}), 0.81)
    assert fw.mode_ == Mode.ACTIVE
    fw.receive(encode("DEVICE_COMMAND", {"command": int(Command.ENTER_SAFE_MODE)}), 0.82)
    assert fw.mode_ == Mode.SAFE
    heartbeat(fw, 0.83)
    new = install(fw, tables[1], 2, now=0.83)
    assert fw.mode_ == Mode.ACTIVE and fw.active_.crc32 == new


def test_a_table_staged_before_a_commanded_safe_mode_does_not_end_it(tables):
    fw = DeviceFirmware(FirmwareConfig(heartbeat_timeout_s=0.2))
    heartbeat(fw, 0.0)
    install(fw, tables[0], 1)
    begin, rows, commit, crc = transfer(tables[1], 2, 2)
    [ack] = feed(fw, [begin, *rows, commit], 0.01)                   # verified and staged …
    assert ack["result"] == AckResult.STAGED and fw.staged_ is not None
    fw.receive(encode("DEVICE_COMMAND", {"command": int(Command.ENTER_SAFE_MODE)}), 0.011)   # … then safe mode
    fw.tick(standing(0.012), 0.012)
    assert fw.mode_ == Mode.SAFE and fw.active_.crc32 == crc and fw.staged_ is None   # held, not run
    fw.receive(encode("DEVICE_COMMAND", {"command": int(Command.LEAVE_SAFE_MODE)}), 0.02)
    assert fw.mode_ == Mode.ACTIVE and fw.active_.crc32 == crc


def test_leaving_safe_mode_needs_a_live_host():
    fw = DeviceFirmware(FirmwareConfig(heartbeat_timeout_s=0.2))
    fw.tick(None, 0.5)
    fw.receive(encode("DEVICE_COMMAND", {"command": int(Command.LEAVE_SAFE_MODE)}), 0.6)
    assert fw.mode_ == Mode.SAFE   # no table and no heartbeat


def test_a_staged_table_waits_for_the_next_heel_strike_while_walking(tables):
    fw = DeviceFirmware()
    old = install(fw, tables[0], 1)
    th = fw.active_.table.thresholds
    t = 0.0

    def step(load: float, moment: float = 0.0, knee: float = 0.3, knee_velocity: float = 0.0) -> None:
        nonlocal t
        t = round(t + 0.001, 6)
        heartbeat(fw, t)
        fw.tick(SensorSample(t, knee, knee_velocity, 0.0, 0.0, load, moment), t)

    loaded = th.we_to_sf_load_N + 50
    for _ in range(100):      # a table given to a leg under a standing person: it stands
        step(loaded)
    assert fw.controller_.standing_
    for _ in range(50):       # the first step: the leg lifted with the knee bending (swing), then landed on load
        step(0.0, knee_velocity=1.0)
    for _ in range(100):
        step(loaded)
    assert fw.controller_.state_ == GaitState.STANCE_FLEXION and not fw.controller_.standing_
    begin, rows, commit, new = transfer(tables[1], 2, 2)
    [ack] = feed(fw, [begin, *rows, commit], t)
    assert ack["result"] == AckResult.STAGED
    ctrl = fw.controller_
    stride = [  # one stride by events, well inside the idle time: SE on moment, WF on unloading, WE past the knee threshold
        # (extending freely at 2 rad/s: slower, the stumble support would take it for a foot held by the floor)
        *[(loaded, th.sf_to_se_ankle_moment_Nm - 1, 0.3, 0.0)] * 100,
        *[(0.0, 0.0, 0.3, 1.0)] * 100,
        *[(0.0, 0.0, math.radians(th.wf_to_we_knee_angle_deg) + 0.1, -2.0)] * 100,
    ]
    for load, moment, knee, velocity in stride:
        step(load, moment, knee, velocity)
        assert fw.active_.crc32 == old and fw.staged_.crc32 == new
    assert ctrl.state_ == GaitState.SWING_EXTENSION and ctrl.guard_transitions_ == 0
    step(0.0)
    assert fw.active_.crc32 == old
    for _ in range(round(ctrl.schedule.heel_strike_hold_s / 0.001)):   # the load must hold before it counts as a heel strike
        step(loaded)
        assert ctrl.state_ == GaitState.SWING_EXTENSION and fw.active_.crc32 == old
    step(loaded)                                      # heel strike recognised: the switch happens on this tick
    assert ctrl.state_ == GaitState.STANCE_FLEXION and fw.active_.crc32 == new and fw.staged_ is None
    assert fw.controller_ is ctrl and ctrl.schedule is fw.active_.schedule


def test_telemetry_carries_the_sample_in_display_units(tables):
    fw = DeviceFirmware()
    install(fw, tables[0], 1)
    heartbeat(fw, 0.02)
    x = SensorSample(0.02, math.radians(12.34), math.radians(100.0), math.radians(-5.0), 0.0, 650.0, -40.0)
    _, _, out = fw.tick(x, 0.02)   # the next 10 ms telemetry slot
    parts = {decode(m)[0]: physical(*decode(m)) for m in out if decode(m)[0].startswith("TELEMETRY")}
    assert parts["TELEMETRY_KNEE"]["angle"] == pytest.approx(12.34, abs=0.005)
    assert parts["TELEMETRY_KNEE"]["velocity"] == pytest.approx(100.0, abs=0.05)
    assert parts["TELEMETRY_ANKLE"]["angle"] == pytest.approx(-5.0, abs=0.005)
    assert parts["TELEMETRY_GAIT"]["load"] == pytest.approx(650.0) and parts["TELEMETRY_GAIT"]["ankle_moment"] == -40.0
    assert len({decode(m)[1]["seq"] for m in out if decode(m)[0].startswith("TELEMETRY")}) == 1


def test_telemetry_says_when_the_leg_stands_and_the_host_reads_it(tables):
    """TELEMETRY_GAIT's behaviour: standing under a table given to a leg that is not walking, walking on the rows
    from the first step, standing again once the loaded leg has been still for the machine's standing time (the
    monitor shows it; the FSM state alone stays the stance state)."""
    from device_bridge.host import LEG_BEHAVIOURS

    fw = DeviceFirmware()
    install(fw, tables[0], 1)
    behaviours = []
    for i in range(1, 1500):      # 0.2 s standing, a step (lifted 50 ms, the knee bending), then landed and still
        t = 0.001 * i
        if i % 100 == 0:
            heartbeat(fw, t)
        lifted = 200 <= i < 250
        x = SensorSample(t, 0.05, 1.0 if lifted else 0.0, 0.0, 0.0, 0.0 if lifted else 600.0, 0.0 if lifted else -2.0)
        _, _, out = fw.tick(x, t)
        behaviours += [LEG_BEHAVIOURS[int(physical(*decode(m))["behaviour"])] for m in out
                       if decode(m)[0] == "TELEMETRY_GAIT"]
    seen = [b for k, b in enumerate(behaviours) if k == 0 or b != behaviours[k - 1]]
    assert seen == ["standing", "walking", "standing"]


def test_a_host_lost_during_commanded_safe_mode_is_flagged_and_no_table_switches_in(tables):
    fw = DeviceFirmware(FirmwareConfig(heartbeat_timeout_s=0.2))
    old = install(fw, tables[0], 1)
    heartbeat(fw, 0.1)
    fw.receive(encode("DEVICE_COMMAND", {"command": int(Command.ENTER_SAFE_MODE)}), 0.1)
    _, _, out = fw.tick(None, 0.35)                 # the host has gone quiet
    assert Fault.HEARTBEAT_LOST in fw.faults_ and fw.mode_ == Mode.SAFE
    assert status(out)["mode"] == Mode.SAFE
    begin, rows, commit, new = transfer(tables[1], 2, 2)
    [ack] = feed(fw, [begin, *rows, commit], 0.36)  # its heartbeats are lost, its table frames are not
    assert ack["result"] == AckResult.STAGED
    fw.tick(None, 0.37)
    assert fw.mode_ == Mode.SAFE and fw.active_.crc32 == old   # no new table runs without a live host
    heartbeat(fw, 0.38)
    fw.tick(None, 0.39)
    assert fw.mode_ == Mode.ACTIVE and fw.active_.crc32 == new


def test_a_hardware_fault_puts_the_leg_in_safe_mode_and_says_so_with_the_temperature(tables):
    """An actuator over its thermal limit (device_bridge.osl.leg hands it over): safe mode at once, the over-temperature
    flag and the measured temperature in the health frame sent with the status, the reason kept on the device."""
    fw = DeviceFirmware()
    install(fw, tables[0], 1)
    heartbeat(fw, 0.01)
    fw.temperature_degC_ = 81.4
    out = fw.hardware_fault("knee: ThermalLimitException: case 81 °C over its limit", 0.01, thermal=True)
    health = next(decode(m)[1] for m in out if decode(m)[0] == "DEVICE_HEALTH")
    assert status(out)["mode"] == Mode.SAFE and fw.mode_ == Mode.SAFE
    assert health["fault_flags"] & Fault.OVER_TEMPERATURE and physical("DEVICE_HEALTH", health)["temperature"] == 81.0
    assert "ThermalLimitException" in fw.hardware_fault_
    knee, _, _ = fw.tick(standing(0.02), 0.02)          # safe mode holds the loaded knee: passive, not the table
    assert fw.mode_ == Mode.SAFE and math.isfinite(knee)
    fw.temperature_degC_ = None
    _, _, frames = fw.tick(standing(0.2), 0.2)
    later = [decode(m)[1] for m in frames if decode(m)[0] == "DEVICE_HEALTH"]
    assert later and all(h["temperature"] == 255 for h in later)            # not measured


def test_a_real_legs_word_on_itself_goes_with_every_status_and_the_simulated_leg_sends_none(tables):
    """DEVICE_LEG (device_bridge/osl/leg.py sets it): calibration per sensor, torque mode, thermal derating."""
    from device_bridge.host import LegState

    fw = DeviceFirmware()
    install(fw, tables[0], 1)
    _, _, out = fw.tick(None, 0.2)
    assert not any(decode(m)[0] == "DEVICE_LEG" for m in out)
    fw.leg_state_ = {"hardware": 1, "calibrated": 0b101, "torque_mode": 2, "derating": 87}
    _, _, out = fw.tick(None, 0.4)
    said = [LegState.from_raw(decode(m)[1]) for m in out if decode(m)[0] == "DEVICE_LEG"]
    assert said and all(s == LegState(True, False, True, "actuator_impedance", 87) for s in said)


def test_the_estimators_leg_lengths_default_to_the_simulated_benchs():
    """The firmware cannot import the bench (MuJoCo is not on a leg), so its defaults are numbers: they must be the
    bench's leg, or the server's simulated leg would estimate its task with another leg's lengths and foot."""
    from device_bridge.sim.leg_model import LegGeometry

    bench, cfg = LegGeometry(), FirmwareConfig()
    assert cfg.thigh_length_m == pytest.approx(bench.thigh_m)
    assert cfg.shank_length_m == pytest.approx(bench.shank_m)
    assert cfg.forefoot_m == pytest.approx(bench.toe_forward_m)
