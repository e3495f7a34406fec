"""Where in its envelope an adaptive leg walked during a session, and how well, from its own task telemetry.

Regions are the envelope's nodes: a node owns the tasks nearer to it than to its neighbours (edges halfway between
nodes, open at the grid's ends), so the histogram reads "time walked near 1.1 m/s, +5°". A task beyond the grid
belongs to the edge node and is also counted as outside (the leg clamps there) when it lies beyond the edge by more
than the estimate's resolution (:data:`controller_core.task_estimator.SPEED_RESOLUTION_MPS`, ``INCLINE_…``): at the
edge, within what the leg can tell apart, is inside. Time counts the samples that carry
an estimate; a stride belongs to the region of the mean estimate over its samples, or is "unestimated".

Errors by task: each stride's knee and ankle angle RMSE (deg) against the able-bodied reference at that stride's
estimated task, averaged per region. The estimate is the only task a real leg knows; where the estimate is wrong the
error is measured against the wrong reference, so the session also reports how often the estimate moved.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Sequence

import numpy as np

from controller_core.gait_metrics import reference_curves, rmse, stride_curves
from controller_core.task_estimator import INCLINE_RESOLUTION_DEG, SPEED_RESOLUTION_MPS
from controller_core.walking_reference import WalkingReference

SCORED_CHANNELS = ("knee_angle_deg", "ankle_angle_deg")
# fixed task classes for trends across sessions whose envelopes differ: slow / moderate / fast (edges 0.9 and
# 1.3 m/s) × downhill / level / uphill (edges ±4°)
TASK_CLASS_SPEEDS_MPS = (0.7, 1.1, 1.5)
TASK_CLASS_INCLINES_DEG = (-8.0, 0.0, 8.0)


def region_index(values: np.ndarray, axis: Sequence[float]) -> np.ndarray:
    """For each value, the index of the nearest node on ``axis`` (edges halfway between nodes); NaN gives -1."""
    v = np.asarray(values, dtype=float)
    edges = 0.5 * (np.asarray(axis[:-1], dtype=float) + np.asarray(axis[1:], dtype=float))
    idx = np.searchsorted(edges, v, side="right")
    return np.where(np.isfinite(v), idx, -1)


def task_regions(t_s: np.ndarray, speed_mps: np.ndarray, incline_deg: np.ndarray, strikes: np.ndarray,
                 speeds_mps: Sequence[float], inclines_deg: Sequence[float]) -> dict:
    """Time (s) and strides per envelope region from per-sample estimates (NaN where there is none).

    Returns ``time_s`` and ``strides`` as lists over speed index of lists over incline index, the unestimated and
    outside-the-grid totals, and per stride its task and region (None when unestimated).
    """
    t = np.asarray(t_s, dtype=float)
    v, g = np.asarray(speed_mps, dtype=float), np.asarray(incline_deg, dtype=float)
    shape = (len(speeds_mps), len(inclines_deg))
    dt = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    seen = np.isfinite(v) & np.isfinite(g)
    iv, ig = region_index(v, speeds_mps), region_index(g, inclines_deg)
    time_s = np.zeros(shape)
    np.add.at(time_s, (iv[seen], ig[seen]), dt)
    dv, dg = SPEED_RESOLUTION_MPS, INCLINE_RESOLUTION_DEG   # within the estimate's resolution of the edge is inside
    outside = seen & ((v < speeds_mps[0] - dv) | (v > speeds_mps[-1] + dv) | (g < inclines_deg[0] - dg)
                      | (g > inclines_deg[-1] + dg))
    strides = np.zeros(shape, dtype=int)
    per_stride: list[dict | None] = []
    for a, b in itertools.pairwise(strikes):
        ok = seen[a:b]
        if not ok.any():
            per_stride.append(None)
            continue
        sv, sg = float(np.mean(v[a:b][ok])), float(np.mean(g[a:b][ok]))
        i, j = int(region_index(np.array([sv]), speeds_mps)[0]), int(region_index(np.array([sg]), inclines_deg)[0])
        strides[i, j] += 1
        per_stride.append({"speed_mps": sv, "incline_deg": sg, "region": (i, j)})
    return {"time_s": np.round(time_s, 3).tolist(), "strides": strides.tolist(),
            "unestimated_s": round(float(np.count_nonzero(~seen)) * dt, 3),
            "unestimated_strides": sum(1 for s in per_stride if s is None),
            "outside_s": round(float(np.count_nonzero(outside)) * dt, 3), "per_stride": per_stride}


def errors_by_region(stride_curves: dict[str, np.ndarray], per_stride: list[dict | None], shape: tuple[int, int],
                     reference_at: Callable[[float, float], WalkingReference],
                     speed_step_mps: float = 0.05, incline_step_deg: float = 0.5,
                     scored: Sequence[bool] | None = None) -> dict:
    """Mean per-stride RMSE (deg) of :data:`SCORED_CHANNELS` per region, each stride against the reference at its
    estimated task (rounded to ``speed_step_mps``/``incline_step_deg``, so nearby strides share one reference).

    ``stride_curves`` maps a channel to (strides, grid) curves, strides in the order of ``per_stride``. Returns
    per channel a (speed × incline) grid of mean RMSE (None where no stride was scored) and the number scored, and
    ``overall``: the mean over every scored stride (what a walk whose task changed is best summarised by).
    ``scored``: per stride, whether it counts (False: the leg did not run its envelope for the whole stride).
    """
    cache: dict[tuple[float, float], dict[str, np.ndarray]] = {}
    sums = {c: np.zeros(shape) for c in SCORED_CHANNELS}
    counts = np.zeros(shape, dtype=int)
    for k, stride in enumerate(per_stride):
        if stride is None or (scored is not None and not scored[k]):
            continue
        key = (round(round(stride["speed_mps"] / speed_step_mps) * speed_step_mps, 4),
               round(round(stride["incline_deg"] / incline_step_deg) * incline_step_deg, 3))
        if key not in cache:
            cache[key] = reference_curves(reference_at(*key))
        i, j = stride["region"]
        counts[i, j] += 1
        for c in SCORED_CHANNELS:
            sums[c][i, j] += rmse(stride_curves[c][k], cache[key][c])
    total = int(counts.sum())
    out: dict[str, object] = {"strides_scored": counts.tolist(), "overall": {"strides": total, **{
        c.replace("_deg", "_per_stride_rmse_deg"): None if not total else round(float(sums[c].sum()) / total, 3)
        for c in SCORED_CHANNELS}}}
    for c in SCORED_CHANNELS:
        mean = np.divide(sums[c], counts, out=np.full(shape, np.nan), where=counts > 0)
        out[c.replace("_deg", "_per_stride_rmse_deg")] = [[None if not np.isfinite(x) else round(float(x), 3)
                                                           for x in row] for row in mean]
    return out


def adaptive_summary(t_s: np.ndarray, knee_angle_rad: np.ndarray, ankle_angle_rad: np.ndarray, strikes: np.ndarray,
                     estimated_speed_mps: np.ndarray, estimated_incline_deg: np.ndarray,
                     adaptive_mode: Sequence[str | None], speeds_mps: Sequence[float], inclines_deg: Sequence[float],
                     reference_at: Callable[[float, float], WalkingReference],
                     running_table: np.ndarray | None = None) -> dict:
    """The envelope part of a session summary: the region histogram, errors by region, and time per adaptive mode
    (nominal, partial, adaptive, clamped; seconds). ``running_table``: per sample, whether the leg ran its envelope
    (not safe mode); a stride with any sample off it is counted in the histogram but not in the errors."""
    t = np.asarray(t_s, dtype=float)
    regions = task_regions(t, estimated_speed_mps, estimated_incline_deg, strikes, speeds_mps, inclines_deg)
    curves = {"knee_angle_deg": stride_curves(np.degrees(knee_angle_rad), strikes),
              "ankle_angle_deg": stride_curves(np.degrees(ankle_angle_rad), strikes)} if strikes.size >= 2 else {}
    running = None if running_table is None else np.asarray(running_table, dtype=bool)
    scored = None if running is None else [bool(running[a:b + 1].all()) for a, b in itertools.pairwise(strikes)]
    errors = errors_by_region(curves, regions["per_stride"], (len(speeds_mps), len(inclines_deg)), reference_at,
                              scored=scored)
    dt = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    modes = [m for m in adaptive_mode if m is not None]
    classes = task_regions(t, estimated_speed_mps, estimated_incline_deg, strikes, TASK_CLASS_SPEEDS_MPS,
                           TASK_CLASS_INCLINES_DEG)
    return {"speeds_mps": list(speeds_mps), "inclines_deg": list(inclines_deg),
            "task_class_time_s": classes["time_s"], "task_class_strides": classes["strides"],
            **{k: v for k, v in regions.items() if k != "per_stride"},
            "stride_tasks": [None if s is None else [round(s["speed_mps"], 3), round(s["incline_deg"], 2)]
                             for s in regions["per_stride"]],
            "errors_by_region": errors,
            "adaptive_mode_s": {m: round(modes.count(m) * dt, 3) for m in ("nominal", "partial", "adaptive", "clamped")},
            "errors_reference": "each stride against the able-bodied reference at the leg's own estimate of its task"}


MIN_STRIDES_TO_JUDGE = 5   # fewer scored strides than this: errors are shown as too few to judge


def own_task_errors(knee_angle_rad: np.ndarray, ankle_angle_rad: np.ndarray, strikes: np.ndarray,
                    stride_tasks: Sequence[tuple[float, float] | None],
                    reference_at: Callable[[float, float], WalkingReference], against: str,
                    scored: Sequence[bool] | None = None) -> dict:
    """The session's headline errors: each stride's knee and ankle angle RMSE (deg) against the able-bodied reference
    at that stride's own task, averaged over the scored strides (a course or an adaptive walk compared with one task's
    reference would blame the leg for the change of task).

    Args:
        stride_tasks: per stride (between consecutive ``strikes``), its (speed m/s, incline deg), or None when unknown
            (left out).
        against: in words, where the strides' tasks come from (shown with the figures).
        scored: per stride, whether it counts (False: the leg did not run its table for the whole stride).
    """
    curves = {"knee_angle_deg": stride_curves(np.degrees(knee_angle_rad), strikes),
              "ankle_angle_deg": stride_curves(np.degrees(ankle_angle_rad), strikes)} if strikes.size >= 2 else {}
    per_stride = [None if task is None else {"speed_mps": task[0], "incline_deg": task[1], "region": (0, 0)}
                  for task in stride_tasks]
    overall = errors_by_region(curves, per_stride, (1, 1), reference_at, scored=scored)["overall"]
    n = int(overall["strides"])
    counted = [True] * len(stride_tasks) if scored is None else [bool(x) for x in scored]
    unknown = sum(1 for task, c in zip(stride_tasks, counted, strict=True) if c and task is None)
    return {"knee_angle_rmse_deg": overall["knee_angle_per_stride_rmse_deg"],
            "ankle_angle_rmse_deg": overall["ankle_angle_per_stride_rmse_deg"], "strides_scored": n,
            "strides_on_table": sum(counted), "strides_without_task": unknown,
            "enough_strides": n >= MIN_STRIDES_TO_JUDGE, "min_strides": MIN_STRIDES_TO_JUDGE, "against": against}
