"""Refinement from walking: a damped least-squares step of a node's rows towards the feature targets.

Per node, the quantities its strides support acting on (:mod:`controller_core.refine_evidence`) are moved towards
their targets by changing the table values in :data:`PARAMETERS`: each stance and swing equilibrium angle, stiffness
and damping that the bench shows moving a controlled quantity (knee stance flexion: its equilibrium angle and
stiffness, and the terminal-swing row's equilibrium angle and damping, which set how the knee lands; swing knee
flexion and its timing: the swing-flexion row's angle, stiffness and damping, and the terminal-swing damping; push-off:
the ankle's stance-extension angle and stiffness, and its swing stiffness).

**Where the sensitivity comes from: the simulated bench**, measured once per task of a grid and shipped
(:mod:`controller_core.refine_sensitivity`, ``quasitune sensitivity``): the central difference of each quantity for a
small change of each value, walked on the nominal leg at the node's task. Chosen over a model of the sub-phase spring
(a feature moving one for one with its own row's θe), which this project used first and which the bench showed wrong
where it matters: the stance knee peak moves about 0.2° per degree of the stance-flexion θe but 0.75° per degree of the
terminal-swing θe and about 2° per 10 % of terminal-swing damping (the knee lands more or less flexed); the swing peak's
timing hardly follows any one row within a step (:func:`out_of_reach`), though larger joint changes of several rows do
move it (docs/results.md). Chosen over the session's
own variation, which does not span the parameters (every stride of a session runs the same rows). The bench
sensitivity costs nothing at refinement time.

**When the sensitivity is wrong** (every patient's leg is not the nominal one). For one quantity the step is e/g_model,
so the next error is e(1 − g_true/g_model): it shrinks monotonically while the true gain lies between 0 and the
model's, oscillates but shrinks up to twice it, and grows only beyond twice it or with the wrong sign. The damping term
and the step limits bound any one round, each round re-measures, and a quantity that moved less than a quarter of what
was expected (or the wrong way) is held for the prosthetist instead of pushed again (:func:`not_responding`): the loop
settles rather than chases.

**The step.** Minimise Σ_q ((e_q + J_q Δ)/tol_q)² + λ² Σ_p (Δ_p/step_p)² (Levenberg–Marquardt with the parameters
scaled by their step), quantities not acted on held (e_q = 0 keeps them where they are), then each Δ clipped to its
step: :attr:`RefineRules.theta_step_deg` (5°) for θe, :attr:`RefineRules.k_step_fraction` (25 %) for k and b, per
round. The sensitivity was measured over ±3° and ×/÷1.25 and is not known beyond (moving the terminal-swing θe 5° down
from the nominal 8° lands the knee straight and delays push-off 8 % of the cycle on the bench, where ±3° around it is
smooth), so where a bench is at hand (the API, the loop on the bench) each node's step is walked before it is taken
(``check``: more falls, strides turned irregular, or a change the sensitivity did not expect): one the bench does not
confirm is halved, then quartered, then left out with why. (A fixed 3° limit
instead cost the heavy-footed leg most of its stance-knee correction in two rounds.) Changes below 0.1° or 1 % are
dropped. The result is clamped into every limit (joint ranges, stance k ≤ 0 (kept by scaling k), the knee's stance
support floor, damping ≥ 0), and the swing threshold follows the expected swing knee peak (85 % of it, the table rule).
Nodes no stride reached stay as they were; the neighbour rule is then held by moving the least
(:func:`controller_core.envelope.neighbour_guard`, sweeping out from the node walked most), and every value so moved is
marked ``neighbour_guard`` with what the refinement gave.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from controller_core.envelope import (
    VALUE_FIELDS,
    Envelope,
    EnvelopeNode,
    grid_neighbours,
    neighbour_guard,
    table_values,
    table_with_values,
)
from controller_core.features import FEATURES_BY_NAME
from controller_core.refine_evidence import QUANTITIES, NodeEvidence, Quantity
from controller_core.refine_search import (
    TOLERANCES,
    EnvelopeBench,
    NodeBench,
    SearchTrace,
    TrustRegionSearch,
    feature_vector,
    search_rows,
)
from controller_core.refine_sensitivity import BenchSensitivity, load_sensitivity
from controller_core.table import DEFAULT_LIMITS, ParameterTable, SafetyLimits, check_table, support_floor_Nm_per_rad
from controller_core.table_edit import EditError, edit_table


@dataclass(frozen=True)
class Parameter:
    """A refined table value: ``field`` as in :data:`controller_core.envelope.VALUE_FIELDS`; stiffnesses and damping
    are stepped in ln|value| (their change is relative), equilibrium angles in deg."""

    field: str
    label: str

    @property
    def joint(self) -> str:
        return self.field.split(".")[0]

    @property
    def subphase(self) -> str:
        return self.field.split(".")[1]

    @property
    def attr(self) -> str:
        return self.field.split(".")[2]

    @property
    def stiffness(self) -> bool:
        return self.attr == "k_Nm_per_rad"

    @property
    def relative(self) -> bool:
        """Stepped in ln|value|: stiffness and damping."""
        return self.attr in ("k_Nm_per_rad", "b_Nm_s_per_rad")

    def value_in(self, table: ParameterTable) -> float:
        """This value in ``table``."""
        return float(getattr(table.row(self.joint, self.subphase), self.attr))

    def stepping(self, value: float) -> float:
        """A value in the stepping unit: ln|value| (k, b) or deg (θe)."""
        return math.log(abs(value)) if self.relative else value

    def moved(self, value: float, step: float) -> float:
        """``value`` moved by ``step`` in the stepping unit."""
        return value * math.exp(step) if self.relative else value + step


PARAMETERS: tuple[Parameter, ...] = (
    Parameter("knee.stance_flexion.theta_e_deg", "knee stance-flexion equilibrium angle"),
    Parameter("knee.stance_flexion.k_Nm_per_rad", "knee stance-flexion stiffness"),
    Parameter("knee.swing_flexion.theta_e_deg", "knee swing-flexion equilibrium angle"),
    Parameter("knee.swing_flexion.k_Nm_per_rad", "knee swing-flexion stiffness"),
    Parameter("knee.swing_flexion.b_Nm_s_per_rad", "knee swing-flexion damping"),
    Parameter("knee.swing_extension.theta_e_deg", "knee terminal-swing (landing) equilibrium angle"),
    Parameter("knee.swing_extension.b_Nm_s_per_rad", "knee terminal-swing damping"),
    Parameter("ankle.stance_extension.theta_e_deg", "ankle push-off equilibrium angle"),
    Parameter("ankle.stance_extension.k_Nm_per_rad", "ankle push-off stiffness"),
    Parameter("ankle.swing_flexion.k_Nm_per_rad", "ankle swing stiffness"),
)
SWING_THRESHOLD = "thresholds.wf_to_we_knee_angle_deg"
RESOLUTION = np.array([math.log(1.01) if p.relative else 0.1 for p in PARAMETERS])   # smaller changes are dropped


@dataclass(frozen=True)
class RefineRules:
    """Hyperparameters of the update (module docstring).

    Args:
        damping: λ of the Levenberg–Marquardt step, in units of one step limit per tolerance.
        theta_step_deg: the most an equilibrium angle moves in one round (deg).
        k_step_fraction: the most a stiffness or a damping changes in one round (fraction of its magnitude).
        swing_threshold_fraction: the WF→WE knee threshold as a fraction of the expected swing peak (the table rule's).
        limits: the safety limits the result must pass.
        sensitivity: the sensitivity grid (:class:`controller_core.refine_sensitivity.BenchSensitivity`); None: the
            one shipped with QuasiTune, measured on the bench.
    """

    damping: float = 1.0
    theta_step_deg: float = 5.0
    k_step_fraction: float = 0.25
    swing_threshold_fraction: float = 0.85
    limits: SafetyLimits = field(default_factory=lambda: DEFAULT_LIMITS)
    sensitivity: BenchSensitivity | None = None

    def __post_init__(self) -> None:
        for name in ("damping", "theta_step_deg", "k_step_fraction", "swing_threshold_fraction"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a positive finite number, got {v!r}")
        if self.k_step_fraction >= 1.0 or self.swing_threshold_fraction > 1.0:
            raise ValueError("k_step_fraction must be below 1 and swing_threshold_fraction at most 1")

    def step(self, p: Parameter) -> float:
        """A parameter's step limit per round, in its stepping unit (deg, or ln|value|)."""
        return math.log1p(self.k_step_fraction) if p.relative else self.theta_step_deg

    def sensitivity_at(self, speed_mps: float, incline_deg: float) -> np.ndarray:
        """The (quantities × parameters) sensitivity at a task, from :attr:`sensitivity` or the shipped grid."""
        grid = self.sensitivity or load_sensitivity()
        grid.check_names(tuple(p.field for p in PARAMETERS), tuple(q.key for q in QUANTITIES))
        return grid.at(speed_mps, incline_deg)


def sensitivity(evidence: NodeEvidence, rules: RefineRules) -> np.ndarray:
    """(quantities × parameters) sensitivity of :data:`QUANTITIES` to :data:`PARAMETERS` at the node's task, from the
    bench (module docstring); a quantity the strides did not measure has a zero row."""
    J = rules.sensitivity_at(evidence.speed_mps, evidence.incline_deg).copy()
    for r, q in enumerate(QUANTITIES):
        if q.key not in evidence.measured:
            J[r, :] = 0.0
    return J


def acted_errors(evidence: NodeEvidence, skip: frozenset[str] = frozenset()) -> np.ndarray:
    """Per quantity, the error the step acts on: the mean error where the evidence supports acting (and the quantity
    is not in ``skip``), else 0 (the quantity is held where it is)."""
    return np.array([q_ev.error if (q_ev := evidence.quantities[q.key]).act and q_ev.error is not None
                     and q.key not in skip else 0.0 for q in QUANTITIES])


def node_step(evidence: NodeEvidence, table: ParameterTable, rules: RefineRules,
              J: np.ndarray | None = None, skip: frozenset[str] = frozenset()) -> np.ndarray:
    """The damped least-squares step of :data:`PARAMETERS` (deg or ln|k|) for one node (module docstring); zeros when
    no quantity is acted on. ``J`` overrides the bench sensitivity (tests, studies); quantities in ``skip`` are held
    instead of moved."""
    J = sensitivity(evidence, rules) if J is None else np.asarray(J, dtype=float)
    e = acted_errors(evidence, skip)
    if not np.any(e):
        return np.zeros(len(PARAMETERS))
    steps = np.array([rules.step(p) for p in PARAMETERS])
    A = (J * steps[None, :]) / TOLERANCES[:, None]      # in scaled parameters u = Δ / step
    b = -e / TOLERANCES
    u = np.linalg.solve(A.T @ A + rules.damping ** 2 * np.eye(len(PARAMETERS)), A.T @ b)
    delta = np.clip(u, -1.0, 1.0) * steps
    delta[np.abs(delta) < RESOLUTION] = 0.0
    return delta


def clamp_value(p: Parameter, value: float, table: ParameterTable, limits: SafetyLimits) -> float:
    """A value of ``p`` held inside every limit that applies to it (range, stance k ≤ 0, the knee's support floor,
    damping ≥ 0)."""
    if p.stiffness:
        stance = p.subphase.startswith("stance")
        rng = limits.stance_k_Nm_per_rad if stance else limits.k_Nm_per_rad
        value = min(max(value, rng.low), rng.high)
        if p.field == "knee.stance_flexion.k_Nm_per_rad":
            value = min(value, support_floor_Nm_per_rad(table.body_mass_kg, limits))
        return value
    if p.relative:
        rng = limits.b_Nm_s_per_rad
    else:
        rng = limits.knee_theta_e_deg if p.joint == "knee" else limits.ankle_theta_e_deg
    return min(max(value, rng.low), rng.high)


def _quantity_words(q: Quantity, error: float) -> str:
    """One quantity's error in clinical words ("swing knee flexion 7.0° short")."""
    if q.part == "value":   # a peak of flexion (max) is short below its target, one of plantarflexion (min) above
        short = (error < 0) == (FEATURES_BY_NAME[q.feature].kind == "max")
        return f"{q.label} {abs(error):.1f}° {'short' if short else 'too much'}"
    return f"{q.label} {abs(error):.1f} % of the cycle {'early' if error < 0 else 'late'}"


def _words(evidence: NodeEvidence, skip: frozenset[str] = frozenset()) -> str:
    """What the node's strides say, in clinical words ("swing knee flexion 7.0° short")."""
    return "; ".join(_quantity_words(q, ev.error) for q in QUANTITIES
                     if (ev := evidence.quantities[q.key]).act and ev.error is not None and q.key not in skip)


def _value_words(e: np.ndarray, J: np.ndarray, delta: np.ndarray, column: int, joint: str | None = None) -> str:
    """Why one value changed, in clinical words: the acted-on quantities its own change moves towards their targets
    (each at least a third of the value's largest such contribution, in tolerances), those of the value's own
    ``joint`` named first (a knee row is explained by the knee where it moves the knee), or, when it moves none, that
    it holds what the other changes would disturb."""
    towards = -np.sign(e) * J[:, column] * delta[column] / TOLERANCES   # > 0: this change moves q towards its target
    towards[e == 0.0] = 0.0
    if np.max(towards, initial=0.0) > 0.0:
        keep = [k for k in np.argsort(-towards) if towards[k] >= max(towards) / 3.0]
        keep.sort(key=lambda k: QUANTITIES[k].feature.split("_")[0] != joint)   # stable: own joint first
        return "; ".join(_quantity_words(QUANTITIES[k], float(e[k])) for k in keep)
    side = -J[:, column] * delta[column] / TOLERANCES                   # what it counters of the others' side effects
    k = int(np.argmax(np.abs(side)))
    return f"holds {QUANTITIES[k].label} while the other values change"


NOT_RESPONDING_RATIO = 0.25
REACH_FRACTION = 0.25   # a quantity one round would move by less than this fraction of its error is out of reach


@dataclass(frozen=True)
class NodeRefinement:
    """One node's refined table (or the unchanged one) and the changes, each ``{"field", "before", "after", "why"}``;
    ``expected_error``: per quantity acted on, the error the sensitivity expects after the step; ``not_responding``:
    quantities held, with why: the last round's change did not move them (:func:`not_responding`), or a round's step
    barely moves them (:func:`out_of_reach`, also listed in ``out_of_reach``); ``step_scale``: the fraction of
    the step taken (below 1 where the check refused a larger one, ``step_refused`` saying why); ``search``: what a
    search on the bench did, where one was made, and ``unreached``: the quantities it left beyond their tolerance."""

    table: ParameterTable
    changes: list[dict]
    left_alone: str | None
    expected_error: dict[str, float] = field(default_factory=dict)
    not_responding: dict[str, str] = field(default_factory=dict)
    out_of_reach: frozenset[str] = frozenset()
    step_scale: float = 1.0
    step_refused: str | None = None
    search: SearchTrace | None = None
    unreached: dict[str, str] = field(default_factory=dict)


def not_responding(evidence: NodeEvidence, previous: dict | None) -> dict[str, str]:
    """Quantities the previous round acted on that moved less than :data:`NOT_RESPONDING_RATIO` of what it expected
    (or the wrong way): their sensitivity on this leg is not the bench's, so they are held and left to the
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
                        f"{now - before:+.1f}: this leg does not respond as the bench does; held, for the prosthetist")
    return out


def out_of_reach(evidence: NodeEvidence, table: ParameterTable, rules: RefineRules, J: np.ndarray,
                 skip: frozenset[str]) -> dict[str, str]:
    """Quantities the step would move by less than :data:`REACH_FRACTION` of their error (and less than their tolerance:
    a large error limited by the step limits is reachable over rounds) while holding the others:
    a round's step barely moves them on the bench (the swing knee peak's timing, mostly), so they are held and named
    for the prosthetist instead of nudging every row for a small gain. Not a claim that no table could: on the bench,
    changes of several rows far beyond one round's limits do move the timing (docs/results.md).
    Decided one at a time, the least reachable first, re-stepping without it."""
    out: dict[str, str] = {}
    while True:
        held = skip | frozenset(out)
        e = acted_errors(evidence, held)
        if not np.any(e):
            return out
        after = e + J @ node_step(evidence, table, rules, J, held)
        moved = np.abs(e) - np.abs(after)
        gain = np.where((e != 0.0) & (moved < TOLERANCES), moved / np.where(e != 0.0, np.abs(e), 1.0), np.inf)
        k = int(np.argmin(gain))
        if gain[k] >= REACH_FRACTION:
            return out
        q = QUANTITIES[k]
        out[q.key] = (f"{e[k]:+.1f}{q.unit_text} off, but a round's step moves it little on the bench (one round "
                      f"would leave {after[k]:+.1f}{q.unit_text} while holding the rest): beyond this refinement's "
                      "reach here; for the prosthetist (alignment, the socket, how the person walks, or larger changes "
                      "by hand, previewed on the bench)")


StepCheck = Callable[[NodeEvidence, ParameterTable, ParameterTable, dict[str, float]], str | None]
STEP_SCALES = (1.0, 0.5, 0.25)   # a step the check refuses is tried at half, then a quarter, then left out


def refine_node(table: ParameterTable, evidence: NodeEvidence, rules: RefineRules,
                J: np.ndarray | None = None, previous: dict | None = None,
                check: StepCheck | None = None, bench: NodeBench | None = None,
                search: TrustRegionSearch | None = None,
                allowed: tuple[list[float], list[float]] | None = None, aim_from: NodeBench | None = None,
                task: tuple[float, float] | None = None) -> NodeRefinement:
    """The node's table moved by one round (module docstring), or unchanged with the reason. ``previous``: this node's
    summary from the round before, if any (:func:`not_responding`). ``check``: called with (evidence, old table, new
    table, the change of each quantity the sensitivity expects), returns None to accept the step or why not; a
    refused step is tried at :data:`STEP_SCALES` and, refused at all of them, not taken (the bench's
    :class:`device_bridge.bench.refine_walks.BenchStepCheck`: the sensitivity holds only near where it was measured).
    ``bench``: where given, the rows are searched on it instead (:mod:`controller_core.refine_search`, with ``search``'s
    settings or the defaults, within ``allowed``: the lowest and highest value of each of
    :data:`controller_core.envelope.VALUE_FIELDS` the node's neighbours allow, walked at ``task``, default the
    node's, aiming at what ``aim_from`` gives of the node's rows there minus the bias, default ``bench``) and ``check``
    is not used."""
    if evidence.strides == 0:
        return NodeRefinement(table, [], "no strides near this node: left as it was")
    held = not_responding(evidence, previous)
    J_used = sensitivity(evidence, rules) if J is None else np.asarray(J, dtype=float)
    if bench is not None:
        return _searched_node(table, evidence, rules, J_used, held, bench, search or TrustRegionSearch(), allowed,
                              aim_from, task)
    reach = out_of_reach(evidence, table, rules, J_used, frozenset(held))
    held.update(reach)
    skip = frozenset(held)
    full = node_step(evidence, table, rules, J_used, skip)
    words = _words(evidence, skip)
    if not words:
        reasons = sorted({q.reason for q in evidence.quantities.values()} | set(held.values()))
        return NodeRefinement(table, [], "nothing to act on: " + "; ".join(reasons), not_responding=held,
                              out_of_reach=frozenset(reach))
    refused = ""
    for scale in STEP_SCALES if check is not None else (1.0,):
        made = _stepped(table, evidence, full * scale, J_used, acted_errors(evidence, skip), rules, words)
        if isinstance(made, str):
            return NodeRefinement(table, [], made, not_responding=held, out_of_reach=frozenset(reach))
        new_table, changes, expected, change = made
        why_not = check(evidence, table, new_table, change) if check is not None else None
        if why_not is None:
            if scale < 1.0:   # said once, on the node's first change (and in its summary), not on every value
                changes[0]["why"] += f" (the node's step at {100 * scale:.0f} %: the bench refused a larger one: {refused})"
            return NodeRefinement(new_table, changes, None, expected, held, frozenset(reach), scale,
                                  refused or None)
        refused = why_not
    return NodeRefinement(table, [], f"{words}, but the bench did not confirm the step, even at a quarter: {refused}",
                          not_responding=held, out_of_reach=frozenset(reach))


def _searched_node(table: ParameterTable, evidence: NodeEvidence, rules: RefineRules, J: np.ndarray,
                   held: dict[str, str], bench: NodeBench, search: TrustRegionSearch,
                   allowed: tuple[list[float], list[float]] | None, aim_from: NodeBench | None = None,
                   task: tuple[float, float] | None = None) -> NodeRefinement:
    """The node's rows found by a search on ``bench`` (:func:`refine_node`)."""
    skip = frozenset(held)
    words = _words(evidence, skip)
    if not words:
        reasons = sorted({q.reason for q in evidence.quantities.values()} | set(held.values()))
        return NodeRefinement(table, [], "nothing to act on: " + "; ".join(reasons), not_responding=held)
    e = acted_errors(evidence, skip)
    steps = np.array([rules.step(p) for p in PARAMETERS])

    def apply(delta: np.ndarray) -> tuple[ParameterTable, np.ndarray] | str:
        made = _stepped(table, evidence, delta, J, e, rules, words)
        return made if isinstance(made, str) else (made[0], taken_step(table, made[0]))

    box = None if allowed is None else step_box(table, *allowed)
    task = task or (evidence.speed_mps, evidence.incline_deg)
    aim = None if aim_from is None else feature_vector(aim_from.errors(table, *task)) - e
    found, trace = search_rows(table, e, J, steps, RESOLUTION, apply, bench, task, search, box, aim)
    if found is table:
        return NodeRefinement(table, [], f"{words}, but no rows the bench walked came closer ({trace.walks} walks on "
                              f"the {bench.leg} leg; {trace.stopped})", not_responding=held, search=trace)
    made = _stepped(table, evidence, trace.proposal, J, e, rules, words)   # the call that built the rows kept
    if isinstance(made, str) or table_values(made[0]) != table_values(found):   # not reached
        return NodeRefinement(table, [], "the rows the bench kept could not be rebuilt", not_responding=held,
                              search=trace)
    new_table, changes, _, _ = made
    moved = trace.after - trace.before
    expected = {q.key: float(e[k] + moved[k]) for k, q in enumerate(QUANTITIES) if e[k] != 0.0 and np.isfinite(moved[k])}
    unreached = {q.key: (f"{e[k]:+.1f}{q.unit_text} off; the bench's search on the {bench.leg} leg moved it "
                         f"{moved[k]:+.1f}{q.unit_text} ({trace.stopped}): the rest is for the prosthetist")
                 for k, q in enumerate(QUANTITIES) if e[k] != 0.0 and np.isfinite(moved[k])
                 and abs(e[k] + moved[k]) > q.tolerance}
    return NodeRefinement(new_table, changes, None, expected, held, search=trace, unreached=unreached)


def step_box(table: ParameterTable, low: Sequence[float], high: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
    """Per :data:`PARAMETERS`, the lowest and highest step (stepping units) that keeps its value within ``low`` and
    ``high`` (each in :data:`controller_core.envelope.VALUE_FIELDS` order); unbounded where a relative value's
    interval reaches across zero."""
    lo, hi = np.full(len(PARAMETERS), -np.inf), np.full(len(PARAMETERS), np.inf)
    for c, p in enumerate(PARAMETERS):
        f = VALUE_FIELDS.index(p.field)
        v = p.value_in(table)
        if not p.relative:
            lo[c], hi[c] = low[f] - v, high[f] - v
        elif v != 0.0:
            a, b = sorted((low[f] / v, high[f] / v))
            lo[c] = math.log(a) if a > 0.0 else -np.inf
            hi[c] = math.log(b) if b > 0.0 else 0.0
    return lo, hi


def neighbour_box(envelope: Envelope, index: int) -> tuple[list[float], list[float]]:
    """The lowest and highest value of each of :data:`controller_core.envelope.VALUE_FIELDS` that node ``index``
    (speed-major) may take under the envelope's neighbour rule, given its grid neighbours' current values."""
    n_i = envelope.shape[1]
    limits = np.array(envelope.neighbour_steps.for_fields())
    near = [a * n_i + b for a, b in grid_neighbours(envelope.shape, *divmod(index, n_i))]
    if not near:
        return [-np.inf] * len(limits), [np.inf] * len(limits)
    values = np.array([table_values(envelope.nodes[k].table) for k in near])
    return (values.max(axis=0) - limits).tolist(), (values.min(axis=0) + limits).tolist()


def taken_step(before: ParameterTable, after: ParameterTable) -> np.ndarray:
    """Per :data:`PARAMETERS`, how far ``after`` lies from ``before`` in stepping units (deg, or ln|value|)."""
    return np.array([0.0 if (a := p.value_in(after)) == (b := p.value_in(before)) else p.stepping(a) - p.stepping(b)
                     for p in PARAMETERS])


def _stepped(table: ParameterTable, evidence: NodeEvidence, delta: np.ndarray, J: np.ndarray, e: np.ndarray,
             rules: RefineRules, words: str) -> tuple[ParameterTable, list[dict], dict[str, float], dict[str, float]] | str:
    """The table moved by ``delta`` (clamped into the limits) with its changes and why, the errors the sensitivity
    expects after it (acted quantities) and the change it expects of every measured quantity; or why no table."""
    delta = np.where(np.abs(delta) < RESOLUTION, 0.0, delta)
    edits: dict[tuple[str, str], dict] = {}
    why: dict[str, str] = {}
    actual = np.zeros(len(PARAMETERS))
    for c, (p, d) in enumerate(zip(PARAMETERS, delta, strict=True)):
        if d == 0.0:
            continue
        old = p.value_in(table)
        new = clamp_value(p, p.moved(old, d), table, rules.limits)
        if abs(new - old) < 1e-9:
            continue
        actual[c] = p.stepping(new) - p.stepping(old)
        edits.setdefault((p.joint, p.subphase), {"joint": p.joint, "subphase": p.subphase})[p.attr] = new
        change = f"{100 * (new / old - 1):+.0f} %" if p.relative else f"{new - old:+.1f}°"
        at = f"{evidence.speed_mps:.2f} m/s, {evidence.incline_deg:+.1f}°"
        why[p.field] = f"{_value_words(e, J, delta, c, p.joint)} at {at}: {p.label} {change}"
    thresholds = _swing_threshold(table, evidence, actual, rules, J)
    if not edits and not thresholds:
        return f"{words}, but the step rounds to nothing within the limits"
    try:
        new_table, changes = edit_table(table, list(edits.values()), thresholds, method="refined", source="refinement")
    except EditError as err:
        return f"no change: {err}"
    violations = check_table(new_table, rules.limits)
    if violations:   # not reached by construction (values are clamped); refused rather than quietly corrected
        return "the refined rows would break a limit: " + "; ".join(v.message for v in violations)
    for ch in changes:
        ch["why"] = why.get(ch["field"], "the swing threshold follows the expected swing knee peak (85 %, as the "
                                         "table rule)")
    moved = J @ actual
    expected = {q.key: float(e[k] + moved[k]) for k, q in enumerate(QUANTITIES) if e[k] != 0.0}
    change = {q.key: float(moved[k]) for k, q in enumerate(QUANTITIES) if q.key in evidence.measured}
    return new_table, changes, expected, change


def _swing_threshold(table: ParameterTable, evidence: NodeEvidence, delta: np.ndarray, rules: RefineRules,
                     J: np.ndarray) -> dict[str, float]:
    """The WF→WE threshold at ``swing_threshold_fraction`` of the swing knee peak the leg is expected to reach after
    the step (measured peak plus the step's predicted change), when that peak was measured on enough strides."""
    ev = evidence.quantities["knee_swing_flexion_peak_deg"]
    if ev.effective_strides < 10.0 or "knee_swing_flexion_peak_deg" not in evidence.measured:
        return {}
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
                    previous: Sequence[dict] | None = None, check: StepCheck | None = None,
                    bench: NodeBench | None = None, search: TrustRegionSearch | None = None) -> EnvelopeRefinement:
    """One round of refinement of every node (speed-major ``evidence``, one per node), then the neighbour rule.
    ``previous``: the node summaries of the round that made ``envelope`` (:attr:`EnvelopeRefinement.nodes`), if it
    was one, so that quantities its changes did not move are held (:func:`not_responding`). ``check``, ``bench`` and
    ``search``: as in :func:`refine_node`."""
    rules = rules or RefineRules()
    if len(evidence) != len(envelope.nodes):
        raise ValueError(f"evidence for {len(evidence)} nodes; the envelope has {len(envelope.nodes)}")
    before = {tuple(n["node"]): n for n in previous or ()}
    if bench is not None and hasattr(bench, "at_node"):
        per_node = _searched_in_turn(envelope, evidence, rules, before, bench, search or TrustRegionSearch())
    else:
        boxes = [neighbour_box(envelope, k) if bench is not None else None for k in range(len(envelope.nodes))]
        per_node = [refine_node(n.table, ev, rules, previous=before.get(ev.node), check=check, search=search,
                                allowed=box, bench=bench)
                    for n, ev, box in zip(envelope.nodes, evidence, boxes, strict=True)]
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
                q["held"] = "out of reach" if key in r.out_of_reach else "not responding"
            if key in r.unreached:
                q["unreached"] = r.unreached[key]
        if r.search is not None:
            node_json["bench_search"] = {"leg": bench.leg if bench is not None else None, **r.search.to_json()}
        if r.step_refused:
            node_json["step_scale"], node_json["step_refused"] = r.step_scale, r.step_refused
        summary.append({**node_json, "changed": bool(node_changes),
                        "left_alone": None if node_changes else (r.left_alone or "no change")})
    return EnvelopeRefinement(envelope.model_copy(update={"nodes": nodes}), summary, changes)


def _searched_in_turn(envelope: Envelope, evidence: Sequence[NodeEvidence], rules: RefineRules,
                      before: dict[tuple[int, int], dict], bench: EnvelopeBench, search: TrustRegionSearch
                      ) -> list[NodeRefinement]:
    """Every node searched on a bench that walks the envelope as the leg runs it, one node after the other, the most
    walked first (Gauss–Seidel): each search begins from the envelope as the nodes before it left it, within what its
    neighbours now allow, and aims at what the original envelope gave at the node's strides' own task minus the bias
    they measured there. Neighbouring nodes share strides, so searched side by side each would remove the same bias
    and together overshoot it; in turn, a node sees what the ones before it already removed."""
    order = sorted(range(len(evidence)), key=lambda k: -evidence[k].weight)
    current = envelope
    out: list[NodeRefinement | None] = [None] * len(evidence)
    for k in order:
        ev, table = evidence[k], envelope.nodes[k].table
        task = ev.strides_task or (ev.speed_mps, ev.incline_deg)
        aim_from = bench.at_node(envelope, k)
        r = refine_node(table, ev, rules, previous=before.get(ev.node), search=search,
                        allowed=neighbour_box(current, k), bench=bench.at_node(current, k),
                        aim_from=aim_from, task=task)
        out[k] = r
        if r.table is not table:
            nodes = list(current.nodes)
            nodes[k] = nodes[k].model_copy(update={"table": r.table})
            current = current.model_copy(update={"nodes": nodes})
    return [r for r in out if r is not None]


def change_in_steps(changes: Sequence[dict], rules: RefineRules | None = None) -> float:
    """How far a round moved the refined values: the sum over its changes of |change| in units of one round's step limit
    (5° of θe, 25 % of a stiffness or damping), so that rounds compare whatever values they moved."""
    rules = rules or RefineRules()
    by_field = {p.field: p for p in PARAMETERS}
    total = 0.0
    for c in changes:
        p = by_field.get(c["field"])
        if p is None or c["before"] == c["after"]:
            continue
        zero = p.relative and 0.0 in (c["before"], c["after"])      # a damping set to 0 has no ln: its change as is
        moved = abs(c["after"] - c["before"]) if zero else abs(p.stepping(c["after"]) - p.stepping(c["before"]))
        total += moved / rules.step(p)
    return round(total, 3)
