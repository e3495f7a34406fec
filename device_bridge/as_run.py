"""What the device will run: the one check of a table or an envelope before it is stored, approved or pushed.

The firmware decodes every value from its wire field and checks it again (limits, stance support, passivity and, for
an envelope, the neighbour rule). The server checks exactly those decoded values, here, so that it never stores,
approves or sends what the device would refuse, and so that what a prosthetist sees is what runs. The wire CRC-32
is the one the device reads back after a push. A table goes to the leg as the envelope of its one node
(:func:`device_bridge.envelope_wire.table_wire`), so both are rounded and checked by one encoding.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Generic, TypeVar

from controller_core.envelope import Envelope
from controller_core.table import LimitViolation, ParameterTable, SafetyLimits, check_table
from device_bridge.envelope_wire import WireEnvelope, check_envelope_as_run, envelope_as_run, table_wire
from device_bridge.protocol import DeviceTable, ValueDoesNotFitError, with_device_values

AS_RUN = "as the device will run it (rounded to the wire's precision): "

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
    wire: WireEnvelope | None = None
    problem: ValueDoesNotFitError | None = None
    try:
        wire = WireEnvelope.from_envelope(item) if isinstance(item, Envelope) else table_wire(item)
    except ValueDoesNotFitError as exc:   # a value no wire field carries: the check names it
        problem = exc
    except ValueError:                    # more nodes than the link carries: the envelope's check names it
        pass
    try:
        device = None if wire is None else wire.to_device()
    except ValueError:   # a non-physical threshold: the check names it
        device = None
    if isinstance(item, Envelope):
        rounded = item if device is None else envelope_as_run(item, device)
        violations = check_envelope_as_run(item, limits, device=device)
    else:
        table = None if device is None else device.tables[0]
        rounded = item if table is None else with_device_values(item, table)
        violations = _check_table_as_run(item, limits, table, problem)
    return AsRun(item=rounded, violations=violations, wire_crc32=None if wire is None else wire.crc32())


def _check_table_as_run(table: ParameterTable, limits: SafetyLimits | None, device: DeviceTable | None,
                        problem: ValueDoesNotFitError | None) -> list[LimitViolation]:
    """Every safety violation of the values the device will run (``device``: the table decoded from its wire). A
    violation that only the rounding creates says so; a value no wire field carries (``problem``) is one too, unless
    the limits, which lie inside the wire's range, already say it in their own words."""
    as_typed = check_table(table, limits)
    if device is None:
        return as_typed or ([] if problem is None else [LimitViolation(
            field=problem.field, value=problem.value, low=problem.low, high=problem.high, message=str(problem))])
    found = check_table(device, limits)
    typed = {(v.field, v.low, v.high) for v in as_typed}
    return [v if (v.field, v.low, v.high) in typed else v.model_copy(update={"message": AS_RUN + v.message})
            for v in found]
