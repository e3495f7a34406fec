"""How command results are printed: the readable proposal table, flat key-value results, JSON files."""

from __future__ import annotations

import json


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
