"""Per-node evidence from walking: how far each controlled feature of the leg's strides lies from its target.

Each measured stride (:mod:`controller_core.stride_features`) is compared with the model's prediction at that stride's
task (the leg's own estimate, as the session report uses), and assigned to the envelope's nodes by the bilinear weights
the leg blends them with (:func:`controller_core.envelope_blend.node_weights`): a stride halfway between two nodes
informs each by half. Per node and quantity: the strides used, the weighted mean error (measured − target: the bias,
which the rows can move) with its 95 % interval (t distribution on the effective number of strides, Kish's
(Σw)²/Σw²), the spread from stride to stride (which no row removes: about 0.8 of it stays as mean absolute error even
with no bias), and whether the strides agree. Strides within a task change
(:attr:`controller_core.stride_features.MeasuredStride.transition`) are counted per node but not judged: they are
evidence of the change, not of the node's task.

**The rule for acting on a node's quantity** (in the spirit of the C-Leg set-up software, which proposes a value after
about ten consistent steps): at least :data:`MIN_CONSISTENT_STRIDES` effective strides; at least
:data:`AGREEMENT_FRACTION` of their weight on the same side of the target (the strides agree); the mean error beyond
the quantity's tolerance; and the 95 % interval clear of zero. Anything less leaves the quantity alone and says why;
strides that scatter by more than the tolerance on both sides of the target (a leg that alternates between two kinds
of stride) are reported as disagreeing before their mean is judged.

Tolerances: 2° for peak angles, about one person's stride-to-stride variability of these peaks and what a clinical
goniometer resolves; 2 % of the gait cycle for their timing (20 ms of a 1 s stride).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from controller_core.envelope_blend import node_weights
from controller_core.model import QuasiStiffnessModel
from controller_core.proposal import FeaturePrediction
from controller_core.stride_features import MeasuredStride

MIN_CONSISTENT_STRIDES = 10.0
AGREEMENT_FRACTION = 0.8


@dataclass(frozen=True)
class Quantity:
    """One controlled quantity: a feature's value or its phase, in display units (deg or % of the gait cycle)."""

    feature: str
    part: str            # "value" or "phase"
    key: str             # JSON name, unit last
    tolerance: float     # in the key's unit
    label: str           # clinical words

    @property
    def unit(self) -> str:
        """The display unit's name in JSON: ``deg`` or ``% gait cycle``."""
        return "deg" if self.part == "value" else "% gait cycle"

    @property
    def unit_text(self) -> str:
        """The display unit as it follows a number in words: ``°`` or `` % of the cycle``."""
        return "°" if self.part == "value" else " % of the cycle"

    def display(self, phase: float, value: float) -> float:
        """The quantity of a (phase fraction, value rad) pair, in its display unit."""
        return math.degrees(value) if self.part == "value" else 100.0 * phase


QUANTITIES: tuple[Quantity, ...] = (
    Quantity("knee_stance_flexion_peak", "value", "knee_stance_flexion_peak_deg", 2.0, "stance knee flexion"),
    Quantity("knee_swing_flexion_peak", "value", "knee_swing_flexion_peak_deg", 2.0, "swing knee flexion"),
    Quantity("knee_swing_flexion_peak", "phase", "knee_swing_flexion_peak_phase_pct", 2.0,
             "timing of the swing knee flexion peak"),
    Quantity("ankle_plantarflexion_peak", "value", "ankle_plantarflexion_peak_deg", 2.0, "push-off plantarflexion"),
    Quantity("ankle_plantarflexion_peak", "phase", "ankle_plantarflexion_peak_phase_pct", 2.0,
             "timing of the push-off plantarflexion peak"),
)
QUANTITY_BY_KEY: dict[str, Quantity] = {q.key: q for q in QUANTITIES}


@dataclass(frozen=True)
class QuantityEvidence:
    """What a node's strides say about one quantity (display units, see :class:`Quantity`)."""

    key: str
    strides: int
    effective_strides: float
    measured: float | None           # weighted mean measured value
    target: float | None             # weighted mean target
    error: float | None              # measured − target
    ci95: tuple[float, float] | None
    agreement: float | None          # weight fraction on the side of the mean error
    act: bool
    reason: str
    spread: float | None = None      # stride-to-stride standard deviation of the error: no row moves it

    @property
    def bias(self) -> float | None:
        """The mean signed error: the part the rows can move."""
        return self.error

    def to_json(self) -> dict[str, object]:
        def r(x: float | None) -> float | None:
            return None if x is None else round(float(x), 3)

        return {"quantity": self.key, "strides": self.strides, "effective_strides": round(self.effective_strides, 2),
                "measured": r(self.measured), "target": r(self.target), "error": r(self.error),
                "ci95": None if self.ci95 is None else [r(self.ci95[0]), r(self.ci95[1])],
                "spread": r(self.spread), "agreement": r(self.agreement), "act": self.act, "reason": self.reason}


@dataclass(frozen=True)
class NodeEvidence:
    """A node's evidence: per quantity, and the weighted means the update's spring model reads (measured peak angles in
    deg, phases and toe-off as fractions)."""

    node: tuple[int, int]
    speed_mps: float
    incline_deg: float
    strides: int
    weight: float
    quantities: dict[str, QuantityEvidence]
    measured: dict[str, float]
    transition_strides: int = 0     # strides near the node within a task change: shown, not judged
    strides_task: tuple[float, float] | None = None   # the judged strides' weighted mean task (m/s, deg)

    def to_json(self) -> dict[str, object]:
        return {"node": list(self.node), "speed_mps": self.speed_mps, "incline_deg": self.incline_deg,
                "strides": self.strides, "stride_weight": round(self.weight, 3),
                "transition_strides": self.transition_strides,
                "strides_task": None if self.strides_task is None else {
                    "speed_mps": round(self.strides_task[0], 3), "incline_deg": round(self.strides_task[1], 2)},
                "quantities": {k: q.to_json() for k, q in self.quantities.items()}}


def t_quantile_975(dof: float) -> float:
    """Student's t 97.5 % quantile at ``dof`` degrees of freedom (a 95 % interval's half-width per standard error).
    SciPy's statistics are imported here, when a walk is judged, not when a server or CLI starts."""
    from scipy import stats

    return float(stats.t.ppf(0.975, dof))


def judge(key: str, values: np.ndarray, targets: np.ndarray, weights: np.ndarray) -> QuantityEvidence:
    """The evidence for one quantity from its strides' measured values, targets and weights (module rule)."""
    q = QUANTITY_BY_KEY[key]
    n = int(np.count_nonzero(weights > 0))
    if n == 0:
        return QuantityEvidence(key, 0, 0.0, None, None, None, None, None, False, "no strides near this node")
    w = weights / weights.sum()
    n_eff = float(weights.sum() ** 2 / np.sum(weights ** 2))
    err = values - targets
    mean = float(np.sum(w * err))
    measured, target = float(np.sum(w * values)), float(np.sum(w * targets))
    agree = float(np.sum(w[np.sign(err) == np.sign(mean)])) if mean != 0.0 else 0.0
    if n_eff < 2.0:
        return QuantityEvidence(key, n, n_eff, measured, target, mean, None, agree, False,
                                f"too few strides ({n_eff:.1f} effective; at least {MIN_CONSISTENT_STRIDES:g} needed)")
    var = float(np.sum(w * (err - mean) ** 2)) * n_eff / (n_eff - 1.0)
    half = t_quantile_975(n_eff - 1.0) * math.sqrt(var / n_eff)
    ci = (mean - half, mean + half)
    spread = math.sqrt(var)
    if n_eff < MIN_CONSISTENT_STRIDES:
        reason, act = f"too few strides ({n_eff:.1f} effective; at least {MIN_CONSISTENT_STRIDES:g} needed)", False
    elif agree < AGREEMENT_FRACTION and math.sqrt(var) > q.tolerance:
        reason, act = (f"strides disagree (only {100 * agree:.0f} % on the side of the mean, spread ±"
                       f"{math.sqrt(var):.1f}; {100 * AGREEMENT_FRACTION:.0f} % needed)"), False
    elif abs(mean) <= q.tolerance:
        reason, act = f"within tolerance ({mean:+.1f} against ±{q.tolerance:g})", False
    elif agree < AGREEMENT_FRACTION:
        reason, act = (f"strides disagree (only {100 * agree:.0f} % on the side of the mean; "
                       f"{100 * AGREEMENT_FRACTION:.0f} % needed)"), False
    elif ci[0] <= 0.0 <= ci[1]:
        reason, act = "the 95 % interval includes zero", False
    else:
        reason, act = f"{n_eff:.0f} consistent strides, {100 * agree:.0f} % agree", True
    return QuantityEvidence(key, n, n_eff, measured, target, mean, ci, agree, act, reason, spread)


def gather_evidence(strides: Sequence[MeasuredStride], speeds_mps: Sequence[float], inclines_deg: Sequence[float],
                    targets_at: Callable[[float, float], dict[str, FeaturePrediction]],
                    ) -> list[NodeEvidence]:
    """Per node of the grid (speed-major), the evidence of the strides (module docstring); a grid of one node (one
    table, at its task) takes every stride at full weight.

    Args:
        strides: measured strides with their tasks (strides without a finite task are left out).
        targets_at: (speed m/s, incline deg) → the model's feature predictions there, by name.
    """
    shape = (len(speeds_mps), len(inclines_deg))
    rows: list[tuple[int, int, float, MeasuredStride, dict[str, FeaturePrediction]]] = []
    changing = np.zeros(shape, dtype=int)
    for s in strides:
        if not (math.isfinite(s.speed_mps) and math.isfinite(s.incline_deg)):
            continue
        weights = ([(0, 0, 1.0)] if shape == (1, 1)    # one table: every stride is its evidence
                   else node_weights(speeds_mps, inclines_deg, s.speed_mps, s.incline_deg))
        if s.transition:
            for i, j, _ in weights:
                changing[i, j] += 1
            continue
        targets = targets_at(s.speed_mps, s.incline_deg)
        rows += [(i, j, w, s, targets) for i, j, w in weights]
    out = []
    for i in range(shape[0]):
        for j in range(shape[1]):
            mine = [(w, s, t) for a, b, w, s, t in rows if (a, b) == (i, j)]
            quantities = {}
            measured: dict[str, float] = {}
            for q in QUANTITIES:
                have = [(w, s.features[q.feature], t[q.feature]) for w, s, t in mine if q.feature in s.features]
                w = np.array([h[0] for h in have], dtype=float)
                values = np.array([q.display(*h[1]) for h in have], dtype=float)
                targets = np.array([q.display(h[2].phase, h[2].value) for h in have], dtype=float)
                quantities[q.key] = judge(q.key, values, targets, w) if have else judge(
                    q.key, np.zeros(0), np.zeros(0), np.zeros(0))
                if have:
                    measured[q.key] = float(np.sum(w * values) / w.sum())
                    measured[q.key + ":target"] = float(np.sum(w * targets) / w.sum())
            toe = [(w, s.toe_off_phase) for w, s, _ in mine if math.isfinite(s.toe_off_phase)]
            if toe:
                tw = np.array([t[0] for t in toe])
                measured["toe_off_pct"] = 100.0 * float(np.sum(tw * np.array([t[1] for t in toe])) / tw.sum())
            weight = float(sum(w for w, _, _ in mine))
            task = None if not mine else (sum(w * s.speed_mps for w, s, _ in mine) / weight,
                                          sum(w * s.incline_deg for w, s, _ in mine) / weight)
            out.append(NodeEvidence((i, j), float(speeds_mps[i]), float(inclines_deg[j]), len(mine), weight,
                                    quantities, measured, int(changing[i, j]), task))
    return out


def model_targets(model: QuasiStiffnessModel) -> Callable[[float, float], dict[str, FeaturePrediction]]:
    """The model's feature predictions at a task, by name, cached on a 0.05 m/s × 0.5° lattice (strides this close
    share one target; the predictions change far less than the features' tolerances over it)."""
    cache: dict[tuple[float, float], dict[str, FeaturePrediction]] = {}

    def at(speed_mps: float, incline_deg: float) -> dict[str, FeaturePrediction]:
        key = (round(round(speed_mps / 0.05) * 0.05, 3), round(round(incline_deg / 0.5) * 0.5, 2))
        if key not in cache:
            cache[key] = {f.spec.name: f for f in model.predict_features(*key)}
        return cache[key]

    return at


def feature_abs_errors(strides: Sequence[MeasuredStride],
                       targets_at: Callable[[float, float], dict[str, FeaturePrediction]]) -> dict[str, float | None]:
    """Per controlled quantity (unit in the key), the mean absolute error of the strides against their targets."""
    out: dict[str, float | None] = {}
    for q in QUANTITIES:
        errs = [abs(q.display(*s.features[q.feature]) - q.display(t.phase, t.value))
                for s in strides if q.feature in s.features
                for t in (targets_at(s.speed_mps, s.incline_deg)[q.feature],)]
        out[q.key] = round(float(np.mean(errs)), 3) if errs else None
    return out
