"""Guided calibration from the clinic over the device link: the host asks, the leg in its stand measures, says what it
measured or why it refused, and keeps the result only when all four steps were accepted and it could write it. The leg
is a stand with mis-mounted sensors (tests/helpers/stand.py); the node and the host link are stepped on one clock."""

from __future__ import annotations

import math

import pytest

from device_bridge.host_calibration import CalibrationClient
from device_bridge.protocol import CalibrationAction as A
from device_bridge.protocol import CalibrationStep as S
from device_bridge.protocol import Command, Fault, LinkMode, Mode
from device_bridge.rig import Rig
from tests.helpers.stand import Stand

MASS_KG = 75.0


def _rig(stand: Stand, port: bool = True) -> Rig:
    return Rig(leg=stand, calibration=stand.port() if port else None)


def _ask(rig: Rig, action: A, step: S | None = None) -> object:
    return rig.link.calibration.command(action, step, MASS_KG)


def _calibrate(rig: Rig, stand: Stand) -> list:
    """The four steps with the poses the prompts ask for; each answer."""
    answers = [_ask(rig, A.START)]
    stand.pose(0.0, 0.0)
    answers.append(_ask(rig, A.MEASURE, S.JOINT_ZERO))
    stand.pose(30.0, 10.0)
    answers.append(_ask(rig, A.MEASURE, S.DIRECTION))
    stand.pose(0.0, 0.0, load_N=0.0)
    answers.append(_ask(rig, A.MEASURE, S.LOADCELL_ZERO))
    stand.pose(0.0, 0.0, load_N=0.5 * MASS_KG * 9.81)
    answers.append(_ask(rig, A.MEASURE, S.LOADCELL_SIGN))
    return answers


def test_the_clinic_guides_a_calibration_that_finds_the_mounting_and_is_kept_on_the_leg():
    """Started from no table, the leg gives no torque while it calibrates; each step answers what it measured in
    words and numbers (the knee's reading at its zero, the reversed sensor, the cell's offset and reversed sign);
    kept, the leg reads the pose it is held in within 0.5° and 1 N, says so in DEVICE_LEG, and is out of calibration."""
    stand = Stand()
    with _rig(stand) as rig:
        stand.pose(20.0, 0.0, load_N=300.0)
        rig.advance(0.2)       # not calibrated: the leg gives no torque (safe mode's would be read from wrong angles)
        assert stand.torques == (0.0, 0.0) and rig.link.status.mode == Mode.NO_TABLE
        started, zero, direction, lc_zero, lc_sign = _calibrate(rig, stand)
        assert started.outcome == "started"
        rig.advance(0.15)
        assert rig.link.status.mode == Mode.CALIBRATING and stand.torques == (0.0, 0.0)
        assert [a.outcome for a in (zero, direction, lc_zero, lc_sign)] == ["accepted"] * 4
        knee = {m.subject: m for m in zero.measured}["knee"]
        assert knee.values["reading_deg"] == pytest.approx(math.degrees(0.52), abs=0.01)
        assert "reads +29.79° at its zero" in knee.words
        knee_dir = {m.subject: m for m in direction.measured}["knee"]
        assert knee_dir.values["sign"] == -1 and "reversed" in knee_dir.words
        assert lc_zero.measured[0].values["force_N"] == pytest.approx(-140.0)
        assert "reversed: compression reads negative" in lc_sign.measured[0].words
        assert stand.kept == []                          # nothing is kept before the prosthetist says so

        kept = _ask(rig, A.KEEP)
        assert kept.outcome == "kept" and len(stand.kept) == 1
        rig.advance(0.15)
        assert rig.link.status.mode == Mode.NO_TABLE
        leg = rig.link.status.leg
        assert leg.knee_calibrated and leg.ankle_calibrated and leg.loadcell_calibrated
        stand.pose(42.0, -7.0, load_N=600.0)
        x = stand.sample()
        rig.advance(0.05)
        assert stand.torques != (0.0, 0.0)           # calibrated, the leg holds the loaded knee again (no table)
        assert math.degrees(x.knee_angle_rad) == pytest.approx(42.0, abs=0.5)
        assert math.degrees(x.ankle_angle_rad) == pytest.approx(-7.0, abs=0.5)
        assert x.load_N == pytest.approx(600.0, abs=1.0)


def test_a_step_that_cannot_be_right_is_refused_with_its_reason_and_can_be_measured_again():
    stand = Stand()
    with _rig(stand) as rig:
        _ask(rig, A.START)
        early = _ask(rig, A.MEASURE, S.DIRECTION)
        assert early.outcome == "refused" and early.refused_reason == "out_of_order"
        stand.pose(0.0, 0.0)
        stand.jitter_rad = math.radians(1.5)            # the hand does not hold the knee still
        shaky = _ask(rig, A.MEASURE, S.JOINT_ZERO)
        assert shaky.outcome == "refused" and shaky.refused_reason == "not_still" and shaky.refused_subject == "knee"
        assert "spread 3.0°" in shaky.refused_words and "hold the joint still" in shaky.refused_words
        stand.jitter_rad = 0.0
        assert _ask(rig, A.MEASURE, S.JOINT_ZERO).outcome == "accepted"
        unmoved = _ask(rig, A.MEASURE, S.DIRECTION)      # the prompt not followed: nothing to read a direction from
        assert unmoved.refused_reason == "too_little_move" and "less than 5°" in unmoved.refused_words
        assert _ask(rig, A.KEEP).refused_reason == "incomplete" and stand.kept == []
        stand.pose(0.0, 0.0, load_N=400.0)             # "unloaded" with the patient still on the foot
        assert _ask(rig, A.MEASURE, S.LOADCELL_ZERO).refused_reason == "load_offset"


def test_a_calibration_that_cannot_be_written_changes_nothing():
    stand = Stand(disk_full=True)
    with _rig(stand) as rig:
        _calibrate(rig, stand)
        answer = _ask(rig, A.KEEP)
        assert answer.refused_reason == "not_saved" and "nothing changed" in answer.refused_words
        assert stand.kept == [] and not stand.calibration.knee.calibrated
        rig.advance(0.15)
        assert rig.link.status.mode == Mode.CALIBRATING      # still calibrating: keep again, or cancel
        assert _ask(rig, A.CANCEL).outcome == "cancelled"
        rig.advance(0.15)
        assert rig.link.status.mode == Mode.NO_TABLE


def test_a_leg_running_a_table_or_without_sensors_is_not_calibrated(tables):
    stand = Stand()
    with _rig(stand) as rig:
        rig.link.push(tables[0], 1)
        rig.run_until(lambda: rig.link.status is not None and rig.link.status.mode == Mode.ACTIVE)
        busy = _ask(rig, A.START)
        assert busy.refused_reason == "leg_busy" and "safe mode" in busy.refused_words
        rig.link.command(Command.ENTER_SAFE_MODE)
        rig.run_until(lambda: rig.link.status.mode == Mode.SAFE)
        assert _ask(rig, A.START).outcome == "started"
        assert _ask(rig, A.CANCEL).outcome == "cancelled"
        rig.advance(0.15)
        assert rig.link.status.mode == Mode.SAFE             # a leg with a table ends in safe mode
    with _rig(Stand(), port=False) as rig:
        assert _ask(rig, A.START).refused_reason == "no_sensors"


@pytest.mark.parametrize("link_mode", [LinkMode.SUPERVISED, LinkMode.AUTONOMOUS])
def test_a_lost_host_ends_the_calibration_in_safe_mode(link_mode):
    """Nobody guides the calibration without the host: safe mode at the heartbeat timeout whatever the lost-link
    choice, the calibration dropped (a measure after the link is back is answered not started)."""
    stand = Stand()
    with _rig(stand) as rig:
        rig.link.command(Command.LINK_AUTONOMOUS if link_mode == LinkMode.AUTONOMOUS else Command.LINK_SUPERVISED)
        _ask(rig, A.START)
        rig.link.pause_heartbeat()
        rig.advance(0.4)
        fw = rig.node.firmware
        assert fw.mode_ == Mode.SAFE and Fault.HEARTBEAT_LOST in fw.faults_ and not fw.calibration_.active
        rig.link.pause_heartbeat(False)
        stand.pose(0.0, 0.0)
        assert _ask(rig, A.MEASURE, S.JOINT_ZERO).refused_reason == "not_started"


def test_a_push_during_calibration_waits_for_its_end(tables):
    stand = Stand()
    with _rig(stand) as rig:
        _ask(rig, A.START)
        rig.link.push(tables[0], 7)
        rig.advance(0.5)
        assert rig.link.status.mode == Mode.CALIBRATING and rig.link.status.pending_version == 7
        _ask(rig, A.CANCEL)
        rig.run_until(lambda: rig.link.status.mode == Mode.ACTIVE and rig.link.status.active_version == 7)


def test_an_answer_that_never_comes_times_out_with_its_reason():
    from device_bridge.clock import SteppedClock

    clock = SteppedClock(0.001)
    client = CalibrationClient(lambda msg: None, clock)
    with pytest.raises(TimeoutError, match="predates calibration from the clinic"):
        client.command(A.START, timeout_s=0.05)
    with pytest.raises(ValueError, match="body mass"):
        client.command(A.MEASURE, S.LOADCELL_SIGN, body_mass_kg=math.nan)
