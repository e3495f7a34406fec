"""Bias and scatter at settled tasks: what refinement is judged on (``quasitune refine``'s ``settled`` evaluation).

A varying course mixes three errors: a bias per task, which the rows can remove; stride-to-stride scatter, which no
table removes; and the strides at a change of task. A settled course holds each task long enough to separate the
first: each of its segments is walked on its own from standing for the segment's duration, at constant speed and
incline, with the envelope blended at the leg's own estimate (as the leg runs it); strides after 2 s are judged
against the model's targets at the walk's true task. Per task and quantity: strides, bias (mean signed error) with its
95 % interval, the spread from stride to stride (standard deviation: the part no row moves) and whether the bias is
within the quantity's tolerance (2° or 2 % of the cycle).
"""

from __future__ import annotations

from controller_core.envelope import Envelope
from controller_core.model import QuasiStiffnessModel
from controller_core.refine_evidence import QUANTITIES
from device_bridge.bench.controllers import make_controller
from device_bridge.bench.feature_walk import walk_errors
from device_bridge.sim.course import Course
from device_bridge.sim.leg_model import LegGeometry

SETTLED_COURSE = "settled"


def settled_evaluation(envelope: Envelope, model: QuasiStiffnessModel, course: Course,
                       geometry: LegGeometry | None = None) -> dict[str, object]:
    """Per segment of ``course`` (module docstring), and ``settled_within_tolerance_fraction`` over every (task,
    quantity) pair with a bias, with the falls of all the walks."""
    tasks, within, pairs, falls = [], 0, 0, 0
    for seg in course.segments:
        ctrl = make_controller("adaptive", envelope.mass_kg, model, envelope=envelope, geometry=geometry)
        walk = walk_errors(ctrl, seg.speed_mps, seg.incline_deg, envelope.mass_kg, model, seg.duration_s, geometry)
        quantities = {}
        for q in QUANTITIES:
            bias = walk["error"][q.key]
            ok = None if bias is None else abs(bias) <= q.tolerance
            pairs += ok is not None
            within += bool(ok)
            quantities[q.key] = {"bias": bias, "ci95": walk["ci95"][q.key], "spread": walk["spread"][q.key],
                                 "tolerance": q.tolerance, "within_tolerance": ok}
        falls += int(walk["falls"])
        tasks.append({"speed_mps": seg.speed_mps, "incline_deg": seg.incline_deg, "seconds": seg.duration_s,
                      "strides": walk["strides"], "falls": walk["falls"], "quantities": quantities})
    return {"course": course.name, "leg": (geometry or LegGeometry()).name, "tasks": tasks, "falls": falls,
            "pairs": pairs, "within_tolerance": within,
            "settled_within_tolerance_fraction": round(within / pairs, 3) if pairs else None}
