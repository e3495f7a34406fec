"""The host's side of the device link: heartbeat, table push with CRC read-back, status and telemetry.

:class:`DeviceLink` owns one python-can bus (any interface: ``virtual`` for tests and the embedded default,
``socketcan`` or another adapter for a real leg). Two threads: one sends the host heartbeat every
``heartbeat_period_s``; one receives, decodes and dispatches — acknowledgements to the push in progress,
DEVICE_STATUS/HEALTH into :attr:`DeviceLink.status` and ``on_status``, telemetry (three frames per sample,
joined on their sequence number) to ``on_telemetry``.

:meth:`DeviceLink.push` returns only when the device acknowledged the exact CRC-32 of the table or envelope sent; on
a refusal or silence it resends (a table's missing rows when the device says which, the whole transfer under a new
transfer id otherwise) until ``timeout_s``, then raises :class:`PushError`. A refusal for the safety limits is final
(the same table would be refused again). An envelope goes whole (:mod:`device_bridge.envelope_wire`; the device names
no missing frames then, only how many, and the data frames are sent again).
"""

from __future__ import annotations

import contextlib
import logging
import math
import queue
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Self

import can

from controller_core.envelope import Envelope, envelope_of_table
from controller_core.table import ParameterTable
from device_bridge.bus_threads import BusThreads
from device_bridge.clock import WALL_CLOCK, Clock
from device_bridge.envelope_wire import WireEnvelope, envelope_begin_frame, envelope_commit_frame
from device_bridge.host_calibration import CalibrationClient
from device_bridge.protocol import (
    FAULT_MASK,
    TELEMETRY_PERIOD_S,
    TEMPERATURE_UNKNOWN_RAW,
    TRANSFER_IDS,
    AckResult,
    Command,
    Fault,
    LegTorqueMode,
    LinkMode,
    Mode,
    ProtocolError,
    decode,
    encode,
    physical,
)

_DEG = math.pi / 180.0
STALE_STATUS_S = 1.0     # a status this much later than the link's usual delay is history, not the leg's state now
LAG_FLOOR_RISE = 0.01    # the usual delay (the smallest seen) may rise this much a second (s/s)
RELEARN_S = 5.0          # every frame this long later than the usual delay: the leg's clock stepped back, relearn it
GAP_MEMORY = 1000        # a skipped sample arriving within this many newer ones was overtaken, not lost (10 s)
LONG_SILENCE_S = 300.0   # telemetry back after a silence this long is placed by time (a 16-bit sequence wraps in 655 s)
log = logging.getLogger(__name__)


class PushError(RuntimeError):
    """A push that the device did not acknowledge with the exact CRC (``reason`` says why)."""

    def __init__(self, message: str, reason: str) -> None:
        super().__init__(message)
        self.reason = reason


@dataclass(frozen=True)
class PushResult:
    """A push the device acknowledged: the version and CRC-32 it holds, attempts made, time taken (ms)."""

    version: int
    crc32: int
    attempts: int
    elapsed_ms: float


@dataclass(frozen=True)
class LegState:
    """A real leg's word on itself (DEVICE_LEG): whether each sensor is calibrated, its torque mode, the torque its
    thermal model allows (%, None: not measured)."""

    knee_calibrated: bool
    ankle_calibrated: bool
    loadcell_calibrated: bool
    torque_mode: str
    derating_pct: int | None

    @classmethod
    def from_raw(cls, raw: dict[str, int]) -> LegState:
        bits, code = int(raw["calibrated"]), int(raw["torque_mode"])
        mode = LegTorqueMode(code).name.lower() if code in {m.value for m in LegTorqueMode} else "unknown"
        return cls(bool(bits & 1), bool(bits & 2), bool(bits & 4), mode,
                   None if raw["derating"] == 255 else int(raw["derating"]))


@dataclass(frozen=True)
class DeviceStatus:
    """The device's latest DEVICE_STATUS and DEVICE_HEALTH, with when they arrived (host clocks)."""

    mode: Mode
    fsm_state: int | None
    active_version: int | None
    active_crc32: int | None
    fault_flags: Fault
    temperature_degC: float | None
    pending_version: int | None
    rx_errors: int
    received_monotonic_s: float
    received_unix_s: float
    link_mode: LinkMode = LinkMode.SUPERVISED
    leg: LegState | None = None       # DEVICE_LEG: a real leg's own word; None for the simulated bench


ADAPTIVE_MODE_NAMES = {1: "nominal", 2: "partial", 3: "adaptive", 4: "clamped"}
LEG_BEHAVIOURS = {0: "walking", 1: "standing", 2: "stumble support"}   # TELEMETRY_GAIT's behaviour


@dataclass(frozen=True)
class TaskTelemetry:
    """What an adaptive leg reports of its task: its estimate (None before one) and where its rows are blended."""

    estimated_speed_mps: float | None
    estimated_incline_deg: float | None
    running_speed_mps: float
    running_incline_deg: float
    adaptive_mode: str

    @classmethod
    def from_physical(cls, v: dict[str, float]) -> TaskTelemetry:
        seen = v["estimated_speed"] < 4.09   # all ones: no estimate yet
        return cls(round(v["estimated_speed"], 3) if seen else None, round(v["estimated_incline"], 2) if seen else None,
                   round(v["running_speed"], 3), round(v["running_incline"], 2),
                   ADAPTIVE_MODE_NAMES.get(int(v["adaptive_mode"]), "unknown"))


@dataclass(frozen=True)
class TelemetrySample:
    """One telemetry sample (SI). ``seq`` counts up without wrapping; ``fsm_state`` is None outside ACTIVE;
    ``task`` only while an envelope runs."""

    seq: int
    fsm_state: int | None
    mode: Mode
    knee_angle_rad: float
    knee_velocity_rad_s: float
    knee_torque_Nm: float
    ankle_angle_rad: float
    ankle_velocity_rad_s: float
    ankle_torque_Nm: float
    load_N: float
    ankle_moment_Nm: float
    received_unix_s: float
    task: TaskTelemetry | None = None
    behaviour: str = "walking"

    def to_json(self) -> dict:
        """Display units with the unit in each name (deg, deg/s, N·m, N, m/s)."""
        d = 1.0 / _DEG
        task = {} if self.task is None else {
            "estimated_speed_mps": self.task.estimated_speed_mps, "estimated_incline_deg": self.task.estimated_incline_deg,
            "running_speed_mps": self.task.running_speed_mps, "running_incline_deg": self.task.running_incline_deg,
            "adaptive_mode": self.task.adaptive_mode}
        return {**task,
            "seq": self.seq, "fsm_state": self.fsm_state, "mode": self.mode.name.lower(),
            "knee_angle_deg": round(self.knee_angle_rad * d, 2),
            "knee_velocity_deg_s": round(self.knee_velocity_rad_s * d, 1),
            "knee_torque_Nm": round(self.knee_torque_Nm, 2),
            "ankle_angle_deg": round(self.ankle_angle_rad * d, 2),
            "ankle_velocity_deg_s": round(self.ankle_velocity_rad_s * d, 1),
            "ankle_torque_Nm": round(self.ankle_torque_Nm, 2),
            "load_N": round(self.load_N, 1), "ankle_moment_Nm": round(self.ankle_moment_Nm, 2),
            "leg_behaviour": self.behaviour,
            "received_unix_s": round(self.received_unix_s, 4),
        }


class _TelemetryJoiner:
    """Joins the three frames of a sample by their 16-bit sequence number and unwraps it: to the nearest of the last
    sample's (a repeat or a sample overtaken on the way, QoS 1 through the broker, lies just behind it), or near a
    number the caller estimates from time (a late sample; a stream back after a long silence)."""

    PARTS = ("TELEMETRY_GAIT", "TELEMETRY_KNEE", "TELEMETRY_ANKLE")

    def __init__(self) -> None:
        self._tasks: dict[int, TaskTelemetry] = {}   # TELEMETRY_TASK, sent before the three parts of its sample
        self._partial: dict[int, dict[str, dict[str, float]]] = {}
        self._last_full: int | None = None   # unwrapped seq of the last complete sample

    def add_task(self, raw: dict[str, int]) -> None:
        if len(self._tasks) > 64:
            self._tasks.clear()
        self._tasks[raw["seq"]] = TaskTelemetry.from_physical(physical("TELEMETRY_TASK", raw))

    def add(self, name: str, raw: dict[str, int], at_unix_s: float,
            near: int | None = None) -> TelemetrySample | None:
        """One telemetry frame; the sample once its three frames are in. ``at_unix_s``: when the sample was made (now
        for a live one, earlier for a late one); ``near``: an unwrapped sequence number the sample's lies within ±32768
        of (estimated from time), else it lies within ±32768 of the last one joined."""
        seq16 = raw["seq"]
        parts = self._partial.setdefault(seq16, {})
        parts[name] = physical(name, raw)
        if len(parts) < 3:
            if len(self._partial) > 64:   # parts of samples that never completed (lost frames)
                for k in list(self._partial)[:32]:
                    del self._partial[k]
            return None
        del self._partial[seq16]
        if near is None:
            near = self._last_full
        seq = seq16 if near is None else near + ((seq16 - near + 0x8000) & 0xFFFF) - 0x8000
        self._last_full = seq
        g, k, a = parts["TELEMETRY_GAIT"], parts["TELEMETRY_KNEE"], parts["TELEMETRY_ANKLE"]
        state = int(g["fsm_state"])
        return TelemetrySample(
            seq=seq, fsm_state=None if state > 3 else state, mode=Mode(int(g["mode"])),
            knee_angle_rad=k["angle"] * _DEG, knee_velocity_rad_s=k["velocity"] * _DEG, knee_torque_Nm=k["torque"],
            ankle_angle_rad=a["angle"] * _DEG, ankle_velocity_rad_s=a["velocity"] * _DEG, ankle_torque_Nm=a["torque"],
            load_N=g["load"], ankle_moment_Nm=g["ankle_moment"],
            received_unix_s=at_unix_s, task=self._tasks.pop(seq16, None),
            behaviour=LEG_BEHAVIOURS.get(int(g.get("behaviour", 0)), "walking"))


def _check_version(version: int, what: str) -> None:
    if not (isinstance(version, int) and 1 <= version <= 0xFFFF):
        raise ProtocolError(f"{what} version must be an integer in [1, 65535], got {version!r}")


@dataclass(frozen=True)
class _Outgoing:
    """One push: the envelope's raw values (a table's: its one node), its version and CRC, and what the clinic calls
    it in a refusal ("table" for one node)."""

    wire: WireEnvelope
    version: int
    crc: int
    kind: str

    @classmethod
    def of(cls, content: ParameterTable | Envelope, version: int) -> _Outgoing:
        envelope = content if isinstance(content, Envelope) else envelope_of_table(content)
        wire = WireEnvelope.from_envelope(envelope)
        return cls(wire, version, wire.crc32(), "table" if envelope.single_node else "envelope")

    def frames(self, tid: int) -> list[can.Message]:
        return self.wire.frames(tid)

    def begin(self, tid: int) -> can.Message:
        return envelope_begin_frame(tid, self.version, self.crc, self.wire.shape)

    def commit(self, tid: int) -> can.Message:
        return envelope_commit_frame(tid, self.version, self.crc, self.wire.shape)


class DeviceLink(BusThreads):
    """Host end of one device's CAN link (see the module docstring).

    Args:
        bus: an open python-can bus to the device (the link closes it on :meth:`close`). A bus that
            ``delivers_frames`` (the broker link's shared connection) calls the link with its frames from its own
            thread, and the link runs no receive thread.
        heartbeat_period_s: host heartbeat period (s); keep it well under the device's timeout (200 ms). None: the
            bus's own ``heartbeat_period_s`` (the broker link's 50 ms), else 20 ms.
        heartbeat_clock: beat from this shared clock (one thread for many links, at its period) instead of a thread
            of the link's own.
        on_status: called with each :class:`DeviceStatus` (from the receive thread, or the bus's: return quickly).
        on_telemetry: called with each complete :class:`TelemetrySample` (from the same thread).
        on_late_telemetry: called with each sample the leg's bridge kept while the link was down and delivered late
            (a bus with ``on_late``, the broker link): stamped with the time it was made, its sequence number placed
            by the live stream's; the late messages' other frames (old statuses, old acknowledgements) are ignored.
    """

    def __init__(self, bus: can.BusABC, heartbeat_period_s: float | None = None,
                 on_status: Callable[[DeviceStatus], None] | None = None,
                 on_telemetry: Callable[[TelemetrySample], None] | None = None,
                 on_late_telemetry: Callable[[TelemetrySample], None] | None = None,
                 heartbeat_clock: HeartbeatClock | None = None, clock: Clock = WALL_CLOCK) -> None:
        if heartbeat_period_s is None:
            heartbeat_period_s = float(getattr(bus, "heartbeat_period_s", 0.02))
        if not (math.isfinite(heartbeat_period_s) and 0.001 <= heartbeat_period_s <= 1.0):
            raise ValueError(f"heartbeat_period_s must be in [0.001, 1] s, got {heartbeat_period_s!r}")
        self.bus = bus
        self.clock = clock
        self.heartbeat_period_s = heartbeat_period_s
        self.on_status = on_status
        self.on_telemetry = on_telemetry
        self.status: DeviceStatus | None = None
        self.rx_errors = 0
        self.callback_errors = 0
        self.last_heartbeat_sent_s: float | None = None   # host monotonic clock
        self._health: dict[str, float] | None = None
        self._leg_state: LegState | None = None
        self._acks: queue.Queue[dict[str, int]] = queue.Queue()
        self.calibration = CalibrationClient(self._send, clock)   # guided calibration from the clinic
        self._send_lock = threading.Lock()
        self._push_lock = threading.Lock()
        self._transfer_id = 0
        self._heartbeat_paused = threading.Event()
        super().__init__([bus])
        self._joiner = _TelemetryJoiner()
        self.on_late_telemetry = on_late_telemetry
        self._late_joiner = _TelemetryJoiner()
        self._live: tuple[int, float] | None = None   # (seq, Unix s) of the newest live sample: places late ones
        self.late_samples = 0
        self.telemetry_received = 0     # live samples joined
        self.telemetry_missing = 0      # live samples skipped by the sequence (a late delivery may fill them in)
        self._newest_seq: int | None = None
        self._gaps: set[int] = set()      # skipped sequence numbers that may still arrive
        self.stale_statuses = 0           # statuses that arrived too late to be the leg's state (see _current)
        self._lag_floor: float | None = None
        self._lag_at = 0.0
        self._late_run: tuple[float, float] | None = None   # every frame late since (arrival, smallest lag): _current
        self.relearned_delays = 0          # times the link's usual delay was learned again (a clock step back)
        if hasattr(bus, "on_late"):
            bus.on_late = self._on_late
        self._heartbeat_counter = 0
        self._clock = heartbeat_clock
        self._pushed = bool(getattr(bus, "delivers_frames", False))
        if not self._pushed:
            self._threads.append(threading.Thread(target=self._rx_loop, name="can-rx", daemon=True))
        if heartbeat_clock is None:
            self._threads.append(threading.Thread(target=self._heartbeat_loop, name="can-heartbeat", daemon=True))

    def start(self) -> Self:
        super().start()
        if self._pushed:       # from now on, as a receive thread would begin reading now
            self.bus.on_frames = self.receive
        if self._clock is not None:
            self._clock.add(self)
        return self

    def close(self) -> None:
        if self._clock is not None:
            self._clock.remove(self)
        if self._pushed:
            self.bus.on_frames = None
        super().close()

    # ------------------------------------------------------------------------------------------ sending

    def _send(self, msg: can.Message) -> None:
        with self._send_lock:
            self.bus.send(msg)

    def _send_all(self, frames: list[can.Message]) -> None:
        """Frames back to back; in one message where the bus carries batches (the broker link: a transfer's hundreds
        of frames as one MQTT message instead of hundreds)."""
        with self._send_lock:
            if callable(getattr(self.bus, "send_batch", None)):
                self.bus.send_batch(frames)
            else:
                for f in frames:
                    self.bus.send(f)

    def pause_heartbeat(self, paused: bool = True) -> None:
        """Stop (or resume) sending heartbeats: for tests and drills of the device's safe mode."""
        if paused:
            self._heartbeat_paused.set()
        else:
            self._heartbeat_paused.clear()

    def command(self, command: Command) -> None:
        """Send a DEVICE_COMMAND (enter/leave safe mode, request status, the lost-link mode)."""
        self._send(encode("DEVICE_COMMAND", {"command": int(command)}))

    def beat(self) -> None:
        """Send one heartbeat (none while paused)."""
        if self._heartbeat_paused.is_set() or self._stop.is_set():
            return
        # a full or closing bus loses the beat: the device's watchdog is the safety net, not this loop
        with contextlib.suppress(can.CanError):
            self._send(encode("HOST_HEARTBEAT", {"counter": self._heartbeat_counter}))
            self.last_heartbeat_sent_s = self.clock.monotonic()
        self._heartbeat_counter = (self._heartbeat_counter + 1) & 0xFFFF

    def _heartbeat_loop(self) -> None:
        clock = self.clock
        next_t = clock.monotonic()
        while not self._stop.is_set():
            self.beat()
            next_t += self.heartbeat_period_s
            clock.wait(self._stop, next_t - clock.monotonic())

    # ------------------------------------------------------------------------------------------ receiving

    def _rx_loop(self) -> None:
        while not self._stop.is_set():
            try:
                msg = self.bus.recv(timeout=0.05)
            except can.CanError:
                if self._stop.is_set():
                    return
                raise
            if msg is not None:
                self.receive([msg])

    def receive(self, frames: list[can.Message]) -> None:
        """Frames from the device, in order: decoded and dispatched (the receive thread, the shared connection's, or a
        stepped rig's)."""
        for msg in frames:
            decoded = self._decoded(msg)
            if decoded is None:
                continue
            try:
                self._dispatch(*decoded, current=self._current(msg.timestamp or self.clock.time()))
            except Exception:   # a failing callback must not stop the link (acknowledgements, heartbeats)
                self.callback_errors += 1
                log.exception("device link: a status or telemetry callback failed")

    def _decoded(self, msg: can.Message) -> tuple[str, dict[str, int]] | None:
        """A frame's message name and raw values; None for an id this protocol does not define, or a malformed frame
        (counted in :attr:`rx_errors`)."""
        try:
            return decode(msg)
        except ProtocolError:
            self.rx_errors += 1
            return None

    def _dispatch(self, name: str, raw: dict[str, int], current: bool = True) -> None:
        """One decoded frame; ``current``: it is the leg's state now (a status that is not is history, :meth:`_current`)."""
        if name == "TABLE_ACK":
            self._acks.put(raw)
        elif name == "CALIBRATION_RESULT":
            if current:
                self.calibration.add(raw)
        elif name == "TELEMETRY_TASK":
            self._joiner.add_task(raw)
        elif name in _TelemetryJoiner.PARTS:
            now = self.clock.time()
            # after a silence of minutes (the link was down while the leg walked) the sequence moved on with time
            near = None if self._live is None or now - self._live[1] < LONG_SILENCE_S else \
                self._live[0] + round((now - self._live[1]) / TELEMETRY_PERIOD_S)
            sample = self._joiner.add(name, raw, now, near=near)
            if sample is not None:
                self._count(sample.seq)
                self._live = (sample.seq, sample.received_unix_s)
                if self.on_telemetry is not None:
                    self.on_telemetry(sample)
        elif name == "DEVICE_HEALTH":
            self._health = dict(raw)
        elif name == "DEVICE_LEG":
            self._leg_state = LegState.from_raw(raw)
        elif name == "DEVICE_STATUS":
            if current:
                self._on_status(raw)
            else:
                self.stale_statuses += 1

    def _current(self, made_unix_s: float) -> bool:
        """Whether a frame that left the leg's bus at ``made_unix_s`` (the leg's clock, carried by the broker link; a
        CAN bus stamps its arrival) is the leg's state now: it took at most :data:`STALE_STATUS_S` longer than the
        link's usual delay, the smallest seen (let rise :data:`LAG_FLOOR_RISE` s a second, so a clock step or a slower
        path is learned). What was in flight when a link broke arrives first when it returns: such a status is
        history, not what the leg does now. The usual delay is learned from the frames themselves, so the very first
        ones (an instance's queue at the broker after a restart) cannot be judged."""
        now = self.clock.time()
        lag = now - made_unix_s
        if self._lag_floor is None:
            self._lag_floor = lag
        else:
            self._lag_floor = min(self._lag_floor + LAG_FLOOR_RISE * max(now - self._lag_at, 0.0), lag)
        self._lag_at = now
        # what a link delivers late after a cut drains in a burst among live frames; when every frame for RELEARN_S is
        # late, it is the leg's clock that stepped back (or a slower path): learn the delay again rather than go deaf
        # for 100 s per second of the step. (A clock set forward lowers the floor at once; a time ahead of its arrival
        # by more than CLOCK_AHEAD_S never reaches here: the broker link takes it at its arrival.)
        if lag - self._lag_floor <= STALE_STATUS_S:
            self._late_run = None
        else:
            since, smallest = self._late_run if self._late_run is not None else (now, lag)
            self._late_run = (since, min(smallest, lag))
            if now - since >= RELEARN_S:
                self._lag_floor, self._late_run = min(smallest, lag), None
                self.relearned_delays += 1
        return lag - self._lag_floor <= STALE_STATUS_S

    def _count(self, seq: int) -> None:
        """Count a live sample; one the sequence skipped is missing until it arrives (overtaken on the way), or for
        good once :data:`GAP_MEMORY` newer samples came."""
        self.telemetry_received += 1
        newest = self._newest_seq
        if newest is not None and seq <= newest:
            if seq >= newest - GAP_MEMORY and seq in self._gaps:
                self._gaps.discard(seq)
                self.telemetry_missing -= 1
            return
        if newest is not None and seq > newest + 1:
            self.telemetry_missing += seq - newest - 1
            self._gaps.update(range(max(newest + 1, seq - GAP_MEMORY), seq))
            if len(self._gaps) > GAP_MEMORY:      # numbers too far behind to be filled any more: forgotten
                self._gaps = {g for g in self._gaps if g >= seq - GAP_MEMORY}
        self._newest_seq = seq

    def _on_late(self, records: list[tuple[float, list[can.Message]]]) -> None:
        """A late message from the leg's bridge (the broker's thread): its telemetry, joined apart from the live stream,
        each sample's sequence number placed near where the live stream puts the time it was made."""
        for at, frames in records:
            near = None if self._live is None else self._live[0] + round((at - self._live[1]) / TELEMETRY_PERIOD_S)
            for msg in frames:
                decoded = self._decoded(msg)
                if decoded is None:
                    continue
                name, raw = decoded
                if name == "TELEMETRY_TASK":
                    self._late_joiner.add_task(raw)
                elif name in _TelemetryJoiner.PARTS:
                    sample = self._late_joiner.add(name, raw, at_unix_s=at, near=near)
                    if sample is not None:
                        self.late_samples += 1
                        if self.on_late_telemetry is not None:
                            try:
                                self.on_late_telemetry(sample)
                            except Exception:
                                self.callback_errors += 1
                                log.exception("device link: the late telemetry callback failed")

    def _on_status(self, raw: dict[str, int]) -> None:
        h = self._health or {}
        try:
            mode = Mode(raw["mode"])
        except ValueError:
            self.rx_errors += 1
            return
        has_table = raw["active_crc32"] != 0 or raw["active_version"] != 0
        temp_raw = h.get("temperature", TEMPERATURE_UNKNOWN_RAW)
        status = DeviceStatus(
            mode=mode, fsm_state=raw["fsm_state"] if raw["fsm_state"] <= 3 else None,
            active_version=raw["active_version"] if has_table else None,
            active_crc32=raw["active_crc32"] if has_table else None,
            fault_flags=Fault(int(h.get("fault_flags", 0)) & FAULT_MASK),
            temperature_degC=None if temp_raw == TEMPERATURE_UNKNOWN_RAW else temp_raw - 40.0,
            pending_version=int(h["pending_version"]) or None if h else None,
            rx_errors=int(h.get("rx_errors", 0)),
            received_monotonic_s=self.clock.monotonic(), received_unix_s=self.clock.time(),
            link_mode=LinkMode.AUTONOMOUS if h.get("link_mode") == LinkMode.AUTONOMOUS else LinkMode.SUPERVISED,
            leg=self._leg_state)
        self.status = status
        if self.on_status is not None:
            self.on_status(status)

    # ------------------------------------------------------------------------------------------ push

    def push(self, content: ParameterTable | Envelope, version: int, timeout_s: float | None = None,
             ack_timeout_s: float | None = None) -> PushResult:
        """Send a table or a whole envelope as ``version`` and wait until the device acknowledges its exact CRC-32
        (all or nothing: until then the device runs what it ran before). The one push: a table goes out as the
        envelope of its one node (axes, the node and their checks), which the device runs as a table.

        Args:
            content: the (approved) table or envelope; rounded to the wire quanta, so the CRC is that of the rounded
                values.
            version: its version, 1–65535 (the backend uses the version's id).
            timeout_s: give up after this long (s; default 2 for a table, 3 for an envelope).
            ack_timeout_s: how long to wait for one acknowledgement before resending (s). The device answers
                within its 1 ms control period; 10 ms for a table (20 for an envelope) on a CAN bus leaves room for
                a busy host, and an answer that comes later only costs a repeated commit, which the device answers
                again (it is idempotent). A bus with a ``round_trip_s`` (the broker link) is waited on at least that
                long: re-asking sooner than the answer can come restarts whole transfers for nothing.

        Raises:
            ProtocolError: a value does not fit the wire format, or the envelope the link (more than 64 nodes);
                nothing sent.
            PushError: refused for the safety limits or the neighbour rule (``reason`` "safety_limit"), aborted by a
                device error ("device_error"), or no matching acknowledgement before ``timeout_s`` ("timeout":
                unconfirmed, the device may have taken it as the acknowledgement was lost).
        """
        transfer = _Outgoing.of(content, version)
        _check_version(version, transfer.kind)
        one = transfer.kind == "table"
        with self._push_lock:
            return self._push(transfer, version, (2.0 if one else 3.0) if timeout_s is None else timeout_s,
                              self._ack_wait(ack_timeout_s, 0.01 if one else 0.02))

    def _ack_wait(self, given: float | None, on_can_s: float) -> float:
        """The acknowledgement wait: as given, else ``on_can_s`` or the bus's own round trip if longer."""
        return given if given is not None else max(on_can_s, float(getattr(self.bus, "round_trip_s", 0.0)))

    def _next_transfer_id(self) -> int:
        self._transfer_id = (self._transfer_id + 1) % TRANSFER_IDS
        return self._transfer_id

    def _wait_ack(self, tid: int, version: int, until: float) -> dict[str, int] | None:
        while True:
            left = until - self.clock.monotonic()
            if left <= 0:
                return None
            try:
                ack = self.clock.get(self._acks, left)
            except queue.Empty:
                return None
            if ack["transfer_id"] == tid and ack["version_low"] == version & 0xFF:
                return ack   # anything else is a late answer to an earlier attempt

    def _push(self, transfer: _Outgoing, version: int, timeout_s: float, ack_timeout_s: float) -> PushResult:
        try:
            return self._transfer(transfer, version, timeout_s, ack_timeout_s)
        except can.CanError as exc:   # the link went down under the transfer (the broker out of reach)
            raise PushError(f"the link to the device went down during the transfer ({exc}); unconfirmed: the "
                            f"device's next status tells whether it took the {transfer.kind}, whole, or kept what it "
                            "ran", "link_lost") from exc

    def _transfer(self, transfer: _Outgoing, version: int, timeout_s: float, ack_timeout_s: float) -> PushResult:
        crc = transfer.crc
        clock = self.clock
        t0 = clock.monotonic()
        deadline = t0 + timeout_s
        while not self._acks.empty():
            self._acks.get_nowait()
        attempts = 0
        last_reason = "no answer from the device"
        while clock.monotonic() < deadline:
            attempts += 1
            tid = self._next_transfer_id()
            frames = transfer.frames(tid)
            commit = transfer.commit(tid)
            self._send_all([transfer.begin(tid), *frames, commit])
            silent = 0
            while clock.monotonic() < deadline:
                ack = self._wait_ack(tid, version, min(deadline, clock.monotonic() + ack_timeout_s))
                if ack is None:
                    silent += 1
                    if silent > 2:      # begin lost, or the device is gone: start over with a new transfer id
                        break
                    self._send(commit)  # the commit or its answer was lost: ask again (idempotent)
                    continue
                result = AckResult(ack["result"]) if ack["result"] in AckResult._value2member_map_ else None
                if result == AckResult.STAGED:
                    if ack["crc32"] == crc:
                        return PushResult(version=version, crc32=crc, attempts=attempts,
                                          elapsed_ms=(clock.monotonic() - t0) * 1e3)
                    last_reason = f"the device acknowledged CRC {ack['crc32']:08x}, expected {crc:08x}"
                    self._send(commit)
                    continue
                if result == AckResult.MISSING_ROWS:   # the device keeps the nodes it has checked: send the data again
                    last_reason = f"{ack['missing_rows']} frame(s) were lost"
                    self._send_all([*frames, commit])
                    continue
                if result == AckResult.SAFETY_LIMIT:
                    rule = " or two neighbouring nodes break the neighbour rule" if transfer.kind == "envelope" else ""
                    raise PushError(f"the device refused the {transfer.kind}: a value is outside its own safety "
                                    f"limits{rule}", "safety_limit")
                if result == AckResult.DEVICE_ERROR:
                    raise PushError(f"the device failed while receiving the {transfer.kind} and aborted it (fault "
                                    "receive_error); it keeps running what it ran before", "device_error")
                last_reason = f"the device refused the transfer ({result.name.lower() if result else ack['result']})"
                break
        raise PushError(f"no acknowledgement of CRC {crc:08x} within {timeout_s:g} s after {attempts} attempt(s): "
                        f"{last_reason}; unconfirmed: the device's next status tells whether it took the "
                        f"{transfer.kind}", "timeout")


class HeartbeatClock(BusThreads):
    """One thread that beats for many links every ``period_s`` (s). For links whose send only queues the frame (the
    broker link's shared connection: paho's publish), so one leg cannot hold back another's beats; a CAN bus's send
    can block on a full adapter, so such a link keeps a thread of its own. Ours because it is one loop over a list."""

    def __init__(self, period_s: float, clock: Clock = WALL_CLOCK) -> None:
        if not (math.isfinite(period_s) and 0.001 <= period_s <= 1.0):
            raise ValueError(f"period_s must be in [0.001, 1] s, got {period_s!r}")
        super().__init__([])
        self.period_s = period_s
        self.clock = clock
        self._links: tuple[DeviceLink, ...] = ()     # replaced whole, so the loop reads it without a lock
        self._lock = threading.Lock()
        self._threads = [threading.Thread(target=self._loop, name="heartbeat-clock", daemon=True)]

    def add(self, link: DeviceLink) -> None:
        with self._lock:
            self._links = (*self._links, link)

    def remove(self, link: DeviceLink) -> None:
        with self._lock:
            self._links = tuple(x for x in self._links if x is not link)

    def beat(self) -> None:
        """One beat for every link (the thread's round; a stepped rig calls it at the period)."""
        for link in self._links:
            link.beat()

    def _loop(self) -> None:
        clock = self.clock
        next_t = clock.monotonic()
        while not self._stop.is_set():
            self.beat()
            next_t += self.period_s
            clock.wait(self._stop, next_t - clock.monotonic())
