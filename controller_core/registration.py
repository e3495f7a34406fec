"""Phase registration and the task trend of a registered reference.

Gait events move with the task: at faster walking, toe-off and the push-off moment peak come earlier in the
cycle. Averaging or regressing curves point by point across tasks then blurs their peaks. Registration
removes that: each curve is re-timed by a piecewise-linear warp that takes its own landmark phases
(for example its toe-off) to the landmarks' mean over the training set (the *canonical* phases). Heel
strike stays at 0 and 1, so the warp keeps the cycle periodic. In registered time, what is left to learn
is how the curve values change with the task, which :class:`TaskTrend` does.

For a new task, the landmarks come from the feature GPRs, and the reference is warped back from canonical
phase to those phases (:func:`unwarp`).

Phases are fractions of the gait cycle in [0, 1]. Values keep the unit of the curve they came from.
"""

from __future__ import annotations

import numpy as np

from controller_core.training_data import training_arrays

# Landmarks must be this far apart (fraction of the cycle) and from heel strike, so every warp segment
# keeps a positive length.
MIN_LANDMARK_GAP = 0.02


def ordered_landmarks(landmarks: np.ndarray) -> np.ndarray:
    """Landmark phases (L,), clipped into (0, 1) and pushed apart to be strictly increasing."""
    lm = np.clip(np.asarray(landmarks, dtype=float), MIN_LANDMARK_GAP, 1.0 - MIN_LANDMARK_GAP)
    for i in range(1, lm.size):
        lm[i] = max(lm[i], lm[i - 1] + MIN_LANDMARK_GAP)
    if lm.size and lm[-1] > 1.0 - MIN_LANDMARK_GAP:
        raise ValueError(f"landmark phases {landmarks} do not fit in one gait cycle")
    return lm


def _knots(landmarks: np.ndarray) -> np.ndarray:
    return np.concatenate([[0.0], landmarks, [1.0]])


def canonical_phase(s: np.ndarray, landmarks: np.ndarray, canonical: np.ndarray) -> np.ndarray:
    """Canonical phase of the phases ``s`` of a curve whose landmarks are at ``landmarks``."""
    return np.interp(s, _knots(ordered_landmarks(landmarks)), _knots(canonical))


def _periodic_sample(grid: np.ndarray, values: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Values (len(at), ...) of a periodic curve sampled on ``grid`` ⊂ [0, 1), linearly interpolated."""
    g = np.append(grid, grid[0] + 1.0)
    v = np.concatenate([values, values[:1]], axis=0)
    at = np.mod(at, 1.0)
    if v.ndim == 1:
        return np.interp(at, g, v)
    return np.column_stack([np.interp(at, g, v[:, c]) for c in range(v.shape[1])])


def register(phase: np.ndarray, values: np.ndarray, landmarks: np.ndarray, canonical: np.ndarray,
             s: np.ndarray) -> np.ndarray:
    """A curve re-timed to canonical phase, sampled at canonical phases ``s``.

    Args:
        phase: (P,) phases of the curve's samples in [0, 1] (1 may be included).
        values: (P,) or (P, C) curve values.
        landmarks: (L,) the curve's own landmark phases.
        canonical: (L,) canonical landmark phases.
        s: canonical phases to sample at.
    """
    original = np.interp(s, _knots(canonical), _knots(ordered_landmarks(landmarks)))
    keep = phase < 1.0
    return _periodic_sample(phase[keep], np.asarray(values)[keep], original)


def unwarp(grid: np.ndarray, registered: np.ndarray, landmarks: np.ndarray, canonical: np.ndarray,
           s: np.ndarray) -> np.ndarray:
    """A registered curve (on canonical ``grid`` ⊂ [0, 1)) shown at real phases ``s`` with ``landmarks``."""
    return _periodic_sample(grid, registered, canonical_phase(s, landmarks, canonical))


class UniformUnwarp:
    """:func:`unwarp` for many curves on one uniform grid ``k/n`` (k = 0…n−1), sampled back on that grid.

    The interpolation indices and weights depend only on the landmarks, so :meth:`at` computes them once
    and :meth:`apply` re-times any number of curves with two gathers.
    """

    def __init__(self, n: int, canonical: np.ndarray) -> None:
        self.n = n
        self.grid = np.arange(n) / n
        self.canonical = np.asarray(canonical, dtype=float)

    def at(self, landmarks: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Indices (i0, i1) and weights w for the curves' values at the grid, given their landmarks."""
        c = canonical_phase(self.grid, landmarks, self.canonical) * self.n
        i0 = np.floor(c).astype(int)
        w = c - i0
        i0 %= self.n
        return i0, (i0 + 1) % self.n, w

    @staticmethod
    def apply(weights: tuple[np.ndarray, np.ndarray, np.ndarray], registered: np.ndarray) -> np.ndarray:
        """Re-time ``registered`` (n, ...) with weights from :meth:`at`."""
        i0, i1, w = weights
        w = w.reshape((-1,) + (1,) * (registered.ndim - 1))
        return registered[i0] * (1.0 - w) + registered[i1] * w


class TaskTrend:
    """Per-point linear trend of curves in the task variables (ridge-regularised least squares).

    ``fit(tasks, residuals)`` learns slopes B for ``residuals ≈ (task − mean task) B``; ``predict(task)``
    returns the trend at a task. Without an intercept the trend is zero at the mean training task, so it
    moves a reference (e.g. a GMR mean) with the task instead of replacing it.

    Args:
        ridge: regularisation of the slopes, relative to the task variance (dimensionless).
    """

    def __init__(self, ridge: float = 1e-3) -> None:
        self.ridge = ridge

    def fit(self, tasks: np.ndarray, residuals: np.ndarray) -> TaskTrend:
        """Fit on tasks (n, d) in physical units and residuals (n, ...) of any trailing shape."""
        T, R = training_arrays(tasks, residuals, "TaskTrend", "tasks with one residual curve each")
        self.task_mean_ = T.mean(axis=0)
        Tc = T - self.task_mean_
        gram = Tc.T @ Tc
        gram += self.ridge * np.trace(gram) / max(T.shape[1], 1) * np.eye(T.shape[1]) + 1e-12 * np.eye(T.shape[1])
        self.slopes_ = np.linalg.solve(gram, Tc.T @ R.reshape(R.shape[0], -1)).reshape((T.shape[1], *R.shape[1:]))
        return self

    def predict(self, task: np.ndarray) -> np.ndarray:
        """Trend at one task (d,), in the residuals' unit and shape."""
        dt = np.asarray(task, dtype=float) - self.task_mean_
        return (dt @ self.slopes_.reshape(dt.size, -1)).reshape(self.slopes_.shape[1:])
