"""Run the firmware on a CAN bus: the simulated prosthesis as a device on the bus.

:class:`DeviceNode` owns a bus, a :class:`device_bridge.firmware.DeviceFirmware` and a leg (anything with
``sample()`` and ``step(knee_Nm, ankle_Nm)``, e.g. :class:`device_bridge.sim.walker.SimWalker`; or none), and reads
the time from its clock (:mod:`device_bridge.clock`). Started, it runs two threads, as a real device has a control
timer and a receive interrupt; in a stepped rig (:mod:`device_bridge.rig`) it runs none, and :meth:`DeviceNode.step`
does one period of both on the rig's thread:

* the **control** thread runs the 1 kHz control period against its clock: every :data:`WAKE_S` it runs the
  ticks that are due, each with its own time stamp (catching up after a stall, at most 100 at a time, then slipping
  rather than racing). Waking every tick would cost a server process that hosts the simulated leg much of its
  throughput in thread switches; the physics and the firmware see the same 1 ms steps either way.
* the **receive** thread takes every frame off the bus as it arrives, stamped with its arrival time, and hands it to
  the firmware at once (sending the answer) when the control thread is between batches; else the control thread
  hands it over before its next tick, as a firmware's main loop empties the receive interrupt's buffer. A control
  loop catching up after a stall therefore never starves the reception of the host's heartbeat.

The control loop never parses a frame, so nothing a frame does can stop it; the firmware itself fails safe in both
(an error in reception aborts that transfer, an error in control puts the leg in safe mode), and each thread logs and
counts anything that still escapes (:attr:`DeviceNode.errors`) and carries on.
:meth:`DeviceNode.snapshot` gives tests and the soak tool a consistent view of the buffers (an oracle the host never
uses).
"""

from __future__ import annotations

import contextlib
import logging
import threading
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import can

from controller_core.fsm import SensorSample
from device_bridge.bus_threads import BusThreads
from device_bridge.clock import WALL_CLOCK, Clock
from device_bridge.firmware import DeviceFirmware, FirmwareConfig, HeldTable
from device_bridge.protocol import Mode
from device_bridge.remote_calibration import CalibrationPort

TICK_S = 0.001
WAKE_S = 0.01
MAX_CATCH_UP_TICKS = 100
log = logging.getLogger(__name__)


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


class DeviceNode(BusThreads):
    """The simulated prosthesis on ``bus`` (see the module docstring)."""

    def __init__(self, bus: can.BusABC, leg: Leg | None = None, config: FirmwareConfig | None = None,
                 clock: Clock = WALL_CLOCK, control_thread: bool = True,
                 calibration: CalibrationPort | None = None) -> None:
        self.bus = bus
        self.leg = leg
        self.clock = clock
        self.firmware = DeviceFirmware(config, now_s=clock.monotonic(), calibration=calibration)
        self._lock = threading.Lock()
        # frames leave in the order the firmware made them (as from a firmware's one thread): each thread queues its
        # frames while it holds the firmware, and whichever sends drains the queue in order. A status built before a
        # push was staged must not reach the host after that push's acknowledgement (the host would take it as the
        # device's word and record the push lost); sending under the firmware lock instead starved the receive loop.
        self._outbox: deque[can.Message] = deque()
        self._send_lock = threading.Lock()
        self._inbox: deque[tuple[can.Message, float]] = deque()   # frames received, not yet handed to the firmware
        super().__init__([bus], join_timeout_s=2.0)
        # control_thread False: the leg's own loop ticks the node (tick(), device_bridge.osl.loop), at its own rate
        self._threads = [threading.Thread(target=self._guarded, args=(self._receive_loop,), name="device-receive",
                                          daemon=True)]
        if control_thread:
            self._threads.insert(0, threading.Thread(target=self._guarded, args=(self._control_loop,),
                                                     name="device-control", daemon=True))
        self.overruns = 0
        self.errors = 0

    @property
    def ticking(self) -> threading.Lock:
        """Held through every control tick: hold it to change the leg between two ticks."""
        return self._lock

    def snapshot(self) -> Snapshot:
        with self._lock:
            fw = self.firmware
            return Snapshot(fw.mode_, fw.active_, fw.staged_, fw.safe_mode_entered_s_, fw.last_heartbeat_s_)

    def _send(self) -> None:
        """Send every queued frame, oldest first."""
        with self._send_lock:
            while self._outbox:
                f = self._outbox.popleft()
                with contextlib.suppress(can.CanError):   # a full queue (host gone): lost, as on a real bus
                    self.bus.send(f)

    def _guarded(self, loop: Callable[[], None]) -> None:
        """Run ``loop`` until closed; an error that escapes it is logged and counted, and the loop starts again."""
        while not self._stop.is_set():
            try:
                loop()
            except Exception:
                self.errors += 1
                log.exception("device node: %s failed; carrying on", threading.current_thread().name)
                self.clock.wait(self._stop, TICK_S)

    def _hand_over(self) -> None:
        """Hand every received frame to the firmware, oldest first, each at its arrival time (hold ``_lock``)."""
        while self._inbox:
            msg, arrived_s = self._inbox.popleft()
            self._outbox.extend(self.firmware.receive(msg, arrived_s))

    def control_tick(self, now_s: float) -> None:
        """One control period at ``now_s`` (s): read the leg, run the firmware, drive the leg; the frames it made are
        queued (call :meth:`_send`, or :meth:`step`)."""
        self._hand_over()
        leg = self.leg
        sample = leg.sample() if leg is not None else None
        take_fault = getattr(leg, "take_fault", None)        # a real leg's hardware (device_bridge.osl.leg)
        if take_fault is not None:
            self.firmware.temperature_degC_ = getattr(leg, "temperature_degC_", None)
            self.firmware.leg_state_ = leg.leg_state()
            self.firmware.leg_drives_ = bool(getattr(leg, "drives", True))
            fault = take_fault()
            if fault is not None:
                self._outbox.extend(self.firmware.hardware_fault(fault[1], now_s, thermal=fault[0] == "thermal"))
        knee, ankle, frames = self.firmware.tick(sample, now_s)
        self._outbox.extend(frames)
        if leg is not None:
            leg.step(knee, ankle)

    def handle(self, msg: can.Message, now_s: float) -> None:
        """One frame from the bus, received at ``now_s``; the firmware's answer is sent at once. A commit's checks run
        before the firmware is taken (:meth:`~device_bridge.firmware.DeviceFirmware.prepare`): a push never holds up
        a control tick."""
        prepared = self.firmware.prepare(msg)
        with self._lock:
            self._outbox.extend(self.firmware.receive(msg, now_s, prepared))
        self._send()

    def tick(self, now_s: float) -> None:
        """One control tick at ``now_s`` on the caller's thread (the leg's loop), its frames sent; the receive thread
        hands frames over meanwhile."""
        with self._lock:
            self.control_tick(now_s)
        self._send()

    def overrun(self, in_a_row: int, now_s: float) -> None:
        """The leg's loop missed ``in_a_row`` ticks in a row: safe mode, the control-error flag, the reason kept."""
        with self._lock:
            self._outbox.extend(self.firmware.hardware_fault(
                f"the control loop missed {in_a_row} ticks in a row", now_s, thermal=False))
        self._send()

    def step(self, now_s: float) -> None:
        """One period of a stepped rig (:mod:`device_bridge.rig`), on the rig's thread instead of the node's two: every
        frame waiting on the bus, then one control tick, then its frames sent."""
        while (msg := self.bus.recv(0.0)) is not None:
            self.handle(msg, now_s)
        with self._lock:
            self.control_tick(now_s)
        self._send()

    def _control_loop(self) -> None:
        clock = self.clock
        next_tick = clock.monotonic()
        while not self._stop.is_set():
            now = clock.monotonic()
            with self._lock:
                ticks = 0
                while next_tick <= now and ticks < MAX_CATCH_UP_TICKS:
                    self.control_tick(next_tick)
                    next_tick += TICK_S
                    ticks += 1
                if next_tick <= now:          # stalled beyond the catch-up budget: slip instead of racing
                    self.overruns += 1
                    next_tick = now + TICK_S
            self._send()
            clock.wait(self._stop, next_tick + WAKE_S - TICK_S - clock.monotonic())

    def _receive_loop(self) -> None:
        """Hand each frame to the firmware as it arrives and send its answer at once."""
        while not self._stop.is_set():
            try:
                msg = self.bus.recv(0.05)
            except can.CanError:
                if self._stop.is_set():
                    return
                raise
            if msg is None:
                continue
            self._inbox.append((msg, self.clock.monotonic()))
            if self._lock.acquire(blocking=False):      # else the control loop hands it over before its next tick
                try:
                    self._hand_over()
                finally:
                    self._lock.release()
                self._send()
