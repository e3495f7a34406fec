"""How a slope changes the gait curves, learned as one person's change from their own level walking.

The only curves on a slope in the shipped data are one participant's (Vielemeyer 2025, Ref01: level walking and
±10° ramps). Their absolute values are one person's, measured in another lab than the speed curves the model is
built on; what they say about slopes is how that person's curves *change* between level and ramp walking. So:

* the change of each ramp condition is taken from the same person's level walking (every level condition
  pooled), with the part that only comes from walking at another speed taken out using the population's speed
  curves (the ramps were walked at a self-selected speed: downhill about 0.2 m/s slower than level);
* per side of level (uphill, downhill) and per phase point, the change per degree is the least-squares slope
  through the origin over that side's ramp conditions, so the change is linear in the incline between level
  and the measured ramps (and keeps growing linearly beyond them, flagged as extrapolation);
* the change is added to the population's level curves at the task's speed (it does not depend on speed: one
  person walked each ramp at one speed, so no speed dependence can be learned).

Uphill and downhill are learned apart because they are different movements (the knee lands flexed uphill and
absorbs the body's descent downhill), not one trend through zero. A side without a ramp condition adds nothing.

Uncertainty: one person's change is one sample of the population's. Its distance from the population's mean
change is of the order of the between-subject spread, which one person cannot show; :meth:`InclineChange.std`
takes the population's between-subject SD of level walking at the task's speed, scaled by |γ| over the measured
ramp (the full SD at ±10°), as that spread. Stride-to-stride variation of the one person is far smaller and is
not what a prosthetist needs to know.

Units as everywhere: phase in [0, 1] on the records' grid, angles in rad, moments in N·m/kg, incline in deg.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from controller_core.reference import ReferenceRecord, ReferenceSet

SIDES: tuple[str, ...] = ("uphill", "downhill")


def _side(incline_deg: float) -> str:
    return "uphill" if incline_deg > 0 else "downhill"


def _pooled_level(records: list[ReferenceRecord], channels: tuple[str, ...]) -> tuple[dict[str, np.ndarray], float]:
    """Stride-weighted mean curves and speed of the level conditions."""
    weights = np.array([max(r.n, 1) for r in records], dtype=float)
    weights /= weights.sum()
    curves = {c: sum(w * r.mean[c] for w, r in zip(weights, records, strict=True)) for c in channels}
    return curves, float(sum(w * r.task["speed_mps"] for w, r in zip(weights, records, strict=True)))


class InclineChange:
    """The change a slope makes to gait curves (see the module docstring): scikit-learn style estimator.

    Args:
        channels: curve channels to learn (``knee_angle`` …, ``hip_angle`` when the bench needs it); each must be
            in every ramp record and in what ``population`` returns.
        level_tolerance_deg: records within this incline of 0 are level walking.
    """

    def __init__(self, channels: tuple[str, ...] = ("knee_angle", "knee_moment", "ankle_angle", "ankle_moment"),
                 level_tolerance_deg: float = 0.5) -> None:
        self.channels = channels
        self.level_tolerance_deg = level_tolerance_deg

    def fit(self, ramps: ReferenceSet, population: Callable[[float], dict[str, np.ndarray]]) -> InclineChange:
        """Learn the change per degree on each side of level.

        Args:
            ramps: one person's records at level and on slopes (tasks with ``speed_mps`` and ``incline_deg``),
                on the phase grid ``population`` answers on.
            population: speed (m/s) → the population's level curves at that speed, per channel.
        """
        level = [r for r in ramps.records if abs(r.task.get("incline_deg", 0.0)) <= self.level_tolerance_deg]
        slopes = [r for r in ramps.records if abs(r.task.get("incline_deg", 0.0)) > self.level_tolerance_deg]
        if not level or not slopes:
            raise ValueError("the ramp records need level walking and at least one slope of the same person")
        missing = [(r.name, c) for r in ramps.records for c in self.channels if c not in r.mean]
        if missing:
            raise ValueError(f"ramp record {missing[0][0]!r} has no {missing[0][1]} curve")
        level_curves, level_speed = _pooled_level(level, self.channels)
        population_level = population(level_speed)
        self.phase_ = ramps.phase
        self.level_speed_mps_ = level_speed
        self.changes_: list[tuple[float, float, dict[str, np.ndarray]]] = []   # (incline, speed, change)
        for r in slopes:
            population_ramp = population(r.task["speed_mps"])
            change = {c: r.mean[c] - level_curves[c] - (population_ramp[c] - population_level[c])
                      for c in self.channels}
            self.changes_.append((float(r.task["incline_deg"]), float(r.task["speed_mps"]), change))
        self.per_degree_: dict[str, dict[str, np.ndarray] | None] = {}
        self.steepest_deg_: dict[str, float | None] = {}
        for side in SIDES:
            mine = [(g, ch) for g, _, ch in self.changes_ if _side(g) == side]
            if not mine:
                self.per_degree_[side], self.steepest_deg_[side] = None, None
                continue
            g = np.array([x for x, _ in mine])
            self.per_degree_[side] = {c: sum(gi * ch[c] for gi, (_, ch) in zip(g, mine, strict=True)) / float(g @ g)
                                      for c in self.channels}
            self.steepest_deg_[side] = float(g[np.argmax(np.abs(g))])
        return self

    def predict(self, incline_deg: float) -> dict[str, np.ndarray]:
        """The change (per channel, on ``phase_``) at ``incline_deg``; zeros on a side without data."""
        slope = self.per_degree_[_side(incline_deg)] if incline_deg != 0.0 else None
        if slope is None:
            return {c: np.zeros_like(self.phase_) for c in self.channels}
        return {c: incline_deg * slope[c] for c in self.channels}

    def fraction_of_measured(self, incline_deg: float) -> float:
        """|γ| over the steepest measured ramp on its side (0 at level; above 1 beyond the data; inf without)."""
        if incline_deg == 0.0:
            return 0.0
        steepest = self.steepest_deg_[_side(incline_deg)]
        return float("inf") if steepest is None else abs(incline_deg / steepest)

    def covers(self, incline_deg: float) -> bool:
        """Whether ``incline_deg`` lies between level and a measured ramp on its side."""
        return self.fraction_of_measured(incline_deg) <= 1.0 + 1e-9

    def std(self, incline_deg: float, between_subject_sd: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """The change's uncertainty as a population estimate: ``between_subject_sd`` (level walking at the task's
        speed) scaled by :meth:`fraction_of_measured`; the full SD where no ramp of that side was measured."""
        scale = min(self.fraction_of_measured(incline_deg), max(1.0, abs(incline_deg) / 10.0))
        return {c: scale * between_subject_sd[c] for c in self.channels}
