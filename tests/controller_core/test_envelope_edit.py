"""Envelope edits: one setting across every node or at one node, by an offset or a percentage."""

from __future__ import annotations

import pytest

from controller_core.content import canonical_json
from controller_core.envelope import check_envelope
from controller_core.envelope_edit import edit_envelope, hold_to_neighbour_rule
from controller_core.table_edit import EditError


@pytest.fixture(scope="module")
def envelope(model):
    return model.propose_envelope([0.9, 1.3], [-4.0, 4.0], 75.0)


def test_a_percentage_everywhere_and_an_offset_at_one_node(envelope):
    edited, changes = edit_envelope(envelope, [
        {"field": "ankle.stance_extension.k_Nm_per_rad", "percent": -20},
        {"field": "thresholds.we_to_sf_load_N", "offset": 15.0, "node": [1, 0]}])
    assert len(changes) == 5 and canonical_json(edited) != canonical_json(envelope)
    for old, new in zip(envelope.nodes, edited.nodes, strict=True):
        ko, kn = old.table.row("ankle", "stance_extension"), new.table.row("ankle", "stance_extension")
        assert kn.k_Nm_per_rad == pytest.approx(0.8 * ko.k_Nm_per_rad) and kn.fit_method == "manual" and kn.r2 is None
        assert kn.theta_e_deg == ko.theta_e_deg and new.table.provenance.source == "edit"
    loads = [n.table.thresholds.we_to_sf_load_N - o.table.thresholds.we_to_sf_load_N
             for o, n in zip(envelope.nodes, edited.nodes, strict=True)]
    assert loads == [0.0, 0.0, pytest.approx(15.0), 0.0]      # node [1, 0] is the third, speed-major
    assert envelope.nodes[0].table.row("ankle", "stance_extension").fit_method != "manual"   # the original is untouched


@pytest.mark.parametrize(("edits", "why"), [
    ([], "no edits"),
    ([{"field": "knee.stance_flexion.k", "offset": 1}], "unknown field"),
    ([{"field": "knee.stance_flexion.k_Nm_per_rad"}], "exactly one"),
    ([{"field": "knee.stance_flexion.k_Nm_per_rad", "offset": float("inf")}], "finite"),
    ([{"field": "knee.stance_flexion.k_Nm_per_rad", "percent": -100}], "percent"),
    ([{"field": "knee.stance_flexion.k_Nm_per_rad", "offset": 1, "node": [2, 0]}], "node"),
    ([{"field": "knee.stance_flexion.k_Nm_per_rad", "offset": 1},
      {"field": "knee.stance_flexion.k_Nm_per_rad", "offset": 2, "node": [0, 0]}], "twice"),
    ([{"field": "knee.stance_flexion.k_Nm_per_rad", "percent": 0}], "changes nothing"),
])
def test_an_edit_that_is_not_one_is_refused_with_the_reason(envelope, edits, why):
    with pytest.raises(EditError, match=why):
        edit_envelope(envelope, edits)


def test_a_value_pushed_past_a_step_is_held_within_it_on_request_and_says_what_the_edit_gave(model):
    env = model.propose_envelope([0.9, 1.2, 1.5], [-5.0, 0.0, 5.0], 75.0)        # nominal 1.2 m/s level: the middle
    field = "knee.stance_flexion.k_Nm_per_rad"
    step = env.neighbour_steps.k_Nm_per_rad
    edited, changes = edit_envelope(env, [{"field": field, "offset": -2 * step, "node": [2, 2]}])   # one corner
    assert check_envelope(edited)                                                # refused as it stands
    held, held_changes = hold_to_neighbour_rule(env, edited, changes)
    assert not check_envelope(held)
    corner = held.node(2, 2).table.row("knee", "stance_flexion")
    wanted = edited.node(2, 2).table.row("knee", "stance_flexion").k_Nm_per_rad
    assert corner.fit_method == "neighbour_guard"
    assert held.node(2, 2).neighbour_guarded[field] == pytest.approx(wanted, abs=1e-6)
    near = [held.node(1, 2).table.row("knee", "stance_flexion").k_Nm_per_rad,
            held.node(2, 1).table.row("knee", "stance_flexion").k_Nm_per_rad]
    assert corner.k_Nm_per_rad == pytest.approx(max(near) - step)               # as firm as the rule allows
    [change] = held_changes
    assert change["node"] == [2, 2] and change["after"] == corner.k_Nm_per_rad
    assert change["held_from"] == pytest.approx(wanted, abs=1e-6)
    assert [n.table for n in held.nodes[:-1]] == [n.table for n in env.nodes[:-1]]   # no other node moved

