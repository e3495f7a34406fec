"""The device link's frames: defined once in ``quasitune.dbc``, encoded and decoded here with cantools.

A parameter table travels as thirteen classic-CAN frames in fixed-point: eight impedance rows (knee then ankle,
sub-phases in walking order), two threshold frames, the body mass, the stumble support's trigger and the early
landing's.
:class:`WireTable` holds those raw integers; its CRC-32 (zlib's polynomial) covers every raw value in row order, packed
as little-endian int32, so the host and the device compute it from exactly the numbers the device will run. The wire
quanta are the table's precision on the device: 0.001 N·m/rad, 0.001°, 0.001 N·m·s/rad, 0.01 N·m, 0.1 N, 1 ms (the
stumble trigger: 0.01°, 0.1 deg/s, 1 % of stance; the early landing's: 1 %); the host rounds to them before
computing the CRC, and :meth:`WireTable.from_table` refuses any value that does not fit its field.

Every decoded frame is checked for its declared length first: a truncated or over-long frame is a
:class:`ProtocolError` naming the message, never a partly decoded one.
"""

from __future__ import annotations

import math
import struct
import zlib
from dataclasses import dataclass
from enum import IntEnum, IntFlag
from functools import cache
from pathlib import Path

import can
import cantools
from cantools.database.can import Database, Message

from controller_core.quasi_stiffness import SUBPHASES
from controller_core.table import LimitViolation, ParameterTable, SafetyLimits, Thresholds, check_table

DBC_PATH = Path(__file__).with_name("quasitune.dbc")

JOINTS: tuple[str, str] = ("knee", "ankle")
ROW_ORDER: tuple[tuple[str, str], ...] = tuple((j, s) for j in JOINTS for s in SUBPHASES)
THRESHOLDS_A_INDEX = len(ROW_ORDER)        # 8
THRESHOLDS_B_INDEX = len(ROW_ORDER) + 1    # 9
BODY_INDEX = len(ROW_ORDER) + 2            # 10: the body mass the table was built for (the support floor needs it)
STUMBLE_INDEX = len(ROW_ORDER) + 3         # 11: the stumble support's trigger
LANDING_INDEX = len(ROW_ORDER) + 4         # 12: the early landing's trigger
ROW_COUNT = len(ROW_ORDER) + 5             # 13 frames between begin and commit
TRANSFER_IDS = 16                          # 4-bit transfer id
TELEMETRY_PERIOD_S = 0.01                  # one telemetry sample every 10 ms (the DBC's TELEMETRY_GAIT comment)


class ProtocolError(ValueError):
    """A frame or a value that the protocol cannot carry (the message says which and why)."""


class ValueDoesNotFitError(ProtocolError):
    """A table value outside the range its wire field can carry (``field`` in the table's naming)."""

    def __init__(self, message: str, field: str, value: float, low: float, high: float) -> None:
        super().__init__(message)
        self.field, self.value, self.low, self.high = field, value, low, high


class Mode(IntEnum):
    """Device operating mode (DEVICE_STATUS.mode)."""

    NO_TABLE = 0   # no valid table yet: passive, damped
    ACTIVE = 1     # running the four-state machine with the active table
    SAFE = 2       # passive, damped; left only on a new valid table or an explicit command
    CALIBRATING = 3   # guided calibration from the clinic: no torque at all (the leg is in a stand); ends in SAFE


class LegTorqueMode(IntEnum):
    """Who computes the leg's torque (DEVICE_LEG.torque_mode)."""

    CURRENT = 0              # QuasiTune computes every torque; the actuator runs its current loop
    TORQUE = 1               # likewise, through the actuator's torque loop
    ACTUATOR_IMPEDANCE = 2   # the actuator runs the spring and damper QuasiTune's state asks for


class AckResult(IntEnum):
    """TABLE_ACK.result: 0 staged, anything else a refusal with its reason."""

    STAGED = 0
    UNKNOWN_TRANSFER = 1   # rows or commit for a transfer the device has not begun (or has dropped)
    MISSING_ROWS = 2       # commit before every row arrived; missing_rows is the bitmask to resend
    CRC_MISMATCH = 3       # the rows held do not give the announced CRC-32 (loss, corruption): nothing kept
    SAFETY_LIMIT = 4       # intact, but a value is outside the device's own safety limits: nothing kept
    TIMEOUT = 5            # the transfer did not complete in time: nothing kept
    MALFORMED = 6          # begin and commit disagree (version, row count, CRC): nothing kept
    DEVICE_ERROR = 7       # the device failed while handling the transfer: it was aborted, nothing kept


class Command(IntEnum):
    """DEVICE_COMMAND.command."""

    ENTER_SAFE_MODE = 1
    LEAVE_SAFE_MODE = 2
    REQUEST_STATUS = 3
    LINK_SUPERVISED = 4    # a lost host heartbeat puts the leg in safe mode (the default)
    LINK_AUTONOMOUS = 5    # a lost host heartbeat is reported and changes nothing the leg does


class CalibrationAction(IntEnum):
    """CALIBRATION_COMMAND.action."""

    START = 1      # the leg stops driving its joints for the calibration (only from safe mode or with no table)
    MEASURE = 2    # measure one step (CalibrationStep) from the readings of the next samples
    KEEP = 3       # keep the four steps' result on the leg (its calibration file), then safe mode
    CANCEL = 4     # leave the calibration unchanged, then safe mode


class CalibrationStep(IntEnum):
    """CALIBRATION_COMMAND.step and CALIBRATION_RESULT.step: the guided calibration's steps, in order
    (:mod:`device_bridge.osl.calibration`); 0 in an answer about the calibration as a whole."""

    JOINT_ZERO = 1
    DIRECTION = 2
    LOADCELL_ZERO = 3
    LOADCELL_SIGN = 4


class CalibrationOutcome(IntEnum):
    """CALIBRATION_RESULT.outcome: MEASURED frames carry one quantity each; every other outcome closes an answer."""

    STARTED = 1
    MEASURED = 2
    ACCEPTED = 3
    REFUSED = 4
    KEPT = 5
    CANCELLED = 6


class CalibrationSubject(IntEnum):
    """CALIBRATION_RESULT.subject: what a quantity or a refusal is about."""

    LEG = 0
    KNEE = 1
    ANKLE = 2
    LOADCELL = 3


class CalibrationRefusal(IntEnum):
    """CALIBRATION_RESULT.reason: why a step (or the calibration) was refused; the words are
    :func:`device_bridge.osl.calibration.refusal_words`."""

    NONE = 0
    NOT_A_NUMBER = 1      # a reading is NaN or missing: the sensor's wiring
    NOT_STILL = 2         # the joint or the foot moved while it was to be held still
    TOO_LITTLE_MOVE = 3   # the prompted movement was under 5°
    BEYOND_RANGE = 4      # from the zero the joint read beyond its range: the zero was not taken at the stop
    LOAD_OFFSET = 5       # the unloaded cell reads beyond what drift gives
    NOT_LOADED = 6        # standing changed the load by under a fifth of the body weight
    OVERLOADED = 7        # over twice the body weight: the body mass or the cell's scale
    BODY_MASS = 8         # no usable body mass (20–200 kg)
    LEG_BUSY = 9          # the leg runs a table: put it in safe mode first
    NO_SENSORS = 10       # this leg has nothing to calibrate (the simulated bench reads itself exactly)
    OUT_OF_ORDER = 11     # a step before the steps it needs
    NOT_STARTED = 12      # a measure, keep or cancel with no calibration under way (or another session's)
    INCOMPLETE = 13       # keep before all four steps were accepted
    NOT_SAVED = 14        # the leg could not write its calibration file: nothing changed


# CALIBRATION_RESULT.quantity: what a MEASURED frame's value is (its unit in the name)
CALIBRATION_QUANTITIES: tuple[str, ...] = (
    "", "reading_deg", "spread_deg", "moved_deg", "sign", "torque_sign", "reach_min_deg", "reach_max_deg",
    "force_N", "moment_Nm", "spread_N", "change_N", "body_weight_N", "body_mass_kg")


class LinkMode(IntEnum):
    """DEVICE_HEALTH.link_mode: what a lost host heartbeat does to the leg (the prosthetist's choice per device).

    SUPERVISED (tuning in the clinic): safe mode on the first tick past the heartbeat timeout, as the leg always did.
    AUTONOMOUS (daily life, no server near): the leg runs on with the approved table or envelope it holds; the lost
    heartbeat is a reported fault, not a change of behaviour. Safe mode from any other cause is unchanged.
    """

    SUPERVISED = 0
    AUTONOMOUS = 1


class Fault(IntFlag):
    """DEVICE_HEALTH.fault_flags."""

    HEARTBEAT_LOST = 1
    TABLE_REFUSED = 2
    MALFORMED_FRAME = 4
    NO_TABLE = 8
    OVER_TEMPERATURE = 16
    RECEIVE_ERROR = 32     # handling a frame failed: that transfer was aborted; the running table and control go on
    CONTROL_ERROR = 64     # the control step failed: the leg went to safe mode


FAULT_MASK = int(sum(Fault))   # every flag this protocol defines (other bits of fault_flags are ignored)


TEMPERATURE_UNKNOWN_RAW = 255


@cache
def database() -> Database:
    """The parsed DBC (read once; the file is part of the package)."""
    return cantools.database.load_file(str(DBC_PATH))


@cache
def message(name: str) -> Message:
    return database().get_message_by_name(name)


@cache
def _by_id(frame_id: int) -> Message | None:
    try:
        return database().get_message_by_frame_id(frame_id)
    except KeyError:
        return None


def frame_id(name: str) -> int:
    return message(name).frame_id


TELEMETRY_MESSAGES = ("TELEMETRY_TASK", "TELEMETRY_GAIT", "TELEMETRY_KNEE", "TELEMETRY_ANKLE")


@cache
def _telemetry_ids() -> frozenset[int]:
    return frozenset(frame_id(name) for name in TELEMETRY_MESSAGES)


def is_telemetry(msg: can.Message) -> bool:
    """A telemetry frame (a sample's part): what may wait a little to share a broker message with the next samples."""
    return msg.arbitration_id in _telemetry_ids() and not msg.is_extended_id


def signal_scale(msg_name: str, signal: str) -> float:
    return float(message(msg_name).get_signal_by_name(signal).scale)


def to_physical(msg_name: str, signal: str, raw: int) -> float:
    """A raw wire integer in the signal's unit, as host and device both compute it: divided by the whole number of
    quanta per unit where there is one (raw 316 at 0.001 gives exactly the double nearest 0.316, so a value shown
    and stored reads as the decimal it is), else multiplied by the quantum."""
    scale = signal_scale(msg_name, signal)
    per_unit = round(1.0 / scale)
    return raw / per_unit if abs(per_unit * scale - 1.0) < 1e-12 else raw * scale


def encode(name: str, raw: dict[str, int]) -> can.Message:
    """A classic-CAN frame of DBC message ``name`` from raw (unscaled) signal values; unnamed signals are 0."""
    m = message(name)
    values = {s.name: int(raw.get(s.name, 0)) for s in m.signals}
    try:
        data = m.encode(values, scaling=False, strict=True)
    except Exception as exc:   # cantools raises EncodeError (or ValueError) naming the signal
        raise ProtocolError(f"{name}: {exc}") from exc
    return can.Message(arbitration_id=m.frame_id, data=data, is_extended_id=False)


def _raw_range(signal) -> tuple[int, int]:
    """The raw integer range of a cantools signal (two's complement when signed)."""
    if signal.is_signed:
        return -(1 << (signal.length - 1)), (1 << (signal.length - 1)) - 1
    return 0, (1 << signal.length) - 1


def encode_scaled(name: str, values: dict[str, float]) -> can.Message:
    """A frame from physical values in the DBC's units, rounded to the signal quanta and clamped to range."""
    m = message(name)
    raw: dict[str, int] = {}
    for s in m.signals:
        v = values.get(s.name, 0.0)
        lo, hi = _raw_range(s)
        raw[s.name] = min(max(round((v - s.offset) / s.scale), lo), hi)
    # clamped just above, so cantools' own range check (most of an encode's cost, 100 frames a second) is skipped
    data = m.encode(raw, scaling=False, strict=False)
    return can.Message(arbitration_id=m.frame_id, data=data, is_extended_id=False)


def decode(msg: can.Message) -> tuple[str, dict[str, int]] | None:
    """(message name, raw signal values) of a frame; None for ids this protocol does not define.

    Raises:
        ProtocolError: a known id whose length is not the declared one (truncated frame) or that cantools
            cannot decode.
    """
    m = _by_id(msg.arbitration_id)
    if m is None or msg.is_extended_id or msg.is_remote_frame or msg.is_error_frame:
        return None
    if len(msg.data) != m.length:
        raise ProtocolError(f"{m.name} (id 0x{m.frame_id:03X}) must be {m.length} bytes, got {len(msg.data)}: "
                            "truncated or malformed frame refused")
    try:
        return m.name, m.decode(bytes(msg.data), scaling=False, decode_choices=False)
    except Exception as exc:
        raise ProtocolError(f"{m.name}: cannot decode: {exc}") from exc


def physical(name: str, raw: dict[str, int]) -> dict[str, float]:
    """Raw signal values of message ``name`` in the DBC's physical units (scale and offset applied)."""
    m = message(name)
    return {s.name: raw[s.name] * s.scale + s.offset for s in m.signals}


# --------------------------------------------------------------------------------------------- tables

ROW_SIGNALS = ("k", "theta_e", "b")   # an impedance row's signals, in frame order (tables and envelope nodes)
# the one map from a wire signal to the table field it carries (rows: ParameterRow; thresholds: Thresholds)
SIGNAL_FIELDS = {
    "k": "k_Nm_per_rad", "theta_e": "theta_e_deg", "b": "b_Nm_s_per_rad",
    "sf_to_se_ankle_moment": "sf_to_se_ankle_moment_Nm", "se_to_wf_load": "se_to_wf_load_N",
    "we_to_sf_load": "we_to_sf_load_N", "wf_to_we_knee_angle": "wf_to_we_knee_angle_deg",
    "min_state_time": "min_state_time_s", "max_state_time": "max_state_time_s",
    "sf_to_se_knee_extension": "sf_to_se_knee_extension_deg_per_s",
    "stumble_knee_margin": "stumble_knee_margin_deg", "stumble_knee_rate": "stumble_knee_rate_deg_per_s",
    "fold_knee_rate": "fold_knee_rate_deg_per_s", "fold_window": "fold_window_of_stance_pct",
    "early_landing_swing": "early_landing_swing_pct", "forefoot_landing": "forefoot_landing_pct",
}
_THRESH_A = ("sf_to_se_ankle_moment", "se_to_wf_load", "we_to_sf_load", "sf_to_se_knee_extension")
_THRESH_B = ("wf_to_we_knee_angle", "min_state_time", "max_state_time")
STUMBLE_SIGNALS = ("stumble_knee_margin", "stumble_knee_rate", "fold_knee_rate", "fold_window")   # tables, nodes
LANDING_SIGNALS = ("early_landing_swing", "forefoot_landing")   # tables and nodes


def quantize(msg_name: str, signal: str, value: float, field: str) -> int:
    s = message(msg_name).get_signal_by_name(signal)
    lo, hi = _raw_range(s)
    scaled = value / s.scale
    raw = round(scaled) if math.isfinite(scaled) else None   # round(inf) raises OverflowError, round(nan) ValueError
    if raw is None or not lo <= raw <= hi:
        raise ValueDoesNotFitError(f"{field} = {value:.6g} does not fit the wire field {msg_name}.{signal} "
                                   f"([{lo * s.scale:g}, {hi * s.scale:g}] {s.unit})",
                                   field, value, lo * s.scale, hi * s.scale)
    return raw


@dataclass(frozen=True)
class DeviceRow:
    """One impedance row as the device holds it (SI stiffness and damping; θe in deg like the table)."""

    joint: str
    subphase: str
    k_Nm_per_rad: float
    theta_e_deg: float
    b_Nm_s_per_rad: float


@dataclass(frozen=True)
class DeviceTable:
    """The table decoded from the wire: what :func:`controller_core.table.check_table` and
    :meth:`controller_core.fsm.ImpedanceSchedule.from_table` need, without a provenance (the device has none)."""

    rows: tuple[DeviceRow, ...]
    thresholds: Thresholds
    body_mass_kg: float

    def row(self, joint: str, subphase: str) -> DeviceRow:
        for r in self.rows:
            if r.joint == joint and r.subphase == subphase:
                return r
        raise KeyError((joint, subphase))


def wire_crc32(raw: list[int]) -> int:
    """The link's one checksum: CRC-32 (zlib) of raw field values, little-endian int32 each, in transfer order. The
    device computes the same over what it received; a table, an envelope and each envelope node use it."""
    return zlib.crc32(struct.pack(f"<{len(raw)}i", *raw))


@dataclass(frozen=True)
class WireTable:
    """A parameter table as raw fixed-point integers, in transfer order.

    Attributes:
        rows: eight (k, θe, b) raw triples in :data:`ROW_ORDER`.
        thresholds: seven raw threshold values (A: moment, toe-off load, heel-strike load, SF→SE knee
            extension speed; B: knee angle, minimum and maximum state time).
        body_mass: the body mass the table was built for (TABLE_BODY, 0.01 kg): the device checks the knee's
            stance support floor, which scales with it, on exactly what it will run.
        stumble: the stumble support's trigger (TABLE_STUMBLE: :data:`STUMBLE_SIGNALS`).
        landing: the early landing's trigger (TABLE_LANDING: :data:`LANDING_SIGNALS`).
    """

    rows: tuple[tuple[int, int, int], ...]
    thresholds: tuple[int, int, int, int, int, int, int]
    body_mass: int
    stumble: tuple[int, int, int, int]
    landing: tuple[int, int]

    @classmethod
    def from_table(cls, table: ParameterTable) -> WireTable:
        """Round a table to the wire quanta (ProtocolError when a value does not fit its field)."""
        rows = []
        for joint, sub in ROW_ORDER:
            r = table.row(joint, sub)
            rows.append(tuple(quantize("TABLE_ROW", f, getattr(r, SIGNAL_FIELDS[f]),
                                        f"{joint}.{sub}.{SIGNAL_FIELDS[f]}") for f in ROW_SIGNALS))
        t = table.thresholds
        th = [quantize("TABLE_THRESHOLDS_A", f, getattr(t, SIGNAL_FIELDS[f]),
                        f"thresholds.{SIGNAL_FIELDS[f]}") for f in _THRESH_A]
        th += [quantize("TABLE_THRESHOLDS_B", f, getattr(t, SIGNAL_FIELDS[f]),
                         f"thresholds.{SIGNAL_FIELDS[f]}") for f in _THRESH_B]
        mass = quantize("TABLE_BODY", "body_mass", table.body_mass_kg, "body_mass_kg")
        stumble = tuple(quantize("TABLE_STUMBLE", f, getattr(t, SIGNAL_FIELDS[f]), f"thresholds.{SIGNAL_FIELDS[f]}")
                        for f in STUMBLE_SIGNALS)
        landing = tuple(quantize("TABLE_LANDING", f, getattr(t, SIGNAL_FIELDS[f]), f"thresholds.{SIGNAL_FIELDS[f]}")
                        for f in LANDING_SIGNALS)
        return cls(rows=tuple(rows), thresholds=tuple(th), body_mass=mass, stumble=stumble,  # type: ignore[arg-type]
                   landing=landing)  # type: ignore[arg-type]

    def crc32(self) -> int:
        """CRC-32 of the raw values in transfer order (what the device verifies and reads back)."""
        return wire_crc32([v for row in self.rows for v in row] + list(self.thresholds) + [self.body_mass]
                          + list(self.stumble) + list(self.landing))

    def to_device_table(self) -> DeviceTable:
        """The physical values the device runs (raises pydantic's ValidationError on a non-physical threshold)."""
        rows = tuple(DeviceRow(joint, sub, *(to_physical("TABLE_ROW", f, raw)
                                             for raw, f in zip(r, ROW_SIGNALS, strict=True)))
                     for (joint, sub), r in zip(ROW_ORDER, self.rows, strict=True))
        names = [("TABLE_THRESHOLDS_A", f) for f in _THRESH_A] + [("TABLE_THRESHOLDS_B", f) for f in _THRESH_B]
        values = {SIGNAL_FIELDS[f]: to_physical(m, f, raw)
                  for (m, f), raw in zip(names, self.thresholds, strict=True)}
        values |= {SIGNAL_FIELDS[f]: to_physical("TABLE_STUMBLE", f, raw)
                   for f, raw in zip(STUMBLE_SIGNALS, self.stumble, strict=True)}
        values |= {SIGNAL_FIELDS[f]: to_physical("TABLE_LANDING", f, raw)
                   for f, raw in zip(LANDING_SIGNALS, self.landing, strict=True)}
        return DeviceTable(rows=rows, thresholds=Thresholds(**values),
                           body_mass_kg=to_physical("TABLE_BODY", "body_mass", self.body_mass))

    def frames(self, transfer_id: int) -> list[can.Message]:
        """The thirteen data frames (row_index 0–12) of a transfer."""
        out = [encode("TABLE_ROW", {"transfer_id": transfer_id, "row_index": i, "k": k, "theta_e": th, "b": b})
               for i, (k, th, b) in enumerate(self.rows)]
        a, b = self.thresholds[:len(_THRESH_A)], self.thresholds[len(_THRESH_A):]
        out.append(encode("TABLE_THRESHOLDS_A", {"transfer_id": transfer_id, "row_index": THRESHOLDS_A_INDEX,
                                                 **dict(zip(_THRESH_A, a, strict=True))}))
        out.append(encode("TABLE_THRESHOLDS_B", {"transfer_id": transfer_id, "row_index": THRESHOLDS_B_INDEX,
                                                 **dict(zip(_THRESH_B, b, strict=True))}))
        out.append(encode("TABLE_BODY", {"transfer_id": transfer_id, "row_index": BODY_INDEX,
                                         "body_mass": self.body_mass}))
        out.append(encode("TABLE_STUMBLE", {"transfer_id": transfer_id, "row_index": STUMBLE_INDEX,
                                            **dict(zip(STUMBLE_SIGNALS, self.stumble, strict=True))}))
        out.append(encode("TABLE_LANDING", {"transfer_id": transfer_id, "row_index": LANDING_INDEX,
                                            **dict(zip(LANDING_SIGNALS, self.landing, strict=True))}))
        return out

    @staticmethod
    def row_from_frame(name: str, raw: dict[str, int]) -> tuple[int, tuple[int, ...]] | None:
        """(row index, raw values) of a decoded data frame; None when its index does not belong to its kind."""
        i = raw["row_index"]
        if name == "TABLE_ROW" and i < THRESHOLDS_A_INDEX:
            return i, tuple(raw[f] for f in ROW_SIGNALS)
        if name == "TABLE_THRESHOLDS_A" and i == THRESHOLDS_A_INDEX:
            return i, tuple(raw[f] for f in _THRESH_A)
        if name == "TABLE_THRESHOLDS_B" and i == THRESHOLDS_B_INDEX:
            return i, tuple(raw[f] for f in _THRESH_B)
        if name == "TABLE_BODY" and i == BODY_INDEX:
            return i, (raw["body_mass"],)
        if name == "TABLE_STUMBLE" and i == STUMBLE_INDEX:
            return i, tuple(raw[f] for f in STUMBLE_SIGNALS)
        if name == "TABLE_LANDING" and i == LANDING_INDEX:
            return i, tuple(raw[f] for f in LANDING_SIGNALS)
        return None

    @classmethod
    def from_row_values(cls, values: dict[int, tuple[int, ...]]) -> WireTable:
        """Assemble from the row values of a complete transfer (index → raw values)."""
        rows = tuple(values[i] for i in range(THRESHOLDS_A_INDEX))
        th = values[THRESHOLDS_A_INDEX] + values[THRESHOLDS_B_INDEX]
        return cls(rows=rows, thresholds=th, body_mass=values[BODY_INDEX][0],  # type: ignore[arg-type]
                   stumble=values[STUMBLE_INDEX], landing=values[LANDING_INDEX])


def begin_frame(transfer_id: int, version: int, crc32: int) -> can.Message:
    return encode("TABLE_BEGIN", {"transfer_id": transfer_id, "version": version, "row_count": ROW_COUNT,
                                  "crc32": crc32})


def commit_frame(transfer_id: int, version: int, crc32: int) -> can.Message:
    return encode("TABLE_COMMIT", {"transfer_id": transfer_id, "version": version, "row_count": ROW_COUNT,
                                   "crc32": crc32})


def with_device_values(table: ParameterTable, device: DeviceTable) -> ParameterTable:
    """``table`` with every row and threshold value replaced by the device's (provenance and fit notes kept)."""
    fields = [SIGNAL_FIELDS[s] for s in ROW_SIGNALS]
    rows = [r.model_copy(update={f: getattr(device.row(r.joint, r.subphase), f) for f in fields}) for r in table.rows]
    return table.model_copy(update={"rows": rows, "thresholds": device.thresholds})


def as_run(table: ParameterTable, device: DeviceTable | None = None) -> ParameterTable:
    """The table rounded to the wire's precision: bit for bit the values the device will run, so that what is
    checked, stored, shown and approved is what runs. A table with a value no wire field can carry is returned
    unchanged (:func:`check_as_run` reports that value). ``device``: its decoded values, when the caller has them."""
    if device is None:
        try:
            device = WireTable.from_table(table).to_device_table()
        except ValueError:
            return table
    return with_device_values(table, device)


AS_RUN = "as the device will run it (rounded to the wire's precision): "


def check_as_run(table: ParameterTable, limits: SafetyLimits | None = None,
                 device: DeviceTable | None = None) -> list[LimitViolation]:
    """Every safety violation of the values the device will run: the table rounded to the wire's quanta, which
    is what the firmware decodes and checks itself. A violation that only the rounding creates says so; a value
    that no wire field can carry is a violation too. The one check the server makes of a table (build, edit,
    approval, push), so that the server never approves what the device would refuse. ``device``: its decoded
    values, when the caller has them already."""
    if device is None:
        try:
            device = WireTable.from_table(table).to_device_table()
        except ValueDoesNotFitError as exc:   # the limits say it better when they are broken too (they lie inside)
            return check_table(table, limits) or [
                LimitViolation(field=exc.field, value=exc.value, low=exc.low, high=exc.high, message=str(exc))]
    found = check_table(device, limits)
    if not found:
        return []
    as_typed = {(v.field, v.low, v.high) for v in check_table(table, limits)}
    return [v if (v.field, v.low, v.high) in as_typed else v.model_copy(update={"message": AS_RUN + v.message})
            for v in found]
