"""Helpers for the device-link tests: a device node and host link stepped together in simulated time (a rig), or on a
virtual bus of their own in real time where real time is the subject; and waiting on either."""

from __future__ import annotations

import itertools
from collections.abc import Callable

import can

from controller_core.envelope import Envelope
from device_bridge.clock import WALL_CLOCK, SteppedClock
from device_bridge.device_node import DeviceNode
from device_bridge.envelope_wire import WireEnvelope, envelope_begin_frame, envelope_commit_frame
from device_bridge.firmware import FirmwareConfig
from device_bridge.host import DeviceLink
from device_bridge.rig import Rig

_channels = itertools.count()


def pair(config: FirmwareConfig | None = None, leg=None, **link_kwargs) -> tuple[DeviceNode, DeviceLink]:
    """A device node (with ``leg``, if any) and host link on a stepped rig (:class:`device_bridge.rig.Rig`): they run
    only while something waits on ``link.clock`` (a push, :func:`until` with ``clock=link.clock``)."""
    rig = Rig(leg=leg, config=config, **link_kwargs)
    return rig.node, rig.link


def wall_pair(config: FirmwareConfig | None = None, leg=None, **link_kwargs) -> tuple[DeviceNode, DeviceLink]:
    """A started device node and host link on a virtual bus of their own, each with its threads on the wall clock: for
    the tests whose subject is the threads themselves (a node running behind, frames from two threads in order)."""
    channel = f"test-link-{next(_channels)}"
    node = DeviceNode(can.Bus(interface="virtual", channel=channel), leg=leg, config=config).start()
    link = DeviceLink(can.Bus(interface="virtual", channel=channel), **link_kwargs).start()
    return node, link


def until(predicate: Callable[[], bool], timeout_s: float = 5.0, poll_s: float = 0.002,
          clock: SteppedClock | None = None) -> None:
    """Wait for ``predicate`` to hold; fail after ``timeout_s``. On a rig's ``clock`` the wait steps the rig (simulated
    seconds); without one it asks every ``poll_s`` of real time (poll slowly where a simulated leg shares the
    interpreter with the test: it would otherwise be starved)."""
    where = "s" if clock is None else "s of simulated time"
    assert (clock or WALL_CLOCK).until(predicate, timeout_s, poll_s), f"condition not reached within {timeout_s:g} {where}"


def assert_same_as_device(table, device) -> None:
    """Every row and threshold value of a stored ``table`` is bit for bit what the device decodes (``device``)."""
    for r in table.rows:
        d = device.row(r.joint, r.subphase)
        assert (r.k_Nm_per_rad, r.theta_e_deg, r.b_Nm_s_per_rad) == (d.k_Nm_per_rad, d.theta_e_deg, d.b_Nm_s_per_rad)
    assert table.thresholds == device.thresholds


def frames_of(env: Envelope, tid: int, version: int):
    """(begin, data frames, commit, CRC) of an envelope transfer, as the host sends them."""
    wire = WireEnvelope.from_envelope(env)
    crc = wire.crc32()
    return (envelope_begin_frame(tid, version, crc, wire.shape), wire.frames(tid),
            envelope_commit_frame(tid, version, crc, wire.shape), crc)
