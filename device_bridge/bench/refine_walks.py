"""The refinement loop on the bench (``quasitune refine``): a leg that is not the model's walks a course with the
envelope, the envelope is refined from those strides, again, then an evaluation course is walked with the original
envelope, the refined one and the FSMIC.

The strides are read as a real leg's session is: heel strikes from the pylon load (10 % of body weight after 150 ms
below it, :func:`controller_core.session_summary.session_strikes`), each stride's task the leg's own estimate (the
estimate the adaptive machine made at the heel strike that closed the stride), the features from its own joint angles
and torques; strides within a change of that estimate are shown, not judged
(:func:`controller_core.stride_features.transitions`), and a round's strides stay evidence in later rounds while no
node they were blended from changes. The bench's checks and searches walk the leg the course is walked on. The bench's
true task is used only to score the evaluation, as every course walk is, and the settled evaluation
(:mod:`device_bridge.bench.settled`) judges bias and spread at tasks held one at a time.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Sequence

import numpy as np

from controller_core.adaptive import StrideDecision
from controller_core.envelope import Envelope
from controller_core.envelope_blend import node_weights
from controller_core.gait_metrics import channel_strides, gait_channels
from controller_core.model import QuasiStiffnessModel
from controller_core.refine import EnvelopeRefinement, RefineRules, change_in_steps, refine_envelope
from controller_core.refine_evidence import (
    QUANTITIES,
    NodeEvidence,
    feature_abs_errors,
    gather_evidence,
    model_targets,
)
from controller_core.refine_search import TrustRegionSearch
from controller_core.session_summary import session_strikes
from controller_core.stride_features import MeasuredStride, measure_strides, toe_off_phases
from controller_core.table import ParameterTable
from controller_core.units import G_MPS2
from device_bridge.bench.controllers import default_envelope, make_controller
from device_bridge.bench.feature_walk import walk_errors
from device_bridge.bench.settled import settled_evaluation
from device_bridge.bench.versus import versus
from device_bridge.sim.course import Course
from device_bridge.sim.course_walk import CourseScore, run_course, score_course
from device_bridge.sim.leg_model import LegGeometry
from device_bridge.sim.simulate import WalkLog

# a spread of the new rows above this many times the old rows' plus the tolerance is an irregular walk: a 12 s walk's
# spread is uncertain by about a factor of 2 (the learned table at 1.2 m/s level: stance knee ±2.3° in 12 s, ±1.3° in 30 s)
IRREGULAR_SPREAD_RATIO = 2.0
DECISION_MATCH_S = 0.3   # a load-based heel strike and the machine's own (at a higher load) within this are one strike


def stride_tasks(log: WalkLog, strikes: np.ndarray, decisions: Sequence[StrideDecision]
                 ) -> list[tuple[float, float] | None]:
    """Per stride (between consecutive ``strikes``), the leg's own estimate of its task: the estimate made at the heel
    strike that closed it; None where there was none (no confident stride yet, or no matching heel strike)."""
    times = np.array([d.time_s for d in decisions]) if decisions else np.zeros(0)
    t = log.channels["time_s"]
    out: list[tuple[float, float] | None] = []
    for _, b in itertools.pairwise(strikes):
        if times.size == 0:
            out.append(None)
            continue
        k = int(np.argmin(np.abs(times - t[b])))
        est = decisions[k].estimate
        ok = (abs(times[k] - t[b]) <= DECISION_MATCH_S and est is not None and math.isfinite(est.speed_mps)
              and math.isfinite(est.incline_deg))
        out.append((float(est.speed_mps), float(est.incline_deg)) if ok else None)   # type: ignore[union-attr]
    return out


def measured_strides(log: WalkLog, decisions: Sequence[StrideDecision], settle_s: float = 2.0
                     ) -> tuple[list[MeasuredStride], dict[str, int], int]:
    """The walk's strides after ``settle_s`` as the leg records them: (measured strides with their estimated tasks,
    per feature the strides without it, strides in all)."""
    c, mass = log.channels, log.mass_kg
    strikes = session_strikes(c["time_s"], c["load_N"], mass)
    strikes = strikes[c["time_s"][strikes] >= settle_s] if strikes.size else strikes
    if strikes.size < 2:
        return [], {}, 0
    measured = gait_channels(c["knee_angle_rad"], c["ankle_angle_rad"], c["knee_torque_Nm"], c["ankle_torque_Nm"],
                             mass)
    tasks = stride_tasks(log, strikes, decisions)
    toe = toe_off_phases(c["load_N"], strikes, 0.1 * mass * G_MPS2)
    strides, not_found = measure_strides(channel_strides(measured, strikes), tasks, toe)
    return strides, not_found, len(tasks)


def walk_envelope(envelope: Envelope, model: QuasiStiffnessModel, course: Course, geometry: LegGeometry,
                  controller: str = "adaptive") -> tuple[CourseScore, list[MeasuredStride], dict[str, int], int]:
    """Walk the course with the envelope (or the FSMIC) on the leg: the score and the strides as the leg records them."""
    ctrl = make_controller(controller, envelope.mass_kg, model, envelope=envelope, geometry=geometry)
    log, traj = run_course(ctrl, course, envelope.mass_kg, geometry)
    decisions = getattr(ctrl, "decisions_", None)
    score = score_course(log, traj, course, decisions)
    if decisions is None:   # the FSMIC estimates nothing: its strides are judged at the bench's true task
        strikes = session_strikes(log.channels["time_s"], log.channels["load_N"], envelope.mass_kg)
        strikes = strikes[log.channels["time_s"][strikes] >= 2.0]
        tasks = [(float(traj.speed_mps[a:b].mean()), float(traj.incline_deg[a:b].mean()))
                 for a, b in itertools.pairwise(strikes)]
        measured = gait_channels(log.channels["knee_angle_rad"], log.channels["ankle_angle_rad"],
                                 log.channels["knee_torque_Nm"], log.channels["ankle_torque_Nm"], envelope.mass_kg)
        strides, not_found = measure_strides(channel_strides(measured, strikes), tasks) if len(tasks) else ([], {})
        return score, strides, not_found, len(tasks)
    strides, not_found, total = measured_strides(log, decisions)
    return score, strides, not_found, total


def bench_feature_errors(table: ParameterTable, speed_mps: float, incline_deg: float, mass_kg: float,
                         model: QuasiStiffnessModel, seconds: float = 12.0, geometry: LegGeometry | None = None
                         ) -> dict[str, object]:
    """What the bench expects of a table at a task: walked ``seconds`` on the leg ``geometry``, its strides read as a
    session's (after 2 s), each controlled quantity's mean error against the model's target (measured − target, the
    quantity's unit) and its spread from stride to stride (``spread``: the standard deviation, same unit; None below
    two strides), with the walk's falls. The same feature definitions as the leg's own strides."""
    return walk_errors(make_controller("table", mass_kg, table=table), speed_mps, incline_deg, mass_kg, model, seconds,
                       geometry)


class BenchStepCheck:
    """The bench's check of a node's step (:data:`controller_core.refine.StepCheck`): the old and the new rows walked
    ``seconds`` at the node's task on the leg ``geometry`` (the patient's, where described; else the nominal one);
    the step is refused when the new rows fall more, when any
    controlled quantity's spread from stride to stride grows beyond :data:`IRREGULAR_SPREAD_RATIO` times what it was
    plus its tolerance (the gait became irregular, alternating long and short strides, which a mean error does not
    show and the per-stride error the patient lives with does), or when any controlled quantity moves further from
    what the sensitivity expects than its tolerance or the expected change itself, whichever is larger (the step left
    the range where the sensitivity holds). Walks are kept, so a table walked again (the old rows at a halved step,
    the API's expected change) costs nothing.

    Args:
        model: the model the targets come from.
        mass_kg: the patient's mass.
        seconds: walking per table (s).
        geometry: the leg walked (None: the nominal bench).
    """

    def __init__(self, model: QuasiStiffnessModel, mass_kg: float, seconds: float = 12.0,
                 geometry: LegGeometry | None = None) -> None:
        self.model = model
        self.mass_kg = mass_kg
        self.seconds = seconds
        self.geometry = geometry or LegGeometry()
        self._walks: dict[tuple[str, ...], dict[str, object]] = {}
        self.refused = 0

    @property
    def walks(self) -> int:
        """Walks made so far (each table, or envelope, once)."""
        return len(self._walks)

    def errors(self, table: ParameterTable, speed_mps: float, incline_deg: float) -> dict[str, object]:
        """:func:`bench_feature_errors` of the table at the task, walked once."""
        return self._once((table.model_dump_json(exclude={"provenance"}), f"{speed_mps:.4f}", f"{incline_deg:.4f}"),
                          lambda: bench_feature_errors(table, speed_mps, incline_deg, self.mass_kg, self.model,
                                                       self.seconds, self.geometry))

    def _once(self, key: tuple[str, ...], walk: Callable[[], dict[str, object]]) -> dict[str, object]:
        """A walk's result, walked the first time its key is asked for."""
        if key not in self._walks:
            self._walks[key] = walk()
        return self._walks[key]

    def at_node(self, envelope: Envelope, index: int) -> NodeInEnvelope:
        """The bench for one node of ``envelope`` (speed-major ``index``): its candidate rows walked as the leg runs
        them, inside the envelope on the leg's own estimate (:class:`NodeInEnvelope`)."""
        return NodeInEnvelope(self, envelope, index)

    def envelope_errors(self, envelope: Envelope, speed_mps: float, incline_deg: float) -> dict[str, object]:
        """What :meth:`errors` gives of a table, of an envelope on the leg's own estimate (walked once)."""
        return self._once((envelope.model_dump_json(), f"{speed_mps:.4f}", f"{incline_deg:.4f}"),
                          lambda: walk_errors(make_controller("adaptive", self.mass_kg, self.model, envelope=envelope,
                                                              geometry=self.geometry),
                                              speed_mps, incline_deg, self.mass_kg, self.model, self.seconds,
                                              self.geometry))

    @property
    def leg(self) -> str:
        """The leg walked: a leg file's name, or ``nominal``."""
        return self.geometry.name

    def worse(self, before: dict[str, object], after: dict[str, object]) -> str | None:
        """Why the walk ``after`` is refused next to ``before``: more falls, or strides turned irregular; else None."""
        if after["falls"] > before["falls"]:
            return f"the new rows fell {after['falls']} times on the bench ({before['falls']} before)"
        for q in QUANTITIES:
            a, b = after["spread"][q.key], before["spread"][q.key]
            if a is not None and b is not None and a > IRREGULAR_SPREAD_RATIO * b + q.tolerance:
                return (f"the strides became irregular on the bench: {q.label} varies ±{a:.1f}{q.unit_text} from "
                        f"stride to stride, ±{b:.1f}{q.unit_text} before")
        return None

    def __call__(self, evidence: NodeEvidence, old: ParameterTable, new: ParameterTable,
                 expected_change: dict[str, float]) -> str | None:
        before = self.errors(old, evidence.speed_mps, evidence.incline_deg)
        after = self.errors(new, evidence.speed_mps, evidence.incline_deg)
        why = self.worse(before, after)
        if why is not None:
            self.refused += 1
            return why
        for q in QUANTITIES:
            a, b = after["error"][q.key], before["error"][q.key]
            if a is None or b is None:
                continue
            moved, expected = a - b, expected_change.get(q.key, 0.0)
            if abs(moved - expected) > max(q.tolerance, abs(expected)):
                self.refused += 1
                return (f"the bench moved {q.label} {moved:+.1f}{q.unit_text} where the sensitivity expected "
                        f"{expected:+.1f}{q.unit_text}")
        return None


class NodeInEnvelope:
    """A node's bench (:class:`controller_core.refine_search.NodeBench`) that walks candidate rows where they run:
    the envelope with that node's rows replaced, blended at the leg's own estimate, at the node's task. Walked alone
    on a fixed table, a node's rows said nothing of the rows the leg blends there (at 1.6 m/s level on the nominal
    leg the swing knee peak came out 8° apart)."""

    def __init__(self, bench: BenchStepCheck, envelope: Envelope, index: int) -> None:
        self.bench, self.envelope, self.index = bench, envelope, index

    @property
    def leg(self) -> str:
        return self.bench.leg

    def errors(self, table: ParameterTable, speed_mps: float, incline_deg: float) -> dict[str, object]:
        nodes = list(self.envelope.nodes)
        nodes[self.index] = nodes[self.index].model_copy(update={"table": table})
        return self.bench.envelope_errors(self.envelope.model_copy(update={"nodes": nodes}), speed_mps, incline_deg)

    def worse(self, before: dict[str, object], after: dict[str, object]) -> str | None:
        return self.bench.worse(before, after)


def blended_nodes(envelope: Envelope, stride: MeasuredStride) -> set[tuple[int, int]]:
    """The nodes whose rows the leg blended for a stride at its estimated task: while none of them changes, the stride
    is evidence of the rows that run there, round after round (a node of the mixed course's 1.6 m/s segment gets
    about 8 clean strides in a 120 s round: short of the 10 it takes to act, reached over two rounds)."""
    if not (math.isfinite(stride.speed_mps) and math.isfinite(stride.incline_deg)):
        return set()
    return {(i, j) for i, j, _ in node_weights(envelope.speeds_mps, envelope.inclines_deg, stride.speed_mps,
                                               stride.incline_deg)}


def _evaluation(score: CourseScore, strides: Sequence[MeasuredStride], targets_at) -> dict[str, object]:
    s = score.summary
    errors = feature_abs_errors(strides, targets_at)
    return {"falls": s["falls"], "toe_catches": s["toe_catches"],
            "loaded_swing_ms_max_stride": s.get("loaded_swing_ms_max_stride"),
            "knee_angle_rmse_deg": s.get("knee_angle_rmse_deg"), "ankle_angle_rmse_deg": s.get("ankle_angle_rmse_deg"),
            "knee_angle_rmse_ci95_deg": s.get("knee_angle_rmse_ci95_deg"),
            "ankle_angle_rmse_ci95_deg": s.get("ankle_angle_rmse_ci95_deg"),
            "hip_sink_max_mm": s.get("hip_sink_max_mm"), "strides": s.get("strides"),
            "feature_abs_error": errors,
            "feature_mean_abs_error": _mean_error(errors)}


def _mean_error(errors: dict[str, float | None]) -> float | None:
    """The mean over the controlled quantities of their mean absolute errors (deg and % cycle alike, each against its
    own 2-unit tolerance, so they weigh the same)."""
    vals = [v for v in errors.values() if v is not None]
    return round(float(np.mean(vals)), 3) if vals else None


def refine_on_bench(model: QuasiStiffnessModel, geometry: LegGeometry, train: Course, evaluate: Course, rounds: int = 2,
                    seconds_per_round: float = 120.0, mass_kg: float = 75.0, envelope: Envelope | None = None,
                    rules: RefineRules | None = None, search: TrustRegionSearch | None = None,
                    settled: Course | None = None) -> dict[str, object]:
    """The loop (module docstring). Returns the JSON of ``quasitune refine``: ``rounds``, ``evaluation`` (``original``,
    ``refined``, ``fsmic``; the first two also ``settled``: bias and spread at each task of the ``settled`` course,
    :func:`device_bridge.bench.settled.settled_evaluation`) and ``refined_minus_original``, plus the refined envelope.
    ``search``: where given, each node's rows are found by a search on the bench walking ``geometry``'s leg
    (:mod:`controller_core.refine_search`) instead of one step through the shipped sensitivity that the bench checks
    (the default: the search is not yet better, docs/results.md)."""
    if not (isinstance(rounds, int) and 1 <= rounds <= 10):
        raise ValueError(f"rounds must be a whole number from 1 to 10, got {rounds!r}")
    original = envelope or default_envelope(model, mass_kg, geometry)
    targets_at = model_targets(model)
    check = BenchStepCheck(model, mass_kg, geometry=geometry)
    course = train.lasting(seconds_per_round)
    current = original
    out_rounds = []
    refinement: EnvelopeRefinement | None = None
    kept: list[MeasuredStride] = []    # earlier rounds' strides on rows no round has changed since
    for k in range(rounds):
        score, strides, not_found, total = walk_envelope(current, model, course, geometry)
        evidence = gather_evidence(kept + strides, current.speeds_mps, current.inclines_deg, targets_at)
        walks_before, refused = check.walks, check.refused
        refinement = refine_envelope(current, evidence, rules, refinement.nodes if refinement else None,
                                     check=check if search is None else None,
                                     bench=check if search is not None else None, search=search)
        out_rounds.append({
            "round": k + 1, "course": course.name, "strides": total, "strides_used": len(strides),
            "strides_kept_from_earlier_rounds": len(kept),
            "strides_without_feature": not_found, "falls": score.summary["falls"],
            "toe_catches": score.summary["toe_catches"],
            "feature_abs_error": feature_abs_errors(strides, targets_at),
            "nodes_changed": sorted({tuple(c["node"]) for c in refinement.changes}),
            "change_in_steps": change_in_steps(refinement.changes, rules),
            "bench_walks": check.walks - walks_before, "steps_refused_by_bench": check.refused - refused,
            "changes": [{**c, "before": round(c["before"], 4), "after": round(c["after"], 4)}
                        for c in refinement.changes],
            "nodes": [n for n in refinement.nodes if n["strides"]],
        })
        changed = {tuple(c["node"]) for c in refinement.changes}
        kept = [st for st in kept + strides if not blended_nodes(current, st) & changed]
        current = refinement.envelope
    walks = {name: walk_envelope(env, model, evaluate, geometry, controller)
             for name, env, controller in (("original", original, "adaptive"), ("refined", current, "adaptive"),
                                           ("fsmic", original, "fsmic"))}
    diff = versus(walks["refined"][0], walks["original"][0], "refined", "original")
    evaluation = {name: _evaluation(w[0], w[1], targets_at) for name, w in walks.items()}
    if settled is not None:
        for name, env in (("original", original), ("refined", current)):
            evaluation[name]["settled"] = settled_evaluation(env, model, settled, geometry)
    return {"leg": geometry.name, "mass_kg": mass_kg, "train_course": course.to_json(),
            "eval_course": evaluate.to_json(), "settled_course": None if settled is None else settled.to_json(),
            "rounds": out_rounds, "evaluation": evaluation,
            "refined_minus_original": {ch: {"difference": d["rmse_difference"], "ci95": d["ci95"],
                                            "verdict": d["verdict"]} for ch, d in diff.items()},
            "refined_envelope": current.to_json()}
