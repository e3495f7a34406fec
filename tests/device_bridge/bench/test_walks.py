"""Walks on the bench at one task."""

from __future__ import annotations

import pandas as pd
import pytest

from device_bridge.bench.walks import simulate


def test_a_given_table_walks_as_the_model_table_at_its_task(model, tmp_path):
    table = model.propose(1.2, 0.0, 75.0).table
    given = simulate("table", 1.2, 0.0, seconds=5.0, mass_kg=75.0, table=table, record=tmp_path / "walk.csv")
    learned = simulate("quasi-stiffness", 1.2, 0.0, seconds=5.0, mass_kg=75.0, model=model)
    assert given.summary["controller"] == "table" and learned.summary["controller"] == "quasi-stiffness"
    assert given.summary["knee_angle_rmse_deg"] == pytest.approx(learned.summary["knee_angle_rmse_deg"])
    frame = pd.read_csv(tmp_path / "walk.csv")
    assert {"time_s", "knee_angle_deg", "state"} <= set(frame.columns) and frame["time_s"].iloc[-1] == pytest.approx(4.999)


def test_a_bad_task_is_refused_before_walking(model):
    with pytest.raises(ValueError, match="speed"):
        simulate("fsmic", -1.0, 0.0, seconds=1.0)
