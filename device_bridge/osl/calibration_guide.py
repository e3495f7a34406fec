"""The guided calibration on the leg: prompts the prosthetist through each step of :mod:`device_bridge.osl.calibration`,
reads the leg's sensors while they hold each pose, says what every step measured, repeats a step it refused, and
returns the leg's :class:`~device_bridge.osl.config.Calibration` (``quasitune leg --calibrate`` keeps it beside the
leg file, :func:`device_bridge.osl.config.save_calibration`).

The prompts are the leg's; ``ask`` shows one and waits until the pose is held (the terminal's Enter), ``say`` reports.
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable

from device_bridge.osl.calibration import (
    CalibrationRefusedError,
    StepResult,
    joint_direction,
    joint_zero,
    loadcell_sign,
    loadcell_zero,
)
from device_bridge.osl.config import Calibration
from device_bridge.osl.leg import OSLLeg

ZERO_POSE = "Hold the knee straight (at its extension stop) and the ankle at neutral, and keep them still."
MOVED_POSE = "Bend the knee by hand to about 30° and lift the toes about 10°, and hold them there."
UNLOADED = "Lift the foot clear of the floor; nobody touches the foot or the pylon."
STANDING = "Stand on the leg with about half your weight, still."
ATTEMPTS = 3


def read_pose(leg: OSLLeg, samples: int, period_s: float, sleep: Callable[[float], None]) -> dict[str, list[float]]:
    """The leg's raw readings over ``samples`` periods: each joint's sensor and actuator output, the load cell."""
    out: dict[str, list[float]] = {k: [] for k in ("knee", "knee_actuator", "ankle", "ankle_actuator", "fz", "my")}
    for _ in range(samples):
        for d in leg.devices:
            d.update()
        for joint in ("knee", "ankle"):
            act, enc = leg.actuators[joint], leg.encoders[joint]
            out[f"{joint}_actuator"].append(float(act.output_position))
            out[joint].append(float(enc.position) if enc is not None else float(act.output_position))
        out["fz"].append(float(leg.loadcell.fz))
        out["my"].append(float(leg.loadcell.my))
        sleep(period_s)
    return out


def guided_calibration(leg: OSLLeg, body_mass_kg: float, ask: Callable[[str], None], say: Callable[[str], None],
                       samples: int = 100, sleep: Callable[[float], None] = time.sleep) -> Calibration:
    """Walk the prosthetist through the four steps (module docstring); a refused step is said and asked again, up to
    :data:`ATTEMPTS` times (then CalibrationRefusedError)."""
    period = leg.config.period_s

    def step(prompt: str, compute: Callable[[dict[str, list[float]]], tuple[StepResult, ...]]
             ) -> tuple[tuple[StepResult, ...], dict[str, list[float]]]:
        for attempt in range(1, ATTEMPTS + 1):
            ask(prompt)
            readings = read_pose(leg, samples, period, sleep)
            try:
                results = compute(readings)
            except CalibrationRefusedError as exc:
                say(f"refused: {exc}" + ("" if attempt < ATTEMPTS else " (no attempts left)"))
                if attempt == ATTEMPTS:
                    raise
                continue
            for r in results:
                say(r.measured)
            return results, readings
        raise AssertionError("unreachable")

    (knee0, ankle0), zero = step(ZERO_POSE, lambda r: (joint_zero("knee", r["knee"]), joint_zero("ankle", r["ankle"])))

    def direction(r: dict[str, list[float]]) -> tuple[StepResult, ...]:
        mean = statistics.fmean
        return tuple(joint_direction(j, c.calibration, [mean(zero[j]), mean(r[j])],
                                     [mean(zero[f"{j}_actuator"]), mean(r[f"{j}_actuator"])])
                     for j, c in (("knee", knee0), ("ankle", ankle0)))

    (knee, ankle), _ = step(MOVED_POSE, direction)
    (lc0,), _ = step(UNLOADED, lambda r: (loadcell_zero(r["fz"], r["my"]),))
    (lc,), _ = step(STANDING, lambda r: (loadcell_sign(lc0.calibration, r["fz"], body_mass_kg),))
    return Calibration(knee=knee.calibration, ankle=ankle.calibration, loadcell=lc.calibration)
