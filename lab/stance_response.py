"""The printed table of ``quasitune stance-response`` (:mod:`device_bridge.bench.stance_response`)."""

from __future__ import annotations

from device_bridge.bench.stance_response import STUDY_K_NM_PER_RAD, STUDY_TASK


def _f(v: object, digits: int = 1) -> str:
    return "—" if v is None else f"{float(v):.{digits}f}"   # type: ignore[arg-type]


def format_stance_response(rows: list[dict]) -> str:
    """Markdown: per person and table, the stance knee peak at each stance-flexion k, the response, how long stance
    flexion lasted and the knee torque as it left, falls; and the learned table with no knee support."""
    soft, stiff = (f"{k:g}" for k in STUDY_K_NM_PER_RAD)
    out = [f"Stance knee flexion peak against the knee's stance-flexion k ({soft} and {stiff} N·m/rad), "
           f"{STUDY_TASK[0]:g} m/s, {STUDY_TASK[1]:+g}°, bench study (limits not checked):", "",
           f"| person | table | peak at k {soft} ° | peak at k {stiff} ° | response ° | stance flexion lasts, ms "
           f"(k {soft} / {stiff}) | knee torque leaving it, N·m | falls | no knee support: falls, sink mm, push BW |",
           "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        a, b = r["by_stance_flexion_k_Nm_per_rad"][soft], r["by_stance_flexion_k_Nm_per_rad"][stiff]
        limp = r.get("no_knee_support")
        limp_text = ("—" if limp is None else
                     f"{limp['falls']}, {_f(limp['hip_sink_max_mm'], 0)}, {_f(limp['support_deficit_max_bw'], 2)}")
        out.append(f"| {r['person']} | {r['table']} | {_f(a['stance_knee_flexion_peak_deg'])} | "
                   f"{_f(b['stance_knee_flexion_peak_deg'])} | {_f(r['response_deg'])} | "
                   f"{_f(a['stance_flexion_stay_ms'], 0)} / {_f(b['stance_flexion_stay_ms'], 0)} | "
                   f"{_f(a['knee_torque_leaving_stance_flexion_Nm'], 0)} / "
                   f"{_f(b['knee_torque_leaving_stance_flexion_Nm'], 0)} | {a['falls']} / {b['falls']} | {limp_text} |")
    return "\n".join(out)
