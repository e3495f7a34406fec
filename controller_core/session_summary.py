"""Summary of a monitored walking session from its telemetry: strides, cadence, errors against the reference.

Telemetry arrives at a fixed period (10 ms from the device). Heel strikes are the pylon load rising above 10 % of
body weight after at least 150 ms below it; each stride between consecutive heel strikes is resampled on the
101-point phase grid and averaged, and the averages are compared with the able-bodied reference at the
session's task — the same metrics as ``quasitune simulate`` (angles in deg, moments in N·m/kg).

A stride during which the leg did not run its table for even one sample (safe mode, no table) is counted
but left out of the errors: it says nothing about the table, and a report must not blame the table for it.
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from controller_core.gait_metrics import (
    GAIT_CHANNELS,
    PHASE_GRID,
    channel_strides,
    gait_channels,
    heel_strikes,
    reference_curves,
    strided_errors,
)
from controller_core.units import G_MPS2
from controller_core.walking_reference import WalkingReference

LONGEST_STRIDE_S = 2.5   # a longer time between two heel strikes is a pause (standing), not a stride: 0.4 m/s walking
                         # takes about 2 s per stride


def device_times(seq: np.ndarray, received_s: np.ndarray, period_s: float) -> np.ndarray:
    """Sample times (s) on the device's clock: the first sample's receive time, then its sequence numbers at the
    device's fixed telemetry period ``period_s`` (s).

    The host's receive times arrive in bursts when the server is busy (a burst of samples a few microseconds apart
    would look like a 150 ms swing lasting one sample), and a short session's first samples can arrive late: a mean
    rate taken from the receive times then squeezes the whole session (a 3 s walk on a loaded machine reported a
    cadence of 165 steps/min for about 110). The sequence counts the device's own period; a lost sample leaves its gap.
    """
    if not (math.isfinite(period_s) and period_s > 0):
        raise ValueError(f"period_s must be a positive number of seconds, got {period_s!r}")
    q = np.asarray(seq, dtype=float)
    r = np.asarray(received_s, dtype=float)
    if q.size == 0:
        return r
    return r[0] + (q - q[0]) * period_s


def session_strikes(t_s: np.ndarray, load_N: np.ndarray, mass_kg: float) -> np.ndarray:
    """Sample indices of heel strikes: load above 10 % of body weight after at least 150 ms below it."""
    t = np.asarray(t_s, dtype=float)
    dt = float(np.median(np.diff(t))) if t.shape[0] > 1 else 0.01
    return heel_strikes(np.asarray(load_N, dtype=float), 0.1 * mass_kg * G_MPS2, max(1, round(0.15 / dt)))


def summarize_session(t_s: np.ndarray, knee_angle_rad: np.ndarray, ankle_angle_rad: np.ndarray,
                      knee_torque_Nm: np.ndarray, ankle_torque_Nm: np.ndarray, load_N: np.ndarray,
                      mass_kg: float, reference: WalkingReference, running_table: np.ndarray | None = None) -> dict:
    """Metrics of one session (see the module docstring); ``None`` for what fewer than two heel strikes cannot give.

    Args:
        t_s: sample times (s), increasing.
        knee_angle_rad, ankle_angle_rad, knee_torque_Nm, ankle_torque_Nm, load_N: telemetry (SI).
        mass_kg: the patient's body mass (kg): normalises torque and sets the load threshold.
        reference: the able-bodied reference at the session's task.
        running_table: per sample, whether the leg ran its table (not safe mode, not without a table); None
            means throughout. Strides with any sample not running it are excluded from the errors.
    """
    t = np.asarray(t_s, dtype=float)
    n = t.shape[0]
    dt = float(np.median(np.diff(t))) if n > 1 else 0.01
    strikes = session_strikes(t, load_N, mass_kg)
    strides = max(int(strikes.shape[0]) - 1, 0)
    measured = gait_channels(knee_angle_rad, ankle_angle_rad, knee_torque_Nm, ankle_torque_Nm, mass_kg)
    ref = reference_curves(reference)
    running = np.ones(n, dtype=bool) if running_table is None else np.asarray(running_table, dtype=bool)
    on_table = np.array([bool(running[a:b + 1].all()) for a, b in itertools.pairwise(strikes)], dtype=bool)
    strided = {k: v[on_table] for k, v in channel_strides(measured, strikes).items()} if on_table.any() else {}
    mean_curves, raw_errors = strided_errors(strided, list(measured), ref)
    errors = {k: None if v is None else round(v, 4) for k, v in raw_errors.items()}
    means = {name: [round(float(v), 3) for v in mean_curves[name]] if name in mean_curves else None
             for name in GAIT_CHANNELS}
    # the cadence of the strides on the table: in safe mode or without a table the load flickers and splits one step
    # into several "strides" (174 steps/min from one safe-mode session), which no patient walked
    durations = np.diff(t[strikes])[on_table] if strides else np.array([])
    stride_time = float(np.mean(durations)) if durations.size else None
    # walking time: the strides, each no longer than a pause; the rest of the recording is standing (or sitting)
    all_durations = np.diff(t[strikes]) if strides else np.array([])
    walking_s = float(all_durations[all_durations <= LONGEST_STRIDE_S].sum())
    duration_s = float(t[-1] - t[0]) if n > 1 else 0.0
    return {
        "samples": n,
        "duration_s": round(duration_s, 3),
        "walking_s": round(walking_s, 3),
        "standing_s": round(max(duration_s - walking_s, 0.0), 3),
        "strides": strides,
        "strides_scored": int(on_table.sum()),
        "strides_off_table": int(strides - on_table.sum()),
        # samples × the reported sample period, as callers count time per mode: a part never exceeds the whole
        "off_table_s": round(float(np.count_nonzero(~running)) * round(dt, 5), 3) if n > 1 else 0.0,
        "stride_time_s": None if stride_time is None else round(stride_time, 4),
        "cadence_steps_per_min": None if stride_time is None else round(120.0 / stride_time, 2),   # scored strides
        "reference_stride_time_s": round(reference.stride_time_s, 4),
        **errors,
        "mean_curves": means,
        "reference_curves": {k: [round(float(v), 3) for v in ref[k]] for k in GAIT_CHANNELS},
        "phase_grid": [round(float(s), 3) for s in PHASE_GRID],
        "reference_source": reference.source,
        "reference_kind": reference.kind,
        "reference_extrapolation": bool(reference.extrapolation),
        "heel_strike_load_threshold_N": round(0.1 * mass_kg * G_MPS2, 1),
        "sample_period_s": round(dt, 5) if math.isfinite(dt) else None,
    }
