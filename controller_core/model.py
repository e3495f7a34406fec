"""The learning quasi-stiffness model: GPR features → KMP through a registered GMR reference → table.

``QuasiStiffnessModel.fit(reference)`` learns, from a :class:`ReferenceSet` (and optional published
feature points):

1. one :class:`FeatureGPR` per feature value and per feature phase (task → feature);
2. per joint, the reference (:mod:`controller_core.registration`): every training curve is re-timed so
   its push-off landmarks (ankle plantarflexor moment peak, ankle plantarflexion peak) sit at their mean
   phases; a GMM on (registered phase, angle, moment) gives, by GMR, the reference mean and covariance;
   a per-phase linear trend of the registered curves in the task variables that vary in the data (speed,
   for the shipped data) moves that mean with the task, and a linear trend of the landmark phases
   re-times it. Amplitudes are held at the edge of the training tasks (the Bovi 2011 ankle push-off
   moment stops growing above 1.5 m/s: a straight line through slower speeds overshoots), timing is
   extrapolated (toe-off keeps moving earlier with speed); beyond the data the GPR features, whose std
   grows, carry the task through the via-points. ``reference_mode="pooled"`` keeps one GMR mean for
   every task (Ma et al.'s set-up; an evaluation baseline);
3. one :class:`KMP` per joint over (angle, moment) on a phase grid, whose factorisation (it depends only
   on the covariance) is cached once.

``propose(speed_mps, incline_deg, mass_kg)`` predicts the features, builds the task's reference, turns
each feature into a KMP via-point on its channel (covariance = the GPR's predictive variance, so an
uncertain feature pulls less), reshapes the reference through them, fits the quasi-stiffness per
stance sub-phase, aims the swing sub-phases at the predicted swing targets (``swing_rule``) and builds the
parameter table.
"""

from __future__ import annotations

import bisect
import hashlib
import math
from dataclasses import dataclass, replace

import numpy as np

from controller_core.envelope import DEFAULT_STEPS, Envelope, NeighbourSteps, build_envelope, validate_axes
from controller_core.features import (
    FEATURES,
    PHASED_FEATURES,
    FeatureNotFoundError,
    curve_feature,
    feature_sd,
    record_features,
)
from controller_core.gmr import GaussianMixtureRegression
from controller_core.gpr import FeatureGPR, FeatureGPRBank
from controller_core.incline import InclineChange
from controller_core.kmp import KMP, ViaPoint
from controller_core.proposal import FeaturePrediction, Proposal
from controller_core.published_features import PublishedPoint
from controller_core.quasi_stiffness import SUBPHASES, SubphaseFit, fit_fixed_k, fit_quasi_stiffness_joints, subphase_masks
from controller_core.reference import CHANNELS, JOINTS, ReferenceRecord, ReferenceSet, level_curves_at
from controller_core.registration import TaskTrend, UniformUnwarp, ordered_landmarks, register
from controller_core.table import DEFAULT_LIMITS, ParameterRow, ParameterTable, Provenance, Thresholds, check_table
from controller_core.task import validate_task
from controller_core.units import body_weight_N

JOINT_RANGE_RAD = {"knee": (0.0, math.radians(120.0)), "ankle": (math.radians(-30.0), math.radians(30.0))}
# Damping is not learned (the fit is τ = kθ + c): editable defaults per kg body mass, of the order of
# published finite-state impedance values for adults. The knee's swing values brake the swinging shank
# (late-swing 0.06 ≈ the Open Source Leg example's 3.816 N·m·s/rad for 60 kg; early swing 0.03 chosen on the
# simulated bench, see docs/results.md).
DEFAULT_DAMPING_NMS_PER_RAD_PER_KG = {
    "knee": {"stance_flexion": 0.04, "stance_extension": 0.04, "swing_flexion": 0.03, "swing_extension": 0.06},
    "ankle": {"stance_flexion": 0.04, "stance_extension": 0.04, "swing_flexion": 0.01, "swing_extension": 0.02},
}
SWING_RULES: tuple[str, ...] = ("target", "least_squares")


def training_data_sha256(reference: ReferenceSet, published: list[PublishedPoint],
                         ramps: ReferenceSet | None = None) -> str:
    """SHA-256 of everything a model learns from: the source hashes of the reference and ramp sets and the
    published points."""
    h = hashlib.sha256(reference.data_sha256.encode())
    for p in published:
        h.update(repr((p.feature, p.speed_mps, p.incline_deg, p.value, p.se, p.source)).encode())
    if ramps is not None:
        h.update(ramps.data_sha256.encode())
    return h.hexdigest()


# Standard error of a feature's phase taken from one person's change on a slope (fraction of the cycle): about the
# between-subject SD of peak timing in level walking.
INCLINE_PHASE_SE = 0.02


@dataclass(frozen=True)
class InclinePoint:
    """A feature of one measured ramp's change carried onto the population's level curves at the speed it was
    walked at (SI units): a training point of the feature's GPRs, value (standard error ``se``) and phase
    (``INCLINE_PHASE_SE``)."""

    feature: str
    speed_mps: float
    incline_deg: float
    value: float
    se: float
    phase: float
    value_change: float = 0.0     # from the same level curves, without the ramp's change
    phase_change: float = 0.0


# Feature GPRs over (speed, incline), additive: a level value over speed plus a change over incline. A slope's
# effect on gait varies smoothly over several degrees, about the spacing at which studies sample slopes: the
# incline length scale is at least 8°.
FEATURE_GPR = {"length_scale_bounds": ((0.3, 3.0), (15.0, 60.0)), "input_scale": (1.0, 10.0), "additive": True}


def published_se(point: PublishedPoint) -> float:
    """How far a published group mean from another lab may lie from what this model's data would show for the same
    task: its standard error and the study's between-subject SD (labs differ in markers, neutral angles and
    normalisation by about that much: Bovi's and Winter's ankle neutrals differ by 19°), or its SE alone where no SD
    was published."""
    return float(np.hypot(point.se, point.sd)) if np.isfinite(point.sd) else point.se


@dataclass
class _JointModel:
    gmm: GaussianMixtureRegression
    kmp: KMP                       # holds the GMR mean and covariance on its grid (mu_ref_, sigma_ref_)
    trend: TaskTrend | None        # task trend of the registered reference (None: pooled reference)


# Gait events whose predicted phases re-time the registered reference (push-off moment peak, toe-off).
LANDMARKS: tuple[str, ...] = ("ankle_plantarflexor_moment_peak", "ankle_plantarflexion_peak")
_PHASE_GPR_INDEX = {f.name: i for i, f in enumerate(PHASED_FEATURES)}  # row of each feature in the phase bank


class QuasiStiffnessModel:
    """Learning quasi-stiffness model (scikit-learn style: hyperparameters here, fitted state with ``_``).

    The defaults were chosen by the leave-one-condition-out evaluation (``quasitune evaluate``), which makes that
    evaluation optimistic for them (docs/results.md). via_mean_scale = 1 is the plain KMP of Huang et al., whose
    mean and covariance share one bordered solve.

    Args:
        n_components: GMM components per joint.
        n_ref_points: KMP reference grid size over [0, 1).
        kmp_length_scale: KMP kernel length (phase units).
        kmp_lambda: KMP λ (= λc).
        gpr_restarts: marginal-likelihood optimizer restarts per GPR.
        load_fractions: (toe-off, heel-strike) vertical-load thresholds as fractions of body weight. The
            default, 15 % and 40 %, is the Open Source Leg walking example's published pair, which the FSMIC
            benchmark uses too (``controller_core/fsmic.py``): the two controllers then differ only in their
            impedance rows, which is what the comparison is about.
        swing_threshold_fraction: WF→WE knee threshold as a fraction of the predicted swing peak.
        state_time_s: (min, max) time in a state.
        reference_mode: ``"registered"`` (default): GMR reference on registered phase, moved with the task
            by a linear trend (see the module docstring); ``"pooled"``: one GMR reference for every task.
        via_mean_scale: KMP via-point pull on the mean (see :class:`KMP`); the curve std is unaffected.
        min_restoring_stiffness_Nm_per_rad_per_kg: passivity ceiling of unstable sub-phases (N·m/rad per kg
            of patient mass): an energy-injecting line whose θe lies inside the angles it sweeps is replaced
            by k = −value·mass and a re-fitted θe (see :mod:`controller_core.quasi_stiffness`). The default,
            0.25 N·m/rad/kg (about 19 N·m/rad at 75 kg), lies within the swing stiffnesses of the Open Source
            Leg's published walking example (0.13–0.66 N·m/rad/kg); 0 disables the guard.
        knee_support_floor_Nm_per_rad_per_kg: the stance support floor (N·m/rad per kg, the safety limit's
            :attr:`~controller_core.table.SafetyLimits.knee_stance_support_Nm_per_rad_per_kg`): a knee
            stance-flexion line softer than −value·mass (where the person's knee does positive work, climbing
            slowly, which a spring cannot) holds −value·mass with a re-fitted θe (``support_floor``).
        knee_extension_window: False (default): the knee's stance-extension row is fitted over the whole
            sub-phase, stance-flexion peak to toe-off (the literal framework, a poor line). True: over the knee's
            extension only, up to its late-stance minimum on the predicted curve (``extension_window``, see
            :mod:`controller_core.quasi_stiffness`). Not the default because the four-state machine runs this
            row through pre-swing too, where the stiff line pushes far more extensor moment against the knee's
            pre-swing flexion than people have (docs/results.md). It is the stance-extension row a machine with
            a separate pre-swing state would use.
        swing_rule: ``"target"`` (default): the swing rows aim at the predicted swing targets (knee swing
            flexion at the GPR's swing-flexion peak, knee swing extension at the predicted heel-strike angle,
            the ankle through swing at its predicted swing dorsiflexion plus ``swing_ankle_clearance_deg``)
            with the restoring stiffnesses below; ``"least_squares"``: the swing rows are fitted like the
            stance rows (the literal framework; on the simulated bench that table falls, docs/results.md).
        swing_knee_stiffness_Nm_per_rad_per_kg: (swing flexion, swing extension) knee stiffness magnitudes per
            kg of patient mass under the target rule: 0.66 and 0.25, about the Open Source Leg example's
            39.7 and 15.9 N·m/rad for 60 kg.
        swing_ankle_stiffness_Nm_per_rad_per_kg: ankle swing stiffness magnitude per kg (target rule).
        swing_ankle_clearance_deg: dorsiflexion added to the ankle's predicted swing angle (deg). On the bench's
            foot the able-bodied swing angles leave −8 to +2 mm of toe clearance where people keep about
            13 mm (Winter 1992); each degree lifts the toe about 3.4 mm, so 5° restores that margin.
        stance_extension_knee_speed_deg_per_s: SF→SE also fires when the loaded knee extends faster than this
            (deg/s; 0 turns it off): the stance-flexion peak, which is the sub-phase boundary. The ankle-moment
            threshold alone is late in a fast, flexed landing (1.95 m/s +5°: the knee held flexed under load, 12
            falls on the bench); 11 deg/s (0.19 rad/s, held 20 ms) is above the knee's speed noise at the peak.
        random_state: seed for EM and optimizer restarts.
        model_version: a label stored in every proposal's provenance (``quasitune train`` sets the package
            version and a hash of this code).
    """

    def __init__(self, n_components: int = 20, n_ref_points: int = 50, kmp_length_scale: float = 0.08,
                 kmp_lambda: float = 10.0, gpr_restarts: int = 2,
                 load_fractions: tuple[float, float] = (0.15, 0.40), swing_threshold_fraction: float = 0.85,
                 state_time_s: tuple[float, float] = (0.05, 1.5), stance_extension_knee_speed_deg_per_s: float = 11.0,
                 reference_mode: str = "registered",
                 via_mean_scale: float = 1.0, min_restoring_stiffness_Nm_per_rad_per_kg: float = 0.25,
                 knee_support_floor_Nm_per_rad_per_kg: float = DEFAULT_LIMITS.knee_stance_support_Nm_per_rad_per_kg,
                 knee_extension_window: bool = False, swing_rule: str = "target",
                 swing_knee_stiffness_Nm_per_rad_per_kg: tuple[float, float] = (0.66, 0.25),
                 swing_ankle_stiffness_Nm_per_rad_per_kg: float = 0.25, swing_ankle_clearance_deg: float = 5.0,
                 random_state: int = 0, model_version: str = "unversioned") -> None:
        self.n_components = n_components
        self.n_ref_points = n_ref_points
        self.kmp_length_scale = kmp_length_scale
        self.kmp_lambda = kmp_lambda
        self.gpr_restarts = gpr_restarts
        self.load_fractions = load_fractions
        self.swing_threshold_fraction = swing_threshold_fraction
        self.state_time_s = state_time_s
        self.stance_extension_knee_speed_deg_per_s = stance_extension_knee_speed_deg_per_s
        self.reference_mode = reference_mode
        self.via_mean_scale = via_mean_scale
        self.min_restoring_stiffness_Nm_per_rad_per_kg = min_restoring_stiffness_Nm_per_rad_per_kg
        self.knee_support_floor_Nm_per_rad_per_kg = knee_support_floor_Nm_per_rad_per_kg
        self.knee_extension_window = knee_extension_window
        self.swing_rule = swing_rule
        self.swing_knee_stiffness_Nm_per_rad_per_kg = swing_knee_stiffness_Nm_per_rad_per_kg
        self.swing_ankle_stiffness_Nm_per_rad_per_kg = swing_ankle_stiffness_Nm_per_rad_per_kg
        self.swing_ankle_clearance_deg = swing_ankle_clearance_deg
        self.random_state = random_state
        self.model_version = model_version

    # ------------------------------------------------------------------ fit
    def fit(self, reference: ReferenceSet, published: list[PublishedPoint] | None = None,
            ramps: ReferenceSet | None = None) -> QuasiStiffnessModel:
        """Fit every part of the model.

        Args:
            reference: training curves; their tasks must be finite in every task dimension.
            published: extra feature-value points (e.g. published incline features).
            ramps: one person's level and ramp walking, from which the change a slope makes is learned
                (:mod:`controller_core.incline`); None: incline is known from ``published`` alone.
        """
        self._check_table_rules()
        if "speed_mps" not in reference.task_names:
            raise ValueError("the reference set needs a 'speed_mps' task column")
        tasks = np.column_stack([
            np.array([r.task.get("speed_mps", np.nan) for r in reference.records]),
            np.array([r.task.get("incline_deg", 0.0) for r in reference.records]),
        ])
        if not np.all(np.isfinite(tasks)):
            raise ValueError("every training record needs a finite speed (m/s) and incline (deg)")
        self.reference_ = reference
        self.train_tasks_ = tasks
        self.published_ = list(published or [])
        self.ramps_ = ramps
        self.data_sha256_ = training_data_sha256(reference, self.published_, ramps)
        self._fit_incline(reference, ramps)
        self._fit_features(reference, tasks)
        self._fit_joints(reference, tasks)
        return self

    def _fit_incline(self, reference: ReferenceSet, ramps: ReferenceSet | None) -> None:
        """The change a slope makes (None without ramps), and the feature points it gives: each measured ramp's
        change added to the population's level curves at the speed it was walked at. Such a point is one
        person's change, so its standard error is the population's between-subject SD (value), or
        :data:`INCLINE_PHASE_SE` (phase)."""
        self.incline_points_: list[InclinePoint] = []
        level = sorted((r for r in reference.records if r.task.get("incline_deg", 0.0) == 0.0),
                       key=lambda r: r.task["speed_mps"])
        self.level_speeds_ = np.array([r.task["speed_mps"] for r in level])
        self.level_sd_ = {c: np.array([np.nan_to_num(r.sd[c]) for r in level]) for c in CHANNELS}
        if ramps is None:
            self.incline_ = None
            return
        self.incline_ = InclineChange().fit(ramps, lambda v: level_curves_at(reference, v)[0])
        for incline, speed, _ in self.incline_.changes_:
            mean, sd = level_curves_at(reference, speed)
            change = self.incline_.predict(incline)
            curves = ReferenceRecord(name=f"{incline:+g} deg change on the level curves at {speed:.2f} m/s",
                                     dataset="derived", task={"speed_mps": speed, "incline_deg": incline},
                                     phase=reference.phase, mean={c: mean[c] + change[c] for c in CHANNELS}, sd=sd)
            level = ReferenceRecord(name=f"level curves at {speed:.2f} m/s", dataset="derived",
                                    task={"speed_mps": speed, "incline_deg": 0.0}, phase=reference.phase, mean=mean,
                                    sd=sd)
            for spec in FEATURES:
                if spec.quantity == "timing":   # stance timing on slopes comes from the published points
                    continue
                try:
                    (phase, value), (phase0, value0) = curve_feature(curves, spec), curve_feature(level, spec)
                except FeatureNotFoundError:
                    continue
                self.incline_points_.append(InclinePoint(spec.name, speed, incline, value,
                                                         feature_sd(curves, spec, phase), phase,
                                                         value - value0, phase - phase0))

    def _fit_features(self, reference: ReferenceSet, tasks: np.ndarray) -> None:
        """Per feature, a GPR of its value and (for features with a phase) one of its phase over (speed,
        incline), additive (:data:`FEATURE_GPR`): from the records, the published points and the measured ramps'
        changes carried onto the level curves (:meth:`_fit_incline`)."""
        per_record = [record_features(r) for r in reference.records]
        self.train_features_ = per_record
        self.value_gprs_: dict[str, FeatureGPR] = {}
        self.phase_gprs_: dict[str, FeatureGPR] = {}
        self._fit_feature_trends()
        gpr = {**FEATURE_GPR, "n_restarts": self.gpr_restarts, "random_state": self.random_state}
        for spec in FEATURES:
            vals = np.array([f[spec.name][1] for f in per_record])
            phases = np.array([f[spec.name][0] for f in per_record])
            se = np.array([feature_sd(r, spec, p) / math.sqrt(r.n) if r.n > 0 else np.nan
                           for r, p in zip(reference.records, phases, strict=True)])
            ramp = [p for p in self.incline_points_ if p.feature == spec.name]
            published = [p for p in self.published_ if p.feature == spec.name]
            extra = published + ramp
            X = np.vstack([tasks, *[[[p.speed_mps, p.incline_deg]] for p in extra]])
            y = np.concatenate([vals, [p.value for p in extra]]) - self._trend(spec.name, X[:, 1], "value")
            y_se = np.concatenate([se, [published_se(p) for p in published], [p.se for p in ramp]])
            self.value_gprs_[spec.name] = FeatureGPR(**gpr).fit(X, y, y_se)
            if spec in PHASED_FEATURES:
                Xp = np.vstack([tasks, *[[[p.speed_mps, p.incline_deg]] for p in ramp]])
                yp = np.concatenate([phases, [p.phase for p in ramp]]) - self._trend(spec.name, Xp[:, 1], "phase")
                se_p = np.concatenate([np.full(len(phases), np.nan), np.full(len(ramp), INCLINE_PHASE_SE)])
                self.phase_gprs_[spec.name] = FeatureGPR(**gpr).fit(Xp, yp, se_p)
        # one bank for values then phases: one batched evaluation and shared hull tests per task
        self.feature_bank_ = FeatureGPRBank([self.value_gprs_[f.name] for f in FEATURES]
                                            + [self.phase_gprs_[f.name] for f in PHASED_FEATURES])
        names = [f.name for f in FEATURES] + [f.name for f in PHASED_FEATURES]
        kinds = ["value"] * len(FEATURES) + ["phase"] * len(PHASED_FEATURES)
        self.trend_per_degree_ = {side: np.array([self.feature_trends_[n][side][k] for n, k in zip(names, kinds,
                                                                                                   strict=True)])
                                  for side in ("uphill", "downhill")}

    def _fit_feature_trends(self) -> None:
        """Per feature and side of level, the change per degree of its value and phase that the measured ramps
        show (zero without them): the prior mean of the feature GPRs on a slope. The GPRs then learn only how the
        population departs from that trend (published points on slopes), so a feature between level and a
        measured ramp follows the measured trend unless data say otherwise, and one side's data do not bend the
        other side's prediction."""
        self.feature_trends_: dict[str, dict[str, dict[str, float]]] = {
            f.name: {side: {"value": 0.0, "phase": 0.0} for side in ("uphill", "downhill")} for f in FEATURES}
        for side, sign in (("uphill", 1.0), ("downhill", -1.0)):
            for spec in FEATURES:
                mine = [p for p in self.incline_points_ if p.feature == spec.name and sign * p.incline_deg > 0]
                if mine:
                    g = np.array([p.incline_deg for p in mine])
                    for kind, attr in (("value", "value_change"), ("phase", "phase_change")):
                        d = np.array([getattr(p, attr) for p in mine])
                        self.feature_trends_[spec.name][side][kind] = float(g @ d / (g @ g))

    def _trend(self, feature: str, inclines: np.ndarray, kind: str) -> np.ndarray:
        """The measured-ramp trend of a feature's value or phase at each incline (:meth:`_fit_feature_trends`)."""
        t = self.feature_trends_[feature]
        return np.where(inclines > 0, t["uphill"][kind], t["downhill"][kind]) * inclines

    def _fit_joints(self, reference: ReferenceSet, tasks: np.ndarray) -> None:
        if self.reference_mode not in ("registered", "pooled"):
            raise ValueError("reference_mode must be 'registered' or 'pooled'")
        registered = self.reference_mode == "registered"
        self.trend_task_dims_ = [j for j in range(tasks.shape[1]) if np.ptp(tasks[:, j]) > 0] if registered else []
        landmarks = np.array([[f[name][0] for name in LANDMARKS] for f in self.train_features_])
        self.canonical_landmarks_ = ordered_landmarks(landmarks.mean(axis=0))
        self.trend_lo_ = tasks[:, self.trend_task_dims_].min(axis=0)
        self.trend_hi_ = tasks[:, self.trend_task_dims_].max(axis=0)
        self.landmark_trend_ = (TaskTrend().fit(tasks[:, self.trend_task_dims_], landmarks)
                                if self.trend_task_dims_ else None)
        self.unwarp_ = UniformUnwarp(self.n_ref_points, self.canonical_landmarks_)
        phase = reference.phase
        self.s_ref_ = np.arange(self.n_ref_points) / self.n_ref_points
        self.s_query_ = np.linspace(0.0, 1.0, 101)
        self.incline_grid_: dict[str, dict[str, np.ndarray]] = {}    # side → joint → change per degree (N, 2)
        if self.incline_ is not None:
            for side, per_degree in self.incline_.per_degree_.items():
                if per_degree is not None:
                    self.incline_grid_[side] = {j: np.column_stack([
                        np.interp(self.s_ref_, self.incline_.phase_, per_degree[f"{j}_{q}"]) for q in ("angle", "moment")])
                        for j in JOINTS}
        self.joints_: dict[str, _JointModel] = {}
        for joint in JOINTS:
            curves = [np.column_stack([r.mean[f"{joint}_angle"], r.mean[f"{joint}_moment"]])
                      for r in reference.records]
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
            floor = np.diag([math.radians(0.5) ** 2, 0.01 ** 2])
            sigma = 0.5 * (sigma + np.swapaxes(sigma, 1, 2)) + floor[None]
            trend = None
            if self.trend_task_dims_:
                on_grid = np.array([np.column_stack([np.interp(self.s_ref_, phase, c[:, k]) for k in (0, 1)])
                                    for c in curves])
                trend = TaskTrend().fit(tasks[:, self.trend_task_dims_], on_grid - mu0[None])
            kmp = KMP(length_scale=self.kmp_length_scale, lam=self.kmp_lambda, lam_c=self.kmp_lambda,
                      via_tolerance=0.5 / self.n_ref_points,
                      via_mean_scale=self.via_mean_scale).fit(self.s_ref_, mu0, sigma, self.s_query_)
            self.joints_[joint] = _JointModel(gmm=gmm, kmp=kmp, trend=trend)

    def reference_means(self, task: np.ndarray, trend_cache: dict | None = None) -> dict[str, np.ndarray]:
        """Reference mean (n_ref_points, 2) of (angle, moment) per joint for a task, before the via-points.

        Registered mode: the GMR mean plus the task trend (task clipped to the training range), in canonical
        phase, re-timed to the landmark phases of the landmark trend (not clipped). Pooled mode: the GMR
        mean, the same array (``kmp.mu_ref_``) for every task. On a slope, plus the change the slope makes
        (:mod:`controller_core.incline`), when the model learned one.

        ``trend_cache``: a dict the caller keeps while it asks for many tasks (an envelope's grid): the trend part
        depends only on the trend's task dimensions (speed, when the training tasks vary only in speed), so tasks
        that share them share it.
        """
        if self.landmark_trend_ is None:
            means = {joint: self.joints_[joint].kmp.mu_ref_ for joint in JOINTS}
        else:
            t = np.asarray(task, dtype=float)[self.trend_task_dims_]
            key = tuple(t.tolist())
            means = None if trend_cache is None else trend_cache.get(key)
            if means is None:
                landmarks = self.canonical_landmarks_ + self.landmark_trend_.predict(t)
                weights = self.unwarp_.at(landmarks)
                t_in = np.clip(t, self.trend_lo_, self.trend_hi_)
                means = {joint: self.unwarp_.apply(weights, jm.kmp.mu_ref_ + jm.trend.predict(t_in))
                         for joint, jm in self.joints_.items()}
                if trend_cache is not None:
                    trend_cache[key] = means
        incline = float(task[1])
        change = self.incline_grid_.get("uphill" if incline > 0 else "downhill") if incline != 0.0 else None
        if change is not None:
            means = {joint: mu + incline * change[joint] for joint, mu in means.items()}
        return means

    # -------------------------------------------------------------- predict
    def predict_features(self, speed_mps: float, incline_deg: float) -> list[FeaturePrediction]:
        """GPR predictions of every feature at a task (SI values; timing value = its phase)."""
        mean, sd, outside = self.feature_bank_.predict(np.array([speed_mps, incline_deg], dtype=float))
        return self._features(incline_deg, mean, sd, outside)

    def predict_features_many(self, tasks: np.ndarray) -> list[list[FeaturePrediction]]:
        """:meth:`predict_features` at many (speed, incline) tasks in one evaluation of the GPRs."""
        tasks = np.atleast_2d(np.asarray(tasks, dtype=float))
        mean, sd, outside = self.feature_bank_.predict_many(tasks)
        return [self._features(float(t[1]), m, s, o) for t, m, s, o in zip(tasks, mean, sd, outside, strict=True)]

    def _features(self, incline_deg: float, mean: np.ndarray, sd: np.ndarray, outside: np.ndarray
                  ) -> list[FeaturePrediction]:
        if incline_deg != 0.0:
            mean = mean + incline_deg * self.trend_per_degree_["uphill" if incline_deg > 0 else "downhill"]
        nv = len(FEATURES)
        mean, sd, outside = mean.tolist(), sd.tolist(), outside.tolist()     # ten features: plain floats
        vals, val_sd, val_out = mean[:nv], sd[:nv], outside[:nv]
        phs, ph_sd, ph_out = mean[nv:], sd[nv:], outside[nv:]
        out = []
        for i, spec in enumerate(FEATURES):
            if spec.quantity == "timing":
                phase, phase_std, extrap = vals[i], val_sd[i], bool(val_out[i])
            elif spec.fixed_phase:
                phase, phase_std, extrap = spec.window[0], 0.0, bool(val_out[i])
            else:
                j = _PHASE_GPR_INDEX[spec.name]
                phase, phase_std, extrap = phs[j], ph_sd[j], bool(val_out[i] or ph_out[j])
            out.append(FeaturePrediction(spec=spec, phase=float(min(max(phase, 0.0), 1.0)),
                                         phase_std=float(phase_std), value=float(vals[i]),
                                         std=float(val_sd[i]), extrapolation=extrap))
        return out

    def via_points(self, joint: str, mu_ref: np.ndarray, features: list[FeaturePrediction]) -> list[ViaPoint]:
        """KMP via-points of one joint from predicted features.

        The feature's channel gets the GPR mean and variance; the other channel keeps the task's reference
        mean and variance at that phase (``mu_ref`` on the KMP grid), so it stays free to follow the data.
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

    def _check_table_rules(self) -> None:
        if not isinstance(self.knee_extension_window, bool):
            raise ValueError(f"knee_extension_window must be True or False, got {self.knee_extension_window!r}")
        if self.swing_rule not in SWING_RULES:
            raise ValueError(f"swing_rule must be one of {', '.join(SWING_RULES)}, got {self.swing_rule!r}")
        stiffnesses = (*self.swing_knee_stiffness_Nm_per_rad_per_kg, self.swing_ankle_stiffness_Nm_per_rad_per_kg)
        if len(stiffnesses) != 3 or not all(math.isfinite(k) and k > 0 for k in stiffnesses):
            raise ValueError("swing stiffnesses must be positive finite magnitudes (N·m/rad per kg), got "
                             f"knee {self.swing_knee_stiffness_Nm_per_rad_per_kg!r}, "
                             f"ankle {self.swing_ankle_stiffness_Nm_per_rad_per_kg!r}")
        if not (math.isfinite(self.swing_ankle_clearance_deg) and 0.0 <= self.swing_ankle_clearance_deg <= 15.0):
            raise ValueError(f"swing_ankle_clearance_deg must be within [0, 15] deg, got {self.swing_ankle_clearance_deg!r}")

    def _swing_lines(self, means: dict[str, np.ndarray], fmap: dict[str, FeaturePrediction], toe_off: float,
                     mass_kg: float) -> list[dict[str, tuple[float, float]]]:
        """Swing rows under the target rule, per joint in :data:`JOINTS` order: sub-phase → (k N·m/rad, θe rad).

        Knee swing flexion aims at the predicted swing-flexion peak, knee swing extension at the predicted
        heel-strike angle (the curve at phase 0); the ankle holds its predicted swing dorsiflexion (the most
        dorsiflexed angle after toe-off) plus the clearance margin through both swing sub-phases.
        """
        def within(joint: str, theta: float) -> float:   # a target clamped to the joint's range (rad)
            lo, hi = JOINT_RANGE_RAD[joint]
            return min(max(float(theta), lo), hi)

        k_wf, k_we = self.swing_knee_stiffness_Nm_per_rad_per_kg
        k_a = -self.swing_ankle_stiffness_Nm_per_rad_per_kg * mass_kg
        ankle_swing = means["ankle_angle"][int(np.searchsorted(self.s_query_, toe_off)):]
        ankle_target = within("ankle", ankle_swing.max() + math.radians(self.swing_ankle_clearance_deg))
        lines = {
            "knee": {"swing_flexion": (-k_wf * mass_kg, within("knee", fmap["knee_swing_flexion_peak"].value)),
                     "swing_extension": (-k_we * mass_kg, within("knee", means["knee_angle"][0]))},
            "ankle": {"swing_flexion": (k_a, ankle_target), "swing_extension": (k_a, ankle_target)},
        }
        return [lines[j] for j in JOINTS]

    def _knee_extension_window(self, knee_angle: np.ndarray, b1: float, b2: float) -> dict[str, tuple[float, float]]:
        """The knee's stance-extension fit window: from the stance-flexion peak ``b1`` to the knee's smallest
        angle before toe-off ``b2`` on the predicted curve (phase units); empty (the whole sub-phase) when the
        curve has fewer than 5 grid points of extension there."""
        s = self.s_query_
        i1, i2 = int(np.searchsorted(s, b1)), int(np.searchsorted(s, b2))
        i_min = i1 + int(np.argmin(knee_angle[i1:i2 + 1]))
        if i_min - i1 < 4:
            return {}
        return {"stance_extension": (float(s[i1]), float(s[i_min]))}

    def propose(self, speed_mps: float, incline_deg: float = 0.0, mass_kg: float = 75.0,
                with_vias: bool = True) -> Proposal:
        """Predict curves and the parameter table for a task and patient.

        Args:
            speed_mps: walking speed (m/s), in [0.1, 3].
            incline_deg: incline (deg, + uphill), within ±20.
            mass_kg: patient body mass (kg), 20-200.
            with_vias: False gives the GMR reference through KMP without via-points (a baseline).

        Raises:
            InvalidTaskError: NaN or out-of-range input.
        """
        validate_task(speed_mps, incline_deg, mass_kg)
        features = self.predict_features(speed_mps, incline_deg)
        fmap = {f.spec.name: f for f in features}
        means, stds, vias = self.predict_curves(np.array([speed_mps, incline_deg], dtype=float), features, with_vias)
        boundaries = self._boundaries(fmap)
        fits = self.fit_subphases(means, fmap, boundaries, mass_kg)
        table = self._table(speed_mps, incline_deg, mass_kg, features, fmap, means, boundaries, fits)
        return Proposal(
            speed_mps=speed_mps, incline_deg=incline_deg, mass_kg=mass_kg,
            model_version=self.model_version, data_sha256=self.data_sha256_,
            extrapolation=table.provenance.extrapolation, features=features, phase=self.s_query_, means=means, stds=stds,
            boundaries=boundaries, fits=fits, table=table, violations=check_table(table), vias=vias)

    def propose_table(self, speed_mps: float, incline_deg: float = 0.0, mass_kg: float = 75.0,
                      features: list[FeaturePrediction] | None = None) -> tuple[ParameterTable, list[FeaturePrediction]]:
        """The parameter table of :meth:`propose` and the features it came from, without the curves' std (an
        envelope needs 25 tables, not their display curves). The same table as ``propose(...).table``.

        Args:
            features: the task's features when already predicted (:meth:`predict_features_many`).

        Raises:
            InvalidTaskError: NaN or out-of-range input.
        """
        validate_task(speed_mps, incline_deg, mass_kg)
        if features is None:
            features = self.predict_features(speed_mps, incline_deg)
        fmap = {f.spec.name: f for f in features}
        task = np.array([speed_mps, incline_deg], dtype=float)
        references = self.reference_means(task)
        means: dict[str, np.ndarray] = {}
        for joint in JOINTS:
            jm = self.joints_[joint]
            mu = references[joint]
            mean = jm.kmp.predict_mean(self.via_points(joint, mu, features), None if mu is jm.kmp.mu_ref_ else mu)
            means[f"{joint}_angle"], means[f"{joint}_moment"] = mean[:, 0], mean[:, 1]
        return self._table_from_means(speed_mps, incline_deg, mass_kg, features, fmap, means), features

    def _table_from_means(self, speed_mps: float, incline_deg: float, mass_kg: float,
                          features: list[FeaturePrediction], fmap: dict[str, FeaturePrediction],
                          means: dict[str, np.ndarray]) -> ParameterTable:
        """The table through the predicted mean curves: sub-phase boundaries, line fits, thresholds."""
        boundaries = self._boundaries(fmap)
        fits = self.fit_subphases(means, fmap, boundaries, mass_kg)
        return self._table(speed_mps, incline_deg, mass_kg, features, fmap, means, boundaries, fits)

    def _table(self, speed_mps: float, incline_deg: float, mass_kg: float, features: list[FeaturePrediction],
               fmap: dict[str, FeaturePrediction], means: dict[str, np.ndarray],
               boundaries: tuple[float, float, float], fits: dict[str, list[SubphaseFit]]) -> ParameterTable:
        """The parameter table from the fitted lines, the thresholds from the curves, and its provenance."""
        return ParameterTable(
            rows=self._rows(fits, mass_kg), thresholds=self._thresholds(means, fmap, boundaries, mass_kg),
            provenance=Provenance(model_version=self.model_version, data_sha256=self.data_sha256_,
                                  speed_mps=speed_mps, incline_deg=incline_deg, patient_mass_kg=mass_kg,
                                  extrapolation=any(f.extrapolation for f in features)))

    @staticmethod
    def _boundaries(fmap: dict[str, FeaturePrediction]) -> tuple[float, float, float]:
        """Sub-phase boundaries (phase): stance-flexion peak, toe-off, swing-flexion peak."""
        return (fmap["knee_stance_flexion_peak"].phase, fmap["toe_off"].value, fmap["knee_swing_flexion_peak"].phase)

    def propose_envelope(self, speeds_mps: list[float] | np.ndarray, inclines_deg: list[float] | np.ndarray,
                         mass_kg: float = 75.0, nominal: tuple[float, float] = (1.2, 0.0),
                         steps: NeighbourSteps = DEFAULT_STEPS) -> Envelope:
        """Tables over a speed × incline grid, each the table :meth:`propose_table` gives (computed together: one
        GPR evaluation, the reference trend once per speed, one stacked KMP solve per joint), held to the neighbour
        rule (:mod:`controller_core.envelope`). Check the result with :func:`controller_core.envelope.check_envelope`.

        Raises:
            InvalidTaskError: a bad axis (fewer than 2 or more than 15 values, not increasing, out of range) or mass.
        """
        validate_task(1.0, 0.0, mass_kg)
        speeds, inclines = list(np.asarray(speeds_mps, dtype=float)), list(np.asarray(inclines_deg, dtype=float))
        validate_axes(speeds, inclines)
        grid = [(s, g) for s in speeds for g in inclines]
        features = self.predict_features_many(np.array(grid))                 # one GPR evaluation
        trends: dict = {}                                                       # the reference's trend, once per speed
        references = [self.reference_means(np.array(task), trends) for task in grid]
        curves: list[dict[str, np.ndarray]] = [{} for _ in grid]
        for joint in JOINTS:                                                    # one stacked KMP solve per joint
            kmp = self.joints_[joint].kmp
            mus = [None if r[joint] is kmp.mu_ref_ else r[joint] for r in references]
            vias = [self.via_points(joint, r[joint], f) for r, f in zip(references, features, strict=True)]
            for c, mean in zip(curves, kmp.predict_mean_many(vias, mus), strict=True):
                c[f"{joint}_angle"], c[f"{joint}_moment"] = mean[:, 0], mean[:, 1]
        tables = {task: (self._table_from_means(*task, mass_kg, f, {x.spec.name: x for x in f}, c), f)
                  for task, f, c in zip(grid, features, curves, strict=True)}

        def node_table(speed: float, incline: float, mass: float) -> tuple[ParameterTable, list[FeaturePrediction]]:
            return tables[(speed, incline)]      # the same table as propose_table(speed, incline, mass) gives

        return build_envelope(node_table, speeds, inclines, mass_kg, self.model_version, self.data_sha256_, nominal,
                              steps)

    def predict_curves(self, task: np.ndarray, features: list[FeaturePrediction], with_vias: bool = True
                       ) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray], dict[str, list[ViaPoint]]]:
        """Mean and std of every channel on the query grid (SI; per kg), and the via-points per joint: the task's
        reference reshaped by KMP through the predicted features."""
        means: dict[str, np.ndarray] = {}
        stds: dict[str, np.ndarray] = {}
        vias_by_joint: dict[str, list[ViaPoint]] = {}
        references = self.reference_means(task)
        for joint in JOINTS:
            jm = self.joints_[joint]
            mu = references[joint]
            mu_arg = None if mu is jm.kmp.mu_ref_ else mu   # None: the cached solve of the fitted means
            vias = self.via_points(joint, mu, features) if with_vias else []
            vias_by_joint[joint] = vias
            mean, sd = jm.kmp.predict_std(vias, mu=mu_arg)
            means[f"{joint}_angle"], means[f"{joint}_moment"] = mean[:, 0], mean[:, 1]
            stds[f"{joint}_angle"], stds[f"{joint}_moment"] = sd[:, 0], sd[:, 1]
        if self.incline_ is not None and task[1] != 0.0:
            extra = self.incline_.std(float(task[1]), self.between_subject_sd(float(task[0])))
            for channel in CHANNELS:   # the incline change's phase grid is the query grid (both 101 points over [0, 1])
                stds[channel] = np.hypot(stds[channel], extra[channel])
        return means, stds, vias_by_joint

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

    def fit_subphases(self, means: dict[str, np.ndarray], fmap: dict[str, FeaturePrediction],
                      boundaries: tuple[float, float, float], mass_kg: float) -> dict[str, list[SubphaseFit]]:
        """Quasi-stiffness lines per joint and sub-phase through the predicted curves (moments scaled to the
        patient's mass): least squares in stance, the swing targets in swing under the default swing rule."""
        floor = self.min_restoring_stiffness_Nm_per_rad_per_kg * mass_kg
        max_k = -floor if floor > 0 else None
        fixed = (self._swing_lines(means, fmap, boundaries[1], mass_kg) if self.swing_rule == "target" else None)
        windows = ([self._knee_extension_window(means["knee_angle"], boundaries[0], boundaries[1]) if j == "knee"
                    else {} for j in JOINTS] if self.knee_extension_window else None)
        joint_fits = fit_quasi_stiffness_joints(
            self.s_query_, np.array([means[f"{j}_angle"] for j in JOINTS]),
            np.array([means[f"{j}_moment"] for j in JOINTS]) * mass_kg,
            boundaries, [JOINT_RANGE_RAD[j] for j in JOINTS], max_k, fixed, windows)
        fits = dict(zip(JOINTS, joint_fits, strict=True))
        fits["knee"][0] = self._support_floor(fits["knee"][0], means, boundaries, mass_kg)
        return fits

    def _support_floor(self, fit: SubphaseFit, means: dict[str, np.ndarray], boundaries: tuple[float, float, float],
                       mass_kg: float) -> SubphaseFit:
        """The knee's stance-flexion line held at the stance support floor where the fit is softer (θe re-fitted
        over the sub-phase with k fixed)."""
        ceiling = -self.knee_support_floor_Nm_per_rad_per_kg * mass_kg
        if fit.k_Nm_per_rad <= ceiling:
            return fit
        inside = subphase_masks(self.s_query_, boundaries)[SUBPHASES.index(fit.subphase)]
        theta_e, r2 = fit_fixed_k(means["knee_angle"][inside], means["knee_moment"][inside] * mass_kg, ceiling,
                                  JOINT_RANGE_RAD["knee"])
        return replace(fit, k_Nm_per_rad=ceiling, theta_e_rad=theta_e, r2=r2, guarded=True, method="support_floor")

    @staticmethod
    def _rows(fits: dict[str, list[SubphaseFit]], mass_kg: float) -> list[ParameterRow]:
        """Table rows from the fits, with the default damping for the patient's mass. The values are finite floats
        by construction and the table is limit-checked as a whole; edited tables go through full validation."""
        return [ParameterRow.model_construct(
            joint=joint, subphase=f.subphase, k_Nm_per_rad=f.k_Nm_per_rad, theta_e_deg=math.degrees(f.theta_e_rad),
            b_Nm_s_per_rad=DEFAULT_DAMPING_NMS_PER_RAD_PER_KG[joint][f.subphase] * mass_kg,
            r2=f.r2, guarded=f.guarded, fit_method=f.method) for joint, jf in fits.items() for f in jf]

    def _thresholds(self, means: dict[str, np.ndarray], fmap: dict[str, FeaturePrediction],
                    boundaries: tuple[float, float, float], mass_kg: float) -> Thresholds:
        """The state machine's transitions: the predicted ankle moment at the end of stance flexion (or the knee
        extending), the load fractions of body weight, and a fraction of the predicted knee swing peak."""
        weight_N = body_weight_N(mass_kg)
        return Thresholds(
            sf_to_se_ankle_moment_Nm=float(np.interp(boundaries[0], self.s_query_, means["ankle_moment"])) * mass_kg,
            se_to_wf_load_N=self.load_fractions[0] * weight_N,
            wf_to_we_knee_angle_deg=self.swing_threshold_fraction * math.degrees(
                fmap["knee_swing_flexion_peak"].value),
            we_to_sf_load_N=self.load_fractions[1] * weight_N,
            min_state_time_s=self.state_time_s[0], max_state_time_s=self.state_time_s[1],
            sf_to_se_knee_extension_deg_per_s=self.stance_extension_knee_speed_deg_per_s)
