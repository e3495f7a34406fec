"""The parameter table's safety limits."""

from __future__ import annotations

import pytest

from controller_core import ParameterTable, SafetyLimitError, assert_safe, check_table
from controller_core.table import ParameterRow


def test_safety_check_names_the_offending_field(model):
    table = model.propose(1.25, 0.0, 75.0).table
    assert check_table(table) == []
    rows = [r.model_copy(update={"k_Nm_per_rad": -5000.0}) if (r.joint, r.subphase) == ("ankle", "stance_extension")
            else r for r in table.rows]
    bad = ParameterTable(rows=rows, thresholds=table.thresholds, provenance=table.provenance)
    with pytest.raises(SafetyLimitError, match=r"ankle\.stance_extension\.k_Nm_per_rad = -5000"):
        assert_safe(bad)
    backwards = table.thresholds.model_copy(update={"sf_to_se_knee_extension_deg_per_s": -5.0})
    with pytest.raises(SafetyLimitError, match=r"sf_to_se_knee_extension_deg_per_s = -5"):
        assert_safe(table.model_copy(update={"thresholds": backwards}))
    with pytest.raises(ValueError, match="finite"):
        ParameterRow.model_validate({**rows[0].model_dump(), "theta_e_deg": float("nan")})
    with pytest.raises(ValueError, match="one row per joint"):
        ParameterTable(rows=rows[:-1], thresholds=table.thresholds, provenance=table.provenance)


@pytest.mark.parametrize("subphase", ["stance_flexion", "stance_extension"])
@pytest.mark.parametrize("joint", ["knee", "ankle"])
def test_a_stance_row_that_injects_energy_is_refused_in_words_a_prosthetist_reads(model, joint, subphase):
    table = model.propose(1.25, 0.0, 75.0).table
    rows = [r.model_copy(update={"k_Nm_per_rad": 150.0}) if (r.joint, r.subphase) == (joint, subphase) else r
            for r in table.rows]
    bad = ParameterTable(rows=rows, thresholds=table.thresholds, provenance=table.provenance)
    [violation] = check_table(bad)
    assert violation.field == f"{joint}.{subphase}.k_Nm_per_rad" and violation.high == 0.0
    assert "gives way" in violation.message or "pushes" in violation.message
    # a pure damper (k = 0) is passive, and swing rows may still brake with a small positive k
    ok = [r.model_copy(update={"k_Nm_per_rad": 0.0}) if (r.joint, r.subphase) == (joint, subphase) else r
          for r in table.rows]
    assert check_table(ParameterTable(rows=ok, thresholds=table.thresholds, provenance=table.provenance)) == []


def test_every_proposal_over_the_task_range_has_passive_stance_rows(model):
    for speed in (0.3, 0.8, 1.4, 2.0, 2.6):
        for incline in (-20.0, -10.0, 0.0, 10.0, 20.0):
            for mass in (45.0, 190.0):
                table = model.propose(speed, incline, mass).table
                for r in table.rows:
                    if r.subphase.startswith("stance"):
                        assert r.k_Nm_per_rad <= 0.0, (speed, incline, mass, r)
