"""The feature model: from a walking task (speed, incline) to the target features, with their uncertainty.

One :class:`FeatureGPR` per feature value and per feature phase over (speed, incline), additive (a level value over
speed plus a change over incline), trained on the reference records, on published group means from other labs and
on the change one person's measured ramps make, carried onto the population's level curves. The measured ramps'
change per degree is the GPRs' prior mean on a slope, so the GPRs learn only how the population departs from it.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from controller_core.features import (
    FEATURES,
    PHASED_FEATURES,
    FeatureNotFoundError,
    curve_feature,
    feature_sd,
    record_features,
)
from controller_core.gpr import FeatureGPR, FeatureGPRBank
from controller_core.incline import InclineChange
from controller_core.proposal import FeaturePrediction
from controller_core.published_features import PublishedPoint
from controller_core.reference import CHANNELS, ReferenceRecord, ReferenceSet

SIDES: tuple[str, ...] = ("uphill", "downhill")
_PHASE_ROW = {f.name: i for i, f in enumerate(PHASED_FEATURES)}   # row of each feature among the phase GPRs


@dataclass(frozen=True)
class InclinePoint:
    """A feature of one measured ramp's change carried onto the population's level curves at the speed it was
    walked at (SI units): a training point of the feature's GPRs, value (standard error ``se``) and phase."""

    feature: str
    speed_mps: float
    incline_deg: float
    value: float
    se: float
    phase: float
    value_change: float = 0.0     # from the same level curves, without the ramp's change
    phase_change: float = 0.0


def published_se(point: PublishedPoint) -> float:
    """How far a published group mean from another lab may lie from what this model's data would show for the same
    task: its standard error and the study's between-subject SD (labs differ in markers, neutral angles and
    normalisation by about that much: Bovi's and Winter's ankle neutrals differ by 19°), or its SE alone where no SD
    was published."""
    return float(np.hypot(point.se, point.sd)) if np.isfinite(point.sd) else point.se


def incline_points(incline: InclineChange, level_curves: Callable[[float], tuple[dict, dict]],
                   phase: np.ndarray) -> list[InclinePoint]:
    """Each measured ramp's change added to the population's level curves at the speed it was walked at
    (``level_curves(speed)`` → (mean, sd) per channel), as feature points. Stance timing on slopes is left to the
    published points. The standard error of a value is the population's between-subject SD at that phase: the
    point is one person's change."""
    points = []
    for slope, speed, _ in incline.changes_:
        mean, sd = level_curves(speed)
        change = incline.predict(slope)
        task = {"speed_mps": speed, "incline_deg": slope}
        sloped = ReferenceRecord(name=f"{slope:+g} deg change on the level curves at {speed:.2f} m/s",
                                 dataset="derived", task=task, phase=phase,
                                 mean={c: mean[c] + change[c] for c in CHANNELS}, sd=sd)
        level = ReferenceRecord(name=f"level curves at {speed:.2f} m/s", dataset="derived",
                                task=task | {"incline_deg": 0.0}, phase=phase, mean=mean, sd=sd)
        for spec in FEATURES:
            if spec.quantity == "timing":
                continue
            try:
                (at, value), (at0, value0) = curve_feature(sloped, spec), curve_feature(level, spec)
            except FeatureNotFoundError:
                continue
            points.append(InclinePoint(spec.name, speed, slope, value, feature_sd(sloped, spec, at), at,
                                       value - value0, at - at0))
    return points


class FeatureModel:
    """Task → target features (scikit-learn style: hyperparameters here, fitted state with ``_``).

    Args:
        length_scale_bounds: the GPRs' RBF length-scale bounds, (speed m/s, incline deg). A slope's effect on gait
            varies smoothly over several degrees, more than the spacing at which studies sample slopes (5°), hence
            an incline length scale of 15° at least.
        input_scale: one scaled GPR input in physical units (1 m/s, 10°).
        additive: one RBF term per task dimension (see :mod:`controller_core.gpr`).
        incline_phase_se: standard error of a feature's phase taken from one person's change on a slope (fraction
            of the cycle): about the between-subject SD of peak timing in level walking.
        n_restarts: marginal-likelihood optimizer restarts per GPR.
        random_state: seed of the optimizer restarts.
    """

    def __init__(self, length_scale_bounds: tuple[tuple[float, float], ...] = ((0.3, 3.0), (15.0, 60.0)),
                 input_scale: tuple[float, ...] = (1.0, 10.0), additive: bool = True, incline_phase_se: float = 0.02,
                 n_restarts: int = 2, random_state: int = 0) -> None:
        self.length_scale_bounds = length_scale_bounds
        self.input_scale = input_scale
        self.additive = additive
        self.incline_phase_se = incline_phase_se
        self.n_restarts = n_restarts
        self.random_state = random_state

    def fit(self, reference: ReferenceSet, tasks: np.ndarray, published: list[PublishedPoint],
            ramp_points: list[InclinePoint]) -> FeatureModel:
        """Fit the value and phase GPRs.

        Args:
            reference: the training records; ``tasks`` their (speed m/s, incline deg), row per record.
            published: published feature values from other labs.
            ramp_points: the measured ramps' changes on the level curves (:func:`incline_points`).
        """
        self.incline_points_ = list(ramp_points)
        self.train_features_ = [record_features(r) for r in reference.records]
        self.feature_trends_ = self._fit_trends(self.incline_points_)
        settings = {"length_scale_bounds": self.length_scale_bounds, "input_scale": self.input_scale,
                    "additive": self.additive, "n_restarts": self.n_restarts, "random_state": self.random_state}
        self.value_gprs_: dict[str, FeatureGPR] = {}
        self.phase_gprs_: dict[str, FeatureGPR] = {}
        for spec in FEATURES:
            values = np.array([f[spec.name][1] for f in self.train_features_])
            phases = np.array([f[spec.name][0] for f in self.train_features_])
            se = np.array([feature_sd(r, spec, p) / math.sqrt(r.n) if r.n > 0 else np.nan
                           for r, p in zip(reference.records, phases, strict=True)])
            ramp = [p for p in self.incline_points_ if p.feature == spec.name]
            mine = [p for p in published if p.feature == spec.name]
            X = np.vstack([tasks, *[[[p.speed_mps, p.incline_deg]] for p in mine + ramp]])
            y = np.concatenate([values, [p.value for p in mine + ramp]]) - self._trend(spec.name, X[:, 1], "value")
            y_se = np.concatenate([se, [published_se(p) for p in mine], [p.se for p in ramp]])
            self.value_gprs_[spec.name] = FeatureGPR(**settings).fit(X, y, y_se)
            if spec in PHASED_FEATURES:
                Xp = np.vstack([tasks, *[[[p.speed_mps, p.incline_deg]] for p in ramp]])
                yp = np.concatenate([phases, [p.phase for p in ramp]]) - self._trend(spec.name, Xp[:, 1], "phase")
                se_p = np.concatenate([np.full(len(phases), np.nan), np.full(len(ramp), self.incline_phase_se)])
                self.phase_gprs_[spec.name] = FeatureGPR(**settings).fit(Xp, yp, se_p)
        # one bank for values then phases: one batched evaluation and shared hull tests per task
        self.bank_ = FeatureGPRBank([self.value_gprs_[f.name] for f in FEATURES]
                                    + [self.phase_gprs_[f.name] for f in PHASED_FEATURES])
        rows = [(f.name, "value") for f in FEATURES] + [(f.name, "phase") for f in PHASED_FEATURES]
        self.trend_per_degree_ = {side: np.array([self.feature_trends_[n][side][k] for n, k in rows]) for side in SIDES}
        return self

    @staticmethod
    def _fit_trends(points: list[InclinePoint]) -> dict[str, dict[str, dict[str, float]]]:
        """Per feature and side of level, the change per degree of its value and phase that the measured ramps show
        (least squares through zero; zero without them). One side's data never bend the other side's trend."""
        trends = {f.name: {side: {"value": 0.0, "phase": 0.0} for side in SIDES} for f in FEATURES}
        for side, sign in zip(SIDES, (1.0, -1.0), strict=True):
            for spec in FEATURES:
                mine = [p for p in points if p.feature == spec.name and sign * p.incline_deg > 0]
                if mine:
                    g = np.array([p.incline_deg for p in mine])
                    for kind, attr in (("value", "value_change"), ("phase", "phase_change")):
                        d = np.array([getattr(p, attr) for p in mine])
                        trends[spec.name][side][kind] = float(g @ d / (g @ g))
        return trends

    def _trend(self, feature: str, inclines: np.ndarray, kind: str) -> np.ndarray:
        """The measured-ramp trend of a feature's value or phase at each incline (deg)."""
        t = self.feature_trends_[feature]
        return np.where(inclines > 0, t["uphill"][kind], t["downhill"][kind]) * inclines

    def predict(self, speed_mps: float, incline_deg: float) -> list[FeaturePrediction]:
        """Every feature at a task (SI values; a timing feature's value is its phase)."""
        mean, sd, outside = self.bank_.predict(np.array([speed_mps, incline_deg], dtype=float))
        return self._features(incline_deg, mean, sd, outside)

    def predict_many(self, tasks: np.ndarray) -> list[list[FeaturePrediction]]:
        """:meth:`predict` at many (speed, incline) tasks in one evaluation of the GPRs."""
        tasks = np.atleast_2d(np.asarray(tasks, dtype=float))
        mean, sd, outside = self.bank_.predict_many(tasks)
        return [self._features(float(t[1]), m, s, o) for t, m, s, o in zip(tasks, mean, sd, outside, strict=True)]

    def _features(self, incline_deg: float, mean: np.ndarray, sd: np.ndarray, outside: np.ndarray
                  ) -> list[FeaturePrediction]:
        if incline_deg != 0.0:
            mean = mean + incline_deg * self.trend_per_degree_["uphill" if incline_deg > 0 else "downhill"]
        n = len(FEATURES)
        mean, sd, outside = mean.tolist(), sd.tolist(), outside.tolist()     # a few values: plain floats
        out = []
        for i, spec in enumerate(FEATURES):
            if spec.quantity == "timing":
                phase, phase_std, extrapolation = mean[i], sd[i], bool(outside[i])
            elif spec.fixed_phase:
                phase, phase_std, extrapolation = spec.window[0], 0.0, bool(outside[i])
            else:
                j = n + _PHASE_ROW[spec.name]
                phase, phase_std, extrapolation = mean[j], sd[j], bool(outside[i] or outside[j])
            out.append(FeaturePrediction(spec=spec, phase=float(min(max(phase, 0.0), 1.0)), phase_std=float(phase_std),
                                         value=float(mean[i]), std=float(sd[i]), extrapolation=extrapolation))
        return out
