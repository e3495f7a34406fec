"""A stepped rig: the leg's firmware, its leg and the host's link stepped together on one thread in simulated time.

What runs on a bench as three pieces with five threads (the device node's control and receive threads, the link's
receive and heartbeat threads, the leg in between) runs here as one loop over a :class:`SteppedClock`: every 1 ms
step the host beats when its period is due, the node takes the frames waiting for it and runs one control tick, and
the link takes the frames the node sent. Nothing waits on the wall clock, so a minute of walking, a heartbeat loss
or a push through a lossy wire costs only the CPU it needs, and the same inputs (leg, configuration, fault seed)
give the same frames: :attr:`Rig.frames` logs every one, with the step it was sent at, for tests that say so.

A wait on the rig's clock drives the rig (:mod:`device_bridge.clock`): ``rig.link.push(...)`` returns once the node
acknowledged, after the simulated milliseconds that took; :meth:`Rig.run_until` steps until a condition holds.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from typing import Any, Self

import can

from device_bridge.clock import SteppedClock
from device_bridge.device_node import TICK_S, DeviceNode, Leg
from device_bridge.faults import FaultInjectingBus
from device_bridge.firmware import FirmwareConfig
from device_bridge.host import DeviceLink
from device_bridge.remote_calibration import CalibrationPort


class RigBus(can.BusABC):
    """One end of an in-memory CAN wire: a frame sent is stamped with the clock's Unix time, logged, and waits in the
    other end's inbox; receiving never blocks. Ours because python-can's ``virtual`` bus stamps the wall clock (the
    link judges a status's age by its stamp) and hands frames across threads."""

    def __init__(self, clock: SteppedClock, log: list[tuple[int, str, int, bytes]] | None, name: str) -> None:
        super().__init__(channel=name)
        self.channel_info = f"rig:{name}"
        self._clock, self._log, self._name = clock, log, name
        self._inbox: deque[can.Message] = deque()
        self.peer: RigBus | None = None

    @classmethod
    def pair(cls, clock: SteppedClock, log: list[tuple[int, str, int, bytes]] | None) -> tuple[RigBus, RigBus]:
        """The host's end and the device's end of one wire (``log``: where to note every frame, or None)."""
        host, device = cls(clock, log, "host"), cls(clock, log, "device")
        host.peer, device.peer = device, host
        return host, device

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        data = bytes(msg.data)
        if self._log is not None:
            self._log.append((self._clock.steps, self._name, msg.arbitration_id, data))
        self.peer._inbox.append(can.Message(timestamp=self._clock.time(), arbitration_id=msg.arbitration_id,
                                            data=data, is_extended_id=msg.is_extended_id))

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        return (self._inbox.popleft() if self._inbox else None), False


def _with_faults(bus: can.BusABC, faults: dict[str, float] | None, seed: int) -> can.BusABC:
    return bus if not faults else FaultInjectingBus(bus, seed=seed, **faults)


class Rig:
    """A :class:`DeviceNode` with ``leg`` and ``config`` and a :class:`DeviceLink` on one wire, stepped every
    :data:`~device_bridge.device_node.TICK_S` by :attr:`clock`.

    Args:
        leg: the leg the node drives (e.g. :class:`device_bridge.sim.walker.SimWalker`), or none.
        config: the firmware's settings.
        heartbeat_period_s: the host's heartbeat period (a whole number of steps).
        to_device, to_host: faults of each direction (``drop``, ``corrupt``, ``reorder`` probabilities,
            :class:`device_bridge.faults.FaultInjectingBus`), drawn from ``seed``.
        clock: a clock shared with other rigs or pieces (a server's, in tests); default a clock of its own.
        keep_frames: log every frame in :attr:`frames` (a long-running rig says no).
        calibration: the leg's calibration port (a leg with sensors to calibrate from the clinic).
        link_kwargs: the link's callbacks (``on_status``, ``on_telemetry``).

    Attributes:
        frames: every frame sent, as (step, "host" or "device", arbitration id, data), in the order sent.
    """

    def __init__(self, leg: Leg | None = None, config: FirmwareConfig | None = None, heartbeat_period_s: float = 0.02,
                 to_device: dict[str, float] | None = None, to_host: dict[str, float] | None = None, seed: int = 0,
                 clock: SteppedClock | None = None, keep_frames: bool = True,
                 calibration: CalibrationPort | None = None, **link_kwargs: Any) -> None:
        self.clock = clock if clock is not None else SteppedClock(TICK_S)
        if self.clock.step_s != TICK_S:
            raise ValueError(f"a rig steps every control tick ({TICK_S} s), its clock every {self.clock.step_s} s")
        self.frames: list[tuple[int, str, int, bytes]] = []
        self._host_end, self._device_end = RigBus.pair(self.clock, self.frames if keep_frames else None)
        self.node = DeviceNode(_with_faults(self._device_end, to_host, seed + 1), leg=leg, config=config,
                               clock=self.clock, calibration=calibration)
        self.link = DeviceLink(_with_faults(self._host_end, to_device, seed), heartbeat_period_s=heartbeat_period_s,
                               clock=self.clock, **link_kwargs)
        self._beat_every = max(1, round(heartbeat_period_s / TICK_S))
        self.clock.add(self._step)

    def _step(self, now_s: float) -> None:
        if (self.clock.steps - 1) % self._beat_every == 0:
            self.link.beat()
        self.node.step(now_s)
        frames = []
        while (msg := self.link.bus.recv(0.0)) is not None:
            frames.append(msg)
        if frames:
            self.link.receive(frames)

    def advance(self, seconds: float) -> None:
        """Run ``seconds`` of simulated time."""
        self.clock.advance(seconds)

    def run_until(self, done: Callable[[], bool], timeout_s: float = 5.0) -> None:
        """Step until ``done()`` holds; AssertionError (a test's failure) after ``timeout_s`` simulated seconds."""
        if not self.clock.until(done, timeout_s):
            raise AssertionError(f"condition not reached within {timeout_s:g} s of simulated time")

    def close(self) -> None:
        self.clock.remove(self._step)
        self.link.close()
        self.node.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
