"""A patient's sessions over days: strides, walking time, cadence, errors, and where they walked (task classes).

One row per calendar day (UTC) of the stopped sessions' summaries. Cadence and errors are stride-weighted means of
the sessions' own figures (a 10-stride session weighs less than a 200-stride one); errors are the sessions' headlines,
each stride against the reference at its own task, and count only the strides that ran the table or envelope. Time
per task class is summed from adaptive sessions (the leg's own estimate, fixed classes so that days with different
envelopes compare); single-table sessions count their whole time at their task's class.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from controller_core.session_regions import TASK_CLASS_INCLINES_DEG, TASK_CLASS_SPEEDS_MPS, region_index

SPEED_CLASSES = ("slow", "moderate", "fast")
INCLINE_CLASSES = ("downhill", "level", "uphill")


def _weighted(values: list[tuple[float | None, int]]) -> float | None:
    pairs = [(v, w) for v, w in values if v is not None and w > 0]
    if not pairs:
        return None
    return round(sum(v * w for v, w in pairs) / sum(w for _, w in pairs), 3)


def _headline(summary: dict) -> dict:
    """A session's headline errors (each stride against its own task); a summary from before headlines existed gives
    its stride-mean errors at the session's task."""
    if summary.get("headline"):
        return summary["headline"]
    return {"knee_angle_rmse_deg": summary.get("knee_angle_rmse_deg"),
            "ankle_angle_rmse_deg": summary.get("ankle_angle_rmse_deg"),
            "strides_scored": summary.get("strides_scored", summary.get("strides") or 0)}


def session_trend(sessions: Iterable[dict]) -> list[dict]:
    """Per day, oldest first, from sessions as the API gives them (``started_at`` ISO, ``task``, ``summary``)."""
    days: dict[str, list[dict]] = {}
    for s in sessions:
        if s.get("summary"):
            days.setdefault(s["started_at"][:10], []).append(s)
    out = []
    for day in sorted(days):
        group = days[day]
        time_by_class = np.zeros((len(SPEED_CLASSES), len(INCLINE_CLASSES)))
        for s in group:
            m = s["summary"]
            adaptive = m.get("adaptive")
            if adaptive:
                time_by_class += np.asarray(adaptive["task_class_time_s"])
            else:
                i = int(region_index(np.array([s["task"]["speed_mps"]]), TASK_CLASS_SPEEDS_MPS)[0])
                j = int(region_index(np.array([s["task"]["incline_deg"]]), TASK_CLASS_INCLINES_DEG)[0])
                time_by_class[i, j] += m.get("walking_s", m.get("duration_s")) or 0.0
        heads = [_headline(s["summary"]) for s in group]
        out.append({
            "day": day, "sessions": len(group), "strides": sum(s["summary"].get("strides") or 0 for s in group),
            # walking only (summaries from before walking_s existed: their whole recording)
            "walking_s": round(sum(s["summary"].get("walking_s", s["summary"].get("duration_s")) or 0.0
                                   for s in group), 1),
            "cadence_steps_per_min": _weighted([(s["summary"].get("cadence_steps_per_min"), s["summary"].get("strides") or 0)
                                                for s in group]),
            "knee_angle_rmse_deg": _weighted([(h["knee_angle_rmse_deg"], h["strides_scored"]) for h in heads]),
            "ankle_angle_rmse_deg": _weighted([(h["ankle_angle_rmse_deg"], h["strides_scored"]) for h in heads]),
            "time_by_task_class_s": {f"{sp}_{inc}": round(float(time_by_class[i, j]), 1)
                                     for i, sp in enumerate(SPEED_CLASSES) for j, inc in enumerate(INCLINE_CLASSES)},
        })
    return out
