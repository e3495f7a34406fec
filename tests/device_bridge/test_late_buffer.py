"""The bridge's store-and-forward buffer: in order, bounded (oldest dropped first, counted), kept across a restart,
forgotten only when delivered; and the late payload that carries it."""

from __future__ import annotations

import can
import pytest

from device_bridge.late_buffer import LateBuffer
from device_bridge.mqtt_bus import pack_frames, pack_late, unpack_late


def _payload(i: int) -> bytes:
    return pack_frames([can.Message(arbitration_id=0x300, data=i.to_bytes(2, "little") + bytes(6),
                                    is_extended_id=False)])


def test_messages_come_back_oldest_first_and_survive_a_restart(tmp_path):
    path = tmp_path / "late.sqlite"
    buffer = LateBuffer(path)
    for i in range(10):
        buffer.append(100.0 + i / 100, _payload(i))
    assert len(buffer) == 10 and buffer.held_bytes == 10 * 11
    buffer.close()                                   # the bridge restarts mid-outage
    again = LateBuffer(path)
    chunk = again.oldest(max_payload_bytes=4 * 11)
    assert [at for _, at, _ in chunk] == [100.0, 100.01, 100.02, 100.03]
    again.forget_through(chunk[-1][0])               # delivered: forgotten
    assert [p for _, _, p in again.oldest(10_000)] == [_payload(i) for i in range(4, 10)]
    again.close()


def test_the_bound_drops_the_oldest_and_counts_them(tmp_path):
    buffer = LateBuffer(tmp_path / "late.sqlite", max_bytes=1024)
    for i in range(200):                             # 2200 bytes into 1024
        buffer.append(float(i), _payload(i))
    buffer.write_pending()
    kept = buffer.oldest(10_000)
    assert buffer.held_bytes <= 1024 and buffer.dropped == 200 - len(kept)
    assert [at for _, at, _ in kept] == [float(i) for i in range(200 - len(kept), 200)]   # the newest kept
    buffer.close()


def test_a_bound_that_is_not_a_size_is_refused(tmp_path):
    for bad in (0, 1023, 1.5e6, -1):
        with pytest.raises(ValueError, match="max_bytes"):
            LateBuffer(tmp_path / "late.sqlite", max_bytes=bad)


def test_a_late_payload_carries_each_records_time_and_frames_and_refuses_a_torn_one():
    records = [(1.25, _payload(1) + _payload(2)), (1.26, _payload(3))]
    back = unpack_late(pack_late(records))
    assert [(at, [bytes(f.data[:2]) for f in frames]) for at, frames in back] == \
        [(1.25, [b"\x01\x00", b"\x02\x00"]), (1.26, [b"\x03\x00"])]
    assert all(f.timestamp == at for at, frames in back for f in frames)
    whole = pack_late(records)
    for torn in (whole[:5], whole[:-3], whole + b"\x00"):
        with pytest.raises(ValueError):
            unpack_late(torn)
