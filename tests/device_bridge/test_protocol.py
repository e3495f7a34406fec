"""The wire: a table in fixed point (the envelope of its one node), its CRC, frames of the wrong length."""

from __future__ import annotations

import dataclasses

import can
import pytest

from device_bridge.envelope_wire import FRAMES_PER_NODE, table_wire
from device_bridge.protocol import (
    ProtocolError,
    decode,
    encode,
    message,
    physical,
)


def test_a_real_table_survives_the_wire_within_half_a_quantum(tables):
    table = tables[0]
    [device] = table_wire(table).to_device().tables
    q = {"k_Nm_per_rad": 0.001, "theta_e_deg": 0.01, "b_Nm_s_per_rad": 0.01}
    for r in table.rows:
        d = device.row(r.joint, r.subphase)
        for name, quantum in q.items():
            assert abs(getattr(d, name) - getattr(r, name)) <= quantum / 2 + 1e-9, (r.joint, r.subphase, name)
    th, dth = table.thresholds, device.thresholds
    assert abs(dth.sf_to_se_ankle_moment_Nm - th.sf_to_se_ankle_moment_Nm) <= 0.005 + 1e-9
    assert abs(dth.we_to_sf_load_N - th.we_to_sf_load_N) <= 0.05 + 1e-9
    assert abs(dth.max_state_time_s - th.max_state_time_s) <= 0.0005 + 1e-9
    assert dth.sf_to_se_knee_extension_deg_per_s == th.sf_to_se_knee_extension_deg_per_s > 0   # whole deg/s
    assert abs(device.body_mass_kg - table.body_mass_kg) <= 0.0005 + 1e-9


def test_the_crc_covers_every_value(tables):
    """A table's transfer is the envelope of its one node: its task, nominal task and body mass, and each of the
    node's values (8 rows × 3, thresholds, the stumble and landing triggers) are under the CRC."""
    wire = table_wire(tables[0])
    base = wire.crc32()
    [node] = wire.nodes
    assert len(node) == FRAMES_PER_NODE
    for i, part in enumerate(node):
        for j in range(len(part)):
            changed = [list(p) for p in node]
            changed[i][j] += 1
            assert dataclasses.replace(wire, nodes=(tuple(tuple(p) for p in changed),)).crc32() != base, (i, j)
    for name in ("speeds", "inclines", "nominal"):
        values = getattr(wire, name)
        for j in range(len(values)):
            changed = list(values)
            changed[j] += 1
            assert dataclasses.replace(wire, **{name: tuple(changed)}).crc32() != base, (name, j)
    assert dataclasses.replace(wire, body_mass=wire.body_mass + 1).crc32() != base


def test_a_value_that_does_not_fit_its_field_is_refused_before_sending(tables):
    row = tables[0].rows[0]
    big = tables[0].model_copy(update={"rows": [row.model_copy(update={"k_Nm_per_rad": -2500.0}), *tables[0].rows[1:]]})
    with pytest.raises(ProtocolError, match=r"^knee\.stance_flexion\.k_Nm_per_rad = -2500 does not fit"):
        table_wire(big)     # named as in the table, not as a node of an envelope
    fast = tables[0].thresholds.model_copy(update={"sf_to_se_knee_extension_deg_per_s": 300.0})
    with pytest.raises(ProtocolError, match=r"sf_to_se_knee_extension_deg_per_s = 300 does not fit.*\[0, 255\] deg/s"):
        table_wire(tables[0].model_copy(update={"thresholds": fast}))


def test_a_truncated_frame_is_refused_and_unknown_ids_are_ignored():
    good = encode("ENVELOPE_ROW", {"transfer_id": 1, "node": 0, "row_index": 2, "k": -5000, "theta_e": 100, "b": 50})
    short = can.Message(arbitration_id=good.arbitration_id, data=good.data[:5], is_extended_id=False)
    with pytest.raises(ProtocolError, match=r"ENVELOPE_ROW \(id 0x207\) must be 8 bytes, got 5"):
        decode(short)
    assert decode(can.Message(arbitration_id=0x7FF, data=bytes(8), is_extended_id=False)) is None
    assert decode(can.Message(arbitration_id=0x201, data=bytes(8), is_extended_id=False)) is None   # link 5's tables
    name, raw = decode(good)
    assert name == "ENVELOPE_ROW" and physical(name, raw)["k"] == pytest.approx(-5.0)
    assert message("ENVELOPE_ROW").get_signal_by_name("k").unit == "N.m/rad"
