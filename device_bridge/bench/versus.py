"""The one comparison of two walks: per gait channel, how much lower one's tracking error is, and whether the strides
resolve it.

At one task (:class:`~device_bridge.sim.simulate.WalkScore`) the error is the RMSE of the stride-averaged curve
against the task's reference, and strides are resampled to bound it (:func:`controller_core.gait_metrics.rmse_difference`).
Over a course (:class:`~device_bridge.sim.course_walk.CourseScore`) every stride has its own reference, so the error
is each stride's RMSE and the difference is of their means (:func:`mean_difference`). Both give a 95 % bootstrap
interval and a verdict: one walk lower when the interval excludes zero, else ``not resolved``.
"""

from __future__ import annotations

import numpy as np

from controller_core.gait_metrics import (
    GAIT_CHANNELS,
    bootstrap_means,
    difference_keys,
    percentile_interval,
    rmse_difference,
    verdict,
)
from device_bridge.sim.course_walk import CourseScore
from device_bridge.sim.simulate import WalkScore


def mean_difference(a: np.ndarray, b: np.ndarray, n_boot: int = 2000, seed: int = 0) -> dict[str, object]:
    """Mean of A minus mean of B (per-stride RMSEs of two independent walks), with a 95 % bootstrap interval and a
    verdict: ``A lower``/``B lower`` when the interval excludes zero, else ``not resolved``."""
    rng = np.random.default_rng(seed)
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if a.size < 2 or b.size < 2:
        return {"difference": None, "interval": None, "verdict": None}
    interval = percentile_interval(bootstrap_means(a, n_boot, rng) - bootstrap_means(b, n_boot, rng))
    return {"difference": float(a.mean() - b.mean()), "interval": list(interval), "verdict": verdict(interval)}


def _difference(a: WalkScore | CourseScore, b: WalkScore | CourseScore, channel: str) -> dict[str, object]:
    if isinstance(a, CourseScore) and isinstance(b, CourseScore):
        return mean_difference(a.stride_rmse[channel], b.stride_rmse[channel])
    if isinstance(a, WalkScore) and isinstance(b, WalkScore):
        sa, sb = a.stride_curves.get(channel), b.stride_curves.get(channel)
        if sa is None or sb is None or sa.shape[0] < 2 or sb.shape[0] < 2:
            return {"difference": None, "interval": None, "verdict": None}
        return rmse_difference(sa, sb, a.reference_curves[channel])
    raise TypeError("compare two walks of the same kind: two at one task, or two over the same course")


def versus(a: WalkScore | CourseScore, b: WalkScore | CourseScore, a_name: str, b_name: str
           ) -> dict[str, dict[str, object]]:
    """Per channel (units in the channel name): ``rmse_difference`` (A − B), ``ci95`` [lo, hi] and ``verdict``
    (``"<a_name> lower"``, ``"<b_name> lower"`` or ``"not resolved"``); all None for a channel either walk could not
    score with at least two strides."""
    words = {"A lower": f"{a_name} lower", "B lower": f"{b_name} lower", "not resolved": "not resolved"}
    out: dict[str, dict[str, object]] = {}
    for channel in GAIT_CHANNELS:
        d = _difference(a, b, channel)
        resolved = d["verdict"] is not None
        out[channel] = {"rmse_difference": d["difference"], "ci95": list(d["interval"]) if resolved else None,
                        "verdict": words[str(d["verdict"])] if resolved else None}
    return out


def against_fsmic(learned: WalkScore, fsmic: WalkScore) -> dict[str, object]:
    """:func:`versus` of a learned walk and the FSMIC's at the same task, as flat keys per channel (units in the
    names): ``knee_angle_rmse_difference_deg``, ``knee_angle_rmse_difference_ci95_deg`` (lo, hi) and
    ``knee_angle_verdict`` (``"learned lower"``, ``"FSMIC lower"`` or ``"not resolved"``)."""
    out: dict[str, object] = {}
    for channel, d in versus(learned, fsmic, "learned", "FSMIC").items():
        key, ci_key, verdict_key = difference_keys(channel)
        out[key], out[ci_key], out[verdict_key] = d["rmse_difference"], d["ci95"], d["verdict"]
    return out
