"""The extrapolation test: inside or outside the training tasks."""

from __future__ import annotations

import numpy as np

from controller_core.hull import TaskHull

# ---------------------------------------------------------------- GPR on real features


def test_hull_handles_degenerate_and_full_rank_sets():
    line = TaskHull().fit(np.array([[0.8, 0.0], [1.2, 0.0], [1.9, 0.0]]))
    assert line.contains(np.array([1.0, 0.0])) and line.contains(np.array([1.0, 0.3]))
    assert not line.contains(np.array([1.0, 2.0])) and not line.contains(np.array([2.2, 0.0]))
    tri = TaskHull().fit(np.array([[0.8, 0.0], [1.9, 0.0], [1.2, 5.0]]))
    assert tri.contains(np.array([1.2, 2.0])) and not tri.contains(np.array([1.9, 4.0]))


def test_the_faces_of_a_full_hull_give_the_same_answer_as_the_distance():
    rng = np.random.default_rng(3)
    hull = TaskHull().fit(np.array([[0.84, 0.0], [1.95, 0.0], [1.31, 10.0], [1.13, -10.0], [1.185, 5.0]]))
    M, q = hull.halfspaces()
    for x in np.column_stack([rng.uniform(0.5, 2.3, 500), rng.uniform(-15, 15, 500)]):
        assert (np.max(M @ x + q) <= 1.0) == hull.contains(x)
    assert TaskHull().fit(np.array([[0.8, 0.0], [1.9, 0.0]])).halfspaces() is None    # a line: tested one by one
