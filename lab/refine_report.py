"""The printed report of ``quasitune refine``: per round the feature errors and the changes, then the evaluation table
(the ``compare --course`` figures plus each controlled feature's mean absolute error against its target)."""

from __future__ import annotations

from controller_core.refine_evidence import QUANTITIES
from lab.comparison import cell


def _ci(v: object) -> str:
    return "—" if not v else f"[{v[0]:.2f}, {v[1]:.2f}]"


def format_refine(result: dict) -> str:
    """Markdown of a refinement on the bench (the JSON of :func:`device_bridge.bench.refine_walks.refine_on_bench`)."""
    keys = [q.key for q in QUANTITIES]
    lines = [f"Leg: {result['leg']}, {result['mass_kg']:g} kg; training: {result['train_course']['name']}; "
             f"evaluation: {result['eval_course']['name']}", "",
             "| round | strides (used) | falls | toe catches | " + " | ".join(keys)
             + " | nodes changed | change (step limits) | bench walks | left beyond tolerance by the search (nodes) |",
             "|" + "---|" * (8 + len(keys))]
    for r in result["rounds"]:
        errs = " | ".join(cell(r["feature_abs_error"].get(k)) for k in keys)
        left: dict[str, int] = {}
        for n in r["nodes"]:
            for k, q in n["quantities"].items():
                if q.get("unreached"):
                    left[k] = left.get(k, 0) + 1
        held = ", ".join(f"{k} ({v})" for k, v in left.items()) or "none"
        lines.append(f"| {r['round']} | {r['strides']} ({r['strides_used']}) | {r['falls']} | {r['toe_catches']} | "
                     f"{errs} | {len(r['nodes_changed'])} | {r.get('change_in_steps', 0.0):.2f} | "
                     f"{r.get('bench_walks', 0)} | {held} |")
    for r in result["rounds"]:
        if not r["changes"]:
            lines += ["", f"Round {r['round']}: no change."]
            continue
        lines += ["", f"Round {r['round']} changes:"]
        for c in r["changes"]:
            held = f" (held from {c['held_from']:.4g})" if "held_from" in c else ""
            lines.append(f"* node {c['node']} {c['field']}: {c['before']:.4g} → {c['after']:.4g}{held}: {c['why']}")
    lines += ["", "Evaluation (each stride at its own task; feature errors mean absolute, deg or % of the cycle):", "",
              "| envelope | strides | falls | toe catches | loaded swing ms (max stride) | knee angle RMSE ° (95 % CI) | "
              "ankle angle RMSE ° (95 % CI) | " + " | ".join(keys) + " | mean |", "|" + "---|" * (8 + len(keys))]
    for name, e in result["evaluation"].items():
        errs = " | ".join(cell(e["feature_abs_error"].get(k)) for k in keys)
        lines.append(f"| {name} | {e['strides']} | {e['falls']} | {e['toe_catches']} | "
                     f"{cell(e['loaded_swing_ms_max_stride'])} | {cell(e['knee_angle_rmse_deg'])} "
                     f"{_ci(e['knee_angle_rmse_ci95_deg'])} | {cell(e['ankle_angle_rmse_deg'])} "
                     f"{_ci(e['ankle_angle_rmse_ci95_deg'])} | {errs} | {cell(e['feature_mean_abs_error'])} |")
    settled = {name: e["settled"] for name, e in result["evaluation"].items() if e.get("settled")}
    if settled:
        lines += ["", "Settled tasks (each walked alone; bias ± stride-to-stride spread per quantity, * beyond "
                  "tolerance):", "", "| envelope | task | strides | falls | " + " | ".join(keys) + " |",
                  "|" + "---|" * (4 + len(keys))]
        for name, st in settled.items():
            for t in st["tasks"]:
                qs = " | ".join("—" if (q := t["quantities"][k])["bias"] is None else
                                f"{q['bias']:+.1f} ± {q['spread'] or 0.0:.1f}{'' if q['within_tolerance'] else ' *'}"
                                for k in keys)
                lines.append(f"| {name} | {t['speed_mps']:g} m/s {t['incline_deg']:+g}° | {t['strides']} | "
                             f"{t['falls']} | {qs} |")
        lines += [""] + [f"* {name}: {st['within_tolerance']} of {st['pairs']} (task, quantity) pairs within "
                         f"tolerance ({cell(st['settled_within_tolerance_fraction'])}), {st['falls']} falls"
                         for name, st in settled.items()]
    lines += ["", "Refined minus original (per-stride RMSE):", ""]
    for ch, d in result["refined_minus_original"].items():
        lines.append(f"* {ch}: {cell(d['difference'])} {_ci(d['ci95'])} {d['verdict'] or '—'}")
    return "\n".join(lines)
