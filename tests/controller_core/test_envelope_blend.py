"""Blending an envelope: exact at the nodes, bilinear between them, clamped outside, refused when unsafe."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controller_core.envelope_blend import EnvelopeBlender, schedule_vector
from controller_core.fsm import ImpedanceSchedule
from controller_core.table import SafetyLimitError

SPEEDS = [0.8, 1.2, 1.6]
INCLINES = [-6.0, 0.0, 6.0]


@pytest.fixture(scope="module")
def envelope(model):
    return model.propose_envelope(SPEEDS, INCLINES, 75.0)


@pytest.fixture(scope="module")
def blender(envelope):
    return EnvelopeBlender(envelope.speeds_mps, envelope.inclines_deg, envelope.tables())


def test_at_a_node_the_blend_is_that_node(envelope, blender):
    for i, speed in enumerate(SPEEDS):
        for j, incline in enumerate(INCLINES):
            b = blender.at(speed, incline)
            assert not b.clamped
            want = schedule_vector(ImpedanceSchedule.from_table(envelope.node(i, j).table))
            np.testing.assert_allclose(schedule_vector(b.schedule), want, rtol=0, atol=1e-12)


def test_between_nodes_the_blend_is_bilinear(envelope, blender):
    corners = [np.array(schedule_vector(ImpedanceSchedule.from_table(envelope.node(i, j).table)))
               for i, j in ((0, 1), (0, 2), (1, 1), (1, 2))]
    b = blender.at(0.9, 1.5)     # a quarter of the way in speed and in incline
    wx, wy = 0.25, 0.25
    want = (1 - wx) * (1 - wy) * corners[0] + (1 - wx) * wy * corners[1] + wx * (1 - wy) * corners[2] + wx * wy * corners[3]
    np.testing.assert_allclose(schedule_vector(b.schedule), want, atol=1e-9)
    assert b.cell == (0, 1) and b.weights == pytest.approx((0.25, 0.25))


def test_outside_the_grid_the_blend_is_clamped_to_the_edge_and_says_so(blender):
    b = blender.at(2.4, -12.0)
    assert b.clamped and (b.speed_mps, b.incline_deg) == (1.6, -6.0)
    np.testing.assert_allclose(schedule_vector(b.schedule), schedule_vector(blender.at(1.6, -6.0).schedule))
    assert not blender.contains(2.4, -12.0) and blender.contains(1.6, -6.0)
    with pytest.raises(ValueError, match="finite"):
        blender.at(math.nan, 0.0)


def test_every_blend_of_safe_nodes_is_safe(blender):
    rng = np.random.default_rng(3)
    for speed, incline in zip(rng.uniform(0.5, 1.8, 300), rng.uniform(-8, 8, 300), strict=True):
        sch = blender.at(float(speed), float(incline)).schedule
        assert max(sch.knee_k[:2]) <= 0.0 and max(sch.ankle_k[:2]) <= 0.0      # stance rows never inject energy
        assert min(sch.knee_b) >= 0.0 and min(sch.ankle_b) >= 0.0
        assert sch.se_to_wf_load_N < sch.we_to_sf_load_N and sch.min_state_time_s < sch.max_state_time_s


def test_a_node_outside_the_limits_or_a_jump_between_nodes_is_refused_whole(envelope):
    tables = envelope.tables()

    def with_knee_sf_k(table, k):
        return table.model_copy(update={"rows": [r.model_copy(update={"k_Nm_per_rad": k})
                                                 if (r.joint, r.subphase) == ("knee", "stance_flexion") else r
                                                 for r in table.rows]})

    with pytest.raises(SafetyLimitError, match="stance"):        # a stance row that injects energy
        EnvelopeBlender(SPEEDS, INCLINES, [with_knee_sf_k(tables[0], 50.0), *tables[1:]])
    with pytest.raises(SafetyLimitError, match="neighbouring nodes"):   # safe alone, but 700 N·m/rad from its neighbours
        EnvelopeBlender(SPEEDS, INCLINES, [*tables[:4], with_knee_sf_k(tables[4], -1150.0), *tables[5:]])
    with pytest.raises(ValueError, match="needs 9 tables"):
        EnvelopeBlender(SPEEDS, INCLINES, tables[:8])
