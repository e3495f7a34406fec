"""The server's devices: one CAN link per configured prosthesis, its last status, telemetry fan-out and recording.

Configured by ``Settings.device``: ``sim`` starts the simulated leg (the firmware driving the MuJoCo bench) on a
python-can ``virtual`` bus inside this process, so the whole loop works out of the box; ``INTERFACE:CHANNEL``
(``socketcan:can0``, ``pcan:PCAN_USBBUS1`` …) opens that python-can bus to a real leg; ``none`` runs without one.
A virtual bus exists only inside one process, so the simulated leg needs the single-worker server.

The link's receive thread calls back here: status updates mark a push ``active`` once the device reports its
version and CRC running; telemetry goes to every WebSocket subscriber (through its event loop) and into the
session being recorded, written to SQLite in batches every 0.25 s by a flusher thread.
"""

from __future__ import annotations

import asyncio
import itertools
import os
import re
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import can

from backend.db import connect
from backend.errors import ConflictError, NotFoundError
from backend.store import devices as store
from controller_core.table import ParameterTable
from controller_core.walking_reference import WalkingReference
from device_bridge.buses import parse_bus_spec
from device_bridge.device_node import DeviceNode
from device_bridge.host import DeviceLink, DeviceStatus, PushResult, TelemetrySample
from device_bridge.protocol import Command, Fault
from device_bridge.sim.walker import SimWalker

ONLINE_WITHIN_S = 1.0        # a device whose status is older than this is offline
SIM_DEVICE_ID = "sim-leg-1"
DEVICE_ID_PATTERN = r"^[A-Za-z0-9._-]{1,64}$"
_sim_counter = itertools.count()


@dataclass(frozen=True)
class DeviceSpec:
    """One configured device: its id, kind (``simulated`` or ``can``) and python-can interface and channel."""

    device_id: str
    kind: str
    interface: str
    channel: str


def parse_device_spec(text: str) -> DeviceSpec | None:
    """``sim`` / ``none`` / ``INTERFACE:CHANNEL`` → a spec (None for ``none``); ValueError with the reason."""
    text = text.strip()
    if text == "none":
        return None
    if text == "sim":
        channel = f"quasitune-sim-{os.getpid()}-{next(_sim_counter)}"
        return DeviceSpec(SIM_DEVICE_ID, "simulated", "virtual", channel)
    try:
        interface, channel = parse_bus_spec(text)
    except ValueError as exc:
        raise ValueError(f"device must be 'sim', 'none' or {str(exc).removeprefix('expected ')}") from None
    device_id = re.sub(r"[^A-Za-z0-9._-]", "-", f"{interface}-{channel}")[:64]
    return DeviceSpec(device_id, "can", interface, channel)


@dataclass
class ManagedDevice:
    spec: DeviceSpec
    link: DeviceLink
    node: DeviceNode | None = None
    walker: SimWalker | None = None
    status: DeviceStatus | None = None
    noted_active: tuple[int, int] | None = None
    subscribers: dict[asyncio.Queue, asyncio.AbstractEventLoop] = field(default_factory=dict)
    recording: int | None = None          # session id
    buffer: list[tuple] = field(default_factory=list)
    samples_seen: int = 0
    last_sample: TelemetrySample | None = None


class DeviceManager:
    """The configured devices of one server process (see the module docstring)."""

    def __init__(self, db_path: Path, specs: list[DeviceSpec]) -> None:
        self.db_path = db_path
        self._specs = specs
        self._devices: dict[str, ManagedDevice] = {}
        self._lock = threading.Lock()
        self._conn = connect(db_path)
        self._db_lock = threading.Lock()
        self._stop = threading.Event()
        self._flusher = threading.Thread(target=self._flush_loop, name="session-flusher", daemon=True)

    # ------------------------------------------------------------------------------------------ life cycle

    def start(self) -> DeviceManager:
        for spec in self._specs:
            store.register_device(self._conn, spec.device_id, spec.kind, spec.interface, spec.channel)
            node = walker = None
            if spec.kind == "simulated":
                walker = SimWalker()
                node = DeviceNode(can.Bus(interface="virtual", channel=spec.channel), leg=walker).start()
            bus = can.Bus(interface=spec.interface, channel=spec.channel)
            dev = ManagedDevice(spec=spec, link=None, node=node, walker=walker)  # type: ignore[arg-type]
            dev.link = DeviceLink(bus, on_status=lambda s, d=dev: self._on_status(d, s),
                                  on_telemetry=lambda x, d=dev: self._on_telemetry(d, x))
            self._devices[spec.device_id] = dev   # before the link starts: its callbacks look the device up
            dev.link.start()
        self._flusher.start()
        return self

    def close(self) -> None:
        self._stop.set()
        if self._flusher.is_alive():
            self._flusher.join(timeout=2.0)
        self._flush()
        for dev in self._devices.values():
            dev.link.close()
            if dev.node is not None:
                dev.node.close()
        self._conn.close()

    # ------------------------------------------------------------------------------------------ queries

    def get(self, device_id: str) -> ManagedDevice:
        dev = self._devices.get(device_id)
        if dev is None:
            known = ", ".join(self._devices) or "none configured"
            raise NotFoundError(f"device {device_id!r} not found (devices: {known})")
        return dev

    def latest_sample(self, device_id: str) -> TelemetrySample | None:
        """The last telemetry sample received from a device (``None`` before the first)."""
        return self.get(device_id).last_sample

    def ids(self) -> list[str]:
        return list(self._devices)

    def online(self, dev: ManagedDevice) -> bool:
        return dev.status is not None and time.monotonic() - dev.status.received_monotonic_s <= ONLINE_WITHIN_S

    def view(self, device_id: str) -> dict:
        """The device as the API shows it: configuration, link state and the latest status (display units)."""
        dev = self.get(device_id)
        s = dev.status
        age = None if s is None else round(time.monotonic() - s.received_monotonic_s, 3)
        return {
            "id": dev.spec.device_id, "kind": dev.spec.kind, "interface": dev.spec.interface,
            "channel": dev.spec.channel, "online": self.online(dev),
            "mode": None if s is None else s.mode.name.lower(),
            "safe_mode": s is not None and s.mode.name == "SAFE",
            "fsm_state": None if s is None else s.fsm_state,
            "active_version": None if s is None else s.active_version,
            "active_crc32": None if s is None or s.active_crc32 is None else f"{s.active_crc32:08x}",
            "pending_version": None if s is None else s.pending_version,
            "faults": [] if s is None else [f.name.lower() for f in Fault if f in s.fault_flags],
            "temperature_degC": None if s is None else s.temperature_degC,
            "rx_errors": None if s is None else s.rx_errors,
            "last_heartbeat_unix_s": None if s is None else round(s.received_unix_s, 3),
            "last_heartbeat_age_s": age,
            "walking": None if dev.walker is None else dev.walker.walking,
            "recording_session_id": dev.recording,
        }

    # ------------------------------------------------------------------------------------------ commands

    def push(self, device_id: str, table: ParameterTable, version: int) -> PushResult:
        """Push a table and wait for the CRC read-back (raises device_bridge's PushError on failure)."""
        dev = self.get(device_id)
        if not self.online(dev):
            raise ConflictError(f"device {device_id} is offline (no status for over {ONLINE_WITHIN_S:g} s); "
                                "nothing was sent")
        return dev.link.push(table, version)

    def command(self, device_id: str, command: Command) -> None:
        dev = self.get(device_id)
        if not self.online(dev):
            raise ConflictError(f"device {device_id} is offline; the command was not sent")
        dev.link.command(command)

    def start_recording(self, device_id: str, session_id: int, reference: WalkingReference | None,
                        mass_kg: float) -> None:
        """Record the device's telemetry into ``session_id``; a simulated leg starts walking at the task."""
        dev = self.get(device_id)
        with self._lock:
            dev.recording = session_id
            dev.buffer = []
        if dev.walker is not None and reference is not None:
            dev.walker.start(reference, mass_kg)

    def stop_recording(self, device_id: str) -> None:
        """Stop recording (everything received so far is written before this returns)."""
        dev = self.get(device_id)
        self._flush()
        with self._lock:
            dev.recording = None
        if dev.walker is not None:
            dev.walker.stop()

    # ------------------------------------------------------------------------------------------ WebSocket fan-out

    def subscribe(self, device_id: str, queue: asyncio.Queue, loop: asyncio.AbstractEventLoop) -> None:
        dev = self.get(device_id)
        with self._lock:
            dev.subscribers[queue] = loop

    def unsubscribe(self, device_id: str, queue: asyncio.Queue) -> None:
        dev = self._devices.get(device_id)
        if dev is not None:
            with self._lock:
                dev.subscribers.pop(queue, None)

    @staticmethod
    def _offer(queue: asyncio.Queue, item: dict) -> None:
        if queue.full():       # a client too slow to keep up loses its oldest item, never blocks the bus
            queue.get_nowait()
        queue.put_nowait(item)

    def _publish(self, dev: ManagedDevice, item: dict) -> None:
        with self._lock:
            targets = list(dev.subscribers.items())
        for queue, loop in targets:
            try:
                loop.call_soon_threadsafe(self._offer, queue, item)
            except RuntimeError:   # the subscriber's loop has closed
                self.unsubscribe(dev.spec.device_id, queue)

    # ------------------------------------------------------------------------------------------ callbacks (rx thread)

    def _on_status(self, dev: ManagedDevice, status: DeviceStatus) -> None:
        dev.status = status
        active = None if status.active_version is None else (status.active_version, status.active_crc32)
        if active is not None and active != dev.noted_active:
            with self._db_lock:
                store.mark_active(self._conn, dev.spec.device_id, active[0], active[1])
            dev.noted_active = active
        if dev.subscribers:
            self._publish(dev, {"type": "status", **self.view(dev.spec.device_id)})

    def _on_telemetry(self, dev: ManagedDevice, x: TelemetrySample) -> None:
        dev.samples_seen += 1
        dev.last_sample = x
        if dev.recording is not None:
            row = (x.seq, x.received_unix_s, int(x.mode), x.fsm_state, x.knee_angle_rad, x.knee_velocity_rad_s,
                   x.knee_torque_Nm, x.ankle_angle_rad, x.ankle_velocity_rad_s, x.ankle_torque_Nm, x.load_N,
                   x.ankle_moment_Nm)
            with self._lock:
                if dev.recording is not None:
                    dev.buffer.append(row)
        if dev.subscribers:
            self._publish(dev, {"type": "telemetry", **x.to_json()})

    def _flush(self) -> None:
        for dev in self._devices.values():
            with self._lock:
                session_id, rows, dev.buffer = dev.recording, dev.buffer, []
            if session_id is not None and rows:
                with self._db_lock:
                    store.add_samples(self._conn, session_id, rows)

    def _flush_loop(self) -> None:
        while not self._stop.wait(0.25):
            self._flush()
