"""Forward every frame between two python-can buses: the device bridge as its own process.

In a deployment the CAN adapter belongs to one small process (``quasitune bridge``) that joins the leg's bus
(``socketcan:can0``) to a bus the API server can reach from another process or container — python-can's
``udp_multicast`` on the host. The protocol is end to end (the CRC-32 read-back, heartbeats and telemetry pass
through unchanged), so the gateway holds no state and needs no knowledge of the frames.
"""

from __future__ import annotations

import threading

import can

from device_bridge.bus_threads import BusThreads


class Gateway(BusThreads):
    """Two threads, one per direction, copying frames from ``a`` to ``b`` and from ``b`` to ``a``.

    Attributes:
        forwarded: frames copied each way (``a_to_b``, ``b_to_a``); ``dropped``: frames a full bus refused.
    """

    def __init__(self, a: can.BusABC, b: can.BusABC) -> None:
        self.a, self.b = a, b
        self.forwarded = {"a_to_b": 0, "b_to_a": 0}
        self.dropped = 0
        super().__init__([a, b])
        self._threads = [threading.Thread(target=self._pump, args=(a, b, "a_to_b"), daemon=True, name="gw-a-b"),
                         threading.Thread(target=self._pump, args=(b, a, "b_to_a"), daemon=True, name="gw-b-a")]

    def wait(self) -> None:
        """Block until :meth:`close` (or Ctrl-C in the caller)."""
        self._stop.wait()

    def _pump(self, src: can.BusABC, dst: can.BusABC, key: str) -> None:
        batching = callable(getattr(dst, "send_batch", None))   # the broker link: one message per burst of frames
        while not self._stop.is_set():
            msg = src.recv(timeout=0.1)
            if msg is None:
                continue
            frames = [_copy(msg)]
            while batching and (more := src.recv(timeout=BURST_GAP_S)) is not None and len(frames) < MAX_BATCH:
                frames.append(_copy(more))      # the rest of a telemetry sample: its frames leave back to back
            try:
                if batching:
                    dst.send_batch(frames)
                else:
                    dst.send(frames[0])
                self.forwarded[key] += len(frames)
            except can.CanError:
                self.dropped += len(frames)


BURST_GAP_S = 0.002   # frames closer than this travel in one broker message (one 10 ms telemetry sample)
MAX_BATCH = 64        # at most this many frames in one message (a push's data frames, in a few messages)


def _copy(msg: can.Message) -> can.Message:
    return can.Message(arbitration_id=msg.arbitration_id, data=bytes(msg.data), is_extended_id=msg.is_extended_id,
                       is_remote_frame=msg.is_remote_frame, is_fd=msg.is_fd, dlc=msg.dlc, timestamp=msg.timestamp)
