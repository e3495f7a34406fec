"""The bench's check of a refinement step: the sensitivity holds near where it was measured, and a step beyond that is
caught by walking it."""

from __future__ import annotations

from controller_core.refine_evidence import NodeEvidence
from controller_core.table_edit import edit_table
from device_bridge.bench.refine_walks import BenchStepCheck


def _at(speed_mps: float, incline_deg: float) -> NodeEvidence:
    return NodeEvidence((0, 0), speed_mps, incline_deg, 10, 10.0, {}, {})


def test_a_small_step_is_confirmed_and_one_that_changes_the_gait_is_refused(model):
    table = model.propose(1.2, 0.0, 75.0).table
    check = BenchStepCheck(model, 75.0, seconds=10.0)
    small = edit_table(table, [{"joint": "knee", "subphase": "stance_flexion",
                                "theta_e_deg": table.row("knee", "stance_flexion").theta_e_deg + 0.5}])[0]
    assert check(_at(1.2, 0.0), table, small, {}) is None
    # the terminal-swing equilibrium 5° down, twice the range the sensitivity was measured over: the knee lands
    # straight and push-off comes late on the bench, far from what a linear sensitivity would say
    straight = edit_table(table, [{"joint": "knee", "subphase": "swing_extension",
                                   "theta_e_deg": table.row("knee", "swing_extension").theta_e_deg - 5.0}])[0]
    why = check(_at(1.2, 0.0), table, straight, {})
    assert why is not None and why.startswith("the bench moved") and "where the sensitivity expected +0.0" in why
    assert check.refused == 1 and check.walks == 3               # the old rows were walked once
