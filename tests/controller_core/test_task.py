"""The task ranges QuasiTune accepts, checked in one place."""

from __future__ import annotations

import pytest

from controller_core.task import InvalidTaskError, validate_task


@pytest.mark.parametrize("task", [(0.1, 0.0, 20.0), (3.0, 20.0, 200.0), (1.2, -20.0, 75)])
def test_the_edges_are_inside(task):
    validate_task(*task)


@pytest.mark.parametrize(("task", "words"), [
    ((float("nan"), 0.0, 75.0), "speed_mps must be a finite number"),
    ((1.2, float("inf"), 75.0), "incline_deg must be a finite number"),
    ((1.2, 0.0, True), "mass_kg must be a finite number"),
    ((1.2, 0.0, "75"), "mass_kg must be a finite number"),
    ((0.09, 0.0, 75.0), r"speed_mps = 0.09 m/s is outside \[0.1, 3\] m/s"),
    ((1.2, -20.5, 75.0), r"incline_deg = -20.5 deg is outside \[-20, 20\] deg"),
    ((1.2, 0.0, 19.0), r"mass_kg = 19 kg is outside \[20, 200\] kg"),
])
def test_a_bad_value_is_refused_by_name_with_its_range(task, words):
    with pytest.raises(InvalidTaskError, match=words):
        validate_task(*task)
    assert issubclass(InvalidTaskError, ValueError)
