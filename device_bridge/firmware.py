"""The code that runs on the leg: table reception, its own safety check, double buffering, heartbeat watchdog,
safe mode, status and telemetry.

:class:`DeviceFirmware` is pure: it is fed frames (:meth:`DeviceFirmware.receive`) and control ticks
(:meth:`DeviceFirmware.tick`) with the time they happen at, and returns the frames to send and the joint torques.
It does no I/O, so every fault path is tested deterministically; :mod:`device_bridge.device_node` runs it on a bus.

Three table buffers: the one being received, the staged one (complete, CRC-verified, safety-checked,
acknowledged) and the active one the state machine runs. A buffer holds one kind of thing, an envelope
(:mod:`device_bridge.envelope_wire`): a fixed-task table is the envelope of one node, whose limits the device
re-checks and which it runs as a table; for an envelope of more nodes the device re-checks every node's limits and
the neighbour rule with its own settings (building :class:`controller_core.envelope_blend.EnvelopeBlender` is that
check) and runs the adaptive controller (:mod:`controller_core.adaptive`), whose rows change at heel strike and, for the
states still to come in a stride, once the stride's own foot-flat slope is in, never under a running state. A staged
table becomes active at the next heel strike (the state machine's swing → stance-flexion transition on load), or
at once when the leg is not walking (no table yet, safe mode, no sensors, or no load-triggered heel strike for
``idle_switch_s``). A machine that starts while the leg is not walking, or takes over from one that stood, starts
standing (the joints held where they are) until the person moves or lifts the leg. Loss, corruption, reordering, a
bad CRC, a refused limit or a timeout only ever discard the buffer being received: the active table runs on
untouched, so a mixed table cannot exist.

The host's heartbeat is watched on every tick: when none arrived for ``heartbeat_timeout_s``, the device raises
HEARTBEAT_LOST on that tick, and what else it does is the device's link mode (:class:`~device_bridge.protocol.LinkMode`,
set by the host's LINK_SUPERVISED / LINK_AUTONOMOUS commands and reported in DEVICE_HEALTH). *Supervised* (the
default, tuning in the clinic): it drops into safe mode (passive, holding a loaded knee against flexion:
:mod:`controller_core.safe_mode`) and leaves it only on a
new valid table (committed after safe mode was entered) or an explicit LEAVE_SAFE_MODE command while the host is
alive and a table is held. *Autonomous* (daily life, far from any server): it runs on with the table or envelope it
holds, and clears the fault when heartbeats come back. Either way a staged table waits for a live host. The link
mode is kept in the device's memory with its tables: a device that restarts starts supervised, with no table.

Times are seconds on the device's monotonic clock; torques N·m; angles rad inside, deg on the wire.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import can

from controller_core.adaptive import AdaptiveController
from controller_core.envelope import DEFAULT_STEPS, NeighbourSteps
from controller_core.envelope_blend import EnvelopeBlender
from controller_core.fsm import (
    ActuatorLimits,
    GaitState,
    Impedance,
    ImpedanceSchedule,
    SensorSample,
    StateMachineController,
)
from controller_core.safe_mode import SafeModeController, SafeModeParameters
from controller_core.table import DEFAULT_LIMITS, SafetyLimitError, SafetyLimits, check_table
from controller_core.task_estimator import TaskEstimator
from device_bridge.envelope_wire import MAX_NODES, DeviceEnvelope, EnvelopeReceiver
from device_bridge.protocol import (
    TELEMETRY_PERIOD_S,
    TEMPERATURE_UNKNOWN_RAW,
    AckResult,
    Command,
    DeviceTable,
    Fault,
    LinkMode,
    Mode,
    ProtocolError,
    decode,
    encode,
    encode_scaled,
)
from device_bridge.remote_calibration import CalibrationPort, RemoteCalibration

ADAPTIVE_MODES = {"nominal": 1, "partial": 2, "adaptive": 3, "clamped": 4}   # TELEMETRY_TASK.adaptive_mode


@dataclass(frozen=True)
class FirmwareConfig:
    """Device-side settings (s, N·m·s/rad).

    Attributes:
        heartbeat_timeout_s: safe mode when no host heartbeat arrived for this long.
        transfer_timeout_s: a transfer of one node (a fixed-task table) not committed this long after its begin is
            dropped.
        envelope_transfer_timeout_s: the same for an envelope of more nodes (ten times the frames, and resends on a
            noisy bus).
        idle_switch_s: without a load-triggered heel strike for this long the leg is not walking, and a staged
            table becomes active at once.
        status_period_s, telemetry_period_s: DEVICE_STATUS/HEALTH and TELEMETRY periods.
        safe_mode: what the leg does in safe mode and without a table: it holds a loaded knee against flexion, lets
            it extend, extends it in swing and holds the ankle near neutral
            (:class:`~controller_core.safe_mode.SafeModeParameters`; a damper alone let a loaded knee fold).
        limits: the safety limits the device enforces itself (the same defaults as the host's).
        neighbour_steps: the envelope neighbour rule the device enforces itself.
        actuator: torque and range limits.
        thigh_length_m, shank_length_m: the patient's hip-to-knee and the leg's knee-to-ankle lengths (m), for the
            task estimator (defaults: a 1.75 m patient by Winter's proportions, the simulated bench's).
        forefoot_m: the foot's forefoot rocker ahead of the ankle (m), for the task estimator's heel-up rule and the
            state machine's early landing on the toe (default
            the simulated bench's foot; None on a leg whose load cell gives no sagittal moment).
        max_speed_step_mps, max_incline_step_deg: the adaptive controller's per-stride rate limit.
    """

    heartbeat_timeout_s: float = 0.2
    transfer_timeout_s: float = 0.5
    envelope_transfer_timeout_s: float = 3.0
    idle_switch_s: float = 2.0
    status_period_s: float = 0.1
    telemetry_period_s: float = TELEMETRY_PERIOD_S
    safe_mode: SafeModeParameters = field(default_factory=SafeModeParameters)
    limits: SafetyLimits = DEFAULT_LIMITS
    neighbour_steps: NeighbourSteps = DEFAULT_STEPS
    actuator: ActuatorLimits = field(default_factory=ActuatorLimits)
    thigh_length_m: float = 0.42875
    shank_length_m: float = 0.4305
    forefoot_m: float | None = 0.1295
    max_speed_step_mps: float = 0.15
    max_incline_step_deg: float = 3.0


@dataclass(frozen=True)
class HeldTable:
    """A verified envelope: its version, CRC-32, decoded values and controller schedule (one node's table, or the
    nominal blend of more), and the blender that adapts it (None for one node: nothing to blend)."""

    version: int
    crc32: int
    envelope: DeviceEnvelope
    schedule: ImpedanceSchedule
    blender: EnvelopeBlender | None = None

    @property
    def table(self) -> DeviceTable | None:
        """The one node's table when the envelope is a fixed-task table, else None."""
        return self.envelope.tables[0] if self.blender is None else None


@dataclass(frozen=True)
class Prepared:
    """A commit verified ahead of :meth:`DeviceFirmware.receive` (:meth:`DeviceFirmware.prepare`): the transfer it
    was verified from, and the table or envelope ready to stage, or the refusal."""

    rx: object
    outcome: HeldTable | AckResult


@dataclass
class _LastCommit:
    transfer_id: int
    version: int
    crc32: int


class DeviceFirmware:
    """The leg's firmware (see the module docstring).

    Attributes:
        mode_: NO_TABLE, ACTIVE, SAFE or CALIBRATING (guided calibration from the clinic: no torque).
        calibration_: the calibration from the clinic (:mod:`device_bridge.remote_calibration`; a leg with sensors
            to calibrate gives its :class:`~device_bridge.remote_calibration.CalibrationPort`).
        active_: the table the state machine runs (None before the first).
        staged_: a verified table waiting for the next heel strike.
        faults_: current fault flags.
        rx_errors_: malformed frames seen.
        safe_mode_entered_s_: when safe mode was last entered (None if never).
        last_heartbeat_s_: when the host's heartbeat last arrived.
        link_mode_: what a lost host heartbeat does (supervised: safe mode; autonomous: nothing but the fault).
        temperature_degC_: the hottest actuator's case temperature the leg reports (None: not measured).
        leg_state_: what a real leg says of itself (its calibration, torque mode, thermal derating), sent with each
            status in DEVICE_LEG; None for the simulated bench.
        leg_drives_: whether the leg gives the torques asked (False: a real leg not yet calibrated, which gives none;
            the telemetry then says 0 N·m, as the leg does).
        hardware_fault_: the reason of the last hardware fault (:meth:`hardware_fault`), None if none.
    """

    def __init__(self, config: FirmwareConfig | None = None, now_s: float = 0.0,
                 calibration: CalibrationPort | None = None) -> None:
        self.config = config or FirmwareConfig()
        self.calibration_ = RemoteCalibration(calibration)
        self.mode_ = Mode.NO_TABLE
        self.active_: HeldTable | None = None
        self.staged_: HeldTable | None = None
        self.faults_ = Fault.NO_TABLE
        self.rx_errors_ = 0
        self.safe_mode_entered_s_: float | None = None
        self.last_heartbeat_s_ = now_s   # the host gets one timeout from boot to appear
        self.link_mode_ = LinkMode.SUPERVISED
        self.temperature_degC_: float | None = None
        self.leg_state_: dict[str, int] | None = None
        self.leg_drives_ = True        # False: a real leg not yet calibrated gives no torque (device_bridge.osl.leg)
        self.hardware_fault_: str | None = None
        self.controller_: StateMachineController | AdaptiveController | None = None
        self._safe = SafeModeController(self.config.safe_mode, self.config.actuator)   # safe mode, and no table
        self._rx: EnvelopeReceiver | None = None
        self._last_commit: _LastCommit | None = None
        self._last_heel_strike_s = -math.inf
        self._now_s = now_s                # the device clock at the last tick or frame
        self._next_status_s = now_s
        self._next_telemetry_s = now_s
        self._status_counter = 0
        self._telemetry_seq = 0

    # ------------------------------------------------------------------------------------------ frames in

    def receive(self, msg: can.Message, now_s: float, prepared: Prepared | None = None) -> list[can.Message]:
        """Handle one received frame; returns the frames to send in reply. ``prepared``: :meth:`prepare`'s work on it.

        Fails safe: any error while handling a frame aborts the transfer being received (a commit is answered
        DEVICE_ERROR), flags RECEIVE_ERROR and returns; the active and staged tables and the control loop are
        untouched."""
        self._now_s = now_s
        try:
            decoded = decode(msg)
        except ProtocolError:
            self.rx_errors_ += 1
            self.faults_ |= Fault.MALFORMED_FRAME
            return []
        if decoded is None:
            return []
        name, raw = decoded
        try:
            return self._handle(name, raw, now_s, prepared)
        except Exception:
            self._rx = None   # a later frame of it meets no transfer; its commit is answered UNKNOWN_TRANSFER
            self.rx_errors_ += 1
            self.faults_ |= Fault.RECEIVE_ERROR
            if name == "ENVELOPE_COMMIT":
                return [self._refuse(raw.get("transfer_id", 0), AckResult.DEVICE_ERROR, raw.get("version", 0))]
            return []

    def _handle(self, name: str, raw: dict[str, int], now_s: float, prepared: Prepared | None) -> list[can.Message]:
        if name == "HOST_HEARTBEAT":
            self.last_heartbeat_s_ = now_s
            return []
        if name == "ENVELOPE_BEGIN":
            n_s, n_i = raw["n_speeds"], raw["n_inclines"]
            if not (n_s == n_i == 1 or (min(n_s, n_i) >= 2 and n_s * n_i <= MAX_NODES)):   # one node, or a grid
                self._rx = None
                return [self._ack(raw["transfer_id"], AckResult.MALFORMED, version=raw["version"])]
            self._rx = EnvelopeReceiver(raw["transfer_id"], raw["version"], raw["crc32"], n_s, n_i, now_s)
            return []
        if name in ("ENVELOPE_AXIS", "ENVELOPE_ROW", "ENVELOPE_THRESHOLDS_A", "ENVELOPE_THRESHOLDS_B", "ENVELOPE_STUMBLE",
                    "ENVELOPE_LANDING", "ENVELOPE_CHECK"):
            rx = self._rx
            if rx is not None and raw["transfer_id"] == rx.transfer_id:
                rx.add(name, raw)
            return []
        if name == "ENVELOPE_COMMIT":
            return [self._commit(raw, prepared)]
        if name == "DEVICE_COMMAND":
            return self._command(raw["command"], now_s)
        if name == "CALIBRATION_COMMAND":
            return self._calibration_command(raw, now_s)
        return []

    def _ack(self, transfer_id: int, result: AckResult, *, crc32: int = 0, missing: int = 0,
             version: int = 0) -> can.Message:
        # a refusal carries CRC 0, so that no single corrupted bit can turn it into a believable acknowledgement
        return encode("TABLE_ACK", {"transfer_id": transfer_id, "result": int(result), "missing_rows": missing,
                                    "crc32": crc32 if result == AckResult.STAGED else 0,
                                    "version_low": version & 0xFF})

    def _stage(self, tid: int, held: HeldTable) -> can.Message:
        """Keep a verified envelope for the next heel strike and acknowledge it with its CRC."""
        self.staged_ = held
        self._last_commit = _LastCommit(tid, held.version, held.crc32)
        self.faults_ &= ~(Fault.TABLE_REFUSED | Fault.RECEIVE_ERROR)
        return self._ack(tid, AckResult.STAGED, crc32=held.crc32, version=held.version)

    def _unknown_or_repeat(self, tid: int, version: int, crc: int) -> can.Message:
        last = self._last_commit
        if last is not None and (last.transfer_id, last.version, last.crc32) == (tid, version, crc) and any(
                h is not None and h.crc32 == crc and h.version == version for h in (self.staged_, self.active_)):
            return self._ack(tid, AckResult.STAGED, crc32=crc, version=version)   # our acknowledgement was lost
        return self._ack(tid, AckResult.UNKNOWN_TRANSFER, version=version)

    def _commit(self, raw: dict[str, int], prepared: Prepared | None) -> can.Message:
        """All or nothing: every frame, the CRC over all of them, every node's limits and the neighbour rule."""
        tid, version, crc = raw["transfer_id"], raw["version"], raw["crc32"]
        rx = self._rx
        if rx is None or rx.transfer_id != tid:
            return self._unknown_or_repeat(tid, version, crc)
        if (rx.version, rx.crc32, rx.n_speeds, rx.n_inclines) != (version, crc, raw["n_speeds"], raw["n_inclines"]):
            self._rx = None
            return self._refuse(tid, AckResult.MALFORMED, version)
        missing = rx.missing()
        if missing:   # the count of missing frames: the host sends the transfer's data again
            return self._ack(tid, AckResult.MISSING_ROWS, missing=min(missing, 0xFFFF), version=version)
        self._rx = None
        outcome = prepared.outcome if prepared is not None and prepared.rx is rx else self._verify(rx)
        if isinstance(outcome, AckResult):
            return self._refuse(tid, outcome, version)
        return self._stage(tid, outcome)

    def _verify(self, rx: EnvelopeReceiver) -> HeldTable | AckResult:
        """A complete envelope transfer checked (CRC, every node's limits, the neighbour rule, the nominal task inside
        the grid) and its blender built (none for one node: a table), or the refusal; changes nothing."""
        wire = rx.wire()
        if wire.crc32() != rx.crc32:
            return AckResult.CRC_MISMATCH
        try:
            device = wire.to_device()
        except ValueError:
            return AckResult.SAFETY_LIMIT
        if rx.n_nodes == 1:
            [table] = device.tables
            if device.nominal != (device.speeds_mps[0], device.inclines_deg[0]):
                return AckResult.MALFORMED   # a table's task is its node's: not a transfer the host can have built
            if check_table(table, self.config.limits):
                return AckResult.SAFETY_LIMIT
            return HeldTable(version=rx.version, crc32=rx.crc32, envelope=device,
                             schedule=ImpedanceSchedule.from_table(table, self.config.limits))
        try:
            blender = EnvelopeBlender(device.speeds_mps, device.inclines_deg, device.tables, self.config.limits,
                                      self.config.neighbour_steps)
            nominal = blender.at(*device.nominal)
        except (SafetyLimitError, ValueError):
            return AckResult.SAFETY_LIMIT
        if nominal.clamped:   # the nominal task lies outside the grid: not an envelope the host can have built
            return AckResult.MALFORMED
        return HeldTable(version=rx.version, crc32=rx.crc32, envelope=device, schedule=nominal.schedule,
                         blender=blender)

    def prepare(self, msg: can.Message) -> Prepared | None:
        """The slow half of a commit (CRC, every limit, an envelope's blender: milliseconds on a small computer) done
        before the caller takes the firmware for :meth:`receive`, so the control loop never waits on it: called on the
        receive thread, the only one that adds frames to a transfer; it changes nothing. None for any other frame, or
        a transfer that is not complete (``receive`` answers those). ``receive`` uses the result only if the
        transfer is still the current one (the control thread may have timed it out meanwhile)."""
        try:
            decoded = decode(msg)
        except ProtocolError:
            return None
        if decoded is None or decoded[0] != "ENVELOPE_COMMIT":
            return None
        raw = decoded[1]
        rx = self._rx
        try:
            if rx is not None and raw["transfer_id"] == rx.transfer_id \
                    and (rx.version, rx.crc32) == (raw["version"], raw["crc32"]) and not rx.missing():
                return Prepared(rx, self._verify(rx))
        except Exception:   # receive() meets the same error and fails safe (DEVICE_ERROR)
            return None
        return None

    def _refuse(self, tid: int, result: AckResult, version: int) -> can.Message:
        self.faults_ |= Fault.TABLE_REFUSED
        return self._ack(tid, result, version=version)

    def _command(self, command: int, now_s: float) -> list[can.Message]:
        if command == Command.ENTER_SAFE_MODE:
            self._enter_safe_holding_staged(now_s)
        elif command == Command.LEAVE_SAFE_MODE:
            host_alive = now_s - self.last_heartbeat_s_ <= self.config.heartbeat_timeout_s
            if self.mode_ == Mode.SAFE and self.active_ is not None and host_alive:
                self._run()
        elif command in (Command.LINK_SUPERVISED, Command.LINK_AUTONOMOUS):
            self.link_mode_ = LinkMode.SUPERVISED if command == Command.LINK_SUPERVISED else LinkMode.AUTONOMOUS
        elif command != Command.REQUEST_STATUS:
            self.rx_errors_ += 1
            self.faults_ |= Fault.MALFORMED_FRAME
        return self._status_frames()

    def _calibration_command(self, raw: dict[str, int], now_s: float) -> list[can.Message]:
        """Guided calibration from the clinic (:mod:`device_bridge.remote_calibration`): started only while no table
        runs; the leg is passive while it lasts and in safe mode after it (with no table: no table)."""
        frames, calibrating = self.calibration_.command(raw, may_start=self.mode_ in (Mode.SAFE, Mode.NO_TABLE))
        if calibrating and self.mode_ != Mode.CALIBRATING:
            self.mode_ = Mode.CALIBRATING
        elif not calibrating and self.mode_ == Mode.CALIBRATING:
            self.mode_ = Mode.NO_TABLE
            if self.active_ is not None:
                self._enter_safe(now_s)
        return [*frames, *self._status_frames()]

    def hardware_fault(self, reason: str, now_s: float, thermal: bool) -> list[can.Message]:
        """The leg's hardware failed (an actuator over its thermal or I²t limit, a sensor that cannot be read): safe
        mode at once, the over-temperature (``thermal``) or control-error flag raised, the reason kept, and the status
        sent now so the clinic sees it within one status period. Left like any safe mode: a new table, or the host's
        command once the cause is gone."""
        self._enter_safe_holding_staged(now_s)
        self.faults_ |= Fault.OVER_TEMPERATURE if thermal else Fault.CONTROL_ERROR
        self.hardware_fault_ = reason
        return self._status_frames()

    # ------------------------------------------------------------------------------------------ modes

    def _enter_safe(self, now_s: float) -> None:
        if self.mode_ == Mode.CALIBRATING:    # a calibration under way ends unkept
            self.calibration_.end()
        if self.mode_ != Mode.SAFE:
            self.mode_ = Mode.SAFE
            self.safe_mode_entered_s_ = now_s
            self._safe.reset()      # the load and the knee's hold found afresh

    def _enter_safe_holding_staged(self, now_s: float) -> None:
        """Safe mode on a command, a hardware fault or a lost host: a table verified before it is held as the one to
        run on LEAVE_SAFE_MODE, not a way out of safe mode at the next idle moment."""
        self._enter_safe(now_s)
        if self.staged_ is not None:
            self.active_, self.staged_ = self.staged_, None

    def fit_leg(self, leg: FirmwareConfig) -> None:
        """The leg this firmware drives is described anew (a simulated leg fitted to the patient who wears it): its
        thigh, shank and forefoot (the task estimate, the early landing on the toe) and its actuators' limits and
        drive friction are taken from ``leg``; everything else of the configuration stays. Safe mode, and a table or
        envelope running now, go on with them from the next tick (call between two ticks): safe mode keeps what it
        knows of the load and the knee's hold (a fresh one forgot a lightly loaded knee and gave it the swing's
        extension assist), only its limits are the new drive's."""
        self.config = dataclasses.replace(self.config, thigh_length_m=leg.thigh_length_m,
                                          shank_length_m=leg.shank_length_m, forefoot_m=leg.forefoot_m,
                                          actuator=leg.actuator)
        self._safe.limits = self.config.actuator
        if self.mode_ == Mode.ACTIVE and self.active_ is not None:
            self._take_over(self._controller_for(self.active_))

    def _take_over(self, new: StateMachineController | AdaptiveController) -> None:
        """``new`` runs from the next tick, standing (:meth:`StateMachineController.stand`) where the one it replaces
        stood or the leg is not walking (no heel strike for ``idle_switch_s``: a first table, safe mode left, a leg
        fitted between walks): a fresh machine starts on the walking rows, and stance flexion's bends a standing knee
        toward its equilibrium (+24 N·m of flexion at 3° under the default table) for the half second standing takes
        to be noticed, longer if the knee moves. Standing ends by itself when the person moves or lifts the leg."""
        old = self.controller_
        stood = getattr(getattr(old, "machine_", old), "standing_", False)
        if stood or not self._walking(self._now_s):
            new.stand()
        self.controller_ = new

    def _walking(self, now_s: float) -> bool:
        """A heel strike within ``idle_switch_s`` (safe mode's landings count too)."""
        return now_s - self._last_heel_strike_s <= self.config.idle_switch_s

    def _controller_for(self, held: HeldTable) -> StateMachineController | AdaptiveController:
        cfg = self.config
        if held.blender is None:
            return StateMachineController(held.schedule, cfg.actuator, forefoot_m=cfg.forefoot_m)
        estimator = TaskEstimator(cfg.thigh_length_m, cfg.shank_length_m, forefoot_m=cfg.forefoot_m)
        adaptive = AdaptiveController(held.blender, estimator, held.envelope.nominal, cfg.actuator,
                                      cfg.max_speed_step_mps, cfg.max_incline_step_deg)
        adaptive.use_forefoot(cfg.forefoot_m)     # the machine's early landing on the toe (controller_core.fsm)
        return adaptive

    def _run(self) -> None:
        """Start (or restart) the state machine on the active table or envelope."""
        assert self.active_ is not None
        self._take_over(self._controller_for(self.active_))
        self.mode_ = Mode.ACTIVE
        self.faults_ &= ~(Fault.HEARTBEAT_LOST | Fault.NO_TABLE)

    def _activate_staged(self) -> None:
        staged = self.staged_
        assert staged is not None
        self.staged_ = None
        self.active_ = staged
        self.faults_ &= ~Fault.CONTROL_ERROR
        ctrl = self.controller_
        if self.mode_ == Mode.ACTIVE and ctrl is not None:   # at heel strike: the leg carries on in stance flexion
            if isinstance(ctrl, StateMachineController) and staged.blender is None:
                ctrl.load(staged.schedule)
            else:
                state = ctrl.state_
                new = self._controller_for(staged)
                new.reset(state)                # a new envelope starts from its nominal task
                self._take_over(new)
        else:
            self._run()

    # ------------------------------------------------------------------------------------------ control tick

    def tick(self, sample: SensorSample | None, now_s: float) -> tuple[float, float, list[can.Message]]:
        """One control period: watchdogs, table switch, torques, and the periodic frames.

        Args:
            sample: the sensors now (None when no leg is attached: torques are 0).
            now_s: device clock (s).

        Returns:
            (knee torque N·m, ankle torque N·m, frames to send).

        Fails safe: an error anywhere in the tick puts the leg in safe mode (CONTROL_ERROR) with passive, damped
        torques, and the next tick carries on.
        """
        out: list[can.Message] = []
        try:
            return self._tick(sample, now_s, out)
        except Exception:
            self._enter_safe(now_s)
            self.faults_ |= Fault.CONTROL_ERROR
            out += self._status_frames()
            knee, ankle, _ = self._safe_torques(sample) if sample is not None else (0.0, 0.0, None)
            return knee, ankle, out

    def _tick(self, sample: SensorSample | None, now_s: float,
              out: list[can.Message]) -> tuple[float, float, list[can.Message]]:
        cfg = self.config
        self._now_s = now_s
        if self._rx is not None and now_s - self._rx.started_s > (
                cfg.transfer_timeout_s if self._rx.n_nodes == 1 else cfg.envelope_transfer_timeout_s):
            out.append(self._refuse(self._rx.transfer_id, AckResult.TIMEOUT, self._rx.version))
            self._rx = None
        host_alive = now_s - self.last_heartbeat_s_ <= cfg.heartbeat_timeout_s
        if not host_alive and Fault.HEARTBEAT_LOST not in self.faults_:   # also when already in safe mode
            if self.link_mode_ == LinkMode.SUPERVISED or self.mode_ == Mode.CALIBRATING:   # nobody guides it now
                self._enter_safe_holding_staged(now_s)
            self.faults_ |= Fault.HEARTBEAT_LOST
            out += self._status_frames()
        elif host_alive and Fault.HEARTBEAT_LOST in self.faults_ and self.link_mode_ == LinkMode.AUTONOMOUS \
                and self.mode_ != Mode.SAFE:   # the link is back; a supervised leg waits for the host to say so
            self.faults_ &= ~Fault.HEARTBEAT_LOST
            out += self._status_frames()
        if self.staged_ is not None and host_alive and self.mode_ != Mode.CALIBRATING:
            idle = sample is None or self.mode_ != Mode.ACTIVE or not self._walking(now_s)
            if idle:
                self._activate_staged()
                out += self._status_frames()
        knee, ankle, state = 0.0, 0.0, GaitState.SWING_EXTENSION
        if self.mode_ == Mode.CALIBRATING:     # no torque: the step being measured takes this period's readings
            out += self.calibration_.tick()
        elif sample is not None and self.leg_drives_:
            knee, ankle, state = self._torques(sample, now_s, out)
        if now_s >= self._next_telemetry_s:
            self._next_telemetry_s = max(self._next_telemetry_s + cfg.telemetry_period_s, now_s)
            if sample is not None:
                out += self._telemetry(sample, state, knee, ankle)
        if now_s >= self._next_status_s:
            self._next_status_s = max(self._next_status_s + cfg.status_period_s, now_s)
            out += self._status_frames()
        return knee, ankle, out

    def _torques(self, x: SensorSample, now_s: float, out: list[can.Message]) -> tuple[float, float, GaitState]:
        if self.mode_ == Mode.ACTIVE and self.controller_ is not None:
            return self._run_controller(self.controller_, x, now_s, out)
        return self._safe_torques(x)

    def _run_controller(self, ctrl: StateMachineController | AdaptiveController, x: SensorSample, now_s: float,
                        out: list[can.Message]) -> tuple[float, float, GaitState]:
        before, guards = ctrl.state_, ctrl.guard_transitions_
        cmd = ctrl.step(x)
        heel_strike = before in (GaitState.SWING_FLEXION, GaitState.SWING_EXTENSION) and \
            cmd.state == GaitState.STANCE_FLEXION
        if heel_strike and ctrl.guard_transitions_ == guards:
            self._last_heel_strike_s = now_s
            if self.staged_ is not None:
                self._activate_staged()
                out += self._status_frames()
        return cmd.knee_torque_Nm, cmd.ankle_torque_Nm, cmd.state

    def _safe_torques(self, x: SensorSample) -> tuple[float, float, GaitState]:
        """Safe mode's passive torques (safe mode, and no table; :mod:`controller_core.safe_mode`), clipped to the
        actuator and range limits. A foot loaded again counts as a heel strike: a person walking on in safe mode is
        walking when the machine takes over again (:meth:`_take_over`)."""
        was_unloaded = not self._safe.loaded_
        cmd = self._safe.step(x)
        if was_unloaded and self._safe.loaded_:
            self._last_heel_strike_s = self._now_s
        return cmd.knee_torque_Nm, cmd.ankle_torque_Nm, cmd.state

    # ------------------------------------------------------------------------------------------ frames out

    def impedance(self) -> Impedance:
        """What each joint runs now as a spring and damper (k N·m/rad, θe rad, b N·m·s/rad): the active controller's,
        or safe mode's (safe mode, and no table): for actuators that run the impedance themselves
        (:mod:`device_bridge.osl.leg`, Dephy impedance mode)."""
        if self.mode_ == Mode.ACTIVE and self.controller_ is not None:
            return self.controller_.impedance()
        if self.mode_ == Mode.CALIBRATING:
            return (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
        return self._safe.impedance()

    @property
    def fsm_state(self) -> int:
        return int(self.controller_.state_) if self.mode_ == Mode.ACTIVE and self.controller_ is not None else 15

    def _status_frames(self) -> list[can.Message]:
        """DEVICE_HEALTH then DEVICE_STATUS, made in the same instant: the host reads a status with the health sent
        just before it, so a status made after a push was staged says so (pending_version)."""
        self._status_counter = (self._status_counter + 1) & 0xFF
        active = self.active_
        faults = self.faults_ | (Fault.NO_TABLE if active is None else Fault(0))
        leg = [] if self.leg_state_ is None else [encode("DEVICE_LEG", self.leg_state_)]
        return [
            *leg,
            encode("DEVICE_HEALTH", {"fault_flags": int(faults), "temperature": self._temperature_raw(),
                                     "pending_version": self.staged_.version if self.staged_ else 0,
                                     "rx_errors": min(self.rx_errors_, 0xFFFF), "link_mode": int(self.link_mode_)}),
            encode("DEVICE_STATUS", {"counter": self._status_counter, "mode": int(self.mode_),
                                     "fsm_state": self.fsm_state,
                                     "active_version": active.version if active else 0,
                                     "active_crc32": active.crc32 if active else 0}),
        ]

    def _temperature_raw(self) -> int:
        t = self.temperature_degC_
        if t is None or not math.isfinite(t):
            return TEMPERATURE_UNKNOWN_RAW
        return min(max(round(t) + 40, 0), TEMPERATURE_UNKNOWN_RAW - 1)

    def _task_telemetry(self, seq: int) -> list[can.Message]:
        """The task frame (sent first, so the host has it when the sample's other frames complete it)."""
        ctrl = self.controller_
        if self.mode_ != Mode.ACTIVE or not isinstance(ctrl, AdaptiveController):
            return []
        est = ctrl.estimator.last_
        seen = est is not None and math.isfinite(est.speed_mps)
        return [encode_scaled("TELEMETRY_TASK", {
            "seq": seq, "estimated_speed": est.speed_mps if seen and est else 4.095,
            "estimated_incline": est.incline_deg if seen and est else -20.48,
            "running_speed": ctrl.speed_mps_, "running_incline": ctrl.incline_deg_,
            "adaptive_mode": ADAPTIVE_MODES[ctrl.mode_]})]

    def _behaviour(self) -> int:
        """TELEMETRY_GAIT's behaviour: 0 walking on the rows (or not running a table), 1 standing, 2 stumble support."""
        ctrl = self.controller_
        machine = getattr(ctrl, "machine_", ctrl)
        if self.mode_ != Mode.ACTIVE or not isinstance(machine, StateMachineController):
            return 0
        return 1 if machine.standing_ else 2 if machine.recovering_ else 0

    def _telemetry(self, x: SensorSample, state: GaitState, knee_Nm: float, ankle_Nm: float) -> list[can.Message]:
        seq = self._telemetry_seq
        self._telemetry_seq = (seq + 1) & 0xFFFF
        deg = 180.0 / math.pi
        fsm = int(state) if self.mode_ == Mode.ACTIVE else 15
        return [*self._task_telemetry(seq),
            encode_scaled("TELEMETRY_GAIT", {"seq": seq, "fsm_state": fsm, "mode": int(self.mode_),
                                             "load": x.load_N, "ankle_moment": x.ankle_moment_Nm,
                                             "behaviour": self._behaviour(), "reserved": 0}),
            encode_scaled("TELEMETRY_KNEE", {"seq": seq, "angle": x.knee_angle_rad * deg,
                                             "velocity": x.knee_velocity_rad_s * deg, "torque": knee_Nm}),
            encode_scaled("TELEMETRY_ANKLE", {"seq": seq, "angle": x.ankle_angle_rad * deg,
                                              "velocity": x.ankle_velocity_rad_s * deg, "torque": ankle_Nm}),
        ]
