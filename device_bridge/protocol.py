"""The device link's frames: defined once in ``quasitune.dbc``, encoded and decoded here with cantools.

Parameters travel in one kind of transfer, an envelope's (:mod:`device_bridge.envelope_wire`; a fixed-task table is
the envelope of its one node) of classic-CAN frames in fixed-point, each value rounded to its field's quantum
(:func:`quantize`, which refuses any value that does not fit) and covered by a CRC-32 (:func:`wire_crc32`), so the
host and the device compute it from exactly the numbers the device will run.

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
from controller_core.table import ParameterTable, Thresholds

DBC_PATH = Path(__file__).with_name("quasitune.dbc")

JOINTS: tuple[str, str] = ("knee", "ankle")
ROW_ORDER: tuple[tuple[str, str], ...] = tuple((j, s) for j in JOINTS for s in SUBPHASES)
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
    UNKNOWN_TRANSFER = 1   # frames or commit for a transfer the device has not begun (or has dropped)
    MISSING_ROWS = 2       # commit before every frame arrived; missing_rows is how many are still missing
    CRC_MISMATCH = 3       # the frames held do not give the announced CRC-32 (loss, corruption): nothing kept
    SAFETY_LIMIT = 4       # intact, but a value is outside the device's own safety limits: nothing kept
    TIMEOUT = 5            # the transfer did not complete in time: nothing kept
    MALFORMED = 6          # begin and commit disagree (version, grid, CRC), or a grid the leg cannot hold: nothing kept
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


# --------------------------------------------------------------------------------------------- parameters

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
STUMBLE_SIGNALS = ("stumble_knee_margin", "stumble_knee_rate", "fold_knee_rate", "fold_window")   # each node's
LANDING_SIGNALS = ("early_landing_swing", "forefoot_landing")


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
    device computes the same over what it received; a whole transfer, its axes and each node use it."""
    return zlib.crc32(struct.pack(f"<{len(raw)}i", *raw))


def with_device_values(table: ParameterTable, device: DeviceTable) -> ParameterTable:
    """``table`` with every row and threshold value replaced by the device's (provenance and fit notes kept)."""
    fields = [SIGNAL_FIELDS[s] for s in ROW_SIGNALS]
    rows = [r.model_copy(update={f: getattr(device.row(r.joint, r.subphase), f) for f in fields}) for r in table.rows]
    return table.model_copy(update={"rows": rows, "thresholds": device.thresholds})
