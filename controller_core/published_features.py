"""Published incline features mapped onto QuasiTune's feature definitions.

The shipped curves are level walking only; the incline information is scalar (``incline_features.csv``).
Where a published feature has the *same definition* as ours, it becomes a GPR training point for that
feature's value (never its phase: no source gives peak timing). The mapping:

| our feature | source feature | source | task |
|---|---|---|---|
| knee_heel_strike_angle | knee_angle_at_initial_contact_deg | Rábago 2016 | +5°, 1.185 m/s |
| knee_stance_flexion_peak | knee_angle_flexion_peak_loading_response_deg | Rábago 2016 | +5°, 1.185 m/s |
| knee_swing_flexion_peak | knee_angle_flexion_peak_swing_deg | Rábago 2016 | +5°, 1.185 m/s |
| ankle_dorsiflexion_peak | ankle_angle_dorsiflexion_peak_terminal_stance_deg | Rábago 2016 | +5°, 1.185 m/s |
| ankle_plantarflexion_peak | ankle_angle_plantarflexion_peak_initial_swing_deg | Rábago 2016 | +5°, 1.185 m/s |
| ankle_plantarflexor_moment_peak | ankle_moment_plantarflexor_peak_terminal_stance | Rábago 2016 | +5°, 1.185 m/s |
| ankle_dorsiflexor_moment_peak | ankle_moment_dorsiflexor_peak_loading_response | Rábago 2016 | +5°, 1.185 m/s |
| toe_off | stance_pct_gait_cycle (÷100) | Rábago 2016 | +5°, 1.185 m/s |
| toe_off | stance time × stride frequency | Franz & Kram 2012 | 0, ±3, ±6, ±9° × 0.75/1.25/1.75 m/s |
| knee_extensor_moment_peak | knee_moment_extensor_peak_stance, downhill/level ratio | Kuster 1993 | −10.9°, self-selected |

Not used, and why:

* Rábago knee moments: flagged ``knee_label_unverified`` in the data (labels not checked against the paper;
  the "extensor midstance" peak is also not our loading-response peak).
* Rábago knee powers: flagged ``knee_power_label_sign_mismatch`` (do not use).
* Sakurai 1994: ``probably_same_cohort_as_kuster1993`` (do not pool); Kuster is used.
* Hip features, vGRF and step/stride lengths: no matching QuasiTune feature.

Kuster 1993 gives no walking speed and its level value (−1.2 N·m/kg) is from another lab than our curves
(Bovi: about −0.42 at the self-selected speed). We therefore transfer the *ratio* downhill/level
(2.6/1.2) onto our self-selected-speed level value and place it at that speed: an explicit assumption
(downhill walking at the self-selected speed), documented here and in the model provenance.

Standard errors: Rábago SD/√10 (per-subject SD computed from 10 controls); Franz & Kram publish SE;
stance fraction SE propagated from stance time and stride frequency SEs (first order, independent);
Kuster ratio SE propagated from both SDs over √12.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from controller_core.reference import SHIPPED_INCLINE_CSV, data_dir, sha256_of

if TYPE_CHECKING:
    import pandas as pd

RABAGO_MAP: dict[str, tuple[str, str]] = {
    # our feature: (source feature, quantity)
    "knee_heel_strike_angle": ("knee_angle_at_initial_contact_deg", "angle"),
    "knee_stance_flexion_peak": ("knee_angle_flexion_peak_loading_response_deg", "angle"),
    "knee_swing_flexion_peak": ("knee_angle_flexion_peak_swing_deg", "angle"),
    "ankle_dorsiflexion_peak": ("ankle_angle_dorsiflexion_peak_terminal_stance_deg", "angle"),
    "ankle_plantarflexion_peak": ("ankle_angle_plantarflexion_peak_initial_swing_deg", "angle"),
    "ankle_plantarflexor_moment_peak": ("ankle_moment_plantarflexor_peak_terminal_stance", "moment"),
    "ankle_dorsiflexor_moment_peak": ("ankle_moment_dorsiflexor_peak_loading_response", "moment"),
    "toe_off": ("stance_pct_gait_cycle", "timing"),
}


@dataclass(frozen=True)
class PublishedPoint:
    """One published feature value usable as a GPR training point (SI units).

    Attributes:
        feature: QuasiTune feature name.
        speed_mps: walking speed (m/s).
        incline_deg: incline (deg, + uphill).
        value: feature value in SI (rad, N·m/kg, or phase fraction for toe-off).
        se: standard error of ``value`` in the same unit.
        source: citation key (``rabago2016`` ...).
        detail: which source columns and what assumption produced it.
        sd: between-subject SD of the feature in that study (same unit); NaN where not published.
    """

    feature: str
    speed_mps: float
    incline_deg: float
    value: float
    se: float
    source: str
    detail: str
    sd: float = float("nan")


def load_incline_table(path: Path | None = None) -> pd.DataFrame:
    """The project's copy of ``incline_features.csv``."""
    import pandas  # when the table is read, not when the model is imported

    return pandas.read_csv(path or data_dir() / SHIPPED_INCLINE_CSV)


def incline_table_sha256() -> str:
    """SHA-256 of the shipped incline feature file."""
    return sha256_of(data_dir() / SHIPPED_INCLINE_CSV)


def _rabago_points(df: pd.DataFrame) -> list[PublishedPoint]:
    rab = df[df["source"] == "rabago2016"].set_index("feature")
    out = []
    for ours, (theirs, quantity) in RABAGO_MAP.items():
        row = rab.loc[theirs]
        n = float(row["n"])
        mean, sd = float(row["mean"]), float(row["sd"])
        if quantity == "angle":
            mean, sd = np.deg2rad(mean), np.deg2rad(sd)
        elif quantity == "timing":
            mean, sd = mean / 100.0, sd / 100.0
        out.append(PublishedPoint(ours, float(row["speed_mps"]), float(row["incline_deg"]), mean,
                                  sd / np.sqrt(n), "rabago2016", f"{theirs} (mean ± SD/sqrt({n:.0f}))", sd))
    return out


def _franz_points(df: pd.DataFrame) -> list[PublishedPoint]:
    fr = df[df["source"] == "franz2012"]
    out = []
    for (speed, incline), g in fr.groupby(["speed_mps", "incline_deg"]):
        rows = g.set_index("feature")
        sf, sf_se = float(rows.loc["stride_frequency_Hz", "mean"]), float(rows.loc["stride_frequency_Hz", "se"])
        st, st_se = float(rows.loc["stance_time_s", "mean"]), float(rows.loc["stance_time_s", "se"])
        frac = st * sf
        se = float(np.hypot(st_se * sf, st * sf_se))
        n = float(rows.loc["stance_time_s", "n"])
        out.append(PublishedPoint("toe_off", float(speed), float(incline), frac, se, "franz2012",
                                  "stance_time_s × stride_frequency_Hz (SE propagated)", se * np.sqrt(n)))
    return out


def _kuster_points(df: pd.DataFrame, self_selected: tuple[float, float] | None) -> list[PublishedPoint]:
    if self_selected is None:
        return []
    speed, level_value = self_selected
    ku = df[(df["source"] == "kuster1993") & (df["feature"] == "knee_moment_extensor_peak_stance")]
    level = ku[ku["incline_deg"] == 0.0].iloc[0]
    down = ku[ku["incline_deg"] < 0.0].iloc[0]
    ratio = float(down["mean"]) / float(level["mean"])
    rel_se = np.hypot(float(down["sd"]) / float(down["mean"]), float(level["sd"]) / float(level["mean"]))
    rel_sd = rel_se
    rel_se /= np.sqrt(float(down["n"]))
    value = level_value * ratio
    return [PublishedPoint(
        "knee_extensor_moment_peak", speed, float(down["incline_deg"]), value, abs(value) * rel_se,
        "kuster1993",
        f"downhill/level ratio {ratio:.3f} applied to the level value {level_value:.3f} N·m/kg at the "
        f"self-selected speed {speed:.2f} m/s (assumption: Kuster's subjects walked at self-selected speed)",
        abs(value) * rel_sd,
    )]


def published_points(self_selected_knee_extensor: tuple[float, float] | None = None,
                     path: Path | None = None) -> list[PublishedPoint]:
    """All published incline points mapped to QuasiTune features.

    Args:
        self_selected_knee_extensor: (speed m/s, level knee extensor moment peak N·m/kg) of the training
            set's self-selected condition, for the Kuster ratio; ``None`` skips Kuster.
        path: alternative incline feature file (default: the shipped copy).
    """
    df = load_incline_table(path)
    return _rabago_points(df) + _franz_points(df) + _kuster_points(df, self_selected_knee_extensor)
