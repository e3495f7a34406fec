"""The bridge process's gateway between the leg's bus and the server's."""

from __future__ import annotations

import can

from device_bridge.device_node import DeviceNode
from device_bridge.gateway import Gateway
from device_bridge.host import DeviceLink
from device_bridge.protocol import WireTable


def test_a_push_and_telemetry_cross_the_bridge(model):
    leg_side, server_side = "test-gw-leg", "test-gw-server"
    node = DeviceNode(can.Bus(interface="virtual", channel=leg_side)).start()
    gateway = Gateway(can.Bus(interface="virtual", channel=leg_side),
                      can.Bus(interface="virtual", channel=server_side)).start()
    link = DeviceLink(can.Bus(interface="virtual", channel=server_side)).start()
    try:
        table = model.propose(1.3, 0.0, 70.0).table
        result = link.push(table, version=12)
        assert result.crc32 == WireTable.from_table(table).crc32() == node.snapshot().staged_or_active_crc32()
        assert gateway.forwarded["a_to_b"] > 0 and gateway.forwarded["b_to_a"] >= 12
    finally:
        link.close()
        gateway.close()
        node.close()
