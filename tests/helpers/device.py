"""Helpers for the device-link tests: a device node and host link on a virtual bus of their own, and waiting."""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable

import can

from device_bridge.device_node import DeviceNode
from device_bridge.firmware import FirmwareConfig
from device_bridge.host import DeviceLink

_channels = itertools.count()


def pair(config: FirmwareConfig | None = None, leg=None, **link_kwargs) -> tuple[DeviceNode, DeviceLink]:
    """A started device node (with ``leg``, if any) and host link sharing a virtual bus of their own."""
    channel = f"test-link-{next(_channels)}"
    node = DeviceNode(can.Bus(interface="virtual", channel=channel), leg=leg, config=config).start()
    link = DeviceLink(can.Bus(interface="virtual", channel=channel), **link_kwargs).start()
    return node, link


def until(predicate: Callable[[], bool], timeout_s: float = 5.0) -> None:
    """Wait for ``predicate`` to hold; fail after ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while not predicate():
        assert time.monotonic() < deadline, "condition not reached in time"
        time.sleep(0.002)


def assert_same_as_device(table, device) -> None:
    """Every row and threshold value of a stored ``table`` is bit for bit what the device decodes (``device``)."""
    for r in table.rows:
        d = device.row(r.joint, r.subphase)
        assert (r.k_Nm_per_rad, r.theta_e_deg, r.b_Nm_s_per_rad) == (d.k_Nm_per_rad, d.theta_e_deg, d.b_Nm_s_per_rad)
    assert table.thresholds == device.thresholds
