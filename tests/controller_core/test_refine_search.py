"""The search on the bench. The "bench" here is synthetic: a made-up response of the five quantities to the table's
values (linear plus a quadratic term, known exactly), so the right answer is known; the table is the model's."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controller_core.refine import PARAMETERS, RefineRules, refine_node, step_box, taken_step
from controller_core.refine_evidence import QUANTITIES
from controller_core.refine_search import TrustRegionSearch, broyden, search_rows
from controller_core.stride_features import transitions
from tests.controller_core.test_refine import node_evidence, synthetic_rules


class SyntheticBench:
    """Bench errors = start + J_true · (step from the first table) + curvature · step², per quantity (display units);
    ``refuse_if``: a step (stepping units) the bench refuses as irregular."""

    leg = "synthetic"

    def __init__(self, first, J_true, start, curvature=0.0, refuse_if=None):
        self.first, self.J_true, self.start = first, np.asarray(J_true), np.asarray(start)
        self.curvature, self.refuse_if = curvature, refuse_if
        self.walked = []

    def errors(self, table, speed_mps, incline_deg):
        x = taken_step(self.first, table)
        self.walked.append(x)
        f = self.start + self.J_true @ x + self.curvature * (self.J_true @ x) ** 2
        return {"error": {q.key: float(v) for q, v in zip(QUANTITIES, f, strict=True)}, "falls": 0,
                "spread": {q.key: 1.0 for q in QUANTITIES}, "strides": 12, "irregular": bool(
                    self.refuse_if is not None and self.refuse_if(x))}

    def worse(self, before, after):
        return "the strides became irregular on the bench" if after["irregular"] else None


def true_sensitivity():
    """Each quantity moved by one or two values (per deg, per unit ln|value|), as the bench's grid medians roughly do."""
    J = np.zeros((len(QUANTITIES), len(PARAMETERS)))
    fields = [p.field for p in PARAMETERS]
    J[0, fields.index("knee.swing_extension.theta_e_deg")] = 0.75
    J[0, fields.index("knee.stance_flexion.theta_e_deg")] = 0.2
    J[1, fields.index("knee.swing_flexion.theta_e_deg")] = 0.7
    J[2, fields.index("knee.swing_flexion.theta_e_deg")] = -0.5      # the timing: through the same row, non-linearly
    J[2, fields.index("knee.swing_flexion.b_Nm_s_per_rad")] = 3.0
    J[3, fields.index("ankle.stance_extension.theta_e_deg")] = -0.9
    J[4, fields.index("ankle.stance_extension.k_Nm_per_rad")] = 2.0
    return J


def wrong_sensitivity(J):
    """What the shipped grid might say on another leg: half the gains, and the timing's damping gain missing."""
    out = 0.5 * J
    out[2, [p.field for p in PARAMETERS].index("knee.swing_flexion.b_Nm_s_per_rad")] = 0.0
    return out


STEPS = np.array([RefineRules().step(p) for p in PARAMETERS])
RESOLUTION = np.array([math.log(1.01) if p.relative else 0.1 for p in PARAMETERS])


def apply_to(table):
    def apply(delta):
        from controller_core.refine import _stepped
        ev = node_evidence(table)
        made = _stepped(table, ev, delta, true_sensitivity(), np.zeros(len(QUANTITIES)), RefineRules(), "words")
        return made if isinstance(made, str) else (made[0], taken_step(table, made[0]))
    return apply


def test_the_search_reaches_an_aim_a_wrong_sensitivity_would_miss(model):
    """A leg with a bias on every quantity, the shipped sensitivity half the truth and blind to the timing's row: the
    search's walks correct it (Broyden) and bring every quantity within its tolerance of the aim."""
    table = model.propose(1.0, 0.0, 75.0).table
    J = true_sensitivity()
    bias = np.array([4.0, -3.0, 3.0, 3.0, -2.5])
    bench = SyntheticBench(table, J, start=np.zeros(5), curvature=0.02)
    found, trace = search_rows(table, bias, wrong_sensitivity(J), STEPS, RESOLUTION, apply_to(table), bench,
                               (1.0, 0.0), TrustRegionSearch(max_walks=10))
    assert found is not table and trace.walks <= 10
    left = trace.after - (trace.before - bias)                      # how far from the aim each quantity ended
    assert np.all(np.abs(left) <= np.array([q.tolerance for q in QUANTITIES])), left
    # one linear step through the wrong sensitivity, as before the search, leaves the timing where it was
    assert abs(trace.after[2] - trace.before[2]) > 1.5


def test_no_walked_step_leaves_the_bound_or_the_neighbours_box(model):
    table = model.propose(1.0, 0.0, 75.0).table
    J = true_sensitivity()
    box = (np.full(len(PARAMETERS), -2.0), np.full(len(PARAMETERS), 2.0))   # the neighbours allow ±2 units only
    bench = SyntheticBench(table, J, start=np.zeros(5))
    search_rows(table, np.array([20.0, 0.0, 0.0, 0.0, 0.0]), J, STEPS, RESOLUTION, apply_to(table), bench,
                (1.0, 0.0), TrustRegionSearch(max_walks=6, bound_steps=2.0), box)
    walked = np.array(bench.walked)
    assert np.all(np.abs(walked) <= np.minimum(2.0 * STEPS, 2.0) + 1e-6)
    assert np.abs(walked).max() > 1.0                                # it did move, up to the box


def test_a_candidate_the_bench_refuses_is_never_kept(model):
    table = model.propose(1.0, 0.0, 75.0).table
    J = true_sensitivity()
    fields = [p.field for p in PARAMETERS]
    landing = fields.index("knee.swing_extension.theta_e_deg")
    bench = SyntheticBench(table, J, start=np.zeros(5), refuse_if=lambda x: x[landing] < -3.0)
    found, trace = search_rows(table, np.array([6.0, 0.0, 0.0, 0.0, 0.0]), J, STEPS, RESOLUTION, apply_to(table),
                               bench, (1.0, 0.0), TrustRegionSearch(max_walks=8))
    assert trace.refused and taken_step(table, found)[landing] >= -3.0


def test_a_node_already_on_target_is_not_walked(model):
    table = model.propose(1.0, 0.0, 75.0).table
    J = true_sensitivity()
    bench = SyntheticBench(table, J, start=np.zeros(5))
    rules = synthetic_rules({})
    r = refine_node(table, node_evidence(table, swing_offset_deg=62.0 - 0.7 * table.row(
        "knee", "swing_flexion").theta_e_deg), rules, bench=bench)
    assert r.table is table and r.changes == [] and bench.walked == []


def test_broyden_makes_the_jacobian_agree_with_the_walk():
    J = np.ones((5, 3))
    dx, df = np.array([1.0, -2.0, 0.5]), np.array([0.3, math.nan, -1.0, 2.0, 0.0])
    out = broyden(J, dx, df)
    ok = np.isfinite(df)
    assert np.allclose(out[ok] @ dx, df[ok]) and np.array_equal(out[~ok], J[~ok])


def test_the_neighbours_box_keeps_a_stiffness_on_its_side_of_zero(model):
    table = model.propose(1.0, 0.0, 75.0).table
    from controller_core.envelope import VALUE_FIELDS, table_values
    values = table_values(table)
    lo, hi = step_box(table, [v - 5.0 for v in values], [v + 5.0 for v in values])
    c = [p.field for p in PARAMETERS].index("knee.swing_flexion.theta_e_deg")
    assert lo[c] == pytest.approx(-5.0) and hi[c] == pytest.approx(5.0)
    k = [p.field for p in PARAMETERS].index("knee.stance_flexion.k_Nm_per_rad")
    v = values[VALUE_FIELDS.index("knee.stance_flexion.k_Nm_per_rad")]
    assert v < 0 and math.exp(lo[k]) * v == pytest.approx(v + 5.0) and math.exp(hi[k]) * v == pytest.approx(v - 5.0)


def test_the_three_strides_of_a_task_change_are_the_changes_and_the_estimates_scatter_is_none():
    tasks = [(1.0, 0.0), (1.12, 0.0), (0.93, 1.4), (1.0, -1.2)]          # scatter within the estimate's resolution
    tasks += [(1.0, 4.0), (1.0, 8.0)] + [(1.0, 8.0)] * 5 + [None, (1.05, 8.5)]   # a ramp: the change's strides, then on
    assert transitions(tasks) == [False] * 4 + [True] * 5 + [False] * 4
