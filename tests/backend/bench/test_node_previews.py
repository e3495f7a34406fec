"""Every node of an envelope walked alone, kept by content, walked side by side by a pool where one is given."""

from __future__ import annotations

import pytest

from backend.bench import node_previews
from backend.bench.node_previews import NodeWalks, envelope_flags, level_index


@pytest.fixture(scope="module")
def envelope(model):
    return model.propose_envelope([0.9, 1.3], [-6.0, 0.0], 75.0)


def test_each_node_is_walked_from_both_starts_and_kept_by_its_content(model, envelope, monkeypatch):
    walked = []
    real = node_previews.walk_node

    def counting(table, ref, mass, start, lead, geometry):
        walked.append((ref.speed_mps, ref.incline_deg, start))
        return real(table, ref, mass, start, lead, geometry)

    monkeypatch.setattr(node_previews, "walk_node", counting)
    walks = NodeWalks()
    nodes = walks.walk(envelope, model)
    # from standing and reached from level walking; the level nodes from standing only (that is their level walking)
    assert sorted(walked) == sorted([(v, g, "standing") for v in (0.9, 1.3) for g in (-6.0, 0.0)]
                                    + [(v, -6.0, "level") for v in (0.9, 1.3)])
    assert [(n["speed_mps"], n["incline_deg"]) for n in nodes] == [(0.9, -6.0), (0.9, 0.0), (1.3, -6.0), (1.3, 0.0)]
    assert [set(n["walks"]) for n in nodes] == [{"standing", "level"}, {"standing"}] * 2
    walked.clear()
    assert walks.walk(envelope, model) == nodes and walked == []        # the same content: nothing walked again
    # one downhill node changed (its knee's stance flexion 10 % firmer): only its two walks are walked again; the
    # level node it is reached from is unchanged
    assert level_index(envelope) == 1
    changed = envelope.model_copy(deep=True)
    row = changed.nodes[2].table.rows[0]
    changed.nodes[2].table.rows[0] = row.model_copy(update={"k_Nm_per_rad": row.k_Nm_per_rad * 1.1})
    walks.walk(changed, model)
    assert sorted(walked) == [(1.3, -6.0, "level"), (1.3, -6.0, "standing")]


def test_a_pool_walks_what_one_process_walks(model, envelope):
    pooled = NodeWalks(processes=2)
    try:
        assert pooled.walk(envelope, model) == NodeWalks().walk(envelope, model)     # the bench is deterministic
    finally:
        pooled.close()


def test_a_flag_names_its_node_and_start_and_a_preview_without_nodes_gates():
    clean = {"falls": 0, "toe_catches": 0, "strides": 5, "heel_strikes_without_stance": 0}
    fall = {"figure": "falls", "severity": "bad", "value": 1, "fsmic_value": None, "unit": "falls", "start": "level",
            "message": "reached from level walking: the leg gave way 1 time(s) on the simulated bench"}
    stored = {"controllers": {"envelope": clean, "fsmic": clean},
              "nodes": [{"speed_mps": 0.6, "incline_deg": -10.0, "walks": {}, "flags": [fall]}]}
    [flag] = envelope_flags(stored)
    assert flag["message"].startswith("at 0.6 m/s, −10°, reached from level walking: the leg gave way")
    assert (flag["node_speed_mps"], flag["node_incline_deg"], flag["start"]) == (0.6, -10.0, "level")
    assert [f["figure"] for f in envelope_flags({"controllers": stored["controllers"]})] == ["nodes_walked"]
