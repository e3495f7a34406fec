"""The shared entry check of the task-regression estimators (:class:`~controller_core.gpr.FeatureGPR`,
:class:`~controller_core.registration.TaskTrend`)."""

from __future__ import annotations

import numpy as np


def training_arrays(X: np.ndarray, y: np.ndarray, estimator: str, targets: str) -> tuple[np.ndarray, np.ndarray]:
    """Tasks as a float (n, d) array and targets as a float array with n rows.

    Raises:
        ValueError: fewer than two tasks, a row-count mismatch, or NaN/inf anywhere; the message names the
            estimator (e.g. ``"TaskTrend"``) and what one target is (e.g. ``"one residual curve each"``).
    """
    X = np.atleast_2d(np.asarray(X, dtype=float))
    y = np.asarray(y, dtype=float)
    if X.shape[0] != y.shape[0] or X.shape[0] < 2:
        raise ValueError(f"{estimator} needs at least two {targets}")
    if not (np.all(np.isfinite(X)) and np.all(np.isfinite(y))):
        raise ValueError(f"{estimator} training data contain NaN or inf")
    return X, y
