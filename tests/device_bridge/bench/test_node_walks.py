"""A node of an envelope walked alone at its own task, from standing and reached from level walking."""

from __future__ import annotations

import pytest

from device_bridge.bench.node_walks import NODE_LEVEL_LEAD_S, NODE_STARTS, level_to_node, simulated_s, walk_node
from device_bridge.bench.task_reference import task_reference


@pytest.fixture(scope="module")
def rows(model):
    """Learned tables at 1.1 m/s: downhill, level and uphill."""
    return {g: model.propose(1.1, g, 75.0).table for g in (-10.0, 0.0, 10.0)}


def test_a_nodes_own_rows_walk_it_from_standing_and_from_level(model, rows):
    ref = task_reference(1.1, -10.0, model, 75.0)
    for start in NODE_STARTS:
        walk = walk_node(rows[-10.0], ref, 75.0, start, level_table=rows[0.0]).to_dict()
        assert walk["start"] == start and walk["falls"] == 0 and walk["strides"] >= 3
        assert walk["seconds"] == pytest.approx(simulated_s(start), abs=0.01)
    # reached from level: the level rows until the slope begins, the node's own from the next heel strike
    reached = walk_node(rows[-10.0], ref, 75.0, "level", level_table=rows[0.0]).to_dict()
    stride = ref.stride_time_s
    assert NODE_LEVEL_LEAD_S <= reached["node_rows_from_s"] <= NODE_LEVEL_LEAD_S + stride + 0.05


def test_rows_that_do_not_fit_the_node_are_found_at_the_node(model, rows):
    """Synthetic misfit, for the test: the +10° rows on a −10° slope (an edit that went wrong at one node). The node
    walk shows it from either start: the leg gives way under the body on the downhill."""
    ref = task_reference(1.1, -10.0, model, 75.0)
    for start in NODE_STARTS:
        walk = walk_node(rows[10.0], ref, 75.0, start, level_table=rows[0.0]).to_dict()
        assert walk["falls"] > 0 and walk["fall_events"], start


def test_a_node_is_reached_from_level_over_the_courses_change():
    course = level_to_node(0.8, 6.0)
    assert [s.incline_deg for s in course.segments] == [0.0, 6.0] and course.segments[0].duration_s == NODE_LEVEL_LEAD_S
    with pytest.raises(ValueError, match="start must be one of"):
        walk_node(None, None, 75.0, "swing")
