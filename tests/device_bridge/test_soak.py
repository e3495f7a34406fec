"""Pushes through a faulty bus never leave a mixed table."""

from __future__ import annotations

from device_bridge.soak import soak


def test_pushes_through_a_faulty_bus_never_leave_a_mixed_table(tables):
    out = soak(tables, 40, drop=0.1, corrupt=0.05, reorder=0.05, seed=7)
    assert out["mixed"] == 0 and out["crc_mismatch"] == 0
    assert out["committed"] + out["kept_old"] + out["committed_unconfirmed"] == 40
    assert out["committed"] >= 30   # retries get nearly all of them through
    assert out["frames"]["host"]["dropped"] > 0 and out["frames"]["host"]["corrupted"] > 0
