"""Target features measured on each recorded stride: the same features the model predicts, found the same way.

A stride is one heel strike to the next, resampled on the 101-point phase grid (:func:`controller_core.gait_metrics.
stride_curves`) in the units it is scored in (deg, N·m/kg). Each feature of :data:`controller_core.features.FEATURES`
is found with its own definition (:func:`controller_core.features.find_extremum`: an interior local extremum in its
phase window); a stride on which a feature has no such extremum is **counted, not guessed**: it is left out of that
feature's evidence, and the count is reported. The moment features read the leg's own joint torques (the leg measures
its actuator torques, not the person's joint moments: the names say ``measured`` torque where it matters).

Units: values in SI like the model's predictions (angles rad, moments N·m/kg), phase as a fraction of the stride.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from controller_core.features import CURVE_FEATURES, FeatureNotFoundError, FeatureSpec, find_extremum
from controller_core.gait_metrics import PHASE_GRID
from controller_core.task_estimator import INCLINE_RESOLUTION_DEG, SPEED_RESOLUTION_MPS

# the features the four-state table moves directly (refinement acts on these; every curve feature is measured)
CONTROLLED_FEATURES: tuple[str, ...] = ("knee_stance_flexion_peak", "knee_swing_flexion_peak",
                                        "ankle_plantarflexion_peak")
_CHANNEL_UNITS = {"angle": "deg", "moment": "Nm_per_kg"}


def channel_key(spec: FeatureSpec) -> str:
    """The stride channel a feature is read from, as recorded (``knee_angle_deg``, ``ankle_moment_Nm_per_kg``)."""
    return f"{spec.joint}_{spec.quantity}_{_CHANNEL_UNITS[spec.quantity]}"


@dataclass(frozen=True)
class MeasuredStride:
    """The features found on one stride, with the task the stride is judged at.

    Attributes:
        speed_mps, incline_deg: the stride's task (the leg's own estimate on a real leg; NaN when it had none).
        features: feature name → (phase, value SI) for each feature found.
        missing: feature name → why it was not found (counted, not guessed).
        toe_off_phase: where the stride's load fell below the toe-off threshold (fraction), NaN when unknown.
        transition: the stride is one of the first :data:`TRANSITION_STRIDES` of a new task (:func:`transitions`):
            evidence of the change, not of the task.
    """

    speed_mps: float
    incline_deg: float
    features: dict[str, tuple[float, float]]
    missing: dict[str, str] = field(default_factory=dict)
    toe_off_phase: float = math.nan
    transition: bool = False


# a task change: the leg's estimate lies more than twice its resolution (the estimator's own, ±0.1 m/s and ±1.5° on
# 90 % of strides) from the median of the three strides before it: the estimate's own stride-to-stride scatter
# exceeds one resolution on about a quarter of strides, twice it almost never; the stride of the change and the next
# two are the change's, as the course scoring's first three strides after a change are
TASK_CHANGE_MPS, TASK_CHANGE_DEG = 2.0 * SPEED_RESOLUTION_MPS, 2.0 * INCLINE_RESOLUTION_DEG
TRANSITION_STRIDES = 3


def transitions(tasks: Sequence[tuple[float, float] | None], strides: int = TRANSITION_STRIDES) -> list[bool]:
    """Per stride, whether it is within ``strides`` strides of a task change (its own stride counted), judged on the
    strides' own tasks (the leg's estimate); a stride without a task breaks nothing."""
    out: list[bool] = []
    since, before = strides, []
    for task in tasks:
        if task is not None and before:
            speed, incline = np.median([t[0] for t in before]), np.median([t[1] for t in before])
            if abs(task[0] - speed) > TASK_CHANGE_MPS or abs(task[1] - incline) > TASK_CHANGE_DEG:
                since = 0
        out.append(since < strides)
        since += 1
        if task is not None:
            before = [*before, task][-3:]
    return out


def _si(spec: FeatureSpec, value: float) -> float:
    return math.radians(value) if spec.quantity == "angle" else value


def measure_stride(curves: dict[str, np.ndarray], specs: Sequence[FeatureSpec] = CURVE_FEATURES,
                   grid: np.ndarray = PHASE_GRID) -> tuple[dict[str, tuple[float, float]], dict[str, str]]:
    """The features of one stride: (found: name → (phase, value SI), missing: name → reason).

    Args:
        curves: channel (``knee_angle_deg`` …) → the stride on ``grid``; a channel that is absent leaves its features
            missing with that reason.
    """
    found: dict[str, tuple[float, float]] = {}
    missing: dict[str, str] = {}
    for spec in specs:
        curve = curves.get(channel_key(spec))
        if curve is None:
            missing[spec.name] = f"the stride has no {channel_key(spec)} channel"
            continue
        curve = np.asarray(curve, dtype=float)
        if curve.shape != grid.shape or not np.all(np.isfinite(curve)):
            missing[spec.name] = f"{channel_key(spec)} is not a finite curve on the {grid.shape[0]}-point phase grid"
            continue
        if spec.fixed_phase:
            at = spec.window[0]
            found[spec.name] = (at, _si(spec, float(np.interp(at, grid, curve))))
            continue
        try:
            phase, value = find_extremum(grid, curve, spec)
        except FeatureNotFoundError as e:
            missing[spec.name] = str(e)
            continue
        found[spec.name] = (phase, _si(spec, value))
    return found, missing


def toe_off_phases(load_N: np.ndarray, strikes: np.ndarray, threshold_N: float) -> np.ndarray:
    """Per stride, the phase (fraction) at which the load first falls to ``threshold_N`` or below after heel strike
    (NaN where it never does)."""
    load = np.asarray(load_N, dtype=float)
    out = []
    for a, b in itertools.pairwise(strikes):
        below = np.flatnonzero(load[a:b] <= threshold_N)
        # the first sample after the loading response (a load cell rings at contact): past 20 % of the stride
        below = below[below > 0.2 * (b - a)]
        out.append(float(below[0]) / (b - a) if below.size else math.nan)
    return np.array(out)


def measure_strides(strided: dict[str, np.ndarray], tasks: Sequence[tuple[float, float] | None],
                    toe_off: Sequence[float] | None = None, use: Sequence[bool] | None = None
                    ) -> tuple[list[MeasuredStride], dict[str, int]]:
    """Every stride's features, and per feature how many strides did not have it.

    Args:
        strided: channel → (strides, grid) curves (:func:`controller_core.gait_metrics.channel_strides`).
        tasks: per stride, its (speed m/s, incline deg), or None when unknown (the stride is left out: it cannot be
            compared with a target).
        toe_off: per stride, the toe-off phase (:func:`toe_off_phases`), if known.
        use: per stride, whether it counts (False: the leg did not run its table for the whole stride).

    Returns:
        (the measured strides, ``not_found``: feature name → strides without it).
    """
    n = len(tasks)
    changing = transitions(tasks)
    not_found = {spec.name: 0 for spec in CURVE_FEATURES}
    out: list[MeasuredStride] = []
    for k in range(n):
        if tasks[k] is None or (use is not None and not use[k]):
            continue
        found, missing = measure_stride({c: v[k] for c, v in strided.items()})
        for name in missing:
            not_found[name] += 1
        speed, incline = tasks[k]   # type: ignore[misc]
        out.append(MeasuredStride(float(speed), float(incline), found, missing,
                                  math.nan if toe_off is None else float(toe_off[k]), changing[k]))
    return out, not_found
