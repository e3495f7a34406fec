"""python-can buses named ``INTERFACE:CHANNEL`` (``socketcan:can0``, ``virtual:leg``, ``udp_multicast:239.74.163.2``)."""

from __future__ import annotations

import can


def parse_bus_spec(text: str) -> tuple[str, str]:
    """(interface, channel) of ``INTERFACE:CHANNEL``; ValueError naming the valid python-can interfaces."""
    interface, sep, channel = text.strip().partition(":")
    if not sep or not channel or interface not in can.VALID_INTERFACES:
        raise ValueError(f"expected INTERFACE:CHANNEL with a python-can interface "
                         f"({', '.join(sorted(can.VALID_INTERFACES))}); got {text!r}")
    return interface, channel


def open_bus(text: str) -> can.BusABC:
    """Open the bus ``INTERFACE:CHANNEL``."""
    interface, channel = parse_bus_spec(text)
    return can.Bus(interface=interface, channel=channel)
