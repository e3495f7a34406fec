"""The reference a walk on the simulated bench is scored against, at any task.

At level walking: the shipped able-bodied curves interpolated in speed
(:func:`controller_core.walking_reference.level_walking_reference`). On a slope the shipped ramp curves reach
(±10°): the measured ramp trend on those level curves (:func:`controller_core.walking_reference.sloped_walking_reference`).
Steeper, where no curves were measured: the model's own prediction (KMP mean) for knee and ankle, with the level
hip trajectory and load at that speed. ``kind`` and ``source`` say which, in every result.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from controller_core.model import QuasiStiffnessModel
from controller_core.task import validate_task
from controller_core.walking_reference import WalkingReference, level_walking_reference, sloped_walking_reference


def task_reference(speed_mps: float, incline_deg: float, model: QuasiStiffnessModel | None = None,
                   mass_kg: float = 75.0) -> WalkingReference:
    """The reference at a task (see the module docstring); ``model`` is needed only off level ground."""
    validate_task(speed_mps, incline_deg, mass_kg)
    measured = sloped_walking_reference(speed_mps, incline_deg)
    if measured is not None:
        return measured
    ref = level_walking_reference(speed_mps)
    if model is None:
        raise ValueError(f"a task at {incline_deg:+g}° needs the model: the shipped ramp curves reach ±10°")
    prop = model.propose(speed_mps, incline_deg, mass_kg)
    s = prop.phase
    return dataclasses.replace(
        ref, incline_deg=float(incline_deg),
        knee_angle_rad=np.interp(ref.phase, s, prop.means["knee_angle"]),
        ankle_angle_rad=np.interp(ref.phase, s, prop.means["ankle_angle"]),
        knee_moment_Nm_per_kg=np.interp(ref.phase, s, prop.means["knee_moment"]),
        ankle_moment_Nm_per_kg=np.interp(ref.phase, s, prop.means["ankle_moment"]),
        toe_off_phase=float(next(f.value for f in prop.features if f.spec.name == "toe_off")),
        kind="model_prediction",
        source=f"the model's prediction at {incline_deg:+g}° (steeper than any measured ramp); hip and load: "
               + ref.source,
        extrapolation=prop.extrapolation or ref.extrapolation)
