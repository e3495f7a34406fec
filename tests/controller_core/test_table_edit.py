"""Hand edits of a table: a new table, the changed cells, and the fit notes that no longer hold."""

from __future__ import annotations

import pytest
from pydantic import ValidationError

from controller_core.table_edit import EditError, edit_table


@pytest.fixture
def table(model):
    return model.propose(1.2, 0.0, 75.0).table


def test_editing_k_makes_the_row_manual_and_editing_damping_keeps_its_fit(table):
    table = table
    knee = table.rows[0]
    new, changes = edit_table(table, rows=[{"joint": knee.joint, "subphase": knee.subphase,
                                            "k_Nm_per_rad": knee.k_Nm_per_rad - 10.0}])
    row = new.row(knee.joint, knee.subphase)
    assert (row.fit_method, row.r2, row.guarded) == ("manual", None, False)
    assert changes == [{"field": f"{knee.joint}.{knee.subphase}.k_Nm_per_rad", "before": knee.k_Nm_per_rad,
                        "after": knee.k_Nm_per_rad - 10.0}]
    assert new.provenance.source == "edit" and table.row(knee.joint, knee.subphase) == knee     # original untouched
    damped, _ = edit_table(table, rows=[{"joint": knee.joint, "subphase": knee.subphase,
                                         "b_Nm_s_per_rad": knee.b_Nm_s_per_rad + 1.0}])
    assert damped.row(knee.joint, knee.subphase).fit_method == knee.fit_method


def test_a_threshold_edit_is_a_change_of_its_own(table):
    table = table
    before = table.thresholds.se_to_wf_load_N
    new, changes = edit_table(table, thresholds={"se_to_wf_load_N": before + 5.0})
    assert new.thresholds.se_to_wf_load_N == before + 5.0 and changes[0]["field"] == "thresholds.se_to_wf_load_N"


@pytest.mark.parametrize(("rows", "thresholds", "words"), [
    ([{"joint": "hip", "subphase": "stance_flexion", "k_Nm_per_rad": -1.0}], None, "no table row for joint 'hip'"),
    ([{"joint": "knee", "subphase": "stance_flexion", "stiffness": -1.0}], None, "unknown table fields"),
    ([], {"toe_off_load": 1.0}, "unknown threshold 'toe_off_load'"),
    ([], None, "changes nothing"),
])
def test_unknown_cells_and_empty_edits_are_refused(table, rows, thresholds, words):
    with pytest.raises(EditError, match=words):
        edit_table(table, rows=rows, thresholds=thresholds)


def test_a_row_edited_twice_or_a_value_that_is_not_a_number_is_refused(table):
    knee = table.rows[0]
    item = {"joint": knee.joint, "subphase": knee.subphase, "k_Nm_per_rad": knee.k_Nm_per_rad - 1.0}
    with pytest.raises(EditError, match="edited twice"):
        edit_table(table, rows=[item, item])
    with pytest.raises(ValidationError):
        edit_table(table, rows=[{**item, "k_Nm_per_rad": float("nan")}])
