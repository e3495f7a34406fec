"""Guided calibration of an Open Source Leg: joint zeros and directions, the load cell's zero and sign.

Each step takes readings gathered while the prosthetist does what the step asks, says what it measured, and refuses a
result that cannot be right (:class:`CalibrationRefusedError`, with the reason and what to do), rather than storing it:

1. **Joint zero** (:func:`joint_zero`): the knee held at full extension, the ankle at neutral; the zero is the mean
   reading. Refused when the readings spread more than 1° (the leg moved) or a reading is not a number.
2. **Direction** (:func:`joint_direction`): from there, the joint moved by hand into flexion (dorsiflexion) by
   10–40°; the sign is the sign of the change of the joint's sensor, the torque sign that of the actuator's output (a
   linkage may reverse one against the other). Refused when it moved less than 5° (nothing to read a direction from)
   or further than the joint's range allows from its zero (an offset beyond the range: the zero step was not done at
   the stop, or the sensor is not on this joint).
3. **Load cell zero** (:func:`loadcell_zero`): the foot off the floor, unloaded. Refused when the axial force
   spreads more than 20 N (someone is touching it) or its offset exceeds 300 N (the foot is loaded, or the cell's
   zero is beyond what an amplifier's drift gives).
4. **Load cell sign** (:func:`loadcell_sign`): the patient standing on the leg with about half their weight. Refused
   when the change from the zero is under a fifth of the body weight (the leg is not loaded) or over twice it.

The result is a :class:`~device_bridge.osl.config.Calibration` kept in the leg's configuration file.
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Sequence
from dataclasses import dataclass

from controller_core.units import body_weight_N
from device_bridge.osl.config import JointCalibration, LoadcellCalibration

STILL_SPREAD_DEG = 1.0
MIN_MOVE_DEG = 5.0
JOINT_RANGE_DEG = {"knee": (0.0, 120.0), "ankle": (-30.0, 30.0)}   # the device's joint ranges (SafetyLimits)
LOAD_STILL_SPREAD_N = 20.0
MAX_LOAD_OFFSET_N = 300.0


class CalibrationRefusedError(ValueError):
    """A calibration step whose result cannot be right; the message says what was measured and what to do."""


@dataclass(frozen=True)
class StepResult:
    """What a step measured (in words, with units) and the calibration it gives."""

    measured: str
    calibration: JointCalibration | LoadcellCalibration


def _finite(values: Sequence[float], what: str) -> list[float]:
    out = [float(v) for v in values]
    if not out:
        raise CalibrationRefusedError(f"{what}: no readings")
    if not all(math.isfinite(v) for v in out):
        raise CalibrationRefusedError(f"{what}: a reading is not a number; check the sensor's wiring")
    return out


def joint_zero(joint: str, readings_rad: Sequence[float], previous: JointCalibration | None = None) -> StepResult:
    """Step 1 for ``joint`` from its sensor's readings (rad) at full extension / neutral."""
    r = _finite(readings_rad, f"{joint} zero")
    spread = math.degrees(max(r) - min(r))
    if spread > STILL_SPREAD_DEG:
        raise CalibrationRefusedError(f"{joint} zero: the readings spread {spread:.1f}° (more than {STILL_SPREAD_DEG:g}°): "
                                 "hold the joint still at its stop and repeat")
    zero = statistics.fmean(r)
    base = previous or JointCalibration()
    return StepResult(f"{joint} reads {math.degrees(zero):+.2f}° at its zero (spread {spread:.2f}°)",
                      base.model_copy(update={"zero_rad": zero, "calibrated": False}))


def joint_direction(joint: str, zeroed: JointCalibration, sensor_rad: Sequence[float],
                    actuator_rad: Sequence[float]) -> StepResult:
    """Step 2: ``sensor_rad`` and ``actuator_rad`` recorded from the zero pose through the prompted flexion (rad)."""
    s = _finite(sensor_rad, f"{joint} direction")
    a = _finite(actuator_rad, f"{joint} direction (actuator)")
    moved = math.degrees(s[-1] - s[0])
    if abs(moved) < MIN_MOVE_DEG:
        raise CalibrationRefusedError(f"{joint} direction: the joint moved {abs(moved):.1f}°, less than {MIN_MOVE_DEG:g}°: "
                                 f"move it by hand into {'flexion' if joint == 'knee' else 'dorsiflexion'} by 10–40°")
    sign = 1 if moved > 0 else -1
    torque_sign = 1 if a[-1] - a[0] > 0 else -1
    lo, hi = JOINT_RANGE_DEG[joint]
    reach = [sign * math.degrees(v - zeroed.zero_rad) for v in s]
    if min(reach) < lo - 5.0 or max(reach) > hi + 5.0:
        raise CalibrationRefusedError(f"{joint} direction: from the zero the joint read {min(reach):+.1f}° … "
                                 f"{max(reach):+.1f}°, beyond its range {lo:g}–{hi:g}°: the zero was not taken at the "
                                 "stop, or the sensor is not on this joint; repeat the zero")
    words = "reversed: the sensor reads flexion as negative" if sign < 0 else "as mounted"
    return StepResult(f"{joint} moved {abs(moved):.1f}°; sensor {words}; actuator torque sign {torque_sign:+d}",
                      zeroed.model_copy(update={"sign": sign, "torque_sign": torque_sign, "calibrated": True}))


def loadcell_zero(fz_N: Sequence[float], my_Nm: Sequence[float]) -> StepResult:
    """Step 3 from the unloaded foot's axial force (N) and sagittal moment (N·m) readings."""
    fz = _finite(fz_N, "load cell zero")
    my = _finite(my_Nm, "load cell zero (moment)")
    spread = max(fz) - min(fz)
    if spread > LOAD_STILL_SPREAD_N:
        raise CalibrationRefusedError(f"load cell zero: the force spread {spread:.0f} N (more than {LOAD_STILL_SPREAD_N:g} "
                                 "N): lift the foot clear and do not touch it")
    zero = statistics.fmean(fz)
    if abs(zero) > MAX_LOAD_OFFSET_N:
        raise CalibrationRefusedError(f"load cell zero: it reads {zero:+.0f} N unloaded, beyond {MAX_LOAD_OFFSET_N:g} N: "
                                 "the foot is loaded, or the cell or its amplifier needs service")
    return StepResult(f"unloaded: {zero:+.1f} N axial, {statistics.fmean(my):+.2f} N·m sagittal (spread {spread:.1f} N)",
                      LoadcellCalibration(fz_zero_N=zero, my_zero_Nm=statistics.fmean(my)))


def loadcell_sign(zeroed: LoadcellCalibration, fz_N: Sequence[float], body_mass_kg: float) -> StepResult:
    """Step 4 from the axial force (N) with the patient of ``body_mass_kg`` standing on the leg."""
    fz = _finite(fz_N, "load cell sign")
    if not (math.isfinite(body_mass_kg) and 20.0 <= body_mass_kg <= 200.0):
        raise CalibrationRefusedError(f"load cell sign: body mass must be 20–200 kg, got {body_mass_kg!r}")
    weight = body_weight_N(body_mass_kg)
    change = statistics.fmean(fz) - zeroed.fz_zero_N
    if abs(change) < 0.2 * weight:
        raise CalibrationRefusedError(f"load cell sign: the force changed {abs(change):.0f} N, under a fifth of the body "
                                 f"weight ({0.2 * weight:.0f} N): stand on the leg with about half your weight")
    if abs(change) > 2.0 * weight:
        raise CalibrationRefusedError(f"load cell sign: the force changed {abs(change):.0f} N, over twice the body weight: "
                                 "check the body mass and the cell's scale")
    sign = 1 if change > 0 else -1
    words = "compression reads positive" if sign > 0 else "reversed: compression reads negative"
    return StepResult(f"standing: {abs(change):.0f} N ({abs(change) / weight:.0%} of body weight); {words}",
                      zeroed.model_copy(update={"fz_sign": sign, "my_sign": sign, "calibrated": True}))
