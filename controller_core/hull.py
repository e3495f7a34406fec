"""Convex hull of training tasks, to flag extrapolation.

Task points are scaled by a tolerance per dimension (e.g. 0.05 m/s, 0.5°); a query counts as inside when
its distance to the hull is at most one tolerance unit. Degenerate hulls (all tasks on one line, e.g.
every curve at 0° incline) are handled by projecting onto the affine span of the training tasks.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import ConvexHull, QhullError


class TaskHull:
    """Membership test for the convex hull of training tasks.

    Args:
        tolerance: per-dimension tolerance in physical units (same order as the task columns).
    """

    def __init__(self, tolerance: tuple[float, ...] = (0.05, 0.5)) -> None:
        self.tolerance = tolerance

    def fit(self, X: np.ndarray) -> TaskHull:
        """Fit on (n, d) training tasks in physical units."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        if X.shape[1] != len(self.tolerance):
            raise ValueError(f"hull has {len(self.tolerance)} task dimensions, data has {X.shape[1]}")
        Z = X / np.asarray(self.tolerance)
        self.center_ = Z.mean(axis=0)
        _U, s, Vt = np.linalg.svd(Z - self.center_, full_matrices=False)
        rank = int(np.sum(s > 1e-9 * max(1.0, s.max(initial=0.0))))
        self.basis_ = Vt[:rank]                      # (rank, d) orthonormal span of the tasks
        P = (Z - self.center_) @ self.basis_.T       # (n, rank) coordinates in the span
        self.rank_ = rank
        if rank == 0:
            self.equations_ = np.zeros((0, 1))
        elif rank == 1:
            lo, hi = P[:, 0].min(), P[:, 0].max()
            self.equations_ = np.array([[1.0, -hi], [-1.0, lo]])
        else:
            try:
                self.equations_ = ConvexHull(P).equations  # rows: unit normal, offset; inside: n.x + b <= 0
            except QhullError as exc:  # pragma: no cover - rank test above prevents flat hulls
                raise ValueError(f"cannot build task hull: {exc}") from exc
        self._scale = 1.0 / np.asarray(self.tolerance, dtype=float)
        self._normals, self._offsets = self.equations_[:, :-1], self.equations_[:, -1]
        return self

    def distance(self, x: np.ndarray) -> float:
        """Distance (tolerance units) from a task to the hull; 0 inside."""
        z = np.asarray(x, dtype=float) * self._scale - self.center_
        if self.rank_ == 0:
            return math.sqrt(float(z @ z))
        in_span = self.basis_ @ z
        r = z - in_span @ self.basis_
        out = max(0.0, float((self._normals @ in_span + self._offsets).max()))
        return math.hypot(math.sqrt(float(r @ r)), out)

    def contains(self, x: np.ndarray) -> bool:
        """True when the task lies within one tolerance unit of the training hull."""
        return self.distance(x) <= 1.0

    def halfspaces(self) -> tuple[np.ndarray, np.ndarray] | None:
        """For a full-rank hull, (M, q) with distance-to-each-face (tolerance units) = M x + q for a task x in
        physical units: inside within tolerance when max(M x + q) ≤ 1. None for a degenerate hull."""
        d = len(self.tolerance)
        if self.rank_ < d or self.rank_ < 2:
            return None
        M = self._normals @ self.basis_ * self._scale[None, :]
        q = self._offsets - self._normals @ (self.basis_ @ self.center_)
        return M, q
