"""Refinement from walking: a damped least-squares step of a node's rows towards the feature targets.

Per node, the quantities its strides support acting on (:mod:`controller_core.refine_evidence`) are moved towards
their targets by changing six parameters, each the one the four-state table holds that quantity with:

====================================  ===================================================================
quantity (display unit)               parameters (sensitivity from the sub-phase spring, see below)
====================================  ===================================================================
stance knee flexion peak (deg)        knee stance-flexion θe (1), ln|k| (−(θpk − θe))
swing knee flexion peak (deg)         knee swing-flexion θe (1), ln|k| (−½(θpk − θe))
its timing (% cycle)                  knee swing-flexion ln|k| (−½(φpk − φtoe-off))
push-off plantarflexion (deg)         ankle stance-extension θe (1)
its timing (% cycle)                  ankle swing-flexion ln|k| (−½(φpk − φtoe-off))
====================================  ===================================================================

**Where the sensitivity comes from: a model of the sub-phase spring**, read at the node's own measured strides. Under
τ = k(θ − θe) the joint holds (stance) or turns around (swing) where the spring's moment balances what drives it, so a
shift of θe shifts the peak one for one, and the peak's distance from θe scales as 1/|k| when a load holds it
(stance: ∂θpk/∂ln|k| = −(θpk − θe)) and as |k|^−½ when inertia carries it (swing: −½(θpk − θe)); a spring–mass reaches
its extreme a quarter period after release, so the time from the sub-phase's start to the peak scales as |k|^−½
(∂φpk/∂ln|k| = −½(φpk − φstart)). Chosen over bench perturbations because it costs nothing per node (a 5 × 5 envelope
refines in milliseconds), has no bench noise, and reads the patient's own strides rather than the model's leg.

**When the sensitivity is wrong.** For one quantity the step is e/g_model, so the next error is e(1 − g_true/g_model):
it shrinks monotonically while the true gain lies between 0 and the model's, oscillates but shrinks up to twice it, and
grows only beyond twice it or with the wrong sign. The model's gains are upper bounds for angles where the joint does
not reach θe (overshoot and friction lower the true gain), so rounds under-step rather than overshoot; the damping
term and the step limits bound any one round, and each round re-measures. A second round therefore changes less than
the first unless the leg's response is non-linear, which the rounds' figures show.

**The step.** Minimise Σ_q ((e_q + J_q Δ)/tol_q)² + λ² Σ_p (Δ_p/step_p)² (Levenberg–Marquardt with the parameters
scaled by their step), quantities not acted on held (e_q = 0 keeps them where they are), then each Δ clipped to its
step: :attr:`RefineRules.theta_step_deg` (5°) for θe, :attr:`RefineRules.k_step_fraction` (25 %) for k, per round.
Changes below 0.1° or 1 % are dropped. The result is clamped into every limit (joint ranges, stance k ≤ 0 (kept by
scaling k), the knee's stance support floor), and the swing threshold follows the expected swing knee peak (85 % of
it, the table rule). Nodes no stride reached stay as they were; the neighbour rule is then held by moving the least
(:func:`controller_core.envelope.neighbour_guard`, sweeping out from the node walked most), and every value so moved is
marked ``neighbour_guard`` with what the refinement gave.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from controller_core.envelope import (
    VALUE_FIELDS,
    Envelope,
    EnvelopeNode,
    neighbour_guard,
    table_values,
    table_with_values,
)
from controller_core.features import FEATURES_BY_NAME
from controller_core.refine_evidence import QUANTITIES, QUANTITY_BY_KEY, NodeEvidence
from controller_core.table import DEFAULT_LIMITS, ParameterTable, SafetyLimits, check_table, support_floor_Nm_per_rad
from controller_core.table_edit import EditError, edit_table


@dataclass(frozen=True)
class Parameter:
    """A refined table value: ``field`` as in :data:`controller_core.envelope.VALUE_FIELDS`; stiffnesses are stepped in
    ln|k| (a stiffness's change is relative), equilibrium angles in deg."""

    field: str
    label: str

    @property
    def joint(self) -> str:
        return self.field.split(".")[0]

    @property
    def subphase(self) -> str:
        return self.field.split(".")[1]

    @property
    def stiffness(self) -> bool:
        return self.field.endswith("k_Nm_per_rad")


PARAMETERS: tuple[Parameter, ...] = (
    Parameter("knee.stance_flexion.theta_e_deg", "knee stance-flexion equilibrium angle"),
    Parameter("knee.stance_flexion.k_Nm_per_rad", "knee stance-flexion stiffness"),
    Parameter("knee.swing_flexion.theta_e_deg", "knee swing-flexion equilibrium angle"),
    Parameter("knee.swing_flexion.k_Nm_per_rad", "knee swing-flexion stiffness"),
    Parameter("ankle.stance_extension.theta_e_deg", "ankle push-off equilibrium angle"),
    Parameter("ankle.swing_flexion.k_Nm_per_rad", "ankle swing stiffness"),
)
SWING_THRESHOLD = "thresholds.wf_to_we_knee_angle_deg"


@dataclass(frozen=True)
class RefineRules:
    """Hyperparameters of the update (module docstring).

    Args:
        damping: λ of the Levenberg–Marquardt step, in units of one step limit per tolerance.
        theta_step_deg: the most an equilibrium angle moves in one round (deg).
        k_step_fraction: the most a stiffness changes in one round (fraction of its magnitude).
        swing_threshold_fraction: the WF→WE knee threshold as a fraction of the expected swing peak (the table rule's).
        limits: the safety limits the result must pass.
    """

    damping: float = 1.0
    theta_step_deg: float = 5.0
    k_step_fraction: float = 0.25
    swing_threshold_fraction: float = 0.85
    limits: SafetyLimits = field(default_factory=lambda: DEFAULT_LIMITS)

    def __post_init__(self) -> None:
        for name in ("damping", "theta_step_deg", "k_step_fraction", "swing_threshold_fraction"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a positive finite number, got {v!r}")
        if self.k_step_fraction >= 1.0 or self.swing_threshold_fraction > 1.0:
            raise ValueError("k_step_fraction must be below 1 and swing_threshold_fraction at most 1")

    def step(self, p: Parameter) -> float:
        """A parameter's step limit per round, in its stepping unit (deg, or ln|k|)."""
        return math.log1p(self.k_step_fraction) if p.stiffness else self.theta_step_deg


def _value(table: ParameterTable, p: Parameter) -> float:
    return float(getattr(table.row(p.joint, p.subphase), p.field.split(".")[2]))


def sensitivity(evidence: NodeEvidence, table: ParameterTable) -> np.ndarray:
    """(quantities × parameters) sensitivity of :data:`QUANTITIES` to :data:`PARAMETERS` from the sub-phase spring
    (module docstring), read at the node's measured peaks; a quantity the strides did not measure has a zero row."""
    m = evidence.measured
    col = {p.field: k for k, p in enumerate(PARAMETERS)}
    toe = m.get("toe_off_pct", 60.0)
    J = np.zeros((len(QUANTITIES), len(PARAMETERS)))
    for r, q in enumerate(QUANTITIES):
        if q.key not in m:
            continue
        x = m[q.key]
        if q.key == "knee_stance_flexion_peak_deg":
            theta_e = _value(table, PARAMETERS[0])
            J[r, col["knee.stance_flexion.theta_e_deg"]] = 1.0
            J[r, col["knee.stance_flexion.k_Nm_per_rad"]] = -(x - theta_e)
        elif q.key == "knee_swing_flexion_peak_deg":
            theta_e = _value(table, PARAMETERS[2])
            J[r, col["knee.swing_flexion.theta_e_deg"]] = 1.0
            J[r, col["knee.swing_flexion.k_Nm_per_rad"]] = -0.5 * (x - theta_e)
        elif q.key == "knee_swing_flexion_peak_phase_pct":
            J[r, col["knee.swing_flexion.k_Nm_per_rad"]] = -0.5 * max(x - toe, 1.0)
        elif q.key == "ankle_plantarflexion_peak_deg":
            J[r, col["ankle.stance_extension.theta_e_deg"]] = 1.0
        elif q.key == "ankle_plantarflexion_peak_phase_pct":
            J[r, col["ankle.swing_flexion.k_Nm_per_rad"]] = -0.5 * max(x - toe, 1.0)
    return J


def acted_errors(evidence: NodeEvidence, skip: frozenset[str] = frozenset()) -> np.ndarray:
    """Per quantity, the error the step acts on: the mean error where the evidence supports acting (and the quantity
    is not in ``skip``), else 0 (the quantity is held where it is)."""
    return np.array([q_ev.error if (q_ev := evidence.quantities[q.key]).act and q_ev.error is not None
                     and q.key not in skip else 0.0 for q in QUANTITIES])


def node_step(evidence: NodeEvidence, table: ParameterTable, rules: RefineRules,
              J: np.ndarray | None = None, skip: frozenset[str] = frozenset()) -> np.ndarray:
    """The damped least-squares step of :data:`PARAMETERS` (deg or ln|k|) for one node (module docstring); zeros when
    no quantity is acted on. ``J`` overrides the spring model's sensitivity (tests, studies); quantities in ``skip``
    are held instead of moved."""
    J = sensitivity(evidence, table) if J is None else np.asarray(J, dtype=float)
    e = acted_errors(evidence, skip)
    if not np.any(e):
        return np.zeros(len(PARAMETERS))
    tol = np.array([q.tolerance for q in QUANTITIES])
    steps = np.array([rules.step(p) for p in PARAMETERS])
    A = (J * steps[None, :]) / tol[:, None]      # in scaled parameters u = Δ / step
    b = -e / tol
    u = np.linalg.solve(A.T @ A + rules.damping ** 2 * np.eye(len(PARAMETERS)), A.T @ b)
    delta = np.clip(u, -1.0, 1.0) * steps
    resolution = np.array([math.log(1.01) if p.stiffness else 0.1 for p in PARAMETERS])
    delta[np.abs(delta) < resolution] = 0.0
    return delta


def _clamp(p: Parameter, value: float, table: ParameterTable, limits: SafetyLimits) -> float:
    """A refined value held inside every limit that applies to it."""
    if p.stiffness:
        stance = p.subphase.startswith("stance")
        rng = limits.stance_k_Nm_per_rad if stance else limits.k_Nm_per_rad
        value = min(max(value, rng.low), rng.high)
        if p.field == "knee.stance_flexion.k_Nm_per_rad":
            value = min(value, support_floor_Nm_per_rad(table.body_mass_kg, limits))
        return value
    rng = limits.knee_theta_e_deg if p.joint == "knee" else limits.ankle_theta_e_deg
    return min(max(value, rng.low), rng.high)


def _words(evidence: NodeEvidence, skip: frozenset[str] = frozenset()) -> str:
    """What the node's strides say, in clinical words ("swing knee flexion 7.0° short")."""
    parts = []
    for q in QUANTITIES:
        ev = evidence.quantities[q.key]
        if not ev.act or ev.error is None or q.key in skip:
            continue
        if q.part == "value":   # a peak of flexion (max) is short below its target, one of plantarflexion (min) above
            short = (ev.error < 0) == (FEATURES_BY_NAME[q.feature].kind == "max")
            parts.append(f"{q.label} {abs(ev.error):.1f}° {'short' if short else 'too much'}")
        else:
            parts.append(f"{q.label} {abs(ev.error):.1f} % of the cycle {'early' if ev.error < 0 else 'late'}")
    return "; ".join(parts)


NOT_RESPONDING_RATIO = 0.25


@dataclass(frozen=True)
class NodeRefinement:
    """One node's refined table (or the unchanged one) and the changes, each ``{"field", "before", "after", "why"}``;
    ``expected_error``: per quantity acted on, the error the spring model expects after the step; ``not_responding``:
    quantities held because the last round's change did not move them (see :func:`not_responding`)."""

    table: ParameterTable
    changes: list[dict]
    left_alone: str | None
    expected_error: dict[str, float] = field(default_factory=dict)
    not_responding: dict[str, str] = field(default_factory=dict)


def not_responding(evidence: NodeEvidence, previous: dict | None) -> dict[str, str]:
    """Quantities the previous round acted on that moved less than :data:`NOT_RESPONDING_RATIO` of what it expected
    (or the wrong way): their sensitivity is not what the spring model says, so they are held and left to the
    prosthetist rather than pushed again (the loop settles instead of chasing). ``previous``: the previous round's
    summary of this node (``quantities`` → ``error``, ``expected_error``)."""
    out: dict[str, str] = {}
    if not previous:
        return out
    for key, prev in (previous.get("quantities") or {}).items():
        before, expected = prev.get("error"), prev.get("expected_error")
        now = evidence.quantities[key].error if key in evidence.quantities else None
        if before is None or expected is None or now is None or abs(before - expected) < 1e-9:
            continue
        ratio = (before - now) / (before - expected)
        if ratio < NOT_RESPONDING_RATIO:
            out[key] = (f"the last change was expected to move it {expected - before:+.1f} and it moved "
                        f"{now - before:+.1f}: its sensitivity is not the spring model's; held, for the prosthetist")
    return out


def refine_node(table: ParameterTable, evidence: NodeEvidence, rules: RefineRules,
                J: np.ndarray | None = None, previous: dict | None = None) -> NodeRefinement:
    """The node's table moved by one round (module docstring), or unchanged with the reason. ``previous``: this node's
    summary from the round before, if any (:func:`not_responding`)."""
    if evidence.strides == 0:
        return NodeRefinement(table, [], "no strides near this node: left as it was")
    held = not_responding(evidence, previous)
    skip = frozenset(held)
    delta = node_step(evidence, table, rules, J, skip)
    words = _words(evidence, skip)
    if not words:
        reasons = sorted({q.reason for q in evidence.quantities.values()} | set(held.values()))
        return NodeRefinement(table, [], "nothing to act on: " + "; ".join(reasons), not_responding=held)
    J_used = sensitivity(evidence, table) if J is None else np.asarray(J, dtype=float)
    e = acted_errors(evidence, skip)
    after = e + J_used @ delta
    expected = {q.key: float(after[k]) for k, q in enumerate(QUANTITIES) if e[k] != 0.0}
    edits: dict[tuple[str, str], dict] = {}
    why: dict[str, str] = {}
    for p, d in zip(PARAMETERS, delta, strict=True):
        if d == 0.0:
            continue
        old = _value(table, p)
        new = _clamp(p, old * math.exp(d) if p.stiffness else old + d, table, rules.limits)
        if abs(new - old) < 1e-9:
            continue
        edits.setdefault((p.joint, p.subphase), {"joint": p.joint, "subphase": p.subphase})[
            p.field.split(".")[2]] = new
        change = f"{100 * (new / old - 1):+.0f} %" if p.stiffness else f"{new - old:+.1f}°"
        at = f"{evidence.speed_mps:.2f} m/s, {evidence.incline_deg:+.1f}°"
        why[p.field] = f"{words} at {at}: {p.label} {change}"
    thresholds = _swing_threshold(table, evidence, delta, rules)
    if not edits and not thresholds:
        return NodeRefinement(table, [], f"{words}, but the step rounds to nothing within the limits",
                              not_responding=held)
    try:
        new_table, changes = edit_table(table, list(edits.values()), thresholds, method="refined", source="refinement")
    except EditError as err:
        return NodeRefinement(table, [], f"no change: {err}", not_responding=held)
    violations = check_table(new_table, rules.limits)
    if violations:   # not reached by construction (values are clamped); refused rather than quietly corrected
        return NodeRefinement(table, [], "the refined rows would break a limit: " + "; ".join(
            v.message for v in violations), not_responding=held)
    for c in changes:
        c["why"] = why.get(c["field"], "the swing threshold follows the expected swing knee peak (85 %, as the "
                                       "table rule)")
    return NodeRefinement(new_table, changes, None, expected, held)


def _swing_threshold(table: ParameterTable, evidence: NodeEvidence, delta: np.ndarray, rules: RefineRules
                     ) -> dict[str, float]:
    """The WF→WE threshold at ``swing_threshold_fraction`` of the swing knee peak the leg is expected to reach after
    the step (measured peak plus the step's predicted change), when that peak was measured on enough strides."""
    ev = evidence.quantities["knee_swing_flexion_peak_deg"]
    if ev.effective_strides < 10.0 or "knee_swing_flexion_peak_deg" not in evidence.measured:
        return {}
    J = sensitivity(evidence, table)
    row = [q.key for q in QUANTITIES].index("knee_swing_flexion_peak_deg")
    expected = evidence.measured["knee_swing_flexion_peak_deg"] + float(J[row] @ delta)
    value = round(rules.swing_threshold_fraction * expected, 2)
    current = table.thresholds.wf_to_we_knee_angle_deg
    return {"wf_to_we_knee_angle_deg": value} if abs(value - current) > 1.0 else {}


@dataclass(frozen=True)
class EnvelopeRefinement:
    """A refined envelope with, per node, its evidence and changes (``held_from`` where the neighbour rule moved a
    value back), and the nodes left alone with why."""

    envelope: Envelope
    nodes: list[dict]
    changes: list[dict]


def refine_envelope(envelope: Envelope, evidence: Sequence[NodeEvidence], rules: RefineRules | None = None,
                    previous: Sequence[dict] | None = None) -> EnvelopeRefinement:
    """One round of refinement of every node (speed-major ``evidence``, one per node), then the neighbour rule.
    ``previous``: the node summaries of the round that made ``envelope`` (:attr:`EnvelopeRefinement.nodes`), if it
    was one, so that quantities its changes did not move are held (:func:`not_responding`)."""
    rules = rules or RefineRules()
    if len(evidence) != len(envelope.nodes):
        raise ValueError(f"evidence for {len(evidence)} nodes; the envelope has {len(envelope.nodes)}")
    before = {tuple(n["node"]): n for n in previous or ()}
    per_node = [refine_node(n.table, ev, rules, previous=before.get(ev.node))
                for n, ev in zip(envelope.nodes, evidence, strict=True)]
    wanted = [table_values(r.table) for r in per_node]
    start = max(range(len(evidence)), key=lambda k: evidence[k].weight)
    held = neighbour_guard(envelope.shape, wanted, divmod(start, len(envelope.inclines_deg)), envelope.neighbour_steps)
    nodes, summary, changes = [], [], []
    for _idx, (node, r, ev, want, keep) in enumerate(zip(envelope.nodes, per_node, evidence, wanted, held, strict=True)):
        table, moved = table_with_values(r.table, keep, want)
        nodes.append(EnvelopeNode(speed_mps=node.speed_mps, incline_deg=node.incline_deg, table=table,
                                  extrapolation=node.extrapolation, feature_std=node.feature_std,
                                  neighbour_guarded={**node.neighbour_guarded, **moved}))
        walked = ev.strides > 0
        why = {c["field"]: c["why"] for c in r.changes}
        node_changes = []
        for f, before, after in zip(VALUE_FIELDS, table_values(node.table), table_values(table), strict=True):
            if before == after:
                continue
            c = {"node": list(ev.node), "speed_mps": node.speed_mps, "incline_deg": node.incline_deg, "field": f,
                 "before": before, "after": after, "walked": walked,
                 "why": why.get(f, "moved only to hold the neighbour rule")}
            if f in moved:
                c["held_from"] = moved[f]
            node_changes.append(c)
        changes += node_changes
        node_json = ev.to_json()
        for key, q in node_json["quantities"].items():
            q["expected_error"] = None if key not in r.expected_error else round(r.expected_error[key], 3)
            if key in r.not_responding:
                q["act"], q["reason"] = False, r.not_responding[key]
        summary.append({**node_json, "changed": bool(node_changes),
                        "left_alone": None if node_changes else (r.left_alone or "no change")})
    return EnvelopeRefinement(envelope.model_copy(update={"nodes": nodes}), summary, changes)


def quantity_units() -> dict[str, str]:
    """Each quantity's unit, for people: deg or % of the gait cycle."""
    return {q.key: ("deg" if q.part == "value" else "% gait cycle") for q in QUANTITY_BY_KEY.values()}
