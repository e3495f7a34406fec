"""The fixed-task comparison: both controllers at each task, their difference, the table and the figure."""

from __future__ import annotations

import pytest

from lab.comparison import cell, compare, format_compare, plot_compare


@pytest.fixture(scope="module")
def results(model):
    return compare(model, speeds_mps=(1.2,), inclines_deg=(0.0,), seconds=6.0, mass_kg=75.0)


def test_each_task_walks_both_controllers_and_the_learned_one_carries_its_difference(results):
    (learned, a), (fsmic, b) = results
    assert (a, b) == ("quasi-stiffness", "fsmic") and "vs_fsmic" not in fsmic.summary
    d = learned.summary["vs_fsmic"]["knee_angle_rmse_difference_deg"]
    assert d == pytest.approx(learned.summary["knee_angle_rmse_deg"] - fsmic.summary["knee_angle_rmse_deg"])


def test_the_table_has_a_row_per_walk_and_a_verdict_row_per_task(results):
    text = format_compare([score.to_dict() for score, _ in results])
    lines = text.splitlines()
    assert lines[0].startswith("| speed_mps | incline_deg | controller |") and sum("| 1.20 |" in x for x in lines) == 3
    assert "learned − FSMIC RMSE, 95 % interval" in text
    assert cell(None) == "—" and cell(1.234) == "1.23" and cell(3) == "3"


def test_the_figure_is_written(results, tmp_path):
    plot_compare(results, tmp_path / "compare.png")
    assert (tmp_path / "compare.png").stat().st_size > 10_000
