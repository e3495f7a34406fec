"""What the device will run: the one check of a table or an envelope before it is stored, approved or pushed.

The firmware decodes every value from its wire field and checks it again (limits, stance support, passivity and, for
an envelope, the neighbour rule). The server checks exactly those decoded values, here, so that it never stores,
approves or sends what the device would refuse, and so that what a prosthetist sees is what runs. The wire CRC-32
is the one the device reads back after a push.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Generic, TypeVar

from controller_core.envelope import Envelope
from controller_core.table import LimitViolation, ParameterTable, SafetyLimits
from device_bridge.envelope_wire import WireEnvelope, check_envelope_as_run, envelope_as_run
from device_bridge.protocol import WireTable, check_as_run
from device_bridge.protocol import as_run as table_as_run

Item = TypeVar("Item", ParameterTable, Envelope)


@dataclass(frozen=True)
class AsRun(Generic[Item]):
    """A table or envelope as the device will run it.

    Attributes:
        item: the values rounded to the wire's quanta, bit for bit what the device decodes (unchanged when a value
            does not fit its field; the violations say which).
        violations: every limit (and neighbour-rule) violation of those values; empty when the device would accept
            them.
        wire_crc32: the CRC-32 the device reads back once it holds them; None when they cannot be sent.
    """

    item: Item
    violations: list[LimitViolation]
    wire_crc32: int | None

    @property
    def ok(self) -> bool:
        return not self.violations


def as_run(item: Item, limits: SafetyLimits | None = None) -> AsRun[Item]:
    """The device's view of a table or an envelope: its rounded values, their violations and the wire CRC, from one
    encoding and one decoding (an envelope's take milliseconds each, and every store, approval and push asks)."""
    envelope = isinstance(item, Envelope)
    wire: WireEnvelope | WireTable | None
    try:
        wire = WireEnvelope.from_envelope(item) if envelope else WireTable.from_table(item)
    except ValueError:   # a value no wire field carries: the check names it
        wire = None
    try:
        device = None if wire is None else wire.to_device() if envelope else wire.to_device_table()
    except ValueError:   # a non-physical threshold: the check names it
        device = None
    if envelope:
        rounded = item if device is None else envelope_as_run(item, device)
        violations = check_envelope_as_run(item, limits, device=device)
    else:
        rounded = item if device is None else table_as_run(item, device)
        violations = check_as_run(item, limits, device=device)
    return AsRun(item=rounded, violations=violations, wire_crc32=None if wire is None else wire.crc32())
