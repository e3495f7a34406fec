"""The bridge process's gateway between the leg's bus and the server's."""

from __future__ import annotations

import time

import can
import pytest

from device_bridge.device_node import DeviceNode
from device_bridge.envelope_wire import table_wire
from device_bridge.gateway import Gateway
from device_bridge.host import DeviceLink
from device_bridge.protocol import frame_id, is_telemetry
from tests.helpers.device import until

pytestmark = [pytest.mark.wallclock, pytest.mark.live]   # the batching window against the leg's sample period


def test_a_push_and_telemetry_cross_the_bridge(model):
    leg_side, server_side = "test-gw-leg", "test-gw-server"
    node = DeviceNode(can.Bus(interface="virtual", channel=leg_side)).start()
    gateway = Gateway(can.Bus(interface="virtual", channel=leg_side),
                      can.Bus(interface="virtual", channel=server_side)).start()
    link = DeviceLink(can.Bus(interface="virtual", channel=server_side)).start()
    try:
        table = model.propose(1.3, 0.0, 70.0).table
        result = link.push(table, version=12)
        assert result.crc32 == table_wire(table).crc32() == node.snapshot().staged_or_active_crc32()
        # the bridge counts a frame once sent; the host may read the acknowledgement before that count is made
        until(lambda: gateway.forwarded["a_to_b"] > 0 and gateway.forwarded["b_to_a"] >= 12, 5.0, poll_s=0.05)
    finally:
        link.close()
        gateway.close()
        node.close()


class _Batches(can.BusABC):
    """The broker link's side of a gateway, keeping each message's frames."""

    def __init__(self) -> None:
        super().__init__(channel="batches")
        self.messages: list[list[int]] = []

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        self.send_batch([msg])

    def send_batch(self, frames: list[can.Message]) -> None:
        self.messages.append([f.arbitration_id for f in frames])

    def _recv_internal(self, timeout: float | None):
        time.sleep(min(timeout or 0.01, 0.01))
        return None, False


def test_telemetry_waits_for_the_window_and_anything_else_leaves_at_once():
    """Samples 10 ms apart share a message (never split); a status closes the message it joins, and telemetry after
    it starts a new one however long the window."""
    channel = "test-gw-batching"
    leg = can.Bus(interface="virtual", channel=channel)
    far = _Batches()
    gateway = Gateway(can.Bus(interface="virtual", channel=channel), far, window_s=0.5, may_wait=is_telemetry).start()
    sample = [frame_id(n) for n in ("TELEMETRY_GAIT", "TELEMETRY_KNEE", "TELEMETRY_ANKLE")]
    status = frame_id("DEVICE_STATUS")
    try:
        for _ in range(6):
            for i in sample:
                leg.send(can.Message(arbitration_id=i, data=bytes(8), is_extended_id=False))
            time.sleep(0.01)
        leg.send(can.Message(arbitration_id=status, data=bytes(8), is_extended_id=False))
        until(lambda: any(status in m for m in far.messages))        # forwarded at once, with what it joined
        for i in sample:
            leg.send(can.Message(arbitration_id=i, data=bytes(8), is_extended_id=False))
        until(lambda: sum(map(len, far.messages)) == 7 * 3 + 1)
        with_status = next(m for m in far.messages if status in m)
        assert with_status[-1] == status                      # nothing waited behind it
        assert all(len([i for i in m if i != status]) % 3 == 0 for m in far.messages)   # no sample split
        assert len(far.messages) <= 3 and far.messages[-1] == sample
    finally:
        gateway.close()
        leg.shutdown()
