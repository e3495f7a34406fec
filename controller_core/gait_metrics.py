"""Gait metrics of a recorded walk: heel strikes, stride-averaged curves on the phase grid, RMSE, events.

Pure numpy on arrays sampled at a fixed period; used for simulated walks and for monitored sessions alike.
Units follow the inputs (SI in, SI out) except where a name says otherwise.
"""

from __future__ import annotations

import itertools

import numpy as np

PHASE_GRID = np.linspace(0.0, 1.0, 101)


def rising_edges(signal: np.ndarray, threshold: float, min_low_samples: int = 1) -> np.ndarray:
    """Indices where ``signal`` goes above ``threshold`` after at least ``min_low_samples`` samples at or below it."""
    above = np.asarray(signal) > threshold
    idx = []
    low_run = 0
    for i, a in enumerate(above):
        if a:
            if low_run >= min_low_samples and i > 0:
                idx.append(i)
            low_run = 0
        else:
            low_run += 1
    return np.asarray(idx, dtype=int)


def heel_strikes(contact_N: np.ndarray, threshold_N: float, min_swing_samples: int) -> np.ndarray:
    """Sample indices of heel strikes: foot contact force rising above ``threshold_N`` after a swing of at
    least ``min_swing_samples`` samples without contact."""
    return rising_edges(contact_N, threshold_N, min_swing_samples)


def stride_curves(signal: np.ndarray, strikes: np.ndarray, grid: np.ndarray = PHASE_GRID) -> np.ndarray:
    """(strides, len(grid)) array: each stride between consecutive strikes resampled on the phase grid."""
    signal = np.asarray(signal, dtype=float)
    out = []
    for a, b in itertools.pairwise(strikes):
        seg = signal[a: b + 1]
        s = np.linspace(0.0, 1.0, seg.shape[0])
        out.append(np.interp(grid, s, seg))
    return np.asarray(out).reshape(-1, grid.shape[0])


def rmse(a: np.ndarray, b: np.ndarray) -> float:
    """Root-mean-square difference of two equally shaped arrays."""
    d = np.asarray(a, dtype=float) - np.asarray(b, dtype=float)
    return float(np.sqrt(np.mean(d * d)))


def episodes(flag: np.ndarray, min_gap_samples: int = 1) -> int:
    """Number of separate runs of True in ``flag`` (runs closer than ``min_gap_samples`` count as one)."""
    starts = rising_edges(np.asarray(flag, dtype=float), 0.5, min_gap_samples).shape[0]
    return int(starts + (1 if len(flag) and flag[0] else 0))
