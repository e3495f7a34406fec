"""The wire: fixed-point tables, their CRC, frames of the wrong length."""

from __future__ import annotations

import dataclasses

import can
import pytest

from controller_core.table import check_table
from device_bridge.protocol import (
    AS_RUN,
    ProtocolError,
    WireTable,
    check_as_run,
    decode,
    encode,
    message,
    physical,
)


def test_a_real_table_survives_the_wire_within_half_a_quantum(tables):
    table = tables[0]
    device = WireTable.from_table(table).to_device_table()
    q = {"k_Nm_per_rad": 0.001, "theta_e_deg": 0.001, "b_Nm_s_per_rad": 0.001}
    for r in table.rows:
        d = device.row(r.joint, r.subphase)
        for name, quantum in q.items():
            assert abs(getattr(d, name) - getattr(r, name)) <= quantum / 2 + 1e-9, (r.joint, r.subphase, name)
    th, dth = table.thresholds, device.thresholds
    assert abs(dth.sf_to_se_ankle_moment_Nm - th.sf_to_se_ankle_moment_Nm) <= 0.005 + 1e-9
    assert abs(dth.we_to_sf_load_N - th.we_to_sf_load_N) <= 0.05 + 1e-9
    assert abs(dth.max_state_time_s - th.max_state_time_s) <= 0.0005 + 1e-9
    assert dth.sf_to_se_knee_extension_deg_per_s == th.sf_to_se_knee_extension_deg_per_s > 0   # whole deg/s


def test_the_crc_covers_every_value(tables):
    wire = WireTable.from_table(tables[0])
    base = wire.crc32()
    for i in range(8):
        for j in range(3):
            rows = [list(r) for r in wire.rows]
            rows[i][j] += 1
            assert dataclasses.replace(wire, rows=tuple(tuple(r) for r in rows)).crc32() != base
    assert dataclasses.replace(wire, body_mass=wire.body_mass + 1).crc32() != base
    for name in ("thresholds", "stumble", "landing"):
        values = getattr(wire, name)
        for j in range(len(values)):
            changed = list(values)
            changed[j] += 1
            assert dataclasses.replace(wire, **{name: tuple(changed)}).crc32() != base, (name, j)


def test_a_value_that_does_not_fit_its_field_is_refused_before_sending(tables):
    row = tables[0].rows[0]
    big = tables[0].model_copy(update={"rows": [row.model_copy(update={"k_Nm_per_rad": -2500.0}), *tables[0].rows[1:]]})
    with pytest.raises(ProtocolError, match=r"knee\.stance_flexion\.k_Nm_per_rad = -2500 does not fit"):
        WireTable.from_table(big)
    fast = tables[0].thresholds.model_copy(update={"sf_to_se_knee_extension_deg_per_s": 300.0})
    with pytest.raises(ProtocolError, match=r"sf_to_se_knee_extension_deg_per_s = 300 does not fit.*\[0, 255\] deg/s"):
        WireTable.from_table(tables[0].model_copy(update={"thresholds": fast}))


def test_a_truncated_frame_is_refused_and_unknown_ids_are_ignored():
    good = encode("TABLE_ROW", {"transfer_id": 1, "row_index": 2, "k": -5000, "theta_e": 1000, "b": 500})
    short = can.Message(arbitration_id=good.arbitration_id, data=good.data[:5], is_extended_id=False)
    with pytest.raises(ProtocolError, match=r"TABLE_ROW \(id 0x201\) must be 8 bytes, got 5"):
        decode(short)
    assert decode(can.Message(arbitration_id=0x7FF, data=bytes(8), is_extended_id=False)) is None
    name, raw = decode(good)
    assert name == "TABLE_ROW" and physical(name, raw)["k"] == pytest.approx(-5.0)
    assert message("TABLE_ROW").get_signal_by_name("k").unit == "N.m/rad"


def test_the_servers_check_is_of_the_values_the_device_will_run(tables):
    table = tables[0]
    th = table.thresholds
    near = table.model_copy(update={"thresholds": th.model_copy(update={"min_state_time_s": 1.49951,
                                                                         "max_state_time_s": 1.5})})
    assert check_table(near) == []                          # fine as typed …
    [v] = check_as_run(near)                                # … but the device runs 1.500 s ≥ 1.500 s
    assert v.field == "thresholds.min_state_time_s" and v.message.startswith(AS_RUN)
    assert check_as_run(table) == []
    row = table.rows[0]
    huge = table.model_copy(update={"rows": [row.model_copy(update={"k_Nm_per_rad": -5000.0}), *table.rows[1:]]})
    [v] = check_as_run(huge)                                # beyond the wire too: the limit says it in its own words
    assert "is outside [-1200, 0]" in v.message
