"""An envelope on the wire: axes, nominal task and every node's table as raw fixed-point integers.

The link carries one kind of buffer: a fixed-task table travels, and is held by the leg, as the envelope of its one
node (:func:`table_wire`; :func:`controller_core.envelope.envelope_of_table`), which the device runs as a table.

A transfer is ENVELOPE_BEGIN, the axis frames (speeds, inclines, the nominal task, the body mass the envelope was
built for, which the knee's stance support floor scales with) and their check, twelve frames per
node (eight rows, two threshold frames, the stumble trigger and the early landing's, each carrying its node index)
and the node's check,
ENVELOPE_COMMIT;
TABLE_ACK answers, as for a table. The CRC-32 (zlib) covers every raw value in transfer order (axes, nominal, then
node by node, row by row), packed as little-endian int32, so host and device compute it from exactly what the device
will run; the device stages the whole envelope or nothing.

A check frame (ENVELOPE_CHECK) carries the CRC-32 of one node's values (``target`` 0, ``node`` its index 0–63) or of
the axes and nominal task (``target`` 1), so every one of the 64 nodes a transfer may carry has its own check. With
twelve frames per node
and 25 nodes, a corrupted frame would otherwise spoil nearly every transfer on a noisy bus (the first copy of a
frame is kept, so the whole transfer would have to start over): the device keeps a node once its frames give its
check and drops the node's frames for fresh copies when they do not, and answers a commit with the number of frames
it still lacks; the host sends the data again until none are missing. The envelope CRC still decides at commit.

Node quanta (fit in one classic-CAN frame with a node index): k 0.001 N·m/rad, θe 0.01°, b 0.01 N·m·s/rad, moment
0.01 N·m, loads 0.1 N, knee angle 0.01°, state times 1 ms (to 4.095 s), knee extension speed 1 deg/s, the stumble
trigger as in a table (0.01°, 0.1 deg/s, 1 %); axes 0.001 m/s
or deg. At most 64 nodes. :func:`check_envelope_as_run` checks what the device will run.
"""

from __future__ import annotations

from dataclasses import dataclass

import can

from controller_core.envelope import Envelope, NeighbourSteps, check_envelope, check_grid, envelope_of_table
from controller_core.table import LimitViolation, ParameterTable, SafetyLimits, Thresholds
from device_bridge.protocol import (
    LANDING_SIGNALS,
    ROW_ORDER,
    ROW_SIGNALS,
    SIGNAL_FIELDS,
    STUMBLE_SIGNALS,
    DeviceRow,
    DeviceTable,
    ProtocolError,
    ValueDoesNotFitError,
    encode,
    quantize,
    to_physical,
    wire_crc32,
    with_device_values,
)

MAX_NODES = 64
FRAMES_PER_NODE = 12
STUMBLE_ROW = 10   # a node's row_index of its ENVELOPE_STUMBLE frame (rows 0–7, thresholds 8 and 9)
LANDING_ROW = 11   # and of its ENVELOPE_LANDING frame
CHECK_NODE, CHECK_AXES = 0, 1   # ENVELOPE_CHECK.target: one node's values, or the axes and nominal task
_A = ("sf_to_se_ankle_moment", "se_to_wf_load", "we_to_sf_load")
_B = ("wf_to_we_knee_angle", "min_state_time", "max_state_time", "sf_to_se_knee_extension")
AXIS_SPEED, AXIS_INCLINE, AXIS_NOMINAL, AXIS_BODY = 0, 1, 2, 3   # AXIS_BODY index 0: body mass (kg)


@dataclass(frozen=True)
class DeviceEnvelope:
    """The envelope as the device holds it: axes (m/s, deg), the nominal task and one table per node."""

    speeds_mps: tuple[float, ...]
    inclines_deg: tuple[float, ...]
    nominal: tuple[float, float]
    tables: tuple[DeviceTable, ...]
    body_mass_kg: float


@dataclass(frozen=True)
class WireEnvelope:
    """Raw integers of an envelope transfer (see the module docstring)."""

    speeds: tuple[int, ...]
    inclines: tuple[int, ...]
    nominal: tuple[int, int]
    body_mass: int
    nodes: tuple[tuple[tuple[int, ...], ...], ...]   # per node: 8 row triples, thresholds A (3) and B (4), stumble (4)

    @property
    def shape(self) -> tuple[int, int]:
        return len(self.speeds), len(self.inclines)

    @classmethod
    def from_envelope(cls, envelope: Envelope) -> WireEnvelope:
        """Round an envelope to the wire quanta.

        Raises:
            ProtocolError: more than 64 nodes or 15 values per axis, or a value that does not fit its field.
        """
        n_s, n_i = envelope.shape
        if n_s > 15 or n_i > 15 or n_s * n_i > MAX_NODES:
            raise ProtocolError(f"an envelope of {n_s} × {n_i} nodes does not fit the link: at most 15 values per "
                                f"axis and {MAX_NODES} nodes")

        def axis(value: float, name: str) -> int:
            return quantize("ENVELOPE_AXIS", "value", value, name)

        nodes = []
        for k, node in enumerate(envelope.nodes):
            t = node.table
            at = "" if envelope.single_node else f"node {k}: "    # a table's values are named as in the table
            rows = [tuple(quantize("ENVELOPE_ROW", f, getattr(t.row(j, s), SIGNAL_FIELDS[f]),
                                    f"{at}{j}.{s}.{SIGNAL_FIELDS[f]}") for f in ROW_SIGNALS) for j, s in ROW_ORDER]
            a = tuple(quantize("ENVELOPE_THRESHOLDS_A", f, getattr(t.thresholds, SIGNAL_FIELDS[f]),
                                f"{at}thresholds.{SIGNAL_FIELDS[f]}") for f in _A)
            b = tuple(quantize("ENVELOPE_THRESHOLDS_B", f, getattr(t.thresholds, SIGNAL_FIELDS[f]),
                                f"{at}thresholds.{SIGNAL_FIELDS[f]}") for f in _B)
            stumble = tuple(quantize("ENVELOPE_STUMBLE", f, getattr(t.thresholds, SIGNAL_FIELDS[f]),
                                     f"{at}thresholds.{SIGNAL_FIELDS[f]}") for f in STUMBLE_SIGNALS)
            landing = tuple(quantize("ENVELOPE_LANDING", f, getattr(t.thresholds, SIGNAL_FIELDS[f]),
                                     f"{at}thresholds.{SIGNAL_FIELDS[f]}") for f in LANDING_SIGNALS)
            nodes.append((*rows, a, b, stumble, landing))
        return cls(speeds=tuple(axis(v, "speeds_mps") for v in envelope.speeds_mps),
                   inclines=tuple(axis(v, "inclines_deg") for v in envelope.inclines_deg),
                   nominal=(axis(envelope.nominal_speed_mps, "nominal_speed_mps"),
                            axis(envelope.nominal_incline_deg, "nominal_incline_deg")),
                   body_mass=axis(envelope.mass_kg, "mass_kg"), nodes=tuple(nodes))

    @property
    def axis_values(self) -> list[int]:
        """The raw axis values in transfer order (what the axes check covers)."""
        return [*self.speeds, *self.inclines, *self.nominal, self.body_mass]

    def crc32(self) -> int:
        """CRC-32 of every raw value in transfer order (little-endian int32 each)."""
        return wire_crc32([*self.axis_values, *(v for node in self.nodes for part in node for v in part)])

    def frames(self, transfer_id: int) -> list[can.Message]:
        """The data frames of a transfer: axes, nominal and their check, then twelve per node and its check."""
        out = [encode("ENVELOPE_AXIS", {"transfer_id": transfer_id, "axis": a, "index": i, "value": v})
               for a, values in ((AXIS_SPEED, self.speeds), (AXIS_INCLINE, self.inclines), (AXIS_NOMINAL, self.nominal),
                                 (AXIS_BODY, (self.body_mass,)))
               for i, v in enumerate(values)]
        out.append(encode("ENVELOPE_CHECK", {"transfer_id": transfer_id, "target": CHECK_AXES, "node": 0,
                                             "crc32": wire_crc32(self.axis_values)}))
        for n, node in enumerate(self.nodes):
            head = {"transfer_id": transfer_id, "node": n}
            out += [encode("ENVELOPE_ROW", {**head, "row_index": i, **dict(zip(ROW_SIGNALS, node[i], strict=True))})
                    for i in range(len(ROW_ORDER))]
            out.append(encode("ENVELOPE_THRESHOLDS_A", {**head, "row_index": 8, **dict(zip(_A, node[8], strict=True))}))
            out.append(encode("ENVELOPE_THRESHOLDS_B", {**head, "row_index": 9, **dict(zip(_B, node[9], strict=True))}))
            out.append(encode("ENVELOPE_STUMBLE", {**head, "row_index": STUMBLE_ROW,
                                                   **dict(zip(STUMBLE_SIGNALS, node[STUMBLE_ROW], strict=True))}))
            out.append(encode("ENVELOPE_LANDING", {**head, "row_index": LANDING_ROW,
                                                   **dict(zip(LANDING_SIGNALS, node[LANDING_ROW], strict=True))}))
            out.append(encode("ENVELOPE_CHECK", {**head, "target": CHECK_NODE, "crc32": _node_crc(node)}))
        return out

    def to_device(self) -> DeviceEnvelope:
        """The physical values the device runs (ValueError on a non-physical threshold)."""
        def axis(raw: int) -> float:
            return to_physical("ENVELOPE_AXIS", "value", raw)

        mass = axis(self.body_mass)
        tables = []
        for node in self.nodes:
            rows = tuple(DeviceRow(j, s, *(to_physical("ENVELOPE_ROW", f, raw)
                                           for raw, f in zip(node[i], ROW_SIGNALS, strict=True)))
                         for i, (j, s) in enumerate(ROW_ORDER))
            values = {SIGNAL_FIELDS[f]: to_physical("ENVELOPE_THRESHOLDS_A", f, raw)
                      for raw, f in zip(node[8], _A, strict=True)}
            values |= {SIGNAL_FIELDS[f]: to_physical("ENVELOPE_THRESHOLDS_B", f, raw)
                       for raw, f in zip(node[9], _B, strict=True)}
            values |= {SIGNAL_FIELDS[f]: to_physical("ENVELOPE_STUMBLE", f, raw)
                       for raw, f in zip(node[STUMBLE_ROW], STUMBLE_SIGNALS, strict=True)}
            values |= {SIGNAL_FIELDS[f]: to_physical("ENVELOPE_LANDING", f, raw)
                       for raw, f in zip(node[LANDING_ROW], LANDING_SIGNALS, strict=True)}
            tables.append(DeviceTable(rows=rows, thresholds=Thresholds(**values), body_mass_kg=mass))
        return DeviceEnvelope(speeds_mps=tuple(axis(v) for v in self.speeds),
                              inclines_deg=tuple(axis(v) for v in self.inclines),
                              nominal=(axis(self.nominal[0]), axis(self.nominal[1])), tables=tuple(tables),
                              body_mass_kg=mass)


def table_wire(table: ParameterTable) -> WireEnvelope:
    """A table's transfer: the envelope of its one node, rounded to the wire quanta (ProtocolError when a value does
    not fit its field). Its CRC-32 is the one the device reads back while it runs the table."""
    return WireEnvelope.from_envelope(envelope_of_table(table))


def _node_crc(node: tuple[tuple[int, ...], ...]) -> int:
    return wire_crc32([v for part in node for v in part])


class EnvelopeReceiver:
    """Collects one envelope transfer's frames on the device, node by node (see the module docstring).

    Frames that name a node outside the grid, an unknown check target or a row index their message does not carry
    are ignored (the envelope CRC decides at commit), never an error.
    """

    def __init__(self, transfer_id: int, version: int, crc32: int, n_speeds: int, n_inclines: int,
                 started_s: float) -> None:
        self.transfer_id, self.version, self.crc32 = transfer_id, version, crc32
        self.n_speeds, self.n_inclines, self.started_s = n_speeds, n_inclines, started_s
        self.axes: dict[tuple[int, int], int] = {}
        self.axes_check: int | None = None
        self.axes_kept = False
        self.rows: dict[tuple[int, int], tuple[int, ...]] = {}
        self.checks: dict[int, int] = {}
        self.kept: set[int] = set()   # nodes whose frames gave their check

    @property
    def n_nodes(self) -> int:
        return self.n_speeds * self.n_inclines

    def _axis_keys(self) -> list[tuple[int, int]]:
        return [(AXIS_SPEED, i) for i in range(self.n_speeds)] + [(AXIS_INCLINE, i) for i in range(self.n_inclines)] + \
            [(AXIS_NOMINAL, 0), (AXIS_NOMINAL, 1), (AXIS_BODY, 0)]

    def _verify_axes(self) -> None:
        """Keep the axes once their values give their check; drop them for fresh copies when they do not."""
        keys = self._axis_keys()
        if self.axes_kept or self.axes_check is None or any(k not in self.axes for k in keys):
            return
        if wire_crc32([self.axes[k] for k in keys]) == self.axes_check:
            self.axes_kept = True
        else:
            self.axes.clear()
            self.axes_check = None

    def _verify(self, node: int) -> None:
        """Keep a complete node whose values give its check; drop it for fresh copies when they do not."""
        if node in self.kept or node not in self.checks:
            return
        if any((node, i) not in self.rows for i in range(FRAMES_PER_NODE)):
            return
        if _node_crc(tuple(self.rows[(node, i)] for i in range(FRAMES_PER_NODE))) == self.checks[node]:
            self.kept.add(node)
        else:
            for i in range(FRAMES_PER_NODE):
                del self.rows[(node, i)]
            del self.checks[node]

    def add(self, name: str, raw: dict[str, int]) -> None:
        if name == "ENVELOPE_AXIS":
            limit = {AXIS_SPEED: self.n_speeds, AXIS_INCLINE: self.n_inclines, AXIS_NOMINAL: 2,
                     AXIS_BODY: 1}.get(raw["axis"], 0)
            if raw["index"] < limit and not self.axes_kept:
                self.axes.setdefault((raw["axis"], raw["index"]), raw["value"])
                self._verify_axes()
            return
        if name == "ENVELOPE_CHECK" and raw["target"] == CHECK_AXES:
            if not self.axes_kept and self.axes_check is None:
                self.axes_check = raw["crc32"]
                self._verify_axes()
            return
        node = raw["node"]
        if node in self.kept or node >= self.n_nodes:
            return
        if name == "ENVELOPE_CHECK":
            if raw["target"] == CHECK_NODE:
                self.checks.setdefault(node, raw["crc32"])
                self._verify(node)
            return
        i = raw["row_index"]
        if name == "ENVELOPE_ROW" and i < len(ROW_ORDER):
            self.rows.setdefault((node, i), tuple(raw[f] for f in ROW_SIGNALS))
        elif name == "ENVELOPE_THRESHOLDS_A" and i == 8:
            self.rows.setdefault((node, i), tuple(raw[f] for f in _A))
        elif name == "ENVELOPE_THRESHOLDS_B" and i == 9:
            self.rows.setdefault((node, i), tuple(raw[f] for f in _B))
        elif name == "ENVELOPE_STUMBLE" and i == STUMBLE_ROW:
            self.rows.setdefault((node, i), tuple(raw[f] for f in STUMBLE_SIGNALS))
        elif name == "ENVELOPE_LANDING" and i == LANDING_ROW:
            self.rows.setdefault((node, i), tuple(raw[f] for f in LANDING_SIGNALS))
        else:
            return
        self._verify(node)

    def missing(self) -> int:
        """How many frames (data and check) the device still lacks: those of every node not yet kept."""
        axes = 0 if self.axes_kept else len(self._axis_keys()) + 1 - len(self.axes) - (self.axes_check is not None)
        nodes = sum(FRAMES_PER_NODE + 1 - sum((n, i) in self.rows for i in range(FRAMES_PER_NODE)) - (n in self.checks)
                    for n in range(self.n_nodes) if n not in self.kept)
        return axes + nodes

    def wire(self) -> WireEnvelope:
        """The complete transfer.

        Raises:
            ProtocolError: a frame is still missing (the caller checks :meth:`missing` first; this is the firmware's
                second line, never a KeyError).
        """
        if self.missing():
            raise ProtocolError(f"envelope transfer {self.transfer_id}: {self.missing()} frame(s) still missing")
        return WireEnvelope(
            speeds=tuple(self.axes[(AXIS_SPEED, i)] for i in range(self.n_speeds)),
            inclines=tuple(self.axes[(AXIS_INCLINE, i)] for i in range(self.n_inclines)),
            nominal=(self.axes[(AXIS_NOMINAL, 0)], self.axes[(AXIS_NOMINAL, 1)]),
            body_mass=self.axes[(AXIS_BODY, 0)],
            nodes=tuple(tuple(self.rows[(n, i)] for i in range(FRAMES_PER_NODE)) for n in range(self.n_nodes)))


def envelope_begin_frame(transfer_id: int, version: int, crc32: int, shape: tuple[int, int]) -> can.Message:
    return encode("ENVELOPE_BEGIN", {"transfer_id": transfer_id, "n_speeds": shape[0], "n_inclines": shape[1],
                                     "version": version, "crc32": crc32})


def envelope_commit_frame(transfer_id: int, version: int, crc32: int, shape: tuple[int, int]) -> can.Message:
    return encode("ENVELOPE_COMMIT", {"transfer_id": transfer_id, "n_speeds": shape[0], "n_inclines": shape[1],
                                      "version": version, "crc32": crc32})


def envelope_as_run(envelope: Envelope, device: DeviceEnvelope | None = None) -> Envelope:
    """The envelope rounded to the node quanta: axes, nominal task and every node's values bit for bit as the device
    runs them (each node's task is its axes' rounded values). Returned unchanged when a value does not fit the link
    (:func:`check_envelope_as_run` reports it). ``device``: its decoded values, when the caller has them already."""
    if device is None:
        try:
            device = WireEnvelope.from_envelope(envelope).to_device()
        except ValueError:
            return envelope
    n_i = len(device.inclines_deg)
    nodes = [node.model_copy(update={"speed_mps": device.speeds_mps[k // n_i],
                                     "incline_deg": device.inclines_deg[k % n_i],
                                     "table": with_device_values(node.table, device.tables[k])})
             for k, node in enumerate(envelope.nodes)]
    return envelope.model_copy(update={
        "speeds_mps": list(device.speeds_mps), "inclines_deg": list(device.inclines_deg),
        "nominal_speed_mps": device.nominal[0], "nominal_incline_deg": device.nominal[1], "nodes": nodes})


def check_envelope_as_run(envelope: Envelope, limits: SafetyLimits | None = None,
                          steps: NeighbourSteps | None = None, device: DeviceEnvelope | None = None
                          ) -> list[LimitViolation]:
    """Every violation of what the device will run: the envelope rounded to the node quanta, each node's limits and
    the neighbour rule (the server's one check of an envelope, so it never approves what the device refuses).
    ``device``: its decoded values, when the caller has them already."""
    if device is None:
        try:
            device = WireEnvelope.from_envelope(envelope).to_device()
        except ValueDoesNotFitError as exc:
            return check_envelope(envelope, limits, steps) or [
                LimitViolation(field=exc.field, value=exc.value, low=exc.low, high=exc.high, message=str(exc))]
        except ProtocolError as exc:
            return [LimitViolation(field="envelope", value=float(len(envelope.nodes)), low=0.0, high=float(MAX_NODES),
                                   message=str(exc))]
    return check_grid(device.speeds_mps, device.inclines_deg, device.tables, steps or envelope.neighbour_steps, limits)
