"""Guided calibration: each step says what it measured, and refuses what cannot be right."""

from __future__ import annotations

import math

import pytest

from device_bridge.osl.calibration import (
    CalibrationRefusedError,
    joint_direction,
    joint_zero,
    loadcell_sign,
    loadcell_zero,
)

DEG = math.pi / 180.0


def test_a_reversed_offset_knee_sensor_is_found_and_corrected():
    """Mounted reversed, reading 0.7 rad at full extension: the zero and the prompted flexion give sign −1, and the
    corrected reading of 30° of flexion is 30°."""
    zero = joint_zero("knee", [0.7 + 0.0005 * i for i in range(5)])
    assert zero.calibration.zero_rad == pytest.approx(0.701) and "at its zero" in zero.measured
    flexion = [0.7 - a * DEG for a in range(0, 31, 5)]           # the sensor falls as the knee bends
    actuator = [a * DEG for a in range(0, 31, 5)]                 # the actuator's output reads it the right way
    step = joint_direction("knee", zero.calibration, flexion, actuator)
    cal = step.calibration
    assert cal.sign == -1 and cal.torque_sign == 1 and cal.calibrated and "reversed" in step.measured
    assert cal.sign * (0.7 - 30 * DEG - cal.zero_rad) == pytest.approx(30 * DEG, abs=0.002)


@pytest.mark.parametrize(("readings", "why"), [
    ([0.1, 0.1, 0.15], "spread"),
    ([0.1, math.nan], "missing or not a number"),
    ([], "missing or not a number"),
])
def test_a_zero_taken_while_moving_or_unread_is_refused(readings, why):
    with pytest.raises(CalibrationRefusedError, match=why):
        joint_zero("ankle", readings)


def test_a_direction_without_movement_or_beyond_the_range_is_refused():
    zero = joint_zero("knee", [0.0, 0.0]).calibration
    with pytest.raises(CalibrationRefusedError, match="less than 5°"):
        joint_direction("knee", zero, [0.0, 2 * DEG], [0.0, 2 * DEG])
    off = zero.model_copy(update={"zero_rad": -2.6})              # a zero 150° away from the stop
    with pytest.raises(CalibrationRefusedError, match="beyond its range"):
        joint_direction("knee", off, [0.0, 20 * DEG], [0.0, 20 * DEG])


def test_an_offset_load_cell_is_zeroed_and_a_reversed_one_signed_from_the_patients_weight():
    zero = loadcell_zero([-140.0, -142.0, -141.0], [3.0, 3.2, 3.1])
    assert zero.calibration.fz_zero_N == pytest.approx(-141.0) and "unloaded" in zero.measured
    standing = [-141.0 - 0.5 * 75 * 9.81] * 3                    # compression reads negative on this cell
    signed = loadcell_sign(zero.calibration, standing, 75.0)
    assert signed.calibration.fz_sign == -1 and signed.calibration.calibrated and "reversed" in signed.measured


@pytest.mark.parametrize(("fz", "why"), [([900.0, 905.0], "beyond 300 N"), ([0.0, 80.0], "spread")])
def test_a_loaded_or_touched_foot_is_no_zero(fz, why):
    with pytest.raises(CalibrationRefusedError, match=why):
        loadcell_zero(fz, [0.0] * len(fz))


def test_a_leg_not_stood_on_gives_no_sign():
    zero = loadcell_zero([5.0, 5.0], [0.0, 0.0]).calibration
    with pytest.raises(CalibrationRefusedError, match="under a fifth"):
        loadcell_sign(zero, [60.0, 62.0], 75.0)
