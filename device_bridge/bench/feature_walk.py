"""A walk's controlled quantities against the model's targets: each quantity's bias, its 95 % interval and its
stride-to-stride spread, the way the leg's own strides are read (heel strikes from the pylon load, strides after 2 s).
What the refinement's bench check and search, and the settled evaluation, measure a walk by."""

from __future__ import annotations

import numpy as np

from controller_core.gait_metrics import channel_strides, episodes, gait_channels
from controller_core.model import QuasiStiffnessModel
from controller_core.refine_evidence import QUANTITIES, judge, model_targets
from controller_core.session_summary import session_strikes
from controller_core.stride_features import measure_strides
from controller_core.units import G_MPS2
from device_bridge.bench.task_reference import task_reference
from device_bridge.sim.leg_model import LegGeometry
from device_bridge.sim.simulate import StepController, fall_mask, run_walk


def walk_errors(controller: StepController, speed_mps: float, incline_deg: float, mass_kg: float,
                model: QuasiStiffnessModel, seconds: float, geometry: LegGeometry | None = None) -> dict[str, object]:
    """``controller`` (a table, an envelope on the leg's own estimate) walked ``seconds`` from standing at the task on
    the leg ``geometry``, strides after 2 s judged against the model's targets at the walk's true task:
    ``{"strides", "falls", "error": per quantity the mean error (measured − target, its unit) or None, "ci95": its
    95 % interval (t distribution) or None below two strides, "spread": the standard deviation from stride to stride,
    "seconds"}``."""
    ref = task_reference(speed_mps, incline_deg, model, mass_kg)
    log = run_walk(controller, ref, mass_kg, seconds, geometry)
    c = log.channels
    strikes = session_strikes(c["time_s"], c["load_N"], mass_kg)
    strikes = strikes[c["time_s"][strikes] >= 2.0] if strikes.size else strikes
    measured = gait_channels(c["knee_angle_rad"], c["ankle_angle_rad"], c["knee_torque_Nm"], c["ankle_torque_Nm"],
                             mass_kg)
    tasks = [(speed_mps, incline_deg)] * max(int(strikes.size) - 1, 0)
    strides, _ = measure_strides(channel_strides(measured, strikes), tasks) if tasks else ([], {})
    targets = model_targets(model)
    judged = {}
    for q in QUANTITIES:     # every stride at the walk's one task: equal weights in the refinement's own statistics
        pairs = [(q.display(*s.features[q.feature]), q.display(t.phase, t.value)) for s in strides
                 if q.feature in s.features for t in (targets(s.speed_mps, s.incline_deg)[q.feature],)]
        values = np.array([v for v, _ in pairs], dtype=float)
        aims = np.array([a for _, a in pairs], dtype=float)
        judged[q.key] = judge(q.key, values, aims, np.ones(len(pairs)))

    def r(x: float | None) -> float | None:
        return None if x is None else round(float(x), 3)

    errors = {k: r(e.error) for k, e in judged.items()}
    spread = {k: r(e.spread) for k, e in judged.items()}
    ci95 = {k: None if e.ci95 is None else [r(e.ci95[0]), r(e.ci95[1])] for k, e in judged.items()}
    return {"strides": len(strides), "falls": int(episodes(fall_mask(c, mass_kg * G_MPS2) & (c["time_s"] >= 2.0),
                                                             round(0.2 / log.timestep_s))),
            "error": errors, "ci95": ci95, "spread": spread, "seconds": seconds}
