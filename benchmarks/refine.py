"""Refinement speed: a 5 × 5 envelope refined from 120 s of strides on a warm model.

The strides are recorded once on the bench (the adaptive envelope walking the ``mixed`` course for 120 s; not timed:
that is walking, not refining), then the refinement is timed from the recorded log: strides cut and measured, their
targets predicted, the evidence gathered per node and the step taken, ``repeats`` times (targets are cached per
refinement, as the API does). The bench's check of each node's step (walks, as the API makes them) is not part of the
target and is timed once on its own: the whole refinement with the check, and the walks it made; so is the search on
the bench (``controller_core.refine_search``, a study), against a round's target of 60 s.
"""

from __future__ import annotations

import statistics
import time

from controller_core import load_default_model
from controller_core.refine import refine_envelope
from controller_core.refine_evidence import gather_evidence, model_targets
from controller_core.refine_search import TrustRegionSearch
from device_bridge.bench.controllers import default_envelope, make_controller
from device_bridge.bench.refine_walks import BenchStepCheck, measured_strides
from device_bridge.sim.course import load_course
from device_bridge.sim.course_walk import run_course
from device_bridge.sim.leg_model import LegGeometry


def run(repeats: int = 10, seconds: float = 120.0) -> dict:
    model = load_default_model()
    model.propose(1.2, 0.0, 75.0)                      # warm
    env = default_envelope(model, 75.0)
    ctrl = make_controller("adaptive", 75.0, model, envelope=env, geometry=LegGeometry())
    log, _ = run_course(ctrl, load_course("mixed").lasting(seconds), 75.0, LegGeometry())
    decisions = ctrl.decisions_
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        strides, _, total = measured_strides(log, decisions)
        evidence = gather_evidence(strides, env.speeds_mps, env.inclines_deg, model_targets(model))
        result = refine_envelope(env, evidence)
        times.append(time.perf_counter() - t0)
    check = BenchStepCheck(model, 75.0)
    t0 = time.perf_counter()
    checked = refine_envelope(env, evidence, check=check)
    checked_s = time.perf_counter() - t0
    bench = BenchStepCheck(model, 75.0)
    t0 = time.perf_counter()
    searched = refine_envelope(env, evidence, bench=bench, search=TrustRegionSearch())
    searched_s = time.perf_counter() - t0
    return {"envelope_nodes": len(env.nodes), "walked_seconds": seconds, "strides": total, "strides_used": len(strides),
            "nodes_changed": len({tuple(c["node"]) for c in result.changes}),
            "refine_s_median": round(statistics.median(times), 4), "refine_s_max": round(max(times), 4),
            "target_s": 2.0, "with_bench_check_s": round(checked_s, 2), "bench_walks": check.walks,
            "steps_refused_by_bench": check.refused,
            "nodes_changed_with_check": len({tuple(c["node"]) for c in checked.changes}),
            "with_bench_search_s": round(searched_s, 2), "bench_search_walks": bench.walks,
            "nodes_changed_with_search": len({tuple(c["node"]) for c in searched.changes}),
            "round_target_s": 60.0, "repeats": repeats}
