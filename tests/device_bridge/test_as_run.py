"""The one check of what the device will run, for a table and an envelope alike."""

from __future__ import annotations

from controller_core.envelope import Envelope
from device_bridge.as_run import as_run
from device_bridge.envelope_wire import WireEnvelope, check_envelope_as_run, envelope_as_run
from device_bridge.protocol import AS_RUN, WireTable


def test_a_table_is_checked_as_rounded_and_carries_the_crc_the_device_reads_back(tables):
    table = tables[0]
    checked = as_run(table)
    assert checked.ok and checked.violations == []
    assert checked.wire_crc32 == WireTable.from_table(table).crc32()
    assert as_run(checked.item).item == checked.item                     # rounding twice changes nothing
    assert as_run(checked.item).wire_crc32 == checked.wire_crc32          # the device sees the same raw values
    th = table.thresholds
    near = table.model_copy(update={"thresholds": th.model_copy(update={"min_state_time_s": 1.49951,
                                                                         "max_state_time_s": 1.5})})
    bad = as_run(near)
    assert not bad.ok and bad.violations[0].message.startswith(AS_RUN)   # only the rounding breaks it


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
