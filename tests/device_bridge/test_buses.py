"""python-can buses named INTERFACE:CHANNEL."""

from __future__ import annotations

import can
import pytest

from device_bridge.buses import open_bus, parse_bus_spec


def test_a_spec_names_an_interface_and_its_channel():
    assert parse_bus_spec(" socketcan:can0 ") == ("socketcan", "can0")
    assert parse_bus_spec("udp_multicast:239.74.163.2") == ("udp_multicast", "239.74.163.2")


@pytest.mark.parametrize("text", ["can0", "socketcan:", "nonsense:can0", ""])
def test_a_bad_spec_lists_the_valid_interfaces(text):
    with pytest.raises(ValueError, match=r"expected INTERFACE:CHANNEL.*virtual"):
        parse_bus_spec(text)


def test_an_opened_virtual_bus_carries_frames_to_another_on_its_channel():
    a, b = open_bus("virtual:test-buses"), open_bus("virtual:test-buses")
    try:
        a.send(can.Message(arbitration_id=0x123, data=b"\x01\x02", is_extended_id=False))
        got = b.recv(timeout=5.0)
        assert got is not None and got.arbitration_id == 0x123 and bytes(got.data) == b"\x01\x02"
    finally:
        a.shutdown()
        b.shutdown()
