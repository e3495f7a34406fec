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

import math
from dataclasses import dataclass

import numpy as np

from controller_core.features import CURVE_FEATURES, FEATURES, feature_sd, record_features
from controller_core.gmr import GaussianMixtureRegression
from controller_core.gpr import FeatureGPR, FeatureGPRBank
from controller_core.kmp import KMP, ViaPoint
from controller_core.proposal import FeaturePrediction, Proposal
from controller_core.published_features import PublishedPoint
from controller_core.quasi_stiffness import fit_quasi_stiffness_joints
from controller_core.reference import JOINTS, ReferenceSet
from controller_core.registration import TaskTrend, UniformUnwarp, ordered_landmarks, register
from controller_core.table import ParameterRow, ParameterTable, Provenance, Thresholds, check_table

G = 9.81  # m/s²

SPEED_RANGE_MPS = (0.0, 3.0)       # exclusive low, inclusive high
INCLINE_LIMIT_DEG = 20.0
MASS_RANGE_KG = (20.0, 200.0)
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


class InvalidTaskError(ValueError):
    """A requested task or patient value is out of range or not a number."""


def validate_task(speed_mps: float, incline_deg: float, mass_kg: float) -> None:
    """Refuse NaN and out-of-range requests with a one-line reason."""
    for name, v in (("speed_mps", speed_mps), ("incline_deg", incline_deg), ("mass_kg", mass_kg)):
        if not isinstance(v, (int, float)) or not math.isfinite(v):
            raise InvalidTaskError(f"{name} must be a finite number, got {v!r}")
    if not SPEED_RANGE_MPS[0] < speed_mps <= SPEED_RANGE_MPS[1]:
        raise InvalidTaskError(f"speed_mps = {speed_mps:g} m/s is outside (0, 3] m/s")
    if abs(incline_deg) > INCLINE_LIMIT_DEG:
        raise InvalidTaskError(f"incline_deg = {incline_deg:g} deg is outside [-20, 20] deg")
    if not MASS_RANGE_KG[0] <= mass_kg <= MASS_RANGE_KG[1]:
        raise InvalidTaskError(f"mass_kg = {mass_kg:g} kg is outside [20, 200] kg")


@dataclass
class _JointModel:
    gmm: GaussianMixtureRegression
    kmp: KMP                       # holds the GMR mean and covariance on its grid (mu_ref_, sigma_ref_)
    trend: TaskTrend | None        # task trend of the registered reference (None: pooled reference)


# Gait events whose predicted phases re-time the registered reference (push-off moment peak, toe-off).
LANDMARKS: tuple[str, ...] = ("ankle_plantarflexor_moment_peak", "ankle_plantarflexion_peak")
_PHASE_GPR_INDEX = {f.name: i for i, f in enumerate(CURVE_FEATURES)}  # row of each feature in the phase bank


class QuasiStiffnessModel:
    """Learning quasi-stiffness model (scikit-learn style: hyperparameters here, fitted state with ``_``).

    Defaults were chosen by the leave-one-condition-out evaluation (``quasitune evaluate``; see
    docs/results.md), which makes that evaluation optimistic for them: 20 components, λ = 10, ℓ = 0.08
    (tuned for the pooled reference and kept for the registered one). via_mean_scale = 1 (the plain KMP of
    Huang et al.): the pooled reference needed a harder pull through the via-points (0.1), the registered
    one does not (within 0.002 N·m/kg and 0.02° either way), and with 1 the mean and the covariance share
    one bordered solve.

    Args:
        n_components: GMM components per joint.
        n_ref_points: KMP reference grid size over [0, 1).
        kmp_length_scale: KMP kernel length (phase units).
        kmp_lambda: KMP λ (= λc).
        gpr_restarts: marginal-likelihood optimizer restarts per GPR.
        load_fractions: (toe-off, heel-strike) vertical-load thresholds as fractions of body weight. The
            default, 15 % and 40 %, is the Open Source Leg walking example's published pair, which the FSMIC
            benchmark uses too (``controller_core/fsmic.py``): the two controllers then differ only in their
            impedance rows, which is what the comparison is about. Until 2026-11-21 it was 5 % and 15 %; with
            the published pair the simulated bench showed no toe catches and a smaller knee moment error
            (docs/results.md).
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
        knee_extension_window: False (default): the knee's stance-extension row is fitted over the whole
            sub-phase, stance-flexion peak to toe-off (the literal framework; R² 0.06 at 1.2 m/s, θe clamped to
            0°). True: over the knee's extension only, up to its late-stance minimum on the predicted curve
            (``extension_window``, R² 0.8–0.99; see :mod:`controller_core.quasi_stiffness`). Not the default
            because the four-state machine runs this row through pre-swing too: on the simulated bench the
            stiff line (about −180 N·m/rad, θe 8.6° at 1.2 m/s, 75 kg) tracked the knee angle better at 7 of 8
            tasks but pushed up to −1.4 N·m/kg of extensor moment against the pre-swing knee flexion, where
            people have −0.2 (docs/results.md). It is the stance-extension row a machine with a separate
            pre-swing state would use.
        swing_rule: ``"target"`` (default): the swing rows aim at the predicted swing targets (knee swing
            flexion at the GPR's swing-flexion peak, knee swing extension at the predicted heel-strike angle,
            the ankle through swing at its predicted swing dorsiflexion plus ``swing_ankle_clearance_deg``)
            with the restoring stiffnesses below; ``"least_squares"``: the swing rows are fitted like the
            stance rows (the literal framework; on the simulated bench that table falls, see docs/results.md).
        swing_knee_stiffness_Nm_per_rad_per_kg: (swing flexion, swing extension) knee stiffness magnitudes per
            kg of patient mass under the target rule: 0.66 and 0.25, about the Open Source Leg example's
            39.7 and 15.9 N·m/rad for 60 kg.
        swing_ankle_stiffness_Nm_per_rad_per_kg: ankle swing stiffness magnitude per kg (target rule).
        swing_ankle_clearance_deg: dorsiflexion added to the ankle's predicted swing angle (deg). On the bench's
            foot the able-bodied swing angles leave −8 to +2 mm of toe clearance where people keep about
            13 mm (Winter 1992); each degree lifts the toe about 3.4 mm, so 5° restores that margin.
        random_state: seed for EM and optimizer restarts.
    """

    def __init__(self, n_components: int = 20, n_ref_points: int = 50, kmp_length_scale: float = 0.08,
                 kmp_lambda: float = 10.0, gpr_restarts: int = 2,
                 load_fractions: tuple[float, float] = (0.15, 0.40), swing_threshold_fraction: float = 0.85,
                 state_time_s: tuple[float, float] = (0.05, 1.5), reference_mode: str = "registered",
                 via_mean_scale: float = 1.0, min_restoring_stiffness_Nm_per_rad_per_kg: float = 0.25,
                 knee_extension_window: bool = False, swing_rule: str = "target",
                 swing_knee_stiffness_Nm_per_rad_per_kg: tuple[float, float] = (0.66, 0.25),
                 swing_ankle_stiffness_Nm_per_rad_per_kg: float = 0.25, swing_ankle_clearance_deg: float = 5.0,
                 random_state: int = 0) -> None:
        self.n_components = n_components
        self.n_ref_points = n_ref_points
        self.kmp_length_scale = kmp_length_scale
        self.kmp_lambda = kmp_lambda
        self.gpr_restarts = gpr_restarts
        self.load_fractions = load_fractions
        self.swing_threshold_fraction = swing_threshold_fraction
        self.state_time_s = state_time_s
        self.reference_mode = reference_mode
        self.via_mean_scale = via_mean_scale
        self.min_restoring_stiffness_Nm_per_rad_per_kg = min_restoring_stiffness_Nm_per_rad_per_kg
        self.knee_extension_window = knee_extension_window
        self.swing_rule = swing_rule
        self.swing_knee_stiffness_Nm_per_rad_per_kg = swing_knee_stiffness_Nm_per_rad_per_kg
        self.swing_ankle_stiffness_Nm_per_rad_per_kg = swing_ankle_stiffness_Nm_per_rad_per_kg
        self.swing_ankle_clearance_deg = swing_ankle_clearance_deg
        self.random_state = random_state

    # ------------------------------------------------------------------ fit
    def fit(self, reference: ReferenceSet, published: list[PublishedPoint] | None = None,
            model_version: str = "unversioned", data_sha256: str | None = None,
            progress=None) -> QuasiStiffnessModel:
        """Fit every part of the model.

        Args:
            reference: training curves; their tasks must be finite in every task dimension.
            published: extra feature-value points (e.g. published incline features).
            model_version: stored in every proposal's provenance.
            data_sha256: hash of all training data (defaults to the reference's hash).
            progress: optional callable ``progress(step_name)`` called after each part.
        """
        tick = progress or (lambda _name: None)
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
        self.model_version_ = model_version
        self.data_sha256_ = data_sha256 or reference.data_sha256
        self.published_ = list(published or [])
        self._fit_features(reference, tasks, tick)
        self._fit_joints(reference, tasks, tick)
        return self

    def _fit_features(self, reference: ReferenceSet, tasks: np.ndarray, tick) -> None:
        per_record = [record_features(r) for r in reference.records]
        self.train_features_ = per_record
        self.value_gprs_: dict[str, FeatureGPR] = {}
        self.phase_gprs_: dict[str, FeatureGPR] = {}
        for spec in FEATURES:
            vals = np.array([f[spec.name][1] for f in per_record])
            phases = np.array([f[spec.name][0] for f in per_record])
            se = np.array([feature_sd(r, spec, p) / math.sqrt(r.n) if r.n > 0 else np.nan
                           for r, p in zip(reference.records, phases, strict=True)])
            X, y, y_se = tasks, vals, se
            extra = [p for p in self.published_ if p.feature == spec.name]
            if extra:
                X = np.vstack([X, [[p.speed_mps, p.incline_deg] for p in extra]])
                y = np.concatenate([y, [p.value for p in extra]])
                y_se = np.concatenate([y_se, [p.se for p in extra]])
            self.value_gprs_[spec.name] = FeatureGPR(n_restarts=self.gpr_restarts,
                                                     random_state=self.random_state).fit(X, y, y_se)
            if spec.quantity != "timing":
                self.phase_gprs_[spec.name] = FeatureGPR(n_restarts=self.gpr_restarts,
                                                         random_state=self.random_state).fit(tasks, phases)
            tick(f"GPR {spec.name}")
        # one bank for values then phases: one batched evaluation and shared hull tests per task
        self._bank = FeatureGPRBank([self.value_gprs_[f.name] for f in FEATURES]
                                    + [self.phase_gprs_[f.name] for f in CURVE_FEATURES])

    def _fit_joints(self, reference: ReferenceSet, tasks: np.ndarray, tick) -> None:
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
        self._unwarp = UniformUnwarp(self.n_ref_points, self.canonical_landmarks_)
        phase = reference.phase
        self.s_ref_ = np.arange(self.n_ref_points) / self.n_ref_points
        self.s_query_ = np.linspace(0.0, 1.0, 101)
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
            tick(f"GMM/KMP {joint}")

    def reference_means(self, task: np.ndarray) -> dict[str, np.ndarray]:
        """Reference mean (n_ref_points, 2) of (angle, moment) per joint for a task, before the via-points.

        Registered mode: the GMR mean plus the task trend (task clipped to the training range), in canonical
        phase, re-timed to the landmark phases of the landmark trend (not clipped). Pooled mode: the GMR
        mean, the same array (``kmp.mu_ref_``) for every task.
        """
        if self.landmark_trend_ is None:
            return {joint: self.joints_[joint].kmp.mu_ref_ for joint in JOINTS}
        t = np.asarray(task, dtype=float)[self.trend_task_dims_]
        landmarks = self.canonical_landmarks_ + self.landmark_trend_.predict(t)
        weights = self._unwarp.at(landmarks)
        t_in = np.clip(t, self.trend_lo_, self.trend_hi_)
        return {joint: self._unwarp.apply(weights, jm.kmp.mu_ref_ + jm.trend.predict(t_in))
                for joint, jm in self.joints_.items()}

    # -------------------------------------------------------------- predict
    def predict_features(self, speed_mps: float, incline_deg: float) -> list[FeaturePrediction]:
        """GPR predictions of every feature at a task (SI values; timing value = its phase)."""
        x = np.array([speed_mps, incline_deg], dtype=float)
        mean, sd, outside = self._bank.predict_one(x)
        nv = len(FEATURES)
        vals, val_sd, val_out = mean[:nv], sd[:nv], outside[:nv]
        phs, ph_sd, ph_out = mean[nv:], sd[nv:], outside[nv:]
        out = []
        for i, spec in enumerate(FEATURES):
            if spec.quantity == "timing":
                phase, phase_std, extrap = vals[i], val_sd[i], bool(val_out[i])
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
        kmp = self.joints_[joint].kmp
        phases = np.array([f.phase for f in mine])
        channel = np.array([0 if f.spec.quantity == "angle" else 1 for f in mine])
        n = self.s_ref_.size                                   # the grid is k/n, k = 0…n−1
        pos = np.mod(phases, 1.0) * n
        i0 = np.floor(pos).astype(int) % n
        w = (pos - np.floor(pos))[:, None]
        means = mu_ref[i0] * (1.0 - w) + mu_ref[(i0 + 1) % n] * w            # reference at each via phase
        var = np.diagonal(kmp.sigma_ref_[np.rint(pos).astype(int) % n], axis1=1, axis2=2).copy()
        k = np.arange(len(mine))
        means[k, channel] = [f.value for f in mine]
        var[k, channel] = np.maximum([f.std for f in mine], 1e-6) ** 2
        return [ViaPoint(phase=float(p), mean=m, cov=np.diag(v)) for p, m, v in zip(phases, means, var, strict=True)]

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
            speed_mps: walking speed (m/s), in (0, 3].
            incline_deg: incline (deg, + uphill), within ±20.
            mass_kg: patient body mass (kg), 20-200.
            with_vias: False gives the GMR reference through KMP without via-points (a baseline).

        Raises:
            InvalidTaskError: NaN or out-of-range input.
        """
        validate_task(speed_mps, incline_deg, mass_kg)
        task = np.array([speed_mps, incline_deg], dtype=float)
        features = self.predict_features(speed_mps, incline_deg)
        fmap = {f.spec.name: f for f in features}
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
        b1 = fmap["knee_stance_flexion_peak"].phase
        b2 = fmap["toe_off"].value
        b3 = fmap["knee_swing_flexion_peak"].phase
        boundaries = (b1, b2, b3)
        s = self.s_query_
        rows: list[ParameterRow] = []
        fits = {}
        floor = self.min_restoring_stiffness_Nm_per_rad_per_kg * mass_kg
        max_k = -floor if floor > 0 else None
        fixed = self._swing_lines(means, fmap, b2, mass_kg) if self.swing_rule == "target" else None
        windows = ([self._knee_extension_window(means["knee_angle"], b1, b2) if j == "knee" else {} for j in JOINTS]
                   if self.knee_extension_window else None)
        joint_fits = fit_quasi_stiffness_joints(
            s, np.array([means[f"{j}_angle"] for j in JOINTS]), np.array([means[f"{j}_moment"] for j in JOINTS]) * mass_kg,
            boundaries, [JOINT_RANGE_RAD[j] for j in JOINTS], max_k, fixed, windows)
        for joint, jf in zip(JOINTS, joint_fits, strict=True):
            fits[joint] = jf
            for f in jf:
                # values computed here are finite floats by construction; check_table() below is the
                # limit check at build time, and edited tables go through full validation
                rows.append(ParameterRow.model_construct(
                    joint=joint, subphase=f.subphase, k_Nm_per_rad=f.k_Nm_per_rad,
                    theta_e_deg=math.degrees(f.theta_e_rad),
                    b_Nm_s_per_rad=DEFAULT_DAMPING_NMS_PER_RAD_PER_KG[joint][f.subphase] * mass_kg,
                    r2=f.r2, guarded=f.guarded, fit_method=f.method))
        extrapolation = any(f.extrapolation for f in features)
        weight_N = mass_kg * G
        thresholds = Thresholds(
            sf_to_se_ankle_moment_Nm=float(np.interp(b1, s, means["ankle_moment"])) * mass_kg,
            se_to_wf_load_N=self.load_fractions[0] * weight_N,
            wf_to_we_knee_angle_deg=self.swing_threshold_fraction * math.degrees(
                fmap["knee_swing_flexion_peak"].value),
            we_to_sf_load_N=self.load_fractions[1] * weight_N,
            min_state_time_s=self.state_time_s[0], max_state_time_s=self.state_time_s[1])
        table = ParameterTable(rows=rows, thresholds=thresholds, provenance=Provenance(
            model_version=self.model_version_, data_sha256=self.data_sha256_, speed_mps=speed_mps,
            incline_deg=incline_deg, patient_mass_kg=mass_kg, extrapolation=extrapolation))
        return Proposal(
            speed_mps=speed_mps, incline_deg=incline_deg, mass_kg=mass_kg,
            model_version=self.model_version_, data_sha256=self.data_sha256_,
            extrapolation=extrapolation, features=features, phase=s, means=means, stds=stds,
            boundaries=boundaries, fits=fits, table=table, violations=check_table(table),
            vias=vias_by_joint)
