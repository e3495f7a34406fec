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


def test_a_nodes_rows_are_walked_where_they_run_inside_the_envelope_on_the_patients_leg(model):
    """The search's bench walks a candidate for one node inside the envelope on the leg's own estimate, on the leg it
    was given: the node's own rows change what the envelope does at the node's task, a far node's do not."""
    from device_bridge.bench.controllers import default_envelope
    from device_bridge.sim.leg_file import load_leg

    leg = load_leg("stiff_geared")
    env = default_envelope(model, 75.0, leg)
    check = BenchStepCheck(model, 75.0, seconds=8.0, geometry=leg)
    assert check.leg == leg.name
    here = env.shape[1] * 2 + 2                    # the 1.1 m/s level node, walked at its task
    far = 0                                        # 0.6 m/s, −10°: never blended at 1.1 m/s level
    node = env.nodes[here]

    def more_push_off(table):     # the ankle's push-off equilibrium 8° further into plantarflexion
        return table.model_copy(update={"rows": [
            r.model_copy(update={"theta_e_deg": r.theta_e_deg - 8.0})
            if (r.joint, r.subphase) == ("ankle", "stance_extension") else r for r in table.rows]})

    base = check.at_node(env, here).errors(node.table, node.speed_mps, node.incline_deg)
    moved = check.at_node(env, here).errors(more_push_off(node.table), node.speed_mps, node.incline_deg)
    elsewhere = check.at_node(env, far).errors(more_push_off(env.nodes[far].table), node.speed_mps, node.incline_deg)
    key = "ankle_plantarflexion_peak_deg"
    assert moved["error"][key] < base["error"][key] - 2.0      # 8° more push-off plantarflexion asked, most of it seen
    assert elsewhere["error"] == base["error"]                  # the same walk: a node that is not blended changes nothing
    assert check.walks == 3
