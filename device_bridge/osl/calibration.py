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

What a step measured and why it refused are numbers with their unit in the name plus a code (the wire's
:class:`~device_bridge.protocol.CalibrationRefusal`), put into words by :func:`measured_words` and
:func:`refusal_words`: the leg's own prompts and the clinic's device page say the same thing from the same numbers.
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Sequence
from dataclasses import dataclass

from controller_core.units import body_weight_N
from device_bridge.osl.config import JointCalibration, LoadcellCalibration
from device_bridge.protocol import CalibrationRefusal, CalibrationStep

STILL_SPREAD_DEG = 1.0
MIN_MOVE_DEG = 5.0
JOINT_RANGE_DEG = {"knee": (0.0, 120.0), "ankle": (-30.0, 30.0)}   # the device's joint ranges (SafetyLimits)
LOAD_STILL_SPREAD_N = 20.0
MAX_LOAD_OFFSET_N = 300.0
MIN_LOAD_SHARE, MAX_LOAD_SHARE = 0.2, 2.0      # standing's load change, as a share of the body weight
BODY_MASS_KG = (20.0, 200.0)

# what each step asks the prosthetist to do before it measures (the leg's prompts and the clinic's page)
PROMPTS = {
    CalibrationStep.JOINT_ZERO: "Hold the knee straight (at its extension stop) and the ankle at neutral, and keep "
                                "them still.",
    CalibrationStep.DIRECTION: "Bend the knee by hand to about 30° and lift the toes about 10°, and hold them there.",
    CalibrationStep.LOADCELL_ZERO: "Lift the foot clear of the floor; nobody touches the foot or the pylon.",
    CalibrationStep.LOADCELL_SIGN: "Stand on the leg with about half your weight, still (the knee straight at its "
                                   "stop: the leg gives no torque while it calibrates; hold the bars).",
}

Values = dict[str, float]


class CalibrationRefusedError(ValueError):
    """A calibration step whose result cannot be right: ``reason`` (the wire's code), ``subject`` (``knee``,
    ``ankle``, ``loadcell``) and what was measured (``values``); its message is :func:`refusal_words`."""

    def __init__(self, reason: CalibrationRefusal, subject: str, values: Values | None = None) -> None:
        self.reason, self.subject, self.values = reason, subject, dict(values or {})
        super().__init__(refusal_words(reason, subject, self.values))


@dataclass(frozen=True)
class StepResult:
    """What a step measured (``values``, units in the names) about ``subject``, and the calibration it gives."""

    subject: str
    values: Values
    calibration: JointCalibration | LoadcellCalibration

    @property
    def measured(self) -> str:
        return measured_words(self.subject, self.values)


def measured_words(subject: str, v: Values) -> str:
    """What a step measured, in words, from its values (the four steps' quantities tell them apart)."""
    if "torque_sign" in v:
        words = "reversed: the sensor reads flexion as negative" if v["sign"] < 0 else "as mounted"
        return f"{subject} moved {abs(v['moved_deg']):.1f}°; sensor {words}; actuator torque sign {v['torque_sign']:+.0f}"
    if "reading_deg" in v:
        return f"{subject} reads {v['reading_deg']:+.2f}° at its zero (spread {v['spread_deg']:.2f}°)"
    if "change_N" in v:
        words = "compression reads positive" if v["sign"] > 0 else "reversed: compression reads negative"
        return (f"standing: {abs(v['change_N']):.0f} N ({abs(v['change_N']) / v['body_weight_N']:.0%} of body "
                f"weight); {words}")
    if "force_N" in v:
        return (f"unloaded: {v['force_N']:+.1f} N axial, {v['moment_Nm']:+.2f} N·m sagittal "
                f"(spread {v['spread_N']:.1f} N)")
    return f"{subject}: " + ", ".join(f"{k} {x:g}" for k, x in v.items())


def refusal_words(reason: CalibrationRefusal, subject: str, v: Values) -> str:
    """Why a step (or the calibration) was refused, what was measured, and what to do."""
    what = {"knee": "knee", "ankle": "ankle", "loadcell": "load cell", "leg": "calibration"}.get(subject, subject)
    r = CalibrationRefusal
    if reason == r.NOT_A_NUMBER:
        return f"{what}: a reading is missing or not a number; check the sensor's wiring"
    if reason == r.NOT_STILL and "spread_N" in v:
        return (f"{what}: the force spread {v['spread_N']:.0f} N (more than {LOAD_STILL_SPREAD_N:g} N): lift the "
                "foot clear and do not touch it")
    if reason == r.NOT_STILL:
        return (f"{what} zero: the readings spread {v.get('spread_deg', math.nan):.1f}° (more than "
                f"{STILL_SPREAD_DEG:g}°): hold the joint still at its stop and repeat")
    if reason == r.TOO_LITTLE_MOVE:
        return (f"{what} direction: the joint moved {abs(v.get('moved_deg', 0.0)):.1f}°, less than {MIN_MOVE_DEG:g}°: "
                f"move it by hand into {'flexion' if subject == 'knee' else 'dorsiflexion'} by 10–40°")
    if reason == r.BEYOND_RANGE:
        lo, hi = JOINT_RANGE_DEG.get(subject, (math.nan, math.nan))
        return (f"{what} direction: from the zero the joint read {v.get('reach_min_deg', math.nan):+.1f}° … "
                f"{v.get('reach_max_deg', math.nan):+.1f}°, beyond its range {lo:g}–{hi:g}°: the zero was not taken "
                "at the stop, or the sensor is not on this joint; repeat the zero")
    if reason == r.LOAD_OFFSET:
        return (f"load cell zero: it reads {v.get('force_N', math.nan):+.0f} N unloaded, beyond "
                f"{MAX_LOAD_OFFSET_N:g} N: the foot is loaded, or the cell or its amplifier needs service")
    if reason == r.NOT_LOADED:
        return (f"load cell sign: the force changed {abs(v.get('change_N', 0.0)):.0f} N, under a fifth of the body "
                f"weight ({MIN_LOAD_SHARE * v.get('body_weight_N', math.nan):.0f} N): stand on the leg with about "
                "half your weight")
    if reason == r.OVERLOADED:
        return (f"load cell sign: the force changed {abs(v.get('change_N', 0.0)):.0f} N, over twice the body weight: "
                "check the body mass and the cell's scale")
    if reason == r.BODY_MASS:
        return (f"load cell sign: body mass must be {BODY_MASS_KG[0]:g}–{BODY_MASS_KG[1]:g} kg, got "
                f"{v.get('body_mass_kg', math.nan):g}: assign the patient (with their mass) to the device first")
    return {
        r.LEG_BUSY: "the leg runs a table: put it in safe mode (and in its stand) before calibrating",
        r.NO_SENSORS: "this leg has no sensors to calibrate (the simulated bench reads itself exactly)",
        r.OUT_OF_ORDER: "this step needs the steps before it: zero, direction, load cell zero, load cell sign",
        r.NOT_STARTED: "no calibration is under way on the leg (another was started, or it ended): start again",
        r.INCOMPLETE: "all four steps must be accepted before the calibration is kept",
        r.NOT_SAVED: "the leg could not write its calibration file: nothing changed; check its storage",
    }.get(reason, f"{what}: refused ({int(reason)})")


def _finite(values: Sequence[float], subject: str) -> list[float]:
    out = [float(v) for v in values]
    if not out or not all(math.isfinite(v) for v in out):
        raise CalibrationRefusedError(CalibrationRefusal.NOT_A_NUMBER, subject)
    return out


def joint_zero(joint: str, readings_rad: Sequence[float], previous: JointCalibration | None = None) -> StepResult:
    """Step 1 for ``joint`` from its sensor's readings (rad) at full extension / neutral."""
    r = _finite(readings_rad, joint)
    spread = math.degrees(max(r) - min(r))
    if spread > STILL_SPREAD_DEG:
        raise CalibrationRefusedError(CalibrationRefusal.NOT_STILL, joint, {"spread_deg": spread})
    zero = statistics.fmean(r)
    base = previous or JointCalibration()
    return StepResult(joint, {"reading_deg": math.degrees(zero), "spread_deg": spread},
                      base.model_copy(update={"zero_rad": zero, "calibrated": False}))


def joint_direction(joint: str, zeroed: JointCalibration, sensor_rad: Sequence[float],
                    actuator_rad: Sequence[float]) -> StepResult:
    """Step 2: ``sensor_rad`` and ``actuator_rad`` recorded from the zero pose through the prompted flexion (rad)."""
    s = _finite(sensor_rad, joint)
    a = _finite(actuator_rad, joint)
    moved = math.degrees(s[-1] - s[0])
    if abs(moved) < MIN_MOVE_DEG:
        raise CalibrationRefusedError(CalibrationRefusal.TOO_LITTLE_MOVE, joint, {"moved_deg": moved})
    sign = 1 if moved > 0 else -1
    torque_sign = 1 if a[-1] - a[0] > 0 else -1
    lo, hi = JOINT_RANGE_DEG[joint]
    reach = [sign * math.degrees(v - zeroed.zero_rad) for v in s]
    if min(reach) < lo - 5.0 or max(reach) > hi + 5.0:
        raise CalibrationRefusedError(CalibrationRefusal.BEYOND_RANGE, joint,
                                      {"reach_min_deg": min(reach), "reach_max_deg": max(reach)})
    return StepResult(joint, {"moved_deg": moved, "sign": sign, "torque_sign": torque_sign},
                      zeroed.model_copy(update={"sign": sign, "torque_sign": torque_sign, "calibrated": True}))


def loadcell_zero(fz_N: Sequence[float], my_Nm: Sequence[float]) -> StepResult:
    """Step 3 from the unloaded foot's axial force (N) and sagittal moment (N·m) readings."""
    fz = _finite(fz_N, "loadcell")
    my = _finite(my_Nm, "loadcell")
    spread = max(fz) - min(fz)
    if spread > LOAD_STILL_SPREAD_N:
        raise CalibrationRefusedError(CalibrationRefusal.NOT_STILL, "loadcell", {"spread_N": spread})
    zero = statistics.fmean(fz)
    if abs(zero) > MAX_LOAD_OFFSET_N:
        raise CalibrationRefusedError(CalibrationRefusal.LOAD_OFFSET, "loadcell", {"force_N": zero})
    return StepResult("loadcell", {"force_N": zero, "moment_Nm": statistics.fmean(my), "spread_N": spread},
                      LoadcellCalibration(fz_zero_N=zero, my_zero_Nm=statistics.fmean(my)))


def loadcell_sign(zeroed: LoadcellCalibration, fz_N: Sequence[float], body_mass_kg: float) -> StepResult:
    """Step 4 from the axial force (N) with the patient of ``body_mass_kg`` standing on the leg."""
    fz = _finite(fz_N, "loadcell")
    if not (math.isfinite(body_mass_kg) and BODY_MASS_KG[0] <= body_mass_kg <= BODY_MASS_KG[1]):
        raise CalibrationRefusedError(CalibrationRefusal.BODY_MASS, "loadcell", {"body_mass_kg": body_mass_kg})
    weight = body_weight_N(body_mass_kg)
    change = statistics.fmean(fz) - zeroed.fz_zero_N
    seen = {"change_N": change, "body_weight_N": weight}
    if abs(change) < MIN_LOAD_SHARE * weight:
        raise CalibrationRefusedError(CalibrationRefusal.NOT_LOADED, "loadcell", seen)
    if abs(change) > MAX_LOAD_SHARE * weight:
        raise CalibrationRefusedError(CalibrationRefusal.OVERLOADED, "loadcell", seen)
    sign = 1 if change > 0 else -1
    return StepResult("loadcell", {**seen, "sign": sign},
                      zeroed.model_copy(update={"fz_sign": sign, "my_sign": sign, "calibrated": True}))
