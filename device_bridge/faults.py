"""A python-can bus that loses, corrupts and reorders the frames it sends: the soak tool's and the tests' wire.

Real CAN controllers reject most corrupted frames by their own CRC; this bus lets corrupted data through on
purpose, to prove that the table's CRC-32 (and the acknowledgement rules) catch what slips past the link layer.
A reordered frame is held back and sent after the next one.
"""

from __future__ import annotations

import math
import random
import threading

import can


class FaultInjectingBus(can.BusABC):
    """Wrap ``inner``; each sent frame is dropped with probability ``drop``, gets one random bit flipped with
    ``corrupt``, or is held and sent after the following frame with ``reorder``.

    Attributes:
        counts: frames sent, dropped, corrupted and reordered so far.
    """

    def __init__(self, inner: can.BusABC, drop: float = 0.0, corrupt: float = 0.0, reorder: float = 0.0,
                 seed: int | None = None) -> None:
        for name, p in (("drop", drop), ("corrupt", corrupt), ("reorder", reorder)):
            if not (math.isfinite(p) and 0.0 <= p < 1.0):
                raise ValueError(f"{name} must be a probability in [0, 1), got {p!r}")
        super().__init__(channel=inner.channel_info)
        self.inner = inner
        self.drop, self.corrupt, self.reorder = drop, corrupt, reorder
        self._rng = random.Random(seed)
        self._held: can.Message | None = None
        self._lock = threading.Lock()
        self.counts = {"sent": 0, "dropped": 0, "corrupted": 0, "reordered": 0}

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        with self._lock:
            self.counts["sent"] += 1
            r = self._rng.random()
            if r < self.drop:
                self.counts["dropped"] += 1
                return
            if r < self.drop + self.corrupt and len(msg.data):
                data = bytearray(msg.data)
                bit = self._rng.randrange(8 * len(data))
                data[bit // 8] ^= 1 << (bit % 8)
                msg = can.Message(arbitration_id=msg.arbitration_id, data=bytes(data), is_extended_id=msg.is_extended_id)
                self.counts["corrupted"] += 1
            elif r < self.drop + self.corrupt + self.reorder and self._held is None:
                self._held = msg
                self.counts["reordered"] += 1
                return
            held, self._held = self._held, None
            self.inner.send(msg, timeout)
            if held is not None:
                self.inner.send(held, timeout)

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        return self.inner.recv(timeout), True

    def shutdown(self) -> None:
        super().shutdown()
        self.inner.shutdown()
