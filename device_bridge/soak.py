"""Soak and drill the device link: many pushes through a faulty bus, and a heartbeat-loss drill.

:func:`soak` pushes the tables or envelopes it is given, in turn (``quasitune device soak``: the model's proposals over
a range of speeds; ``--envelopes``: envelopes for patients of different masses), to a
:class:`~device_bridge.device_node.DeviceNode` through :class:`~device_bridge.faults.FaultInjectingBus` in both
directions, and after every push inspects the device's buffers (an oracle the host never has) to classify it:

* ``committed``: the host was told the exact CRC, and the device runs that table, intact;
* ``kept_old``: the host gave up, and the device still runs the previous table, intact;
* ``committed_unconfirmed``: the host gave up, but the device did take the new table intact (its status will say so);
* ``mixed``: the device holds a table (or envelope) that is neither the old nor the new one — must be 0;
* ``crc_mismatch``: the host was told a CRC the device does not hold, or a held table's values do not give
  its CRC — must be 0.

:func:`heartbeat_drill` stops the host heartbeat and measures how long after the device's timeout the safe mode
is reported back on the bus.
"""

from __future__ import annotations

import itertools
import statistics
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import can

from controller_core.envelope import Envelope
from controller_core.fsmic import fsmic_table
from controller_core.table import ParameterTable
from device_bridge.device_node import DeviceNode
from device_bridge.envelope_wire import DeviceEnvelope, WireEnvelope, table_wire
from device_bridge.faults import FaultInjectingBus
from device_bridge.firmware import FirmwareConfig, HeldTable
from device_bridge.host import DeviceLink, PushError, PushResult
from device_bridge.protocol import Mode

_channel_counter = itertools.count()


def _channel(prefix: str) -> str:
    return f"quasitune-{prefix}-{time.monotonic_ns()}-{next(_channel_counter)}"


@dataclass(frozen=True)
class _Known:
    """A table or envelope the soak pushes, with the values and CRC-32 the device holds when it arrives intact (a
    table: the envelope of its one node)."""

    item: ParameterTable | Envelope
    values: DeviceEnvelope
    crc32: int

    @classmethod
    def of(cls, item: ParameterTable | Envelope) -> _Known:
        wire = WireEnvelope.from_envelope(item) if isinstance(item, Envelope) else table_wire(item)
        return cls(item, wire.to_device(), wire.crc32())

    def held_as(self, held: HeldTable) -> bool:
        return held.envelope == self.values

    def push(self, link: DeviceLink, version: int, timeout_s: float) -> PushResult:
        return link.push(self.item, version, timeout_s=timeout_s)


def soak(items: Sequence[ParameterTable | Envelope], trials: int, drop: float, corrupt: float, reorder: float,
         seed: int = 0, push_timeout_s: float = 2.0) -> dict:
    """Push ``trials`` of ``items`` (two at least, in turn: tables, envelopes or both) through a fault-injecting
    virtual bus and classify each outcome (module docstring)."""
    if not 1 <= trials <= 100_000:
        raise ValueError(f"trials must be in [1, 100000], got {trials!r}")
    if len(items) < 2:
        raise ValueError("the soak needs at least two different tables or envelopes to tell the old from the new")
    channel = _channel("soak")
    node = DeviceNode(FaultInjectingBus(can.Bus(interface="virtual", channel=channel), drop, corrupt, reorder,
                                        seed=seed)).start()
    host_bus = FaultInjectingBus(can.Bus(interface="virtual", channel=channel), drop, corrupt, reorder, seed=seed + 1)
    link = DeviceLink(host_bus).start()
    try:
        counts = soak_link(link, node, items, trials, push_timeout_s)
    finally:
        link.close()
        node.close()
    return {**counts, "faults": {"drop": drop, "corrupt": corrupt, "reorder": reorder, "seed": seed},
            "frames": {"host": host_bus.counts}}


def soak_link(link: DeviceLink, node: DeviceNode, items: Sequence[ParameterTable | Envelope], trials: int,
              push_timeout_s: float = 2.0, between: Callable[[int], None] | None = None) -> dict:
    """The soak's trials over a link and device node set up by the caller (a faulty bus, a broker between them …):
    ``between(i)`` runs before trial ``i`` (a broker restart, say). Outcomes as in the module docstring, with the
    push times (ms) of every trial, given up or not."""
    known = [_Known.of(t) for t in items]
    counts = {"committed": 0, "kept_old": 0, "committed_unconfirmed": 0, "mixed": 0, "crc_mismatch": 0}
    push_ms: list[float] = []
    old: _Known | None = None
    for i in range(trials):
        if between is not None:
            between(i)
        new = known[i % len(known)]
        if new is old:
            new = known[(i + 1) % len(known)]
        version = i % 0xFFFF + 1
        t0 = time.monotonic()
        try:
            result = new.push(link, version, push_timeout_s)
            ok_crc: int | None = result.crc32
            push_ms.append(result.elapsed_ms)
        except PushError:
            ok_crc = None
            push_ms.append((time.monotonic() - t0) * 1e3)
        snap = _settled(node)
        counts[_classify(snap.active, snap.staged, old, new, ok_crc)] += 1
        if snap.active is not None and new.held_as(snap.active):
            old = new
    ordered = sorted(push_ms)
    return {"trials": trials, **counts,
            "median_push_ms": round(statistics.median(ordered), 3),
            "p99_push_ms": round(ordered[min(len(ordered) - 1, int(0.99 * len(ordered)))], 3)}


def _settled(node: DeviceNode, wait_s: float = 0.05):
    """The device's buffers once a staged table (if any) has been switched in (it is not walking: at once)."""
    deadline = time.monotonic() + wait_s
    snap = node.snapshot()
    while snap.staged is not None and time.monotonic() < deadline:
        time.sleep(0.0005)
        snap = node.snapshot()
    return snap


def _classify(active: HeldTable | None, staged: HeldTable | None, old: _Known | None, new: _Known,
              ok_crc: int | None) -> str:
    for held in (active, staged):
        if held is None:
            continue
        match = next((k for k in (old, new) if k is not None and k.held_as(held)), None)
        if match is None:
            return "mixed"
        if match.crc32 != held.crc32:
            return "crc_mismatch"
    if ok_crc is not None:
        if active is None or active.crc32 != ok_crc or not new.held_as(active) or ok_crc != new.crc32:
            return "crc_mismatch"
        return "committed"
    if active is not None and new.held_as(active):
        return "committed_unconfirmed"
    return "kept_old"


def heartbeat_drill(repeats: int = 5, timeout_s: float = 0.2) -> dict:
    """Stop the host heartbeat ``repeats`` times; report how long after the device's timeout the host hears of
    safe mode (ms), from the last heartbeat the host sent."""
    channel = _channel("drill")
    table = fsmic_table(75.0)
    node = DeviceNode(can.Bus(interface="virtual", channel=channel),
                      config=FirmwareConfig(heartbeat_timeout_s=timeout_s)).start()
    link = DeviceLink(can.Bus(interface="virtual", channel=channel)).start()
    late_ms: list[float] = []
    try:
        for r in range(repeats):
            link.pause_heartbeat(False)
            link.push(table, version=r + 1)
            _wait(lambda: link.status is not None and link.status.mode == Mode.ACTIVE, 2.0)
            link.pause_heartbeat(True)
            _wait(lambda: link.status is not None and link.status.mode == Mode.SAFE, 2.0)
            assert link.status is not None and link.last_heartbeat_sent_s is not None
            last_beat = link.last_heartbeat_sent_s
            late_ms.append((link.status.received_monotonic_s - last_beat - timeout_s) * 1e3)
    finally:
        link.close()
        node.close()
    return {"repeats": repeats, "heartbeat_timeout_ms": timeout_s * 1e3,
            "safe_mode_after_timeout_ms_max": round(max(late_ms), 2),
            "safe_mode_after_timeout_ms_median": round(statistics.median(late_ms), 2)}


def _wait(predicate, timeout_s: float) -> None:
    deadline = time.monotonic() + timeout_s
    while not predicate():
        if time.monotonic() > deadline:
            raise TimeoutError("the device did not reach the expected state in time")
        time.sleep(0.001)
