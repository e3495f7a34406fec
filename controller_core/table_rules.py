"""The table rules: from a task's predicted curves and features to the parameter table the leg runs.

Sub-phase windows at the predicted stance-flexion peak, toe-off and swing-flexion peak; a least-squares line
τ = k(θ − θe) per stance sub-phase (:mod:`controller_core.quasi_stiffness`), with the passivity guard and the knee's
stance support floor; swing rows aimed at the predicted swing targets; default damping per kg; the state machine's
thresholds from the curves. No fitted state: the rules are settings.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from controller_core.proposal import FeaturePrediction
from controller_core.quasi_stiffness import SUBPHASES, SubphaseFit, fit_fixed_k, fit_quasi_stiffness_joints, subphase_masks
from controller_core.reference import JOINTS
from controller_core.table import DEFAULT_LIMITS, ParameterRow, ParameterTable, Provenance, Thresholds
from controller_core.units import body_weight_N

JOINT_RANGE_RAD = {"knee": (0.0, math.radians(120.0)), "ankle": (math.radians(-30.0), math.radians(30.0))}
# Damping is not learned (the fit is τ = kθ + c): editable defaults per kg body mass, of the order of published
# finite-state impedance values for adults. The knee's swing values brake the swinging shank: early swing 0.03, chosen
# on the simulated bench; late swing 0.13, about critical with its stiffness (TableRules,
# swing_knee_stiffness_Nm_per_rad_per_kg, says why; the Open Source Leg example's 3.816 N·m·s/rad for 60 kg is 0.06).
DEFAULT_DAMPING_NMS_PER_RAD_PER_KG = {
    "knee": {"stance_flexion": 0.04, "stance_extension": 0.04, "swing_flexion": 0.03, "swing_extension": 0.13},
    "ankle": {"stance_flexion": 0.04, "stance_extension": 0.04, "swing_flexion": 0.01, "swing_extension": 0.02},
}
SWING_RULES: tuple[str, ...] = ("target", "least_squares")
Boundaries = tuple[float, float, float]


# the rows that move the swinging leg against its own inertia: the knee's terminal-swing extension (its flexion is
# thrown by the hip and the push-off, the row there only a light pull toward the peak), the ankle all through swing
SWING_SCALED = {"knee": ("swing_extension",), "ankle": ("swing_flexion", "swing_extension")}
SWING_INERTIA_RATIO_RANGE = (0.5, 2.0)   # legs beyond it are outside what the swing rules were tuned for: held at it


def swing_scale(swing_inertia_ratio: tuple[float, float]) -> dict[str, float]:
    """Per joint, what the swing rows of :data:`SWING_SCALED` multiply their stiffness and damping by on a leg whose
    swing inertia about the knee and the ankle (shank, foot and actuator about the knee; foot and actuator about the
    ankle) is this ratio of the reference leg's, the leg the per-kg swing settings were tuned on: the ratio itself,
    held within :data:`SWING_INERTIA_RATIO_RANGE`. Stiffness and damping in proportion to the inertia keep the swing's
    natural frequency (√(k/I)) and damping ratio (b / 2√(kI)): the shank and foot swing through in the time they had
    on the reference leg. With the reference leg's settings a foot half again as heavy (inertia about the knee 1.5×)
    overshot to full extension and landed 100–200 ms late, a geared knee-ankle with 1.9× the ankle's inertia dragged
    its toe at 1.6 m/s −10°, and both fell on the bench; scaled, neither did (``docs/results.md``). The knee's
    swing-flexion row is left as it is: the knee is thrown into flexion by the hip and the push-off, and scaling that
    light pull made the geared leg catch its toe again at 1.6 m/s −10°.

    Raises:
        ValueError: a ratio that is not a positive finite number.
    """
    lo, hi = SWING_INERTIA_RATIO_RANGE
    out = {}
    for joint, ratio in zip(JOINTS, swing_inertia_ratio, strict=True):
        if not (math.isfinite(ratio) and ratio > 0.0):
            raise ValueError(f"the {joint}'s swing inertia ratio must be a positive finite number, got {ratio!r}")
        out[joint] = min(max(float(ratio), lo), hi)
    return out


def boundaries(features: dict[str, FeaturePrediction]) -> Boundaries:
    """Sub-phase boundaries (phase): the predicted knee stance-flexion peak, toe-off and knee swing-flexion peak."""
    return (features["knee_stance_flexion_peak"].phase, features["toe_off"].value,
            features["knee_swing_flexion_peak"].phase)


class TableRules:
    """How a table is made from predicted curves (hyperparameters only; nothing is fitted).

    Args:
        load_fractions: (toe-off, heel-strike) vertical-load thresholds as fractions of body weight. The default,
            15 % and 40 %, is the Open Source Leg walking example's published pair, which the FSMIC benchmark uses
            too: the two controllers then differ only in their impedance rows, which is what the comparison is about.
        swing_threshold_fraction: WF→WE knee threshold as a fraction of the predicted swing peak.
        state_time_s: (min, max) time in a state.
        stance_extension_knee_speed_deg_per_s: SF→SE also fires when the loaded knee extends faster than this
            (deg/s; 0 turns it off): the stance-flexion peak, which is the sub-phase boundary. The ankle-moment
            threshold alone is late in a fast, flexed landing (1.95 m/s +5° on the bench); 11 deg/s (0.19 rad/s,
            held 20 ms) is above the knee's speed noise at the peak.
        min_restoring_stiffness_Nm_per_rad_per_kg: passivity ceiling of unstable sub-phases (N·m/rad per kg): an
            energy-injecting line whose θe lies inside the angles it sweeps is replaced by k = −value·mass and a
            re-fitted θe. 0.25 (about 19 N·m/rad at 75 kg) lies within the swing stiffnesses of the Open Source
            Leg's published walking example (0.13–0.66 N·m/rad/kg); 0 disables the guard.
        knee_support_floor_Nm_per_rad_per_kg: the stance support floor (the safety limit's
            :attr:`~controller_core.table.SafetyLimits.knee_stance_support_Nm_per_rad_per_kg`): a knee
            stance-flexion line softer than −value·mass holds −value·mass with a re-fitted θe (``support_floor``).
        knee_extension_window: False (default): the knee's stance-extension row is fitted over the whole sub-phase,
            stance-flexion peak to toe-off (the literal framework). True: over the knee's extension only, up to its
            late-stance minimum on the predicted curve (``extension_window``): the row a machine with a separate
            pre-swing state would use; the four-state machine runs this row through pre-swing, where the stiff
            line pushes far more extensor moment against the knee's pre-swing flexion than people have.
        swing_rule: ``"target"`` (default): the swing rows aim at the predicted swing targets (knee swing flexion at
            the swing-flexion peak, knee swing extension at the predicted heel-strike angle, the ankle through swing
            at its predicted swing dorsiflexion plus ``swing_ankle_clearance_deg``); ``"least_squares"``: fitted
            like the stance rows (the literal framework, which falls on the simulated bench).
        swing_knee_stiffness_Nm_per_rad_per_kg: (swing flexion, swing extension) knee stiffness magnitudes per kg
            under the target rule. Swing flexion 0.66, about the Open Source Leg example's 39.7 N·m/rad for 60 kg.
            Swing extension 0.8, with damping 0.13 N·m·s/rad per kg (:data:`DEFAULT_DAMPING_NMS_PER_RAD_PER_KG`): the
            knee, extending at about 300 °/s in terminal swing, comes to rest at its predicted heel-strike angle instead
            of striking its extension stop, as a microprocessor knee's terminal-swing extension damping does; the
            damping is about critical for the shank, foot and actuator about the knee (b ≈ 2√(|k|·I), I ≈ 0.3 kg·m² at
            75 kg). With the example's 0.25 and 0.06 the knee hit full extension on every other stride; a straight knee
            under a thigh still flexed 27° reaches about 15 mm less far down than one flexed 5°, so that foot landed
            100–200 ms late, the next swing started late and landed early on a flexed knee, and the walk alternated
            between a straight and a crouched stride (the simulated bench, 0.84–1.95 m/s).
        swing_ankle_stiffness_Nm_per_rad_per_kg: ankle swing stiffness magnitude per kg (target rule).
        swing_ankle_clearance_deg: dorsiflexion added to the ankle's predicted swing angle (deg). On the bench's foot
            the able-bodied swing angles leave −8 to +2 mm of toe clearance where people keep about 13 mm (Winter
            1992); each degree lifts the toe about 3.4 mm, so 5° restores that margin.
        damping_Nms_per_rad_per_kg: damping per joint and sub-phase per kg (not learned; editable defaults).
    """

    def __init__(self, load_fractions: tuple[float, float] = (0.15, 0.40), swing_threshold_fraction: float = 0.85,
                 state_time_s: tuple[float, float] = (0.05, 1.5), stance_extension_knee_speed_deg_per_s: float = 11.0,
                 min_restoring_stiffness_Nm_per_rad_per_kg: float = 0.25,
                 knee_support_floor_Nm_per_rad_per_kg: float = DEFAULT_LIMITS.knee_stance_support_Nm_per_rad_per_kg,
                 knee_extension_window: bool = False, swing_rule: str = "target",
                 swing_knee_stiffness_Nm_per_rad_per_kg: tuple[float, float] = (0.66, 0.8),
                 swing_ankle_stiffness_Nm_per_rad_per_kg: float = 0.25, swing_ankle_clearance_deg: float = 5.0,
                 damping_Nms_per_rad_per_kg: dict[str, dict[str, float]] | None = None) -> None:
        self.load_fractions = load_fractions
        self.swing_threshold_fraction = swing_threshold_fraction
        self.state_time_s = state_time_s
        self.stance_extension_knee_speed_deg_per_s = stance_extension_knee_speed_deg_per_s
        self.min_restoring_stiffness_Nm_per_rad_per_kg = min_restoring_stiffness_Nm_per_rad_per_kg
        self.knee_support_floor_Nm_per_rad_per_kg = knee_support_floor_Nm_per_rad_per_kg
        self.knee_extension_window = knee_extension_window
        self.swing_rule = swing_rule
        self.swing_knee_stiffness_Nm_per_rad_per_kg = swing_knee_stiffness_Nm_per_rad_per_kg
        self.swing_ankle_stiffness_Nm_per_rad_per_kg = swing_ankle_stiffness_Nm_per_rad_per_kg
        self.swing_ankle_clearance_deg = swing_ankle_clearance_deg
        self.damping_Nms_per_rad_per_kg = damping_Nms_per_rad_per_kg

    def check(self) -> None:
        """Refuse settings the rules cannot use (ValueError naming the setting)."""
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

    def fit_subphases(self, phase: np.ndarray, means: dict[str, np.ndarray], features: dict[str, FeaturePrediction],
                      bounds: Boundaries, mass_kg: float) -> dict[str, list[SubphaseFit]]:
        """Quasi-stiffness lines per joint and sub-phase through the predicted curves (on ``phase``; moments per kg,
        scaled here to the patient's mass): least squares in stance, the swing targets in swing under the default
        swing rule, then the guards."""
        floor = self.min_restoring_stiffness_Nm_per_rad_per_kg * mass_kg
        fixed = self._swing_lines(phase, means, features, bounds[1], mass_kg) if self.swing_rule == "target" else None
        windows = ([self._knee_extension_window(phase, means["knee_angle"], bounds) if j == "knee" else {}
                    for j in JOINTS] if self.knee_extension_window else None)
        joint_fits = fit_quasi_stiffness_joints(
            phase, np.array([means[f"{j}_angle"] for j in JOINTS]), np.array([means[f"{j}_moment"] for j in JOINTS])
            * mass_kg, bounds, [JOINT_RANGE_RAD[j] for j in JOINTS], -floor if floor > 0 else None, fixed, windows)
        fits = dict(zip(JOINTS, joint_fits, strict=True))
        fits["knee"][0] = self._support_floor(phase, fits["knee"][0], means, bounds, mass_kg)
        return fits

    def table(self, phase: np.ndarray, means: dict[str, np.ndarray], features: list[FeaturePrediction],
              mass_kg: float, provenance: Provenance, swing_inertia_ratio: tuple[float, float] = (1.0, 1.0)
              ) -> tuple[ParameterTable, Boundaries, dict[str, list[SubphaseFit]]]:
        """The parameter table through the predicted mean curves, with the boundaries and fits it came from.
        ``swing_inertia_ratio``: the patient's leg's swing inertia about the knee and the ankle over the reference
        leg's (:func:`swing_scale`)."""
        fmap = {f.spec.name: f for f in features}
        bounds = boundaries(fmap)
        fits = self.fit_subphases(phase, means, fmap, bounds, mass_kg)
        scale = swing_scale(swing_inertia_ratio)
        table = ParameterTable(rows=self._rows(fits, mass_kg, scale),
                               thresholds=self._thresholds(phase, means, fmap, bounds, mass_kg),
                               provenance=provenance.model_copy(update={"swing_inertia_ratio": (scale["knee"],
                                                                                                scale["ankle"])}))
        return table, bounds, fits

    def _swing_lines(self, phase: np.ndarray, means: dict[str, np.ndarray], fmap: dict[str, FeaturePrediction],
                     toe_off: float, mass_kg: float) -> list[dict[str, tuple[float, float]]]:
        """Swing rows under the target rule, per joint in :data:`JOINTS` order: sub-phase → (k N·m/rad, θe rad)."""
        def within(joint: str, theta: float) -> float:   # a target clamped to the joint's range (rad)
            lo, hi = JOINT_RANGE_RAD[joint]
            return min(max(float(theta), lo), hi)

        k_wf, k_we = self.swing_knee_stiffness_Nm_per_rad_per_kg
        k_a = -self.swing_ankle_stiffness_Nm_per_rad_per_kg * mass_kg
        ankle_swing = means["ankle_angle"][int(np.searchsorted(phase, toe_off)):]
        ankle_target = within("ankle", ankle_swing.max() + math.radians(self.swing_ankle_clearance_deg))
        lines = {
            "knee": {"swing_flexion": (-k_wf * mass_kg, within("knee", fmap["knee_swing_flexion_peak"].value)),
                     "swing_extension": (-k_we * mass_kg, within("knee", means["knee_angle"][0]))},
            "ankle": {"swing_flexion": (k_a, ankle_target), "swing_extension": (k_a, ankle_target)},
        }
        return [lines[j] for j in JOINTS]

    @staticmethod
    def _knee_extension_window(phase: np.ndarray, knee_angle: np.ndarray, bounds: Boundaries
                               ) -> dict[str, tuple[float, float]]:
        """The knee's stance-extension fit window: from the stance-flexion peak to the knee's smallest angle before
        toe-off on the predicted curve (phase units); empty (the whole sub-phase) with fewer than 5 grid points."""
        i1, i2 = int(np.searchsorted(phase, bounds[0])), int(np.searchsorted(phase, bounds[1]))
        i_min = i1 + int(np.argmin(knee_angle[i1:i2 + 1]))
        if i_min - i1 < 4:
            return {}
        return {"stance_extension": (float(phase[i1]), float(phase[i_min]))}

    def _support_floor(self, phase: np.ndarray, fit: SubphaseFit, means: dict[str, np.ndarray], bounds: Boundaries,
                       mass_kg: float) -> SubphaseFit:
        """The knee's stance-flexion line held at the stance support floor where the fit is softer (θe re-fitted
        over the sub-phase with k fixed)."""
        ceiling = -self.knee_support_floor_Nm_per_rad_per_kg * mass_kg
        if fit.k_Nm_per_rad <= ceiling:
            return fit
        inside = subphase_masks(phase, bounds)[SUBPHASES.index(fit.subphase)]
        theta_e, r2 = fit_fixed_k(means["knee_angle"][inside], means["knee_moment"][inside] * mass_kg, ceiling,
                                  JOINT_RANGE_RAD["knee"])
        return replace(fit, k_Nm_per_rad=ceiling, theta_e_rad=theta_e, r2=r2, guarded=True, method="support_floor")

    def _rows(self, fits: dict[str, list[SubphaseFit]], mass_kg: float, scale: dict[str, float]) -> list[ParameterRow]:
        """Table rows from the fits, with the damping for the patient's mass, the swing rows' stiffness and damping
        times ``scale`` per joint (the leg's swing inertia: :func:`swing_scale`). The values are finite floats by
        construction and the table is limit-checked as a whole; edited tables go through full validation."""
        damping = self.damping_Nms_per_rad_per_kg or DEFAULT_DAMPING_NMS_PER_RAD_PER_KG

        def times(joint: str, subphase: str) -> float:
            return scale[joint] if subphase in SWING_SCALED[joint] else 1.0

        return [ParameterRow.model_construct(
            joint=joint, subphase=f.subphase, k_Nm_per_rad=f.k_Nm_per_rad * times(joint, f.subphase),
            theta_e_deg=math.degrees(f.theta_e_rad),
            b_Nm_s_per_rad=damping[joint][f.subphase] * mass_kg * times(joint, f.subphase),
            r2=f.r2, guarded=f.guarded, fit_method=f.method) for joint, jf in fits.items() for f in jf]

    def _thresholds(self, phase: np.ndarray, means: dict[str, np.ndarray], fmap: dict[str, FeaturePrediction],
                    bounds: Boundaries, mass_kg: float) -> Thresholds:
        """The state machine's transitions: the predicted ankle moment at the end of stance flexion (or the knee
        extending), the load fractions of body weight, and a fraction of the predicted knee swing peak."""
        weight_N = body_weight_N(mass_kg)
        return Thresholds(
            sf_to_se_ankle_moment_Nm=float(np.interp(bounds[0], phase, means["ankle_moment"])) * mass_kg,
            se_to_wf_load_N=self.load_fractions[0] * weight_N,
            wf_to_we_knee_angle_deg=self.swing_threshold_fraction * math.degrees(fmap["knee_swing_flexion_peak"].value),
            we_to_sf_load_N=self.load_fractions[1] * weight_N,
            min_state_time_s=self.state_time_s[0], max_state_time_s=self.state_time_s[1],
            sf_to_se_knee_extension_deg_per_s=self.stance_extension_knee_speed_deg_per_s)
