"""How command results are printed: the readable proposal table, flat key-value results, the comparison tables."""

from __future__ import annotations

import json
from pathlib import Path

from controller_core.gait_metrics import GAIT_CHANNELS, difference_keys


def print_proposal(d: dict) -> None:
    """A proposal (its JSON form) as readable tables: task, features ± SD, parameter table, thresholds, safety."""
    t = d["task"]
    print(f"Task: {t['speed_mps']:.2f} m/s, incline {t['incline_deg']:+.1f} deg, patient {t['mass_kg']:.1f} kg")
    print(f"Model: {d['model']['version']}  data sha256 {d['model']['data_sha256'][:16]}…")
    if d["extrapolation"]:
        print("WARNING: task outside the training data for some features (extrapolation); see std.")
    print("\nPredicted features (GPR, mean ± 1 SD)")
    print(f"  {'feature':34s} {'phase %':>9s} {'value':>16s}  unit")
    for f in d["features"]:
        flag = "  (extrapolated)" if f["extrapolation"] else ""
        print(f"  {f['name']:34s} {100 * f['phase']:5.1f}±{100 * f['phase_std']:<3.1f}"
              f" {f['value']:8.3f} ± {f['std']:<6.3f} {f['unit']}{flag}")
    print("\nParameter table (τ = k(θ − θe) − bθ̇; k < 0 is restoring)")
    print(f"  {'joint':6s} {'sub-phase':17s} {'k N·m/rad':>10s} {'k N·m/deg':>10s} {'θe deg':>8s} "
          f"{'b N·m·s/rad':>11s} {'R²':>6s}")
    for r in d["table"]:
        g = f" {r['fit_method'].replace('_', ' ')}" if r["guarded"] else ""
        print(f"  {r['joint']:6s} {r['subphase']:17s} {r['k_Nm_per_rad']:10.1f} {r['k_Nm_per_deg']:10.3f} "
              f"{r['theta_e_deg']:8.2f} {r['b_Nm_s_per_rad']:11.2f} {r['r2']:6.2f}{g}")
    if any(r["fit_method"] == "swing_target" for r in d["table"]):
        print("  swing target: not a fit; θe is the predicted swing target, k the model's swing stiffness")
    th = d["thresholds"]
    print("\nState-machine thresholds")
    for k, v in th.items():
        print(f"  {k:28s} {v:9.2f}")
    s = d["safety"]
    print("\nSafety limits: " + ("all within limits" if s["ok"] else "VIOLATIONS:"))
    for v in s["violations"]:
        print(f"  - {v['message']}")


def emit(d: dict, fmt: str) -> None:
    """Print a flat result as one JSON object or as aligned ``key value`` lines."""
    if fmt == "json":
        print(json.dumps(d))
    else:
        for k, v in d.items():
            print(f"{k:40s} {v}")


def _cell(v: object) -> str:
    return "—" if v is None else f"{v:.2f}" if isinstance(v, float) else str(v)


def format_compare(rows: list[dict]) -> str:
    """Markdown table of a comparison (one row per task and controller)."""
    cols = ["speed_mps", "incline_deg", "controller", "strides", "falls", "toe_catches", "loaded_swing_ms_max_stride",
            "knee_angle_rmse_deg", "ankle_angle_rmse_deg", "knee_moment_rmse_Nm_per_kg", "ankle_moment_rmse_Nm_per_kg",
            "real_time_factor"]
    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    lines += ["| " + " | ".join(_cell(r.get(c)) for c in cols) + " |" for r in rows]
    verdicts = [r for r in rows if r.get("vs_fsmic")]
    if verdicts:
        keys = [difference_keys(channel) for channel in GAIT_CHANNELS]
        lines += ["", "learned − FSMIC RMSE, 95 % interval over strides (bootstrap), verdict:", "",
                  "| speed_mps | incline_deg | " + " | ".join(k for k, _, _ in keys) + " |",
                  "|" + "---|" * (2 + len(keys))]
        for r in verdicts:
            v = r["vs_fsmic"]
            cells = []
            for key, ci_key, verdict_key in keys:
                d, ci = v.get(key), v.get(ci_key)
                cells.append("—" if d is None else f"{d:+.2f} [{ci[0]:+.2f}, {ci[1]:+.2f}] {v[verdict_key]}")
            lines.append(f"| {_cell(r.get('speed_mps'))} | {_cell(r.get('incline_deg'))} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def format_course_compare(result: dict) -> str:
    """Markdown tables of a course comparison: per controller, per segment, estimation, adaptive minus the others."""
    from controller_core.gait_metrics import GAIT_CHANNELS

    def ci(v: object) -> str:
        return "—" if not v else f"[{v[0]:.2f}, {v[1]:.2f}]"

    keys = [c.replace("_deg", "_rmse_deg").replace("_Nm_per_kg", "_rmse_Nm_per_kg") for c in GAIT_CHANNELS]
    c = result["course"]
    lines = [f"Course {c['name']}: " + " → ".join(f"{s['speed_mps']:g} m/s {s['incline_deg']:+g}°" for s in c["segments"])
             + f" ({c['transition_s']:g} s transitions); each stride scored at its own task", "",
             "| controller | strides | falls | toe_catches | loaded_swing_ms_max_stride | "
             + " | ".join(f"{k} (95 % CI)" for k in keys) + " |", "|" + "---|" * (5 + len(keys))]
    for r in result["rows"]:
        cells = [f"{_cell(r.get(k))} {ci(r.get(k.replace('_rmse_', '_rmse_ci95_')))}" for k in keys]
        lines.append(f"| {r['controller']} | {r['strides']} | {r['falls']} | {r['toe_catches']} | "
                     f"{_cell(r.get('loaded_swing_ms_max_stride'))} | " + " | ".join(cells) + " |")
    lines += ["", "Per segment (knee / ankle angle RMSE, deg):", "",
              "| segment | " + " | ".join(r["controller"] for r in result["rows"]) + " |",
              "|" + "---|" * (1 + len(result["rows"]))]
    for k, seg in enumerate(result["rows"][0]["by_segment"]):
        cells = []
        for r in result["rows"]:
            s = r["by_segment"][k]
            cells.append(f"{_cell(s['knee_angle_rmse_deg'])} / {_cell(s['ankle_angle_rmse_deg'])} ({s['strides']})")
        lines.append(f"| {seg['speed_mps']:g} m/s {seg['incline_deg']:+g}° | " + " | ".join(cells) + " |")
    for r in result["rows"]:
        if "estimation" in r:
            e = r["estimation"]
            lines += ["", f"Task estimation ({r['controller']}): speed within ±0.1 m/s on "
                          f"{100 * (e['speed_within_0_1_mps_fraction'] or 0):.1f} % and incline within ±1.5° on "
                          f"{100 * (e['incline_within_1_5_deg_fraction'] or 0):.1f} % of {e['strides_counted']} "
                          f"strides (first {e['skipped_after_each_change']} after each change not counted); "
                          f"strides by mode {r['strides_by_mode']}"]
    lines += ["", "adaptive − other, mean per-stride RMSE, 95 % interval (bootstrap over strides), verdict:", "",
              "| other | " + " | ".join(GAIT_CHANNELS) + " |", "|" + "---|" * (1 + len(GAIT_CHANNELS))]
    for other, rows in result["adaptive_minus"].items():
        cells = []
        for ch in GAIT_CHANNELS:
            d = rows[ch]
            cells.append("—" if d["rmse_difference"] is None else
                         f"{d['rmse_difference']:+.2f} [{d['ci95'][0]:+.2f}, {d['ci95'][1]:+.2f}] {d['verdict']}")
        lines.append(f"| {other} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def write_json(path: Path, data: object) -> None:
    """Write ``data`` as indented JSON (creating the folder) and say so."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data, indent=2))
    print(f"\nwrote {path}")
