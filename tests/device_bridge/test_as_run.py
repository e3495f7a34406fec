"""The one check of what the device will run, for a table and an envelope alike."""

from __future__ import annotations

from controller_core.envelope import Envelope
from controller_core.table import check_table
from device_bridge.as_run import AS_RUN, as_run
from device_bridge.envelope_wire import WireEnvelope, check_envelope_as_run, envelope_as_run, table_wire


def test_a_table_is_checked_as_rounded_and_carries_the_crc_the_device_reads_back(tables):
    table = tables[0]
    checked = as_run(table)
    assert checked.ok and checked.violations == []
    assert checked.wire_crc32 == table_wire(table).crc32()
    assert as_run(checked.item).item == checked.item                     # rounding twice changes nothing
    assert as_run(checked.item).wire_crc32 == checked.wire_crc32          # the device sees the same raw values
    th = table.thresholds
    near = table.model_copy(update={"thresholds": th.model_copy(update={"min_state_time_s": 1.49951,
                                                                         "max_state_time_s": 1.5})})
    assert check_table(near) == []                                       # fine as typed …
    [v] = as_run(near).violations                                        # … but the device runs 1.500 s ≥ 1.500 s
    assert v.field == "thresholds.min_state_time_s" and v.message.startswith(AS_RUN)


def test_a_value_beyond_the_limits_and_the_wire_is_refused_in_the_limits_words(tables):
    table = tables[0]
    row = table.rows[0]
    huge = table.model_copy(update={"rows": [row.model_copy(update={"k_Nm_per_rad": -5000.0}), *table.rows[1:]]})
    [v] = as_run(huge).violations
    assert v.field == "knee.stance_flexion.k_Nm_per_rad" and "is outside [-1200, 0]" in v.message


def test_a_value_the_link_cannot_carry_is_a_violation_and_has_no_crc(tables):
    table = tables[0]
    row = table.rows[0]
    huge = table.model_copy(update={"rows": [row.model_copy(update={"k_Nm_per_rad": -1e9}), *table.rows[1:]]})
    checked = as_run(huge)
    assert not checked.ok and checked.wire_crc32 is None and checked.item == huge


def test_an_envelope_is_checked_node_by_node_and_by_the_neighbour_rule(model):
    env: Envelope = model.propose_envelope([0.8, 1.2], [-5.0, 5.0], 75.0)
    checked = as_run(env)
    assert checked.ok and checked.item == envelope_as_run(env)
    assert checked.wire_crc32 == WireEnvelope.from_envelope(env).crc32()
    node = env.nodes[0]
    row = node.table.rows[0]
    jumped = node.table.model_copy(update={"rows": [row.model_copy(update={"k_Nm_per_rad": row.k_Nm_per_rad - 400.0}),
                                                    *node.table.rows[1:]]})
    broken = env.model_copy(update={"nodes": [node.model_copy(update={"table": jumped}), *env.nodes[1:]]})
    assert as_run(broken).violations == check_envelope_as_run(broken) != []
