"""The parameter table's safety limits."""

from __future__ import annotations

import pytest

from controller_core import ParameterTable, SafetyLimitError, assert_safe, check_table
from controller_core.table import ParameterRow, support_floor_Nm_per_rad


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
    # a pure damper (k = 0) is passive; only the knee's stance flexion must also hold the support floor
    ok = [r.model_copy(update={"k_Nm_per_rad": 0.0}) if (r.joint, r.subphase) == (joint, subphase) else r
          for r in table.rows]
    found = check_table(ParameterTable(rows=ok, thresholds=table.thresholds, provenance=table.provenance))
    if (joint, subphase) == ("knee", "stance_flexion"):
        assert [v.field for v in found] == ["knee.stance_flexion.k_Nm_per_rad"] and "support floor" in found[0].message
    else:
        assert found == []


@pytest.mark.parametrize("mass_kg", [50.0, 82.0, 140.0])
def test_the_knee_stance_support_floor_scales_with_body_mass(model, mass_kg):
    """A knee stance-flexion k softer than 1.2 N·m/rad per kg is refused, naming the floor, the rate and the mass;
    one just firmer than the floor passes."""
    table = model.propose(1.25, 0.0, mass_kg).table
    floor = support_floor_Nm_per_rad(mass_kg)
    assert floor == pytest.approx(-1.2 * mass_kg)

    def with_knee_sf(k: float) -> ParameterTable:
        rows = [r.model_copy(update={"k_Nm_per_rad": k}) if (r.joint, r.subphase) == ("knee", "stance_flexion")
                else r for r in table.rows]
        return ParameterTable(rows=rows, thresholds=table.thresholds, provenance=table.provenance)

    [violation] = check_table(with_knee_sf(floor + 1.0))
    assert violation.field == "knee.stance_flexion.k_Nm_per_rad" and violation.high == pytest.approx(floor)
    assert f"{mass_kg:g} kg" in violation.message and "1.2 N·m/rad per kg" in violation.message
    assert "buckle" in violation.message
    assert check_table(with_knee_sf(floor - 1.0)) == []


def test_a_body_mass_outside_the_range_is_a_violation(model):
    table = model.propose(1.25, 0.0, 75.0).table
    odd = table.model_copy(update={"provenance": table.provenance.model_copy(update={"patient_mass_kg": 5.0})})
    assert "body_mass_kg" in [v.field for v in check_table(odd)]


def test_every_proposal_over_the_task_range_has_passive_stance_rows(model):
    for speed in (0.3, 0.8, 1.4, 2.0, 2.6):
        for incline in (-20.0, -10.0, 0.0, 10.0, 20.0):
            for mass in (45.0, 190.0):
                table = model.propose(speed, incline, mass).table
                for r in table.rows:
                    if r.subphase.startswith("stance"):
                        assert r.k_Nm_per_rad <= 0.0, (speed, incline, mass, r)


@pytest.mark.parametrize(("name", "value", "why"), [
    ("stumble_knee_margin_deg", 40.0, "a toe caught on a 50° knee is never seen stalled"),
    ("stumble_knee_rate_deg_per_s", 120.0, "a freely swinging knee taken for a planted one"),
    ("fold_knee_rate_deg_per_s", 45.0, "every downhill stance held stiff"),
    ("fold_window_of_stance_pct", 85.0, "pre-swing's flexion held stiff"),
    ("early_landing_swing_pct", 98.0, "an ordinary stride's shorter swing taken for an early landing"),
    ("early_landing_swing_pct", 30.0, "a foot put down on an obstacle in late swing not seen"),
    ("forefoot_landing_pct", 10.0, "a foot landing flat taken for one on its toe"),
])
def test_the_stumble_support_is_part_of_the_table_and_cannot_be_set_out_of_its_limits(model, name, value, why):
    """The trigger of the stumble support travels with the table: the schedule the leg runs reads it, and a value
    outside its limits is refused by name (the support cannot be switched off)."""
    table = model.propose(1.2, 0.0, 75.0).table
    assert check_table(table) == []
    bad = table.model_copy(update={"thresholds": table.thresholds.model_copy(update={name: value})})
    with pytest.raises(SafetyLimitError, match=rf"thresholds\.{name}"):
        assert_safe(bad)
    with pytest.raises(ValueError, match="finite"):
        type(table.thresholds).model_validate({**table.thresholds.model_dump(), name: float("nan")})


def test_the_leg_runs_the_stumble_support_the_table_states(model):
    import math

    from controller_core.fsm import ImpedanceSchedule

    table = model.propose(1.2, 0.0, 75.0).table
    changed = table.thresholds.model_copy(update={"stumble_knee_margin_deg": 20.0, "stumble_knee_rate_deg_per_s": 45.0,
                                                  "fold_knee_rate_deg_per_s": 120.0, "fold_window_of_stance_pct": 40.0,
                                                  "early_landing_swing_pct": 75.0, "forefoot_landing_pct": 40.0})
    sch = ImpedanceSchedule.from_table(table.model_copy(update={"thresholds": changed}))
    assert sch.stumble_knee_margin_rad == pytest.approx(math.radians(20.0))
    assert sch.stumble_knee_rate_rad_s == pytest.approx(math.radians(45.0))
    assert sch.fold_knee_rate_rad_s == pytest.approx(math.radians(120.0))
    assert sch.fold_window_of_stance == pytest.approx(0.4)
    assert (sch.early_landing_fraction, sch.forefoot_landing_fraction) == pytest.approx((0.75, 0.4))
