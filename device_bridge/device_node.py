"""Run the firmware on a CAN bus in real time: the simulated prosthesis as a device on the bus.

:class:`DeviceNode` owns a bus, a :class:`device_bridge.firmware.DeviceFirmware` and a leg (anything with
``sample()`` and ``step(knee_Nm, ankle_Nm)``, e.g. :class:`device_bridge.sim.walker.SimWalker`; or none). Its thread
runs the 1 kHz control period against the wall clock: every :data:`WAKE_S` it runs the ticks that are due, each with
its own time stamp (catching up after a stall, at most 100 at a time, then slipping rather than racing), and in
between it hands every received frame to the firmware as it arrives and sends the answer at once (also when the
ticks ran late: behind schedule it still reads the bus after every batch). Waking every
tick would cost a server process that hosts the simulated leg much of its throughput in thread switches
(docs/results.md); the physics and the firmware see the same 1 ms steps either way.
:meth:`DeviceNode.snapshot` gives tests and the soak tool a consistent view of the
buffers (an oracle the host never uses).
"""

from __future__ import annotations

import contextlib
import threading
import time
from dataclasses import dataclass
from typing import Protocol

import can

from controller_core.fsm import SensorSample
from device_bridge.firmware import DeviceFirmware, FirmwareConfig, HeldTable
from device_bridge.protocol import Mode

TICK_S = 0.001
WAKE_S = 0.01
MAX_CATCH_UP_TICKS = 100


class Leg(Protocol):
    def sample(self) -> SensorSample | None: ...
    def step(self, knee_torque_Nm: float, ankle_torque_Nm: float) -> None: ...


@dataclass(frozen=True)
class Snapshot:
    """The firmware's buffers and mode at one instant."""

    mode: Mode
    active: HeldTable | None
    staged: HeldTable | None
    safe_mode_entered_s: float | None
    last_heartbeat_s: float

    def staged_or_active_crc32(self) -> int | None:
        """CRC-32 of the newest verified table held (staged if any, else active)."""
        held = self.staged or self.active
        return None if held is None else held.crc32


class DeviceNode:
    """The simulated prosthesis on ``bus`` (see the module docstring)."""

    def __init__(self, bus: can.BusABC, leg: Leg | None = None, config: FirmwareConfig | None = None) -> None:
        self.bus = bus
        self.leg = leg
        self.firmware = DeviceFirmware(config, now_s=time.monotonic())
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, name="device-node", daemon=True)
        self.overruns = 0

    def start(self) -> DeviceNode:
        self._thread.start()
        return self

    def close(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=2.0)
        self.bus.shutdown()

    def __enter__(self) -> DeviceNode:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def snapshot(self) -> Snapshot:
        with self._lock:
            fw = self.firmware
            return Snapshot(fw.mode_, fw.active_, fw.staged_, fw.safe_mode_entered_s_, fw.last_heartbeat_s_)

    def _send(self, frames: list[can.Message]) -> None:
        for f in frames:
            with contextlib.suppress(can.CanError):   # a full queue (host gone): lost, as on a real bus
                self.bus.send(f)

    def _loop(self) -> None:
        fw, leg = self.firmware, self.leg
        next_tick = time.monotonic()
        while not self._stop.is_set():
            now = time.monotonic()
            out: list[can.Message] = []
            with self._lock:
                ticks = 0
                while next_tick <= now and ticks < MAX_CATCH_UP_TICKS:
                    sample = leg.sample() if leg is not None else None
                    knee, ankle, frames = fw.tick(sample, next_tick)
                    out += frames
                    if leg is not None:
                        leg.step(knee, ankle)
                    next_tick += TICK_S
                    ticks += 1
                if next_tick <= now:          # stalled beyond the catch-up budget: slip instead of racing
                    self.overruns += 1
                    next_tick = now + TICK_S
            self._send(out)
            self._answer_frames_until(next_tick + WAKE_S - TICK_S)

    def _answer_frames_until(self, deadline: float) -> None:
        """Hand each frame that arrives before ``deadline`` to the firmware at once and send its answer. Frames
        already waiting are handled even when the ticks ran late and the deadline has passed, as a real device's
        receive interrupt would: running behind, the node must not stop hearing the host's heartbeat."""
        while not self._stop.is_set():
            left = deadline - time.monotonic()
            msg = self.bus.recv(min(left, 0.05) if left > 0 else 0.0)
            if msg is None:
                if left <= 0:
                    return
                continue
            with self._lock:
                out = self.firmware.receive(msg, time.monotonic())
            self._send(out)
