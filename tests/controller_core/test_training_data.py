"""The shared entry check of the task-regression estimators."""

from __future__ import annotations

import numpy as np
import pytest

from controller_core.training_data import training_arrays


def test_tasks_become_a_float_matrix_with_one_target_per_row():
    X, y = training_arrays([[0.8], [1.2], [1.6]], [[0.1, 0.2], [0.3, 0.4], [0.5, 0.6]], "TaskTrend", "curves")
    assert X.shape == (3, 1) and y.shape == (3, 2)
    X, y = training_arrays(np.array([[0.8, 0.0], [1.2, 5.0]]), [1.0, 2.0], "FeatureGPR", "tasks")
    assert X.dtype == float and X.shape == (2, 2) and y.tolist() == [1.0, 2.0]


@pytest.mark.parametrize(("X", "y", "words"), [
    ([[1.0, 0.0]], [1.0], "FeatureGPR needs at least two tasks"),
    ([[1.0, 0.0], [2.0, 0.0]], [1.0], "FeatureGPR needs at least two tasks"),
    ([[1.0, 0.0], [np.nan, 0.0]], [1.0, 2.0], "FeatureGPR training data contain NaN or inf"),
    ([[1.0, 0.0], [2.0, 0.0]], [1.0, np.inf], "FeatureGPR training data contain NaN or inf"),
])
def test_too_few_mismatched_or_non_finite_data_are_refused_naming_the_estimator(X, y, words):
    with pytest.raises(ValueError, match=words):
        training_arrays(X, y, "FeatureGPR", "tasks")
