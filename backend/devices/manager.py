"""The configured devices of one server process: a CAN link each, its latest status, pushes and commands.

``sim`` starts the simulated leg (the device firmware driving the MuJoCo bench) on a python-can ``virtual`` bus
inside this process, so the whole loop works out of the box; a real leg is reached over the python-can bus of its
spec. The link's receive thread calls back here; telemetry goes to the WebSocket fan-out and to the session recorder.

The device's own status (mode, the version and CRC it runs, the version it holds staged) is the truth about the leg:
at start-up pushes a stopped server left ``sending`` become ``unconfirmed``, and whenever a device's report changes
(its first status included) :func:`backend.store.pushes.reconcile` makes the records say what it reports. Pushes to
one device are one at a time (:meth:`DeviceManager.push_slot`): the check of what the leg runs now and the push are
one step.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import threading
from collections.abc import Iterator
from dataclasses import dataclass, field

import can
from sqlalchemy import Connection, Engine

from backend.db import pooled
from backend.devices.fanout import TelemetryFanout
from backend.devices.recorder import FLUSH_PERIOD_S, SessionRecorder
from backend.devices.specs import DeviceSpec
from backend.errors import ConflictError, NotFoundError
from backend.services import pushes as push_views
from backend.store import devices as devices_store
from backend.store import pushes as pushes_store
from controller_core.envelope import Envelope
from controller_core.table import ParameterTable
from controller_core.walking_reference import WalkingReference
from device_bridge.clock import WALL_CLOCK, Clock, SteppedClock
from device_bridge.device_node import DeviceNode
from device_bridge.host import DeviceLink, DeviceStatus, HeartbeatClock, PushResult, TelemetrySample
from device_bridge.host_calibration import CalibrationAnswer, CalibrationTimeoutError
from device_bridge.protocol import CalibrationAction, CalibrationStep, Command, Fault
from device_bridge.rig import Rig
from device_bridge.sim.course import Course
from device_bridge.sim.leg_file import parse_leg
from device_bridge.sim.leg_model import LegGeometry
from device_bridge.sim.walker import SimWalker

ONLINE_WITHIN_S = 1.0        # a device whose status is older than this is offline
log = logging.getLogger(__name__)
WITHDRAWAL_RECHECK_S = 5.0   # a leg reporting the same thing is checked again for a withdrawal (another instance's)
LEAVE_SAFE_TRY_S = 3.0      # a requested LEAVE_SAFE_MODE is repeated while the leg still reports safe mode, this long
LINK_MODE_RESEND_S = 0.5     # a device still reporting another lost-link mode is sent the choice again after this
STORED_VIEW_MAX_AGE_S = 1.0  # a live stream's statuses show the assignment and tables as read at most this long ago
_LINK_COMMANDS = {"supervised": Command.LINK_SUPERVISED, "autonomous": Command.LINK_AUTONOMOUS}


@dataclass
class ManagedDevice:
    spec: DeviceSpec
    link: DeviceLink | None = None
    node: DeviceNode | None = None
    walker: SimWalker | None = None
    status: DeviceStatus | None = None
    fanout: TelemetryFanout = field(default_factory=TelemetryFanout)
    last_sample: TelemetrySample | None = None
    tables: dict[tuple[int, int | None], dict] = field(default_factory=dict)   # (version, crc) -> its push
    in_flight: set[int] = field(default_factory=set)        # push ids being sent now (their sender decides them)
    reconciled: tuple | None = None                         # (report, epoch) the records were last made to follow
    epoch: int = 0                                          # counts finished pushes: a report is reconciled anew
    acknowledged: tuple[int, float] | None = None           # (push id, monotonic s) of the last CRC read back
    push_lock: threading.Lock = field(default_factory=threading.Lock)
    link_mode: str = "supervised"                           # the stored lost-link choice as this process last read it
    link_mode_sent_s: float = float("-inf")                 # monotonic s the choice was last sent to the device
    stored: tuple | None = None                             # (status key, monotonic s, parts) of the last stored read
    withdrawal_checked: tuple = (None, float("-inf"))       # (status key, wall monotonic s) last checked for a withdrawal
    leave_safe_until_s: float = float("-inf")                # monotonic s: LEAVE_SAFE_MODE is sent again until then
    leave_safe_sent_s: float = float("-inf")                 # monotonic s it was last sent


class DeviceManager:
    """Opens a link per spec on :meth:`start`; :meth:`close` ends them and the recorder."""

    def __init__(self, db: Engine, specs: list[DeviceSpec], bench_leg: LegGeometry | None = None,
                 bus_options: dict[str, dict] | None = None, clock: Clock = WALL_CLOCK) -> None:
        self.db = db
        self.clock = clock
        self._specs = specs
        self._bus_options = bus_options or {}   # per interface: the broker link's address and identity
        self._bench_leg = bench_leg   # the simulated leg's leg and person (None: the nominal bench)
        self._devices: dict[str, ManagedDevice] = {}
        self._heartbeats: HeartbeatClock | None = None   # one heartbeat thread for the legs of a shared broker connection
        self.recorder = SessionRecorder(db, tuple(spec.device_id for spec in specs), clock=clock)
        self._withdrawals = 0     # counts withdrawals made through this process
        self.instance_name: str | None = None    # this API instance's (its pushes name it: backend.store.pushes)

    def start(self) -> DeviceManager:
        with pooled(self.db) as conn:
            for spec in self._specs:
                devices_store.register_device(conn, spec.device_id, spec.kind, spec.interface, spec.channel)
            # a server of these devices that stopped mid-push: each device's status decides
            pushes_store.interrupted_pushes(conn, [spec.device_id for spec in self._specs])
        for spec in self._specs:
            dev = ManagedDevice(spec=spec)
            with pooled(self.db) as conn:
                dev.link_mode = devices_store.link_mode(conn, spec.device_id)
            callbacks = {"on_status": lambda s, d=dev: self._on_status(d, s),
                         "on_telemetry": lambda x, d=dev: self._on_telemetry(d, x),
                         "on_late_telemetry": lambda x, d=dev: self._on_late_telemetry(d, x)}
            if spec.kind == "simulated":
                dev.walker = SimWalker(self._bench_leg)
                if isinstance(self.clock, SteppedClock):   # leg and link on one thread, moved by whoever waits
                    rig = Rig(leg=dev.walker, config=dev.walker.firmware_config(), clock=self.clock,
                              keep_frames=False, **callbacks)
                    dev.node, dev.link = rig.node, rig.link
                    self._devices[spec.device_id] = dev
                    continue
                dev.node = DeviceNode(can.Bus(interface="virtual", channel=spec.channel), leg=dev.walker,
                                      config=dev.walker.firmware_config(), clock=self.clock).start()
            bus = can.Bus(interface=spec.interface, channel=spec.channel, **self._bus_options.get(spec.interface, {}))
            dev.link = DeviceLink(bus, heartbeat_clock=self._heartbeats_for(bus), clock=self.clock, **callbacks)
            self._devices[spec.device_id] = dev   # before the link starts: its callbacks look the device up
            dev.link.start()
        if isinstance(self.clock, SteppedClock):     # the recorder thread's rounds, on the rig's clock
            every = round(FLUSH_PERIOD_S / self.clock.step_s)
            self.clock.add(lambda _now: self.recorder.periodic() if self.clock.steps % every == 0 else None)
        else:
            self.recorder.start()
        with pooled(self.db) as conn:
            for spec in self._specs:
                self.worn_by(spec.device_id, devices_store.assignment(conn, spec.device_id))
        return self

    def _heartbeats_for(self, bus: can.BusABC) -> HeartbeatClock | None:
        """The shared heartbeat clock for a leg whose frames come through the instance's broker connection (its send
        only queues: :class:`~device_bridge.host.HeartbeatClock`); None (a thread of its own) for a CAN bus."""
        if not getattr(bus, "delivers_frames", False):
            return None
        if self._heartbeats is None:
            self._heartbeats = HeartbeatClock(float(getattr(bus, "heartbeat_period_s", 0.05)), clock=self.clock).start()
        return self._heartbeats

    def worn_by(self, device_id: str, worn: dict | None) -> None:
        """A simulated leg's patient (``worn``: the device's assignment, :func:`backend.store.devices.assignment`):
        stands on it between walks, or nobody wears it (None). The leg is fitted to the patient's: as their record
        describes it, the server's bench leg where it does not (the leg walked, and its firmware's thigh, shank,
        forefoot and drive friction), so its sessions are walked on the leg the patient's versions were made for. A
        walk under way goes on; a real leg's sensors say for themselves."""
        dev = self.get(device_id)
        walker = dev.walker
        if walker is None or walker.walking:
            return
        with self._leg_still(dev):
            fitted = _leg_of(worn) or self._bench_leg or LegGeometry()
            if fitted != walker.geometry:
                walker.geometry = fitted
                if dev.node is not None:
                    dev.node.firmware.fit_leg(walker.firmware_config())
            if worn is None:
                walker.stop()
            else:
                walker.stand(worn["body_mass_kg"])

    def close(self) -> None:
        self.recorder.close()
        for dev in self._devices.values():
            if dev.link is not None:
                dev.link.close()
            if dev.node is not None:
                dev.node.close()
        if self._heartbeats is not None:
            self._heartbeats.close()

    # ------------------------------------------------------------------------------------------ queries

    def get(self, device_id: str) -> ManagedDevice:
        dev = self._devices.get(device_id)
        if dev is None:
            known = ", ".join(self._devices) or "none configured"
            raise NotFoundError(f"device {device_id!r} not found (devices: {known})")
        return dev

    def ids(self) -> list[str]:
        return list(self._devices)

    def online(self, dev: ManagedDevice, status: DeviceStatus | None = None) -> bool:
        """Whether the device reported within :data:`ONLINE_WITHIN_S`; ``status``: judge this snapshot of its status
        (a view reads the status once, so that "online" and the mode it shows come from the same frame)."""
        s = dev.status if status is None else status
        return s is not None and self.clock.monotonic() - s.received_monotonic_s <= ONLINE_WITHIN_S

    def _table(self, conn: Connection, dev: ManagedDevice, version: int | None,
               crc32: int | None) -> dict | None:
        """Which table or envelope (patient, version, task) a version the device reports is; pushes never change."""
        if version is None:
            return None
        key = (version, crc32)
        if key not in dev.tables:
            push = push_views.push_of_version(conn, dev.spec.device_id, version, crc32)
            if push is None:
                return None
            dev.tables[key] = {k: push[k] for k in ("kind", "proposal_id", "proposal_version", "envelope_id",
                                                    "envelope_version", "patient_id", "patient_code", "label",
                                                    "table_label", "task", "body_mass_kg", "override_reason",
                                                    "approval_override", "extrapolation_reason")}
        return dev.tables[key]

    def view(self, device_id: str, fresh: bool = True) -> dict:
        """The device as the API shows it: configuration, link state, the latest status (display units), the
        patient it is assigned to and which tables its status reports. ``fresh=False`` (the live stream's 10 Hz
        statuses): the stored parts may be up to :data:`STORED_VIEW_MAX_AGE_S` old while the device reports the same
        tables."""
        dev = self.get(device_id)
        s = dev.status
        age = None if s is None else round(self.clock.monotonic() - s.received_monotonic_s, 3)
        patient, active, pending, link_mode, notice = self._stored(dev, 0.0 if fresh else STORED_VIEW_MAX_AGE_S)
        return {
            "patient": patient, "active_table": active, "pending_table": pending,
            "body_mass_mismatch": mass_mismatch(active, patient),
            "id": dev.spec.device_id, "kind": dev.spec.kind, "interface": dev.spec.interface,
            "channel": dev.spec.channel, "online": self.online(dev, s),
            "mode": None if s is None else s.mode.name.lower(),
            "safe_mode": s is not None and s.mode.name == "SAFE",
            "fsm_state": None if s is None else s.fsm_state,
            "active_version": None if s is None else s.active_version,
            "active_crc32": None if s is None or s.active_crc32 is None else f"{s.active_crc32:08x}",
            "pending_version": None if s is None else s.pending_version,
            "faults": [] if s is None else [f.name.lower() for f in Fault if f in s.fault_flags],
            "temperature_degC": None if s is None else s.temperature_degC,
            "leg": None if s is None or s.leg is None else dataclasses.asdict(s.leg),
            "rx_errors": None if s is None else s.rx_errors,
            "last_heartbeat_unix_s": None if s is None else round(s.received_unix_s, 3),
            "last_heartbeat_age_s": age,
            "walking": None if dev.walker is None else dev.walker.walking,
            "bench_state": None if dev.walker is None else dev.walker.state,
            "bench_task": _bench_task(dev.walker),
            "bench_leg": None if dev.walker is None else dev.walker.geometry.name,
            "recording_session_id": self.recorder.session_of(device_id),
            "link_mode": link_mode,
            "withdrawal_notice": notice,
            "link_mode_on_device": None if s is None else s.link_mode.name.lower(),
            "telemetry_samples_received": 0 if dev.link is None else dev.link.telemetry_received,
            "telemetry_samples_missing": 0 if dev.link is None else dev.link.telemetry_missing,
        }

    def _stored(self, dev: ManagedDevice, max_age_s: float) -> tuple:
        """(patient, active table, pending table, lost-link choice) from the database, read again unless read within
        ``max_age_s`` for the tables the device reports now (another instance may change the assignment or the
        choice: a stream shows that within the age)."""
        s = dev.status
        key = None if s is None else (s.active_version, s.active_crc32, s.pending_version)
        now = WALL_CLOCK.monotonic()      # the age of a database read: the server's own time, not the leg's
        if max_age_s > 0 and dev.stored is not None and dev.stored[0] == key and now - dev.stored[1] <= max_age_s:
            return dev.stored[2]
        with pooled(self.db) as conn:
            patient = devices_store.assignment(conn, dev.spec.device_id)
            active = None if s is None else self._table(conn, dev, s.active_version, s.active_crc32)
            pending = None if s is None else self._table(conn, dev, s.pending_version, None)
            link_mode = devices_store.link_mode(conn, dev.spec.device_id)   # another instance may have changed it
            notice = None if s is None else _withdrawal_notice(conn, dev.spec.device_id, s)
        dev.stored = (key, now, (patient, active, pending, link_mode, notice))
        return dev.stored[2]

    def on_leg(self, conn: Connection, device_id: str, running_only: bool = False) -> dict:
        """What the device reports it runs (``running_only``) or will run from its next heel strike, as its last
        status says (with a CRC this process read back since then): ``push`` (ours, or None), ``version`` and
        ``crc32`` as reported, ``mode``, and ``words`` for people ("P-001 · envelope v3", "no table", "a table this
        server did not send (version 7, CRC 1a2b3c4d)", "nothing reported yet")."""
        dev = self.get(device_id)
        if running_only:   # a CRC just read back: the device reports its switch in its next status (100 ms)
            self._status_after(dev, dev.acknowledged[1] if dev.acknowledged else 0.0)
        s = dev.status
        if s is None:
            return {"push": None, "version": None, "crc32": None, "mode": None, "words": "nothing reported yet"}
        push = None
        if not running_only and dev.acknowledged is not None and dev.acknowledged[1] > s.received_monotonic_s:
            push = push_views.get_push(conn, dev.acknowledged[0])
        elif not running_only and s.pending_version is not None:
            push = push_views.push_of_version(conn, device_id, s.pending_version)
        if push is None and s.active_version is not None:
            push = push_views.push_of_version(conn, device_id, s.active_version, s.active_crc32)
        if push is not None:
            words = push["label"]
        elif s.active_version is None:
            words = "no table"
        else:
            words = f"a table this server did not send (version {s.active_version}, CRC {s.active_crc32:08x})"
        return {"push": push, "version": s.active_version, "crc32": s.active_crc32, "mode": s.mode.name.lower(),
                "words": words}

    def _status_after(self, dev: ManagedDevice, after_monotonic_s: float, wait_s: float = 0.5) -> None:
        """Wait (at most ``wait_s``) for a status received after ``after_monotonic_s``, if the last one is older."""
        self.clock.until(lambda: (dev.status is not None and dev.status.received_monotonic_s > after_monotonic_s)
                         or not self.online(dev), wait_s)

    @contextlib.contextmanager
    def push_slot(self, device_id: str, wait_s: float = 15.0) -> Iterator[ManagedDevice]:
        """One push at a time per device: the caller checks what the leg runs, records, sends and finishes inside.
        A second push waits its turn (then sees what the first left on the leg), or is refused after ``wait_s``."""
        dev = self.get(device_id)
        if not dev.push_lock.acquire(timeout=wait_s):
            raise ConflictError(f"another push to device {device_id} is still in progress; nothing was sent")
        try:
            yield dev
        finally:
            dev.push_lock.release()

    def push_started(self, device_id: str, push_id: int) -> None:
        self.get(device_id).in_flight.add(push_id)

    def push_finished(self, device_id: str, push_id: int, acknowledged: bool) -> None:
        """The push's outcome is recorded: from now on the device's reports decide it."""
        dev = self.get(device_id)
        if acknowledged:
            dev.acknowledged = (push_id, self.clock.monotonic())
        dev.in_flight.discard(push_id)
        dev.epoch += 1   # the next status (sent after this push ended) is reconciled whatever it says

    # ------------------------------------------------------------------------------------------ commands

    def push(self, device_id: str, content: ParameterTable | Envelope, version: int) -> PushResult:
        """Push a version's content, a table or a whole envelope, and wait for the CRC read-back (raises
        device_bridge's PushError on failure). The one push path of the server; the link sends each kind its way."""
        return self._link_for_push(device_id).push(content, version)

    def _link_for_push(self, device_id: str) -> DeviceLink:
        dev = self.get(device_id)
        if not self.online(dev) or dev.link is None:
            raise ConflictError(f"device {device_id} is offline (no status for over {ONLINE_WITHIN_S:g} s); "
                                "nothing was sent")
        dev.tables.clear()      # the device's 16-bit version numbers wrap: a number may now name another push
        return dev.link

    def command(self, device_id: str, command: Command) -> None:
        """Send a command now. LEAVE_SAFE_MODE is sent again with each status that still shows safe mode (at most every
        :data:`LINK_MODE_RESEND_S`, for :data:`LEAVE_SAFE_TRY_S`): the leg leaves only while it hears the host, and just
        after a cut its first heartbeats may still be on their way; ENTER_SAFE_MODE ends that."""
        dev = self.get(device_id)
        if not self.online(dev) or dev.link is None:
            raise ConflictError(f"device {device_id} is offline; the command was not sent")
        now = self.clock.monotonic()
        leaving = command == Command.LEAVE_SAFE_MODE
        dev.leave_safe_until_s, dev.leave_safe_sent_s = (now + LEAVE_SAFE_TRY_S, now) if leaving else (float("-inf"),) * 2
        dev.link.command(command)

    def calibrate(self, device_id: str, action: CalibrationAction, step: CalibrationStep | None,
                  body_mass_kg: float) -> CalibrationAnswer:
        """One guided-calibration command to a real leg, and its answer (:mod:`device_bridge.host_calibration`);
        ConflictError when the leg is offline or does not answer."""
        dev = self.get(device_id)
        if not self.online(dev) or dev.link is None:
            raise ConflictError(f"device {device_id} is offline; nothing was sent")
        try:
            return dev.link.calibration.command(action, step, body_mass_kg)
        except CalibrationTimeoutError as exc:
            raise ConflictError(str(exc)) from exc

    def link_mode_chosen(self, device_id: str, mode: str) -> None:
        """The stored lost-link choice changed (:func:`backend.store.devices.set_link_mode`): tell the device now if it
        is online, else when it next reports (every status that shows another mode sends the choice again)."""
        dev = self.get(device_id)
        dev.link_mode, dev.link_mode_sent_s = mode, float("-inf")
        if dev.status is not None:
            self._apply_link_mode(dev, dev.status)

    def _apply_link_mode(self, dev: ManagedDevice, status: DeviceStatus) -> None:
        """Send the device the stored lost-link choice when its report differs (a restarted device starts
        supervised), at most every :data:`LINK_MODE_RESEND_S`; the choice is read again first, since another instance
        may have changed it."""
        reported = status.link_mode.name.lower()
        now = self.clock.monotonic()
        if reported == dev.link_mode or now - dev.link_mode_sent_s < LINK_MODE_RESEND_S or dev.link is None:
            return
        with pooled(self.db) as conn:
            dev.link_mode = devices_store.link_mode(conn, dev.spec.device_id)
        if reported != dev.link_mode:
            dev.link_mode_sent_s = now
            with contextlib.suppress(can.CanError):   # a full or closed bus: the next status tries again
                dev.link.command(_LINK_COMMANDS[dev.link_mode])

    def _leave_safe_again(self, dev: ManagedDevice, status: DeviceStatus) -> None:
        now = self.clock.monotonic()
        if status.mode.name != "SAFE" or now > dev.leave_safe_until_s:
            dev.leave_safe_until_s = float("-inf") if status.mode.name != "SAFE" else dev.leave_safe_until_s
            return
        if now - dev.leave_safe_sent_s >= LINK_MODE_RESEND_S and dev.link is not None:
            dev.leave_safe_sent_s = now
            with contextlib.suppress(can.CanError):   # a full or closed bus: the next status tries again
                dev.link.command(Command.LEAVE_SAFE_MODE)

    def withdrawn(self) -> None:
        """A version was withdrawn: every leg's next status is checked for it (:meth:`_refuse_withdrawn`)."""
        self._withdrawals += 1

    def _refuse_withdrawn(self, dev: ManagedDevice, status: DeviceStatus) -> None:
        """A leg that runs a withdrawn version, with nothing else on its way to it, is put in safe mode (a leg that was
        offline when it was withdrawn, or whose return to an earlier version failed). Checked when its report or the
        withdrawals change, and every :data:`WITHDRAWAL_RECHECK_S` (another instance may have withdrawn it)."""
        key = (_running(status), status.pending_version, status.mode, self._withdrawals)
        now = WALL_CLOCK.monotonic()
        if (key == dev.withdrawal_checked[0] and now - dev.withdrawal_checked[1] < WITHDRAWAL_RECHECK_S) \
                or status.mode.name == "SAFE" or status.active_version is None or dev.in_flight or dev.link is None:
            return
        dev.withdrawal_checked = (key, now)
        with pooled(self.db) as conn:
            notice = _withdrawal_notice(conn, dev.spec.device_id, status)
        if notice is not None and notice["state"] == "runs_withdrawn":   # the monitor's rule, the same reads
            log.warning("device %s runs %s, which was withdrawn: safe mode", dev.spec.device_id, notice["label"])
            with contextlib.suppress(can.CanError):   # a full or closed bus: the next status tries again
                dev.link.command(Command.ENTER_SAFE_MODE)

    def _leg_still(self, dev: ManagedDevice) -> contextlib.AbstractContextManager:
        """Hold a simulated leg between two of its control ticks while its patient is told to walk, stand or stop (the
        tick runs on another thread: the paced or stepped clock's, or the node's control thread)."""
        if isinstance(self.clock, SteppedClock):
            return self.clock.between_steps()
        return dev.node.ticking if dev.node is not None else contextlib.nullcontext()

    def start_recording(self, device_id: str, session_id: int, reference: WalkingReference | None,
                        mass_kg: float, course: Course | None = None) -> None:
        """Record the device's telemetry into ``session_id``; a simulated leg starts walking at the task, or walks
        the course."""
        dev = self.get(device_id)
        # the simulated patient sets off first (planning a course takes a moment, stood still), then the recording
        # begins: the session holds the walk, not the stance before it
        with self._leg_still(dev):
            if dev.walker is not None and course is not None:
                dev.walker.start_course(course, mass_kg)
            elif dev.walker is not None and reference is not None:
                dev.walker.start(reference, mass_kg)
        self.recorder.begin(device_id, session_id)

    def stop_recording(self, device_id: str) -> tuple[list[dict], int]:
        """Stop recording (everything received so far is written before this returns). Returns what the device's
        status reported while it walked, most reported first: mode, table version and CRC (None: no table), the
        version's name when this server sent it, and the share of the status reports; and how many samples arrived
        late (kept by the leg's bridge while its link was down)."""
        dev = self.get(device_id)
        reports, late = self.recorder.end(device_id)
        if not reports and dev.status is not None:   # shorter than one status period: its latest report
            reports[(dev.status.mode.name.lower(), _running(dev.status))] = 1
        if dev.walker is not None:
            with pooled(self.db) as conn:
                worn = devices_store.assignment(conn, device_id)
            with self._leg_still(dev):
                dev.walker.stop()
            self.worn_by(device_id, worn)   # the patient stands
        total = sum(reports.values()) or 1
        out = []
        with pooled(self.db) as conn:
            for (mode, active), n in reports.most_common():
                push = None if active is None else push_views.push_of_version(conn, device_id, *active)
                out.append({"mode": mode, "table_version": None if active is None else active[0],
                            "crc32": None if active is None else f"{active[1]:08x}",
                            "label": None if push is None else push["label"], "share": round(n / total, 3)})
        return out, late

    # ------------------------------------------------------------------------------------------ callbacks (rx thread)

    def _on_status(self, dev: ManagedDevice, status: DeviceStatus) -> None:
        dev.status = status
        active = _running(status)
        key = ((active, status.pending_version), dev.epoch)   # the epoch first, then who is in flight (see below)
        in_flight = set(dev.in_flight)
        if key != dev.reconciled:
            with pooled(self.db) as conn:
                pushes_store.reconcile(conn, dev.spec.device_id, active, status.pending_version, in_flight)
            # a push that finished meanwhile moved the epoch on: the next status is reconciled again
            dev.reconciled = key
        self.recorder.note_status(dev.spec.device_id, status.mode.name.lower(), active)
        self._apply_link_mode(dev, status)
        self._leave_safe_again(dev, status)
        self._refuse_withdrawn(dev, status)
        if dev.fanout:
            dev.fanout.publish({"type": "status", **self.view(dev.spec.device_id, fresh=False)})

    def _on_telemetry(self, dev: ManagedDevice, x: TelemetrySample) -> None:
        dev.last_sample = x
        self.recorder.add(dev.spec.device_id, _sample_row(x))
        if dev.fanout:
            dev.fanout.publish({"type": "telemetry", **x.to_json()})

    def _on_late_telemetry(self, dev: ManagedDevice, x: TelemetrySample) -> None:
        """A sample the leg's bridge kept while the link was down: for the session record only (the live monitor
        shows the leg now)."""
        self.recorder.add(dev.spec.device_id, _sample_row(x), late=True)


def _sample_row(x: TelemetrySample) -> tuple:
    """A sample as the session store takes it (:data:`backend.store.sessions.SAMPLE_COLUMNS` order)."""
    return (x.seq, x.received_unix_s, int(x.mode), x.fsm_state, x.knee_angle_rad, x.knee_velocity_rad_s,
            x.knee_torque_Nm, x.ankle_angle_rad, x.ankle_velocity_rad_s, x.ankle_torque_Nm, x.load_N,
            x.ankle_moment_Nm, *_task_columns(x))


MASS_MISMATCH = 0.05   # a table built for a body mass more than 5 % from the patient's current one is flagged


def _withdrawal_notice(conn: Connection, device_id: str, s: DeviceStatus) -> dict | None:
    """What the monitor says about a withdrawal on this leg: it runs a withdrawn version (and is put in safe mode), or
    what it runs or will run was sent back because the version before was withdrawn (which, by whom, why)."""
    active = push_views.push_of_version(conn, device_id, s.active_version, s.active_crc32)
    pending = push_views.push_of_version(conn, device_id, s.pending_version)
    if active is not None and active["withdrawal"] is not None and (pending is None or pending["withdrawal"]):
        w = active["withdrawal"]
        return {"state": "runs_withdrawn", "label": active["label"], **w,
                "words": f"{active['label']} was withdrawn by {w['by']} ({w['reason']}): the leg is put in safe mode"}
    for push in (pending, active):
        if push is not None and push["sent_back_reason"]:
            return {"state": "sent_back", "label": push["label"], "by": push["requested_by"], "at": push["requested_at"],
                    "reason": push["sent_back_reason"],
                    "words": f"sent back to {push['label']}: {push['sent_back_reason']}"}
    return None


def mass_differs(built_kg: float, now_kg: float) -> bool:
    """The patient's body mass now lies more than 5 % from the one a table or envelope was built for: its torques and
    load thresholds no longer fit (flagged on the device, and a push needs a written reason)."""
    return abs(now_kg - built_kg) > MASS_MISMATCH * built_kg


def mass_mismatch(table: dict | None, patient: dict | None) -> dict | None:
    """The running table's body mass against its patient's current one, when they differ by more than 5 %."""
    if table is None or patient is None or patient["patient_id"] != table["patient_id"]:
        return None
    built, now = table["body_mass_kg"], patient["body_mass_kg"]
    if not mass_differs(built, now):
        return None
    pct = 100.0 * (now - built) / built
    return {"built_for_kg": built, "patient_now_kg": now, "difference_percent": round(pct, 1),
            "message": f"{table['label']} was built for {built:g} kg and {patient['patient_code']} now weighs {now:g} "
                       f"kg ({pct:+.0f} %): its torques and load thresholds scale with body mass; propose again for "
                       "the new mass and push it"}


def _running(status: DeviceStatus) -> tuple[int, int] | None:
    """(version, CRC) of the table a status reports running, or None for none."""
    return None if status.active_version is None else (status.active_version, status.active_crc32)


def _task_columns(x: TelemetrySample) -> tuple:
    """The adaptive leg's task telemetry as stored (NULLs while a single table runs)."""
    t = x.task
    if t is None:
        return (None, None, None, None, None)
    return (t.estimated_speed_mps, t.estimated_incline_deg, t.running_speed_mps, t.running_incline_deg,
            t.adaptive_mode)


def _bench_task(walker: SimWalker | None) -> dict | None:
    task = None if walker is None else walker.task
    if task is None:
        return None
    return {"speed_mps": round(task[0], 3), "incline_deg": round(task[1], 2), "course": walker.course}


def _leg_of(worn: dict | None) -> LegGeometry | None:
    """The leg described on the record of the patient wearing a device (None: none described, or nobody)."""
    return None if worn is None or worn["leg"] is None else parse_leg(worn["leg"], "the patient's leg")
