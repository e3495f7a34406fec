"""Forward every frame between two python-can buses: the device bridge as its own process.

In a deployment the CAN adapter belongs to one small process (``quasitune bridge``) that joins the leg's bus
(``socketcan:can0``) to the broker (:class:`~device_bridge.mqtt_bus.MqttBus`). The protocol is end to end (the CRC-32
read-back, heartbeats and telemetry pass through unchanged), so the gateway holds no state.

Towards a bus that carries batches (the broker link) frames travel several to a message: always the rest of their
burst (frames closer than :data:`BURST_GAP_S`: one telemetry sample's three or four frames leave the leg back to back),
and, through :meth:`Gateway.to_broker`, telemetry waits up to :data:`TELEMETRY_WINDOW_S` for the samples after it:
20 messages a second per walking leg instead of 100, which is what lets two API instances read 50 legs on two cores
(``python -m benchmarks fleet``), for at most 50 ms of added latency on a live monitor that draws 30 frames a second.
Any other frame (an acknowledgement, a status) leaves with its burst at once: a push never waits for the window.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Self

import can

from device_bridge.bus_threads import BusThreads
from device_bridge.clock import WALL_CLOCK, Clock
from device_bridge.protocol import is_telemetry


class Gateway(BusThreads):
    """Two threads, one per direction, copying frames from ``a`` to ``b`` and from ``b`` to ``a``.

    Args:
        window_s: towards a bus that carries batches, how long a message may stay open after its first frame (s)
            while every frame in it ``may_wait``.
        may_wait: which frames may wait for the window (None: none; each message is one burst).

    Attributes:
        forwarded: frames copied each way (``a_to_b``, ``b_to_a``); ``dropped``: frames a full bus refused.
    """

    def __init__(self, a: can.BusABC, b: can.BusABC, window_s: float = 0.0,
                 may_wait: Callable[[can.Message], bool] | None = None, clock: Clock = WALL_CLOCK) -> None:
        if not 0.0 <= window_s <= 1.0:
            raise ValueError(f"window_s must be in [0, 1] s, got {window_s!r}")
        self.a, self.b = a, b
        self.window_s, self.may_wait = window_s, may_wait
        self.clock = clock
        self.forwarded = {"a_to_b": 0, "b_to_a": 0}
        self.dropped = 0
        super().__init__([a, b])
        self._threads = [threading.Thread(target=self._pump, args=(a, b, "a_to_b"), daemon=True, name="gw-a-b"),
                         threading.Thread(target=self._pump, args=(b, a, "b_to_a"), daemon=True, name="gw-b-a")]

    @classmethod
    def to_broker(cls, leg: can.BusABC, broker: can.BusABC) -> Self:
        """The bridge at the leg: its CAN bus to the broker link, telemetry batched over :data:`TELEMETRY_WINDOW_S`."""
        return cls(leg, broker, window_s=TELEMETRY_WINDOW_S, may_wait=is_telemetry)

    def wait(self, timeout_s: float | None = None) -> bool:
        """Block until :meth:`close` or for ``timeout_s``; whether it was closed."""
        return self._stop.wait(timeout_s)

    def _pump(self, src: can.BusABC, dst: can.BusABC, key: str) -> None:
        batching = callable(getattr(dst, "send_batch", None))   # the broker link: one message per burst of frames
        while not self._stop.is_set():
            msg = src.recv(timeout=0.1)
            if msg is None:
                continue
            frames = [_copy(msg)]
            if batching:
                self._fill(src, frames)
            try:
                if batching:
                    dst.send_batch(frames)
                else:
                    dst.send(frames[0])
                self.forwarded[key] += len(frames)
            except can.CanError:
                self.dropped += len(frames)


    def _fill(self, src: can.BusABC, frames: list[can.Message]) -> None:
        """The rest of a message begun with ``frames[0]``: the rest of its burst, and while every frame in it may
        wait, what else comes before the window closes (then the rest of that burst: a sample is never split)."""
        closes_at = self.clock.monotonic() + self.window_s
        waiting = self.may_wait is not None and self.window_s > 0.0 and self.may_wait(frames[0])
        while len(frames) < MAX_BATCH:
            timeout = max(closes_at - self.clock.monotonic(), BURST_GAP_S) if waiting else BURST_GAP_S
            more = src.recv(timeout=timeout)
            if more is None:
                return
            frames.append(_copy(more))
            waiting = waiting and self.may_wait(more)


BURST_GAP_S = 0.002         # frames closer than this travel in one broker message (one 10 ms telemetry sample)
TELEMETRY_WINDOW_S = 0.05   # through the broker, telemetry waits up to this long for more to share its message
MAX_BATCH = 64              # at most this many frames in one message (a push's data frames, in a few messages)


def _copy(msg: can.Message) -> can.Message:
    return can.Message(arbitration_id=msg.arbitration_id, data=bytes(msg.data), is_extended_id=msg.is_extended_id,
                       is_remote_frame=msg.is_remote_frame, is_fd=msg.is_fd, dlc=msg.dlc, timestamp=msg.timestamp)
