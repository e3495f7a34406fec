"""Per-node evidence from strides. The strides and targets are synthetic: made-up feature values around fixed targets."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controller_core.envelope_blend import node_weights
from controller_core.features import FEATURES_BY_NAME
from controller_core.proposal import FeaturePrediction
from controller_core.refine_evidence import gather_evidence, judge
from controller_core.stride_features import MeasuredStride

TARGETS = {"knee_stance_flexion_peak": (0.15, 18.0), "knee_swing_flexion_peak": (0.72, 62.0),
           "ankle_plantarflexion_peak": (0.64, -16.0)}
SPEEDS, INCLINES = [0.6, 1.0, 1.4], [-5.0, 0.0, 5.0]


def targets_at(speed_mps: float, incline_deg: float) -> dict[str, FeaturePrediction]:
    return {name: FeaturePrediction(FEATURES_BY_NAME[name], p, 0.01, math.radians(v), 0.03, False)
            for name, (p, v) in TARGETS.items()}


def stride(speed: float, incline: float, swing_error_deg: float = 0.0, stance_error_deg: float = 0.0
           ) -> MeasuredStride:
    feats = {name: (p, math.radians(v)) for name, (p, v) in TARGETS.items()}
    p, v = TARGETS["knee_swing_flexion_peak"]
    feats["knee_swing_flexion_peak"] = (p, math.radians(v + swing_error_deg))
    p, v = TARGETS["knee_stance_flexion_peak"]
    feats["knee_stance_flexion_peak"] = (p, math.radians(v + stance_error_deg))
    return MeasuredStride(speed, incline, feats, toe_off_phase=0.61)


def test_bilinear_weights_sum_to_one_and_split_a_stride_between_nodes():
    w = node_weights(SPEEDS, INCLINES, 1.2, 0.0)
    assert sorted((i, j, round(x, 6)) for i, j, x in w) == [(1, 1, 0.5), (2, 1, 0.5)]
    w = node_weights(SPEEDS, INCLINES, 2.0, -9.0)   # beyond the grid: clamped to the corner
    assert w == [(2, 0, 1.0)]
    assert sum(x for *_, x in node_weights(SPEEDS, INCLINES, 0.83, 2.7)) == pytest.approx(1.0)


def test_a_stride_between_two_nodes_informs_each_by_half():
    rng = np.random.default_rng(1)
    strides = [stride(1.2, 0.0, swing_error_deg=-6.0 + rng.normal(0, 1)) for _ in range(24)]
    ev = gather_evidence(strides, SPEEDS, INCLINES, targets_at)
    at = {e.node: e for e in ev}
    assert at[(1, 1)].weight == pytest.approx(12.0) and at[(2, 1)].weight == pytest.approx(12.0)
    q = at[(1, 1)].quantities["knee_swing_flexion_peak_deg"]
    assert q.act and q.error == pytest.approx(-6.0, abs=0.8) and q.ci95[1] < 0.0
    assert at[(0, 0)].strides == 0 and not at[(0, 0)].quantities["knee_swing_flexion_peak_deg"].act


@pytest.mark.parametrize(("errors", "reason"), [
    (np.full(6, -5.0) + np.linspace(-1, 1, 6), "too few strides"),
    (np.tile([-6.0, 6.5], 8), "strides disagree"),
    (np.full(14, 1.2) + np.linspace(-0.5, 0.5, 14), "within tolerance"),
])
def test_strides_that_do_not_make_a_consistent_case_are_left_alone_and_say_why(errors, reason):
    q = judge("knee_swing_flexion_peak_deg", 62.0 + errors, np.full(errors.size, 62.0), np.ones(errors.size))
    assert not q.act and reason in q.reason


def test_ten_consistent_strides_are_enough_to_act():
    errors = -4.0 + np.linspace(-1.5, 1.5, 10)
    q = judge("knee_swing_flexion_peak_deg", 62.0 + errors, np.full(10, 62.0), np.ones(10))
    assert q.act and q.effective_strides == pytest.approx(10.0) and q.agreement == 1.0
    assert q.ci95[0] < -4.0 < q.ci95[1] < 0.0
