"""The bench's check of a refinement step: the sensitivity holds near where it was measured, and a step beyond that is
caught by walking it."""

from __future__ import annotations

from controller_core.refine_evidence import QUANTITIES, NodeEvidence
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
    # straight on every other stride on the bench (the stance knee peak alternates), far from what a linear
    # sensitivity would say
    straight = edit_table(table, [{"joint": "knee", "subphase": "swing_extension",
                                   "theta_e_deg": table.row("knee", "swing_extension").theta_e_deg - 5.0}])[0]
    why = check(_at(1.2, 0.0), table, straight, {})
    assert why is not None and why.startswith("the strides became irregular on the bench: stance knee flexion")
    assert check.refused == 1 and check.walks == 3               # the old rows were walked once


def test_a_step_that_makes_the_strides_irregular_is_refused_though_its_mean_error_looks_better(model, monkeypatch):
    """Made-up bench results (said here): the new rows bring the stance knee's mean error to zero by alternating long
    and short strides (its spread ±9° where it was ±2°, beyond twice that plus the 2° tolerance); a mean error alone
    would call that a success."""
    import device_bridge.bench.refine_walks as walks

    table = model.propose(1.2, 0.0, 75.0).table
    new = edit_table(table, [{"joint": "knee", "subphase": "swing_flexion",
                              "theta_e_deg": table.row("knee", "swing_flexion").theta_e_deg - 5.0}])[0]
    key = "knee_stance_flexion_peak_deg"

    def made_up(t, *args, **kwargs):
        limping = t is new
        return {"strides": 8, "falls": 0, "seconds": 12.0,
                "error": {q.key: (0.0 if limping else 4.0) if q.key == key else 1.0 for q in QUANTITIES},
                "spread": {q.key: (9.0 if limping else 2.0) if q.key == key else 1.0 for q in QUANTITIES}}

    monkeypatch.setattr(walks, "bench_feature_errors", made_up)
    check = BenchStepCheck(model, 75.0)
    why = check(_at(1.2, 0.0), table, new, {key: -4.0})
    assert why is not None and "irregular" in why and "±9.0°" in why and "±2.0° before" in why
    # a spread that grows less than that is within what a 12 s walk can tell (its start's strides)
    steady = {"strides": 8, "falls": 0, "seconds": 12.0, "error": {q.key: 0.0 if q.key == key else 1.0 for q in QUANTITIES},
              "spread": {q.key: 5.5 if q.key == key else 1.0 for q in QUANTITIES}}
    monkeypatch.setattr(walks, "bench_feature_errors", lambda t, *a, **k: steady if t is new else made_up(t))
    assert BenchStepCheck(model, 75.0)(_at(1.2, 0.0), table, new, {key: -4.0}) is None   # within the tolerance
