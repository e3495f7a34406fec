"""Envelope: every node from the pipeline and within limits, the neighbour rule and its guard, JSON with a CRC."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from controller_core.content import canonical_json, content_sha256
from controller_core.envelope import (
    VALUE_FIELDS,
    Envelope,
    NeighbourSteps,
    check_envelope,
    envelope_of_table,
    neighbour_guard,
    neighbour_violations,
    table_values,
)
from controller_core.table import check_table
from controller_core.task import InvalidTaskError

SPEEDS = [0.6, 0.85, 1.1, 1.35, 1.6]
INCLINES = [-10.0, -5.0, 0.0, 5.0, 10.0]


@pytest.fixture(scope="module")
def envelope(model):
    return model.propose_envelope(SPEEDS, INCLINES, 75.0)


def test_a_5_by_5_envelope_has_every_node_from_the_pipeline_within_the_limits(model, envelope):
    assert envelope.shape == (5, 5) and len(envelope.nodes) == 25
    assert check_envelope(envelope) == []
    for node in envelope.nodes:
        assert check_table(node.table) == []
        assert node.extrapolation == node.table.provenance.extrapolation
        assert node.feature_std and all(math.isfinite(v) and v >= 0 for v in node.feature_std.values())
        assert any(k.endswith("_deg") for k in node.feature_std) and any(k.endswith("_Nm_per_kg") for k in node.feature_std)
        fitted, _ = model.propose_table(node.speed_mps, node.incline_deg, 75.0)
        moved = {VALUE_FIELDS.index(f) for f in node.neighbour_guarded}
        for f, (a, b) in enumerate(zip(table_values(node.table), table_values(fitted), strict=True)):
            if f in moved:   # a guarded value records what the pipeline fitted
                assert node.neighbour_guarded[VALUE_FIELDS[f]] == pytest.approx(b, abs=1e-5)
            else:
                assert a == pytest.approx(b, rel=1e-9, abs=1e-9)
    # the corners of the training data are flagged, its middle is not
    assert envelope.node(0, 0).extrapolation and not envelope.node(2, 2).extrapolation


def test_propose_table_is_the_table_of_propose(model):
    for speed, incline in ((0.9, 0.0), (1.3, 6.0), (1.5, -8.0)):
        np.testing.assert_allclose(table_values(model.propose_table(speed, incline, 80.0)[0]),
                                   table_values(model.propose(speed, incline, 80.0).table), rtol=1e-9, atol=1e-9)


def test_the_guard_moves_the_least_into_the_steps_and_keeps_the_start_node():
    # synthetic values (a test of the rule, not data): one value per node on a 3 x 3 grid with a jump in a corner
    steps = NeighbourSteps(k_Nm_per_rad=100.0)
    width = len(VALUE_FIELDS)
    grid = [[-200.0] + [0.0] * (width - 1) for _ in range(9)]
    grid[8][0] = -900.0            # far corner: 700 N·m/rad from its neighbours
    grid[4][0] = -120.0            # centre
    out = neighbour_guard((3, 3), grid, (1, 1), steps)
    assert out[4][0] == -120.0     # the start node is never moved
    assert out[8][0] == pytest.approx(-300.0)   # the least move into both neighbours' steps (-200 - 100)
    for i in range(3):
        for j in range(3):
            for a, b in ((i + 1, j), (i, j + 1)):
                if a < 3 and b < 3:
                    assert abs(out[i * 3 + j][0] - out[a * 3 + b][0]) <= 100.0 + 1e-9
    # every guarded value lies between its fitted value and its neighbours': inside any interval limit they satisfy
    assert all(min(-900.0, -200.0) <= v[0] <= -120.0 + 1e-9 for v in out)


def test_a_jump_between_neighbours_is_named_with_both_nodes(envelope):
    tables = envelope.tables()
    knee = tables[0].row("knee", "stance_flexion")
    jumped = tables[0].model_copy(update={"rows": [r.model_copy(update={"k_Nm_per_rad": r.k_Nm_per_rad - 500.0})
                                                   if r is knee else r for r in tables[0].rows]})
    broken = neighbour_violations(SPEEDS, INCLINES, [jumped, *tables[1:]])
    assert broken and all("knee.stance_flexion.k_Nm_per_rad" in v.field for v in broken)
    assert any("0.60 m/s, -10.0 deg" in v.message and "0.85 m/s, -10.0 deg" in v.message for v in broken)


def test_json_carries_units_and_a_content_hash_that_catches_a_changed_value(envelope):
    text = canonical_json(envelope)
    assert "k_Nm_per_rad" in text and "theta_e_deg" in text and "speeds_mps" in text and "inclines_deg" in text
    assert Envelope.from_json(json.loads(text)) == envelope
    body = json.loads(text)
    body["nodes"][7]["table"]["rows"][0]["theta_e_deg"] += 0.001
    assert content_sha256(canonical_json(Envelope.from_json(body))) != content_sha256(text)
    legacy = {**envelope.to_json(), "crc32": 12345}           # what an older release stored: read past
    assert Envelope.from_json(legacy) == envelope
    with pytest.raises(ValueError, match="JSON object"):
        Envelope.from_json([])


@pytest.mark.parametrize(("speeds", "inclines", "why"), [
    ([1.0], [0.0, 5.0], "at least 2"),
    ([1.0, 0.8], [0.0, 5.0], "strictly increasing"),
    ([0.8, float("nan")], [0.0, 5.0], "finite"),
    ([0.8, 1.2], [0.0, 25.0], "within"),
    ([0.05, 1.2], [0.0, 5.0], "within"),
])
def test_a_grid_that_is_not_a_grid_of_walking_tasks_is_refused(model, speeds, inclines, why):
    with pytest.raises(InvalidTaskError, match=why):
        model.propose_envelope(speeds, inclines, 75.0)


def test_a_range_of_one_task_is_refused_but_a_table_is_the_envelope_of_its_one_node(model):
    """A range of tasks needs two values per axis (1 × 1 asked as a range is refused like 1 × 2); a fixed-task table
    is the 1 × 1 envelope at its own task, mass and model, which checks, round-trips and blends as the table."""
    with pytest.raises(InvalidTaskError, match="at least 2"):
        model.propose_envelope([1.2], [0.0], 75.0)
    table = model.propose(1.2, 3.0, 80.0).table
    one = envelope_of_table(table)
    assert one.single_node and one.shape == (1, 1) and one.nodes[0].table == table
    assert (one.speeds_mps, one.inclines_deg, one.nominal_speed_mps, one.nominal_incline_deg) == ([1.2], [3.0], 1.2, 3.0)
    assert (one.mass_kg, one.model_version) == (80.0, table.provenance.model_version)
    assert Envelope.from_json(json.loads(canonical_json(one))) == one
    assert check_envelope(one) == []
    with pytest.raises(ValueError, match="at least 2"):       # one value on one axis only is not a grid
        Envelope.model_validate({**one.to_json(), "inclines_deg": [3.0, 5.0]})


def test_the_nominal_task_is_clamped_into_the_grid(model):
    env = model.propose_envelope([0.8, 1.0], [0.0, 4.0], 70.0, nominal=(1.2, 0.0))
    assert (env.nominal_speed_mps, env.nominal_incline_deg) == (1.0, 0.0)
    assert env.mass_kg == 70.0 and all(n.table.provenance.patient_mass_kg == 70.0 for n in env.nodes)


def test_features_predicted_for_many_tasks_at_once_are_those_of_each_task(model):
    tasks = np.array([[s, g] for s in (0.5, 1.1, 2.4) for g in (-12.0, 0.0, 7.5)])
    for task, many in zip(tasks, model.predict_features_many(tasks), strict=True):
        for a, b in zip(many, model.predict_features(*task), strict=True):
            assert a.spec == b.spec and a.extrapolation == b.extrapolation
            assert (a.value, a.std, a.phase, a.phase_std) == pytest.approx((b.value, b.std, b.phase, b.phase_std),
                                                                           rel=1e-9, abs=1e-12)


def test_where_the_knee_does_positive_work_the_envelope_holds_the_stance_support_floor(model):
    """The default grid for 70 kg: at 0.6 m/s up a 10° ramp the fit wants a knee that barely resists (the person's
    knee does positive work climbing slowly); the row holds −1.2 N·m/rad/kg × 70 kg instead, says so, and every node
    (neighbour guard included) is at least that firm."""
    env = model.propose_envelope([0.6, 0.8, 1.0, 1.3, 1.6], [-10.0, -5.0, 0.0, 5.0, 10.0], 70.0)
    floor = -1.2 * 70.0
    rows = {(n.speed_mps, n.incline_deg): n.table.row("knee", "stance_flexion") for n in env.nodes}
    assert all(r.k_Nm_per_rad <= floor + 1e-9 for r in rows.values())
    held = rows[(0.6, 10.0)]
    assert held.fit_method == "support_floor" and held.guarded and held.k_Nm_per_rad == pytest.approx(floor)
    assert 0.0 <= held.theta_e_deg <= 120.0
    assert check_envelope(env) == []
