"""Target features: the extrema that characterise a walking task, each as (phase, value).

A feature is found in a phase window as the most extreme *interior local* extremum (first-difference sign
change), refined by a parabola through the three samples around it, so a curve that is monotonic in the
window raises :class:`FeatureNotFoundError` instead of silently returning the window edge. A feature of kind
``at`` is the curve's value at a fixed phase instead (the knee's flexion at heel strike, the feature a slope
moves most: about 1° on the level, 28° up a 10° ramp).

Units: phase in [0, 1]; angle values in rad; moment values in N·m/kg (project sign convention: knee
flexion +, ankle dorsiflexion +, internal moment + in the direction of + angle). Toe-off is a timing
feature whose value is its phase.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from controller_core.reference import ReferenceRecord


class FeatureNotFoundError(ValueError):
    """A curve has no interior extremum of the required kind in the feature's window."""


@dataclass(frozen=True)
class FeatureSpec:
    """Definition of one target feature.

    Attributes:
        name: stable identifier used in JSON and in the model.
        joint: ``knee``, ``ankle`` or ``limb`` (timing).
        quantity: ``angle``, ``moment`` or ``timing``.
        kind: ``max``, ``min`` or ``at`` (the value at ``window[0]``: a fixed phase).
        window: (start, end) phase window searched, in [0, 1].
        label: clinician-readable description.
    """

    name: str
    joint: str
    quantity: str
    kind: str
    window: tuple[float, float]
    label: str

    @property
    def fixed_phase(self) -> bool:
        """The feature sits at a fixed phase (kind ``at``): only its value is predicted."""
        return self.kind == "at"

    @property
    def channel(self) -> str:
        """Curve channel the feature is read from (``knee_angle`` ...); empty for timing features."""
        return f"{self.joint}_{self.quantity}" if self.quantity in ("angle", "moment") else ""


FEATURES: tuple[FeatureSpec, ...] = (
    FeatureSpec("knee_heel_strike_angle", "knee", "angle", "at", (0.0, 0.0),
                "knee flexion at heel strike"),
    FeatureSpec("knee_stance_flexion_peak", "knee", "angle", "max", (0.03, 0.30),
                "knee stance-flexion peak (loading response)"),
    FeatureSpec("knee_swing_flexion_peak", "knee", "angle", "max", (0.55, 0.90),
                "knee swing-flexion peak"),
    FeatureSpec("ankle_dorsiflexion_peak", "ankle", "angle", "max", (0.20, 0.62),
                "ankle peak dorsiflexion (terminal stance)"),
    FeatureSpec("ankle_plantarflexion_peak", "ankle", "angle", "min", (0.55, 0.80),
                "ankle peak plantarflexion (initial swing)"),
    FeatureSpec("knee_extensor_moment_peak", "knee", "moment", "min", (0.02, 0.30),
                "knee extensor moment peak (loading response)"),
    FeatureSpec("knee_flexor_moment_peak", "knee", "moment", "max", (0.80, 1.00),
                "knee flexor moment peak (terminal swing)"),
    FeatureSpec("ankle_plantarflexor_moment_peak", "ankle", "moment", "min", (0.35, 0.65),
                "ankle plantarflexor moment peak (terminal stance)"),
    FeatureSpec("ankle_dorsiflexor_moment_peak", "ankle", "moment", "max", (0.00, 0.16),
                "ankle dorsiflexor moment peak (loading response)"),
    FeatureSpec("toe_off", "limb", "timing", "max", (0.45, 0.80),
                "toe-off (end of stance)"),
)
FEATURES_BY_NAME: dict[str, FeatureSpec] = {f.name: f for f in FEATURES}
CURVE_FEATURES: tuple[FeatureSpec, ...] = tuple(f for f in FEATURES if f.quantity != "timing")
PHASED_FEATURES: tuple[FeatureSpec, ...] = tuple(f for f in CURVE_FEATURES if not f.fixed_phase)


def find_extremum(phase: np.ndarray, curve: np.ndarray, spec: FeatureSpec) -> tuple[float, float]:
    """Most extreme interior local extremum of ``curve`` in ``spec.window``.

    Returns:
        (phase, value) refined by a parabola through the neighbouring samples.

    Raises:
        FeatureNotFoundError: no interior extremum of the required kind in the window.
    """
    sign = 1.0 if spec.kind == "max" else -1.0
    y = sign * np.asarray(curve, dtype=float)
    lo, hi = spec.window
    idx = np.flatnonzero((phase >= lo) & (phase <= hi))
    # interior candidates: strictly within the sampled curve and within the window
    cands = [i for i in idx if 0 < i < len(y) - 1 and y[i] >= y[i - 1] and y[i] > y[i + 1]]
    if not cands:
        raise FeatureNotFoundError(
            f"{spec.name}: no {spec.kind} inside phase window {lo:.2f}-{hi:.2f} (curve is monotonic there)"
        )
    i = max(cands, key=lambda j: y[j])
    y0, y1, y2 = y[i - 1], y[i], y[i + 1]
    denom = y0 - 2.0 * y1 + y2
    delta = 0.0 if denom == 0.0 else float(np.clip(0.5 * (y0 - y2) / denom, -0.5, 0.5))
    step = phase[i + 1] - phase[i]
    value = y1 - 0.25 * (y0 - y2) * delta
    return float(phase[i] + delta * step), float(sign * value)


def estimate_toe_off(phase: np.ndarray, ankle_moment: np.ndarray, fraction: float = 0.05) -> float:
    """Toe-off estimated from the ankle moment when no event is published.

    The stance plantarflexor moment falls to about zero when the foot leaves the ground; toe-off is
    taken as the first phase after the plantarflexor peak where |moment| < ``fraction`` × |peak|
    (linear interpolation between samples).
    """
    peak_phase, peak_value = find_extremum(
        phase, ankle_moment, FEATURES_BY_NAME["ankle_plantarflexor_moment_peak"])
    i_peak = int(np.searchsorted(phase, peak_phase))
    threshold = fraction * abs(peak_value)
    for i in range(i_peak, len(phase) - 1):
        a, b = abs(ankle_moment[i]), abs(ankle_moment[i + 1])
        if b < threshold <= a:
            return float(phase[i] + (a - threshold) / (a - b) * (phase[i + 1] - phase[i]))
    raise FeatureNotFoundError("toe_off: ankle moment never returns near zero after its plantarflexor peak")


def curve_feature(rec: ReferenceRecord, spec: FeatureSpec) -> tuple[float, float]:
    """One curve feature of a record: (phase, value) in SI (raises :class:`FeatureNotFoundError`)."""
    if spec.fixed_phase:
        at = spec.window[0]
        return at, float(np.interp(at, rec.phase, rec.mean[spec.channel]))
    return find_extremum(rec.phase, rec.mean[spec.channel], spec)


def record_features(rec: ReferenceRecord) -> dict[str, tuple[float, float]]:
    """All features of one record: name -> (phase, value) in SI (timing value = its phase)."""
    out: dict[str, tuple[float, float]] = {spec.name: curve_feature(rec, spec) for spec in CURVE_FEATURES}
    if np.isfinite(rec.toe_off_phase):
        to = float(rec.toe_off_phase)
    else:
        to = estimate_toe_off(rec.phase, rec.mean["ankle_moment"])
    out["toe_off"] = (to, to)
    return out


def feature_sd(rec: ReferenceRecord, spec: FeatureSpec, phase: float) -> float:
    """Published between-subject SD of the curve at the feature's phase (NaN for timing/unknown)."""
    if not spec.channel:
        return float("nan")
    return float(np.interp(phase, rec.phase, rec.sd[spec.channel]))
