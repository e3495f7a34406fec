"""An independent check of the model's incline change against many people: the UM21 envelopes (LocoHub).

Reznick et al. 2021 (UM21: 10 adults, level walking and ±5°/±10° ramps at 0.8, 1.0 and 1.2 m/s) is not shipped;
LocoHub publishes its 95th-percentile min–max ranges at 0, 25, 50 and 75 % of the cycle, per task, pooled over the
task's inclines and speeds (``controller_core/data/locohub_um21_phase_ranges.csv``, copied unchanged). The midpoint
of a range is a crude stand-in for the mean, and the difference of a sloped task's midpoint and level walking's for
the mean change a slope makes: lab offsets (markers, neutral angles) cancel in it, as they do in a change from the
same people's level walking. Nothing here is trained on: the model's change from level, ``propose(v, γ) −
propose(v, 0)`` averaged over the same conditions, is compared with it, next to a model that ignores incline (no
change), as RMSE over the four phases.

Conventions: LocoHub's ankle angle is plantarflexion-positive (its level walking reads −19…−9° at 50 % of the cycle,
where every other source has about 10° of dorsiflexion), so it is negated here; its moments already follow ours
(N·m/kg, ankle plantarflexor negative); knee flexion is positive. LocoHub has no moments for incline walking, so
moments are checked downhill only.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from controller_core.model import QuasiStiffnessModel
from controller_core.reference import CHANNEL_DISPLAY, data_dir

UM21_CSV = "locohub_um21_phase_ranges.csv"
UM21_SPEEDS_MPS: tuple[float, ...] = (0.8, 1.0, 1.2)
UM21_INCLINES_DEG: dict[str, tuple[float, ...]] = {"incline_walking": (5.0, 10.0), "decline_walking": (-5.0, -10.0)}
# LocoHub variable → (our channel, sign that brings it to our convention)
VARIABLES: dict[str, tuple[str, float]] = {
    "knee_flexion_angle_ipsi_rad": ("knee_angle", 1.0), "ankle_flexion_angle_ipsi_rad": ("ankle_angle", -1.0),
    "knee_flexion_moment_ipsi_Nm": ("knee_moment", 1.0), "ankle_flexion_moment_ipsi_Nm": ("ankle_moment", 1.0)}

Ranges = dict[tuple[str, str, int], tuple[float, float]]


def load_um21_ranges(path: str | Path | None = None) -> Ranges:
    """(task, channel, phase %) → (low, high) in our convention and SI (rad, N·m/kg); rows without values skipped.

    Raises:
        ValueError: a row whose unit is not the one its variable's name says (rad or Nm).
    """
    out: Ranges = {}
    with open(path or data_dir() / UM21_CSV, newline="") as f:
        for row in csv.DictReader(f):
            variable = row["variable_as_in_source"]
            if variable not in VARIABLES:
                continue                                    # hip: not a prosthesis joint
            unit = row["unit_as_in_source"]
            if unit.split(" ", 1)[0] != variable.rsplit("_", 1)[1]:       # "rad", or "Nm (label; … look like Nm/kg)"
                raise ValueError(f"{variable}: unit {unit!r} is not the one its name says")
            lo, hi = float(row["lo_as_in_source"]), float(row["hi_as_in_source"])
            if not (math.isfinite(lo) and math.isfinite(hi)):
                continue
            channel, sign = VARIABLES[variable]
            lo, hi = sorted((sign * lo, sign * hi))
            out[(row["task"], channel, int(row["phase_pct"]))] = (lo, hi)
    return out


def _mean_change(model: QuasiStiffnessModel, inclines_deg: tuple[float, ...]) -> dict[str, np.ndarray]:
    """The model's change from level walking per channel on its query grid, averaged over the UM21 conditions."""
    changes: dict[str, list[np.ndarray]] = {c: [] for c in CHANNEL_DISPLAY}
    for speed in UM21_SPEEDS_MPS:
        level = model.propose(speed, 0.0, 75.0).means
        for incline in inclines_deg:
            sloped = model.propose(speed, incline, 75.0).means
            for c in CHANNEL_DISPLAY:
                changes[c].append(sloped[c] - level[c])
    return {c: np.mean(v, axis=0) for c, v in changes.items()}


def um21_change_check(model: QuasiStiffnessModel, ranges: Ranges | None = None) -> dict:
    """The model's change from level against UM21's (range midpoints), per side of level and channel: the values
    at each phase (display units), RMSE over the phases for the model and for ignoring incline, their ratio, and
    the mean ratio over every (side, channel) that UM21 has."""
    ranges = ranges if ranges is not None else load_um21_ranges()
    out: dict[str, object] = {"source": "Reznick et al. 2021 (UM21) via LocoHub validation ranges, midpoints",
                              "speeds_mps": list(UM21_SPEEDS_MPS), "sides": {}}
    ratios = []
    for task, inclines in UM21_INCLINES_DEG.items():
        model_change = _mean_change(model, inclines)
        side: dict[str, dict] = {}
        for c, (name, scale) in CHANNEL_DISPLAY.items():
            phases = [p for p in (0, 25, 50, 75) if (task, c, p) in ranges and ("level_walking", c, p) in ranges]
            if not phases:
                continue
            measured = np.array([(sum(ranges[(task, c, p)]) - sum(ranges[("level_walking", c, p)])) / 2.0 * scale
                                 for p in phases])
            predicted = np.array([np.interp(p / 100.0, model.s_query_, model_change[c]) * scale for p in phases])
            rmse_model = float(np.sqrt(np.mean((predicted - measured) ** 2)))
            rmse_ignore = float(np.sqrt(np.mean(measured ** 2)))
            ratio = rmse_model / rmse_ignore
            ratios.append(ratio)
            side[name] = {"phase_pct": phases, "um21_change": measured.tolist(), "model_change": predicted.tolist(),
                          "rmse_model": rmse_model, "rmse_ignore_incline": rmse_ignore, "ratio_to_ignore_incline": ratio}
        out["sides"][task] = {"inclines_deg": list(inclines), "channels": side}   # type: ignore[index]
    out["mean_ratio_to_ignore_incline"] = float(np.mean(ratios))
    return out


def format_um21_report(report: dict) -> str:
    """Markdown table of :func:`um21_change_check`'s report."""
    lines = ["Change from level walking against UM21 (10 people; LocoHub range midpoints, pooled ±5°/±10° and "
             "0.8–1.2 m/s)", "", "| side | channel | phase % | UM21 | model | RMSE model | RMSE ignoring incline "
             "| ratio |", "|---|---|---|---|---|---|---|---|"]
    for task, side in report["sides"].items():
        for channel, r in side["channels"].items():
            fmt = (lambda v: f"{v:+.1f}") if channel.endswith("_deg") else (lambda v: f"{v:+.2f}")
            lines.append(f"| {task.split('_')[0]} | {channel} | {'/'.join(map(str, r['phase_pct']))} "
                         f"| {' '.join(fmt(v) for v in r['um21_change'])} | {' '.join(fmt(v) for v in r['model_change'])} "
                         f"| {r['rmse_model']:.3f} | {r['rmse_ignore_incline']:.3f} | {r['ratio_to_ignore_incline']:.2f} |")
    lines += ["", f"Mean ratio to ignoring incline: {report['mean_ratio_to_ignore_incline']:.2f} (a crude check: "
                  "range midpoints stand in for means)"]
    return "\n".join(lines)
