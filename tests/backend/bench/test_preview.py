"""The dashboard's simulated preview of a table."""

from __future__ import annotations

import pytest

from backend.bench.preview import preview_table
from controller_core.fsmic import fsmic_table
from controller_core.table import SafetyLimitError


def test_a_table_preview_walks_the_table_and_the_fsmic_with_their_difference(model):
    table = model.propose(1.2, 0.0, 75.0).table
    p = preview_table(table, 1.2, 0.0, 75.0, model, seconds=5.0)
    assert len(p["phase_grid"]) == 101 and set(p["controllers"]) == {"table", "fsmic"}
    t, f = p["controllers"]["table"], p["controllers"]["fsmic"]
    assert t["vs_fsmic"]["knee_angle_rmse_difference_deg"] == pytest.approx(
        t["knee_angle_rmse_deg"] - f["knee_angle_rmse_deg"])
    assert len(t["mean_curves"]["knee_angle_deg"]) == 101 and "vs_fsmic" not in f
    same = preview_table(fsmic_table(75.0), 1.2, 0.0, 75.0, model, seconds=5.0)["controllers"]["table"]
    assert same["vs_fsmic"]["knee_angle_rmse_difference_deg"] == pytest.approx(0.0, abs=1e-9)


def test_an_unsafe_table_is_never_walked(model):
    table = model.propose(1.2, 0.0, 75.0).table
    row = table.rows[0]
    bad = table.model_copy(update={"rows": [row.model_copy(update={"k_Nm_per_rad": 50.0}), *table.rows[1:]]})
    with pytest.raises(SafetyLimitError):
        preview_table(bad, 1.2, 0.0, 75.0, model, seconds=5.0)
