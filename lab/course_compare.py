"""The course comparison (``quasitune compare --course``): the adaptive envelope (the leg estimates its task and
blends the envelope's rows there), the model's fixed table at the nominal task and the FSMIC over the same course,
each stride scored against the reference at its own true task; the adaptive walk's per-stride errors against each
other's (:func:`device_bridge.bench.versus.versus`).
"""

from __future__ import annotations

from collections.abc import Callable

from controller_core.envelope import Envelope
from controller_core.gait_metrics import GAIT_CHANNELS
from controller_core.model import QuasiStiffnessModel
from device_bridge.as_run import as_run
from device_bridge.bench.controllers import default_envelope
from device_bridge.bench.versus import versus
from device_bridge.bench.walks import walk_course
from device_bridge.sim.course import Course
from device_bridge.sim.course_walk import CourseScore
from device_bridge.sim.leg_model import LegGeometry
from lab.comparison import cell

COURSE_CONTROLLERS: tuple[str, ...] = ("adaptive", "quasi-stiffness", "fsmic")
_PARTS: dict[str, Callable[[CourseScore], CourseScore]] = {
    "adaptive_minus": lambda s: s,
    "adaptive_minus_after_change": lambda s: s.only(s.stride_after_change),
    "adaptive_minus_between_changes": lambda s: s.only(~s.stride_after_change),
}


def compare_course(model: QuasiStiffnessModel, course: Course, mass_kg: float = 75.0,
                   envelope: Envelope | None = None, geometry: LegGeometry | None = None,
                   start: str = "standing") -> dict[str, object]:
    """All three controllers over the course on the leg ``geometry`` (default the nominal bench), each from ``start``
    (``swing`` or ``standing``), and the adaptive one's per-stride errors against each other's."""
    env = envelope or default_envelope(model, mass_kg, geometry)
    scores = {name: walk_course(name, course, model, mass_kg, env, geometry=geometry, start=start)
              for name in COURSE_CONTROLLERS}
    return {"course": course.to_json(), "leg": (geometry or LegGeometry()).name, "start": start,
            "envelope": {"speeds_mps": env.speeds_mps, "inclines_deg": env.inclines_deg,
                         "wire_crc32": as_run(env).wire_crc32,
                         "nominal": [env.nominal_speed_mps, env.nominal_incline_deg]},
            "rows": [scores[name].to_dict() for name in COURSE_CONTROLLERS],
            # on all strides, and apart on the strides right after each change and on the rest (issue 56)
            **{key: {other: versus(part(scores["adaptive"]), part(scores[other]), "adaptive", other)
                     for other in ("quasi-stiffness", "fsmic")} for key, part in _PARTS.items()}}


def format_course_compare(result: dict) -> str:
    """Markdown tables of a course comparison: per controller, per segment, estimation, adaptive minus the others."""
    def ci(v: object) -> str:
        return "—" if not v else f"[{v[0]:.2f}, {v[1]:.2f}]"

    keys = [c.replace("_deg", "_rmse_deg").replace("_Nm_per_kg", "_rmse_Nm_per_kg") for c in GAIT_CHANNELS]
    c = result["course"]
    lines = [f"Course {c['name']}: " + " → ".join(f"{s['speed_mps']:g} m/s {s['incline_deg']:+g}°" for s in c["segments"])
             + f" ({c['transition_s']:g} s transitions); each stride scored at its own task", "",
             "| controller | strides | falls | toe_catches | loaded_swing_ms_max_stride | "
             + " | ".join(f"{k} (95 % CI)" for k in keys) + " |", "|" + "---|" * (5 + len(keys))]
    for r in result["rows"]:
        cells = [f"{cell(r.get(k))} {ci(r.get(k.replace('_rmse_', '_rmse_ci95_')))}" for k in keys]
        lines.append(f"| {r['controller']} | {r['strides']} | {r['falls']} | {r['toe_catches']} | "
                     f"{cell(r.get('loaded_swing_ms_max_stride'))} | " + " | ".join(cells) + " |")
    lines += ["", "Per segment (knee / ankle angle RMSE, deg):", "",
              "| segment | " + " | ".join(r["controller"] for r in result["rows"]) + " |",
              "|" + "---|" * (1 + len(result["rows"]))]
    for k, seg in enumerate(result["rows"][0]["by_segment"]):
        cells = []
        for r in result["rows"]:
            s = r["by_segment"][k]
            cells.append(f"{cell(s['knee_angle_rmse_deg'])} / {cell(s['ankle_angle_rmse_deg'])} ({s['strides']})")
        lines.append(f"| {seg['speed_mps']:g} m/s {seg['incline_deg']:+g}° | " + " | ".join(cells) + " |")
    for r in result["rows"]:
        if "estimation" in r:
            e = r["estimation"]
            lines += ["", f"Task estimation ({r['controller']}): speed within ±0.1 m/s on "
                          f"{100 * (e['speed_within_0_1_mps_fraction'] or 0):.1f} % and incline within ±1.5° on "
                          f"{100 * (e['incline_within_1_5_deg_fraction'] or 0):.1f} % of {e['strides_counted']} "
                          f"strides (first {e['skipped_after_each_change']} after each change not counted); "
                          f"strides by mode {r['strides_by_mode']}"]
            e1 = r.get("estimation_from_second_stride")
            if e1:
                lines += [f"From the second stride after each change: speed within ±0.1 m/s on "
                          f"{100 * (e1['speed_within_0_1_mps_fraction'] or 0):.1f} %, incline within ±1.5° on "
                          f"{100 * (e1['incline_within_1_5_deg_fraction'] or 0):.1f} % of {e1['strides_counted']} "
                          "strides"]
    first = result["rows"][0].get("after_change", {}).get("strides_per_change", 3)
    lines += ["", f"Right after a change (each segment's first {first} strides) / the rest, knee / ankle angle RMSE, deg:",
              "", "| strides | " + " | ".join(r["controller"] for r in result["rows"]) + " |",
              "|" + "---|" * (1 + len(result["rows"]))]
    for part, label in (("after_change", "after a change"), ("between_changes", "the rest")):
        cells = [f"{cell(r[part]['knee_angle_rmse_deg'])} / {cell(r[part]['ankle_angle_rmse_deg'])} "
                 f"({r[part]['strides']})" for r in result["rows"] if part in r]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    for key, title in (("adaptive_minus", "all strides"), ("adaptive_minus_after_change", "right after a change"),
                       ("adaptive_minus_between_changes", "the rest")):
        if key not in result:
            continue
        lines += ["", f"adaptive − other, {title}: mean per-stride RMSE, 95 % interval (bootstrap over strides), "
                      "verdict:", "", "| other | " + " | ".join(GAIT_CHANNELS) + " |",
                  "|" + "---|" * (1 + len(GAIT_CHANNELS))]
        for other, rows in result[key].items():
            cells = []
            for ch in GAIT_CHANNELS:
                d = rows[ch]
                cells.append("—" if d["rmse_difference"] is None else
                             f"{d['rmse_difference']:+.2f} [{d['ci95'][0]:+.2f}, {d['ci95'][1]:+.2f}] {d['verdict']}")
            lines.append(f"| {other} | " + " | ".join(cells) + " |")
    return "\n".join(lines)
