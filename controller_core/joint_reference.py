"""The joint reference: the reference (angle, moment) curves of each joint at a task, reshaped through features.

Per joint (:mod:`controller_core.registration`): every training curve is re-timed so its push-off landmarks (ankle
plantarflexor moment peak, ankle plantarflexion peak) sit at their mean phases; a GMM on (registered phase, angle,
moment) gives, by GMR, the reference mean and covariance; a per-phase linear trend of the registered curves in the
task variables that vary in the data (speed, for the shipped data) moves that mean with the task, and a linear
trend of the landmark phases re-times it. Amplitudes are held at the edge of the training tasks (the Bovi 2011
ankle push-off moment stops growing above 1.5 m/s: a straight line through slower speeds overshoots), timing is
extrapolated (toe-off keeps moving earlier with speed); beyond the data the features, whose std grows, carry the
task through the via-points. ``reference_mode="pooled"`` keeps one GMR mean for every task (Ma et al.'s set-up; an
evaluation baseline). On a slope the change the measured ramps make is added (:mod:`controller_core.incline`).

One :class:`KMP` per joint over (angle, moment) reshapes the task's reference through via-points at the predicted
features (covariance = the feature's predictive variance, so an uncertain feature pulls less). Its factorisation
depends only on the covariance, so it is computed once; :meth:`JointReference.curves` is the one path from tasks and
features to curves, for a proposal (with std), a table or an envelope (means only, one stacked solve per joint).
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass

import numpy as np

from controller_core.gmr import GaussianMixtureRegression
from controller_core.incline import InclineChange
from controller_core.kmp import KMP, ViaPoint
from controller_core.proposal import FeaturePrediction
from controller_core.reference import CHANNELS, JOINTS, ReferenceSet
from controller_core.registration import TaskTrend, UniformUnwarp, ordered_landmarks, register

# Gait events whose predicted phases re-time the registered reference (push-off moment peak, toe-off).
LANDMARKS: tuple[str, ...] = ("ankle_plantarflexor_moment_peak", "ankle_plantarflexion_peak")
QUERY_POINTS = 101   # curves are given on 101 phases over [0, 1], the grid of the shipped data and of the ramps


@dataclass
class JointModel:
    """One joint's fitted reference: the GMR, the KMP holding its mean and covariance on the reference grid
    (``kmp.mu_ref_``, ``kmp.sigma_ref_``), and the task trend of the registered curves (None: pooled)."""

    gmm: GaussianMixtureRegression
    kmp: KMP
    trend: TaskTrend | None


@dataclass(frozen=True)
class TaskReference:
    """The reference means (n_ref_points, 2) of (angle, moment) per joint at one task, before the via-points.

    ``fitted`` is True when they are the KMP's own fitted means (pooled mode on level ground): the KMP then takes
    its cached solve; otherwise it solves once more for these means (same covariance, so same factorisation).
    """

    means: dict[str, np.ndarray]
    fitted: bool

    def kmp_mean(self, joint: str) -> np.ndarray | None:
        """The ``mu`` argument of the KMP's predict methods: None asks for the cached solve of the fitted means."""
        return None if self.fitted else self.means[joint]


@dataclass
class Curves:
    """Curves of every channel on the query grid (SI; moments per kg), their std (None when not asked for) and the
    via-points per joint they pass through."""

    means: dict[str, np.ndarray]
    stds: dict[str, np.ndarray] | None
    vias: dict[str, list[ViaPoint]]


class JointReference:
    """Task and features → joint curves (scikit-learn style: hyperparameters here, fitted state with ``_``).

    Args:
        n_components: GMM components per joint.
        n_ref_points: KMP reference grid size over [0, 1).
        kmp_length_scale: KMP kernel length (phase units).
        kmp_lambda: KMP λ (= λc).
        via_mean_scale: KMP via-point pull on the mean (see :class:`KMP`); the curve std is unaffected. 1 is the
            plain KMP of Huang et al., whose mean and covariance share one bordered solve.
        reference_mode: ``"registered"`` (default) or ``"pooled"`` (see the module docstring).
        covariance_floor: added to the GMR covariance's diagonal, (angle rad², moment (N·m/kg)²): 0.5° and
            0.01 N·m/kg, about the resolution of the published curves, so no phase claims more certainty.
        random_state: seed of the EM.
    """

    def __init__(self, n_components: int = 20, n_ref_points: int = 50, kmp_length_scale: float = 0.08,
                 kmp_lambda: float = 10.0, via_mean_scale: float = 1.0, reference_mode: str = "registered",
                 covariance_floor: tuple[float, float] = (math.radians(0.5) ** 2, 0.01 ** 2),
                 random_state: int = 0) -> None:
        self.n_components = n_components
        self.n_ref_points = n_ref_points
        self.kmp_length_scale = kmp_length_scale
        self.kmp_lambda = kmp_lambda
        self.via_mean_scale = via_mean_scale
        self.reference_mode = reference_mode
        self.covariance_floor = covariance_floor
        self.random_state = random_state

    def check(self) -> None:
        """Refuse settings the reference cannot use (ValueError naming the setting)."""
        if self.reference_mode not in ("registered", "pooled"):
            raise ValueError(f"reference_mode must be 'registered' or 'pooled', got {self.reference_mode!r}")
        if not (isinstance(self.n_components, int) and self.n_components >= 1):
            raise ValueError(f"n_components must be a positive integer, got {self.n_components!r}")

    def fit(self, reference: ReferenceSet, tasks: np.ndarray, landmarks: np.ndarray,
            incline: InclineChange | None) -> JointReference:
        """Fit the reference of every joint.

        Args:
            reference: the training records; ``tasks`` their (speed m/s, incline deg), row per record.
            landmarks: (records, len(LANDMARKS)) each record's landmark phases.
            incline: the change a slope makes, learned from measured ramps (None: none).
        """
        self.check()
        registered = self.reference_mode == "registered"
        self.trend_task_dims_ = [j for j in range(tasks.shape[1]) if np.ptp(tasks[:, j]) > 0] if registered else []
        self.canonical_landmarks_ = ordered_landmarks(landmarks.mean(axis=0))
        self.trend_lo_ = tasks[:, self.trend_task_dims_].min(axis=0)
        self.trend_hi_ = tasks[:, self.trend_task_dims_].max(axis=0)
        self.landmark_trend_ = (TaskTrend().fit(tasks[:, self.trend_task_dims_], landmarks)
                                if self.trend_task_dims_ else None)
        self.unwarp_ = UniformUnwarp(self.n_ref_points, self.canonical_landmarks_)
        self.s_ref_ = np.arange(self.n_ref_points) / self.n_ref_points
        self.s_query_ = np.linspace(0.0, 1.0, QUERY_POINTS)
        self._fit_spread(reference, incline)
        self.joints_ = {joint: self._fit_joint(reference, tasks, landmarks, joint, registered) for joint in JOINTS}
        return self

    def _fit_spread(self, reference: ReferenceSet, incline: InclineChange | None) -> None:
        """What the curves' std adds besides the KMP's: the level records' between-subject SD, and on a slope
        the uncertainty of the change the ramps measured; and that change per degree on the reference grid."""
        level = sorted((r for r in reference.records if r.task.get("incline_deg", 0.0) == 0.0),
                       key=lambda r: r.task["speed_mps"])
        self.level_speeds_ = np.array([r.task["speed_mps"] for r in level])
        self.level_sd_ = {c: np.array([np.nan_to_num(r.sd[c]) for r in level]) for c in CHANNELS}
        self.incline_ = incline
        self.incline_grid_: dict[str, dict[str, np.ndarray]] = {}    # side → joint → change per degree (N, 2)
        for side, per_degree in ({} if incline is None else incline.per_degree_).items():
            if per_degree is not None:
                self.incline_grid_[side] = {j: np.column_stack([
                    np.interp(self.s_ref_, incline.phase_, per_degree[f"{j}_{q}"]) for q in ("angle", "moment")])
                    for j in JOINTS}

    def _fit_joint(self, reference: ReferenceSet, tasks: np.ndarray, landmarks: np.ndarray, joint: str,
                   registered: bool) -> JointModel:
        phase = reference.phase
        curves = [np.column_stack([r.mean[f"{joint}_angle"], r.mean[f"{joint}_moment"]]) for r in reference.records]
        if registered:   # re-time every curve to the canonical landmarks before pooling
            curves = [register(phase, c, lm, self.canonical_landmarks_, phase)
                      for c, lm in zip(curves, landmarks, strict=True)]
        rows = []
        for c in curves:
            base = np.column_stack([phase, c])
            # wrap 10 % of the cycle across heel strike so the mixture is continuous at s = 0 ≡ 1
            lo, hi = base[phase <= 0.1].copy(), base[phase >= 0.9].copy()
            lo[:, 0] += 1.0
            hi[:, 0] -= 1.0
            rows += [base, lo, hi]
        gmm = GaussianMixtureRegression(n_components=self.n_components,
                                        random_state=self.random_state).fit(np.vstack(rows))
        mu0, sigma = gmm.predict(self.s_ref_[:, None], in_idx=(0,))
        sigma = 0.5 * (sigma + np.swapaxes(sigma, 1, 2)) + np.diag(self.covariance_floor)[None]
        trend = None
        if self.trend_task_dims_:
            on_grid = np.array([np.column_stack([np.interp(self.s_ref_, phase, c[:, k]) for k in (0, 1)])
                                for c in curves])
            trend = TaskTrend().fit(tasks[:, self.trend_task_dims_], on_grid - mu0[None])
        kmp = KMP(length_scale=self.kmp_length_scale, lam=self.kmp_lambda, lam_c=self.kmp_lambda,
                  via_tolerance=0.5 / self.n_ref_points,
                  via_mean_scale=self.via_mean_scale).fit(self.s_ref_, mu0, sigma, self.s_query_)
        return JointModel(gmm=gmm, kmp=kmp, trend=trend)

    def at_task(self, task: np.ndarray, trend_cache: dict | None = None) -> TaskReference:
        """The reference means at a task (speed m/s, incline deg), before the via-points.

        Registered mode: the GMR mean plus the task trend (task clipped to the training range), in canonical phase,
        re-timed to the landmark phases of the landmark trend (not clipped). Pooled mode: the GMR mean. On a slope,
        plus the change the slope makes, when the model learned one.

        ``trend_cache``: a dict the caller keeps while it asks for many tasks (an envelope's grid): the trend part
        depends only on the trend's task dimensions, so tasks that share them share it.
        """
        fitted = self.landmark_trend_ is None
        if fitted:
            means = {joint: jm.kmp.mu_ref_ for joint, jm in self.joints_.items()}
        else:
            t = np.asarray(task, dtype=float)[self.trend_task_dims_]
            key = tuple(t.tolist())
            means = None if trend_cache is None else trend_cache.get(key)
            if means is None:
                weights = self.unwarp_.at(self.canonical_landmarks_ + self.landmark_trend_.predict(t))
                t_in = np.clip(t, self.trend_lo_, self.trend_hi_)
                means = {joint: self.unwarp_.apply(weights, jm.kmp.mu_ref_ + jm.trend.predict(t_in))
                         for joint, jm in self.joints_.items()}
                if trend_cache is not None:
                    trend_cache[key] = means
        incline = float(task[1])
        change = self.incline_grid_.get("uphill" if incline > 0 else "downhill") if incline != 0.0 else None
        if change is not None:
            means, fitted = {joint: mu + incline * change[joint] for joint, mu in means.items()}, False
        return TaskReference(means=means, fitted=fitted)

    def via_points(self, joint: str, mu_ref: np.ndarray, features: list[FeaturePrediction]) -> list[ViaPoint]:
        """KMP via-points of one joint from predicted features.

        The feature's channel gets the GPR mean and variance; the other channel keeps the task's reference mean
        and variance at that phase (``mu_ref`` on the KMP grid), so it stays free to follow the data.
        """
        mine = [f for f in features if f.spec.joint == joint and f.spec.quantity in ("angle", "moment")]
        if not mine:
            return []
        n = self.s_ref_.size                                   # the grid is k/n, k = 0…n−1
        mu = mu_ref.tolist()                                   # a handful of points: plain floats beat array calls
        ref_var = np.diagonal(self.joints_[joint].kmp.sigma_ref_, axis1=1, axis2=2).tolist()
        vias = []
        for f in mine:
            pos = (f.phase % 1.0) * n
            i0 = math.floor(pos)
            w = pos - i0
            lo, hi = mu[i0 % n], mu[(i0 + 1) % n]
            mean = [lo[0] * (1.0 - w) + hi[0] * w, lo[1] * (1.0 - w) + hi[1] * w]    # reference at the via phase
            var = list(ref_var[round(pos) % n])
            channel = 0 if f.spec.quantity == "angle" else 1
            mean[channel], var[channel] = f.value, max(f.std, 1e-6) ** 2
            vias.append(ViaPoint(phase=f.phase, mean=np.array(mean), cov=np.array([[var[0], 0.0], [0.0, var[1]]])))
        return vias

    def curves(self, tasks: np.ndarray, features: list[list[FeaturePrediction]], with_std: bool,
               with_vias: bool = True) -> list[Curves]:
        """Curves at each task (rows of (speed m/s, incline deg)): the task's reference reshaped by the KMP through
        that task's predicted features.

        Args:
            with_std: also the std of every channel (a proposal's display: one KMP solve per task and joint);
                without it only the means, from one stacked solve per joint (a table, an envelope's grid).
            with_vias: False gives the reference through the KMP without via-points (a baseline).
        """
        tasks = np.atleast_2d(np.asarray(tasks, dtype=float))
        trends: dict = {}
        references = [self.at_task(task, trends) for task in tasks]
        out = [Curves(means={}, stds={} if with_std else None, vias={}) for _ in tasks]
        for joint, jm in self.joints_.items():
            for c, ref, f in zip(out, references, features, strict=True):
                c.vias[joint] = self.via_points(joint, ref.means[joint], f) if with_vias else []
            if with_std:
                solved = [jm.kmp.predict_std(c.vias[joint], mu=ref.kmp_mean(joint))
                          for c, ref in zip(out, references, strict=True)]
            else:
                means = jm.kmp.predict_mean_many([c.vias[joint] for c in out], [r.kmp_mean(joint) for r in references])
                solved = [(mean, None) for mean in means]
            for c, (mean, sd) in zip(out, solved, strict=True):
                c.means[f"{joint}_angle"], c.means[f"{joint}_moment"] = mean[:, 0], mean[:, 1]
                if sd is not None:
                    c.stds[f"{joint}_angle"], c.stds[f"{joint}_moment"] = sd[:, 0], sd[:, 1]
        if with_std and self.incline_ is not None:
            for c, task in zip(out, tasks, strict=True):
                if task[1] != 0.0:   # the incline change's phase grid is the query grid
                    extra = self.incline_.std(float(task[1]), self.between_subject_sd(float(task[0])))
                    c.stds = {ch: np.hypot(c.stds[ch], extra[ch]) for ch in CHANNELS}
        return out

    def between_subject_sd(self, speed_mps: float) -> dict[str, np.ndarray]:
        """The population's between-subject SD curves of level walking at a speed (linear between the training
        records, the nearest beyond them; zeros without level records)."""
        speeds = self.level_speeds_.tolist()
        if not speeds:
            return {c: np.zeros_like(self.s_query_) for c in CHANNELS}
        hi = min(max(bisect.bisect_left(speeds, speed_mps), 1), max(len(speeds) - 1, 1))
        lo = hi - 1 if len(speeds) > 1 else 0
        gap = speeds[hi] - speeds[lo]
        w = 0.0 if gap == 0.0 else min(max((speed_mps - speeds[lo]) / gap, 0.0), 1.0)
        return {c: (1.0 - w) * sd[lo] + w * sd[hi] for c, sd in self.level_sd_.items()}
