"""The faulty bus: drops, flips a bit, or holds a frame back for one."""

from __future__ import annotations

import can
import pytest

from device_bridge.faults import FaultInjectingBus


def _pair(channel: str, **faults):
    sender = FaultInjectingBus(can.Bus(interface="virtual", channel=channel), **faults)
    return sender, can.Bus(interface="virtual", channel=channel)


def _frames(n: int) -> list[can.Message]:
    return [can.Message(arbitration_id=0x200 + i, data=bytes([i] * 8), is_extended_id=False) for i in range(n)]


def _received(bus: can.BusABC) -> list[can.Message]:
    out = []
    while (msg := bus.recv(timeout=0.2)) is not None:
        out.append(msg)
    return out


def test_a_clean_setting_passes_every_frame_in_order():
    sender, receiver = _pair("faults-clean")
    try:
        for m in _frames(20):
            sender.send(m)
        assert [m.arbitration_id for m in _received(receiver)] == [0x200 + i for i in range(20)]
        assert sender.counts == {"sent": 20, "dropped": 0, "corrupted": 0, "reordered": 0}
    finally:
        sender.shutdown()
        receiver.shutdown()


def test_faults_are_counted_and_seeded():
    sender, receiver = _pair("faults-some", drop=0.2, corrupt=0.2, reorder=0.2, seed=3)
    try:
        for m in _frames(200):
            sender.send(m)
        got = _received(receiver)
        c = sender.counts
        assert c["sent"] == 200 and c["dropped"] > 0 and c["corrupted"] > 0 and c["reordered"] > 0
        ids = [m.arbitration_id for m in got]
        assert len(got) <= 200 - c["dropped"] and ids != sorted(ids)          # some came out of order
        flipped = [m for m in got if bytes(m.data) != bytes([m.arbitration_id - 0x200] * 8)]
        assert len(flipped) == c["corrupted"] and all(
            bin(int.from_bytes(bytes(m.data), "big") ^ int.from_bytes(bytes([m.arbitration_id - 0x200] * 8), "big"))
            .count("1") == 1 for m in flipped)                                # exactly one bit each
    finally:
        sender.shutdown()
        receiver.shutdown()


@pytest.mark.parametrize("bad", [{"drop": 1.0}, {"corrupt": -0.1}, {"reorder": float("nan")}])
def test_a_probability_outside_zero_to_one_is_refused(bad):
    with pytest.raises(ValueError, match="must be a probability in"):
        FaultInjectingBus(can.Bus(interface="virtual", channel="faults-bad"), **bad)
