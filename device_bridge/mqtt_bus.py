"""CAN frames through an MQTT broker, as a python-can bus: the leg's link beyond one room.

The leg's bridge (``quasitune bridge --broker``) and the API server both connect out to a broker (Mosquitto over TLS)
with identities of their own; the frames travel unchanged inside MQTT messages, so everything the CAN protocol checks
(the CRC read-back of a push, heartbeats, safe mode, the telemetry sequence) stays end to end: a broker or a bridge
that altered a frame is caught by the protocol exactly as a noisy bus is.

* Topics, per device: ``quasitune/v1/devices/{device_id}/up`` (the leg's frames: telemetry, status, health,
  acknowledgements) and ``…/down`` (the server's: heartbeats, pushes, commands). The broker's access rules let a
  device publish only its own ``up`` and read only its own ``down``, and only the server publish ``down``.
* Payload: classic CAN frames of 11 bytes each: the 11-bit id (u16 little-endian), the data length (u8, 0-8) and 8
  data bytes (zero-padded). The server's (``down``) are frames only; the leg's (``up`` and ``late``) are records of
  (the time the frames left the leg's bus, f64 Unix s; their count, u8; the frames), one per burst, so the server can
  tell a status that was in flight when the link broke, and arrives first when it returns, from the leg's state now
  (:meth:`device_bridge.host.DeviceLink._current`). A message that is not whole frames or records, or a frame whose
  id or length is out of range, is dropped whole and counted in :attr:`MqttBus.malformed`.
* Batching: :meth:`MqttBus.send_batch` puts frames in one message. The bridge (:meth:`Gateway.to_broker
  <device_bridge.gateway.Gateway.to_broker>`) sends a burst of frames (one telemetry sample's three or four leave the
  leg back to back every 10 ms) in one message, and lets telemetry wait up to 50 ms for the samples after it: 20
  messages a second per walking leg instead of 300-400 frames; an acknowledgement or a status leaves at once.
* **Up (the leg's frames): QoS 1**, persistent sessions: at least once (a repeated telemetry sample is joined once on
  its sequence number, a repeated acknowledgement is an answer already had), so nothing the leg sent in the moment
  the link broke is lost.
* **Down (the server's frames): QoS 0**, at most once: a frame that cannot be delivered now must never be delivered
  later. The protocol retries what matters itself (a transfer until its CRC is read back, the heartbeat every 20 ms),
  and a stale one is harmful: a transfer the broker redelivered to a leg after a restart was staged again as a "new
  table" and ended a supervised safe mode the host had not lifted (found by the link-cut test, 1 run in 10).
* **Store and forward** (the leg's side, with a :class:`~device_bridge.late_buffer.LateBuffer`): while the broker is
  out of reach the leg's messages go to the bounded buffer on disk instead of into the link, each with the time it
  left the leg's bus; once the link is back they are delivered, oldest first, on ``…/{id}/late``: records of
  (time f64 Unix s, frame count u8, the frames), several to a message. They are *late*: the server takes the
  telemetry from them for the session record (at the time each sample was made) and nothing else, since a status or
  an acknowledgement from a minute ago says nothing about the leg now.

paho-mqtt (the Eclipse client) keeps the connection: TLS, reconnection with back-off, the QoS 1 retries upward.
"""

from __future__ import annotations

import math
import queue
import ssl
import struct
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from typing import Protocol
from urllib.parse import urlsplit

import can
import paho.mqtt.client as mqtt
from paho.mqtt.enums import CallbackAPIVersion

from device_bridge.gateway import BURST_GAP_S
from device_bridge.late_buffer import WRITE_PERIOD_S, LateBuffer

FRAME = struct.Struct("<HB8s")          # id, dlc, data
LATE_RECORD = struct.Struct("<dB")      # when the frames left the leg's bus (Unix s), how many follow
LATE_CHUNK_BYTES = 48 * 1024            # a late message carries at most about this much
MAX_MESSAGE_BYTES = 64 * 1024           # nothing larger is read (the broker's max_packet_size refuses it first)
TOPIC_PREFIX = "quasitune/v1/devices"
Role = str   # "server" (sends down, reads up) or "device" (sends up, reads down)


class SharedConnection(Protocol):
    """What a bus needs of a server instance's one broker connection (:class:`device_bridge.mqtt_connection.
    MqttConnection` is one): a bus attaches to it, publishes through it and detaches; the connection module imports
    this one, never the other way round."""

    description: str

    def attach(self, bus: MqttBus) -> None: ...
    def detach(self, bus: MqttBus) -> None: ...
    def publish(self, topic_name: str, payload: bytes, qos: int) -> object: ...



def topic(device_id: str, direction: str) -> str:
    """The topic of one device's frames in one direction (``up`` from the leg, ``down`` to it)."""
    if direction not in ("up", "down", "late"):
        raise ValueError(f"direction must be 'up', 'down' or 'late', got {direction!r}")
    if not device_id or any(c in device_id for c in "/+#") or len(device_id) > 64:
        raise ValueError(f"a device id is 1-64 characters without '/', '+' or '#', got {device_id!r}")
    return f"{TOPIC_PREFIX}/{device_id}/{direction}"


def pack_frames(frames: Iterable[can.Message]) -> bytes:
    """Classic 11-bit CAN frames as one payload (ValueError for a frame the link does not carry)."""
    out = bytearray()
    for f in frames:
        if f.is_extended_id or f.is_fd or f.is_remote_frame or not 0 <= f.arbitration_id <= 0x7FF:
            raise ValueError(f"only classic 11-bit data frames travel the broker link, not {f!r}")
        data = bytes(f.data)
        if len(data) > 8:
            raise ValueError(f"a classic CAN frame carries at most 8 bytes, got {len(data)}")
        out += FRAME.pack(f.arbitration_id, len(data), data.ljust(8, b"\0"))
    return bytes(out)


def unpack_frames(payload: bytes) -> list[can.Message]:
    """The frames of one payload; ValueError (nothing returned) for a payload that is not whole frames."""
    if not payload or len(payload) % FRAME.size:
        raise ValueError(f"a payload of {len(payload)} bytes is not a whole number of {FRAME.size}-byte frames")
    frames = []
    for offset in range(0, len(payload), FRAME.size):
        arbitration_id, dlc, data = FRAME.unpack_from(payload, offset)
        if arbitration_id > 0x7FF or dlc > 8:
            raise ValueError(f"frame {offset // FRAME.size}: id 0x{arbitration_id:x} or length {dlc} out of range")
        frames.append(can.Message(arbitration_id=arbitration_id, data=data[:dlc], is_extended_id=False,
                                  timestamp=time.time()))
    return frames


def _bursts(frames: list[can.Message], gap_s: float = BURST_GAP_S) -> Iterator[tuple[float, list[can.Message]]]:
    """Frames in runs that left the leg's bus within ``gap_s`` of each run's first (one telemetry sample each), with
    that first frame's time (Unix s; now for frames without one)."""
    run: list[can.Message] = []
    for f in frames:
        if run and abs((f.timestamp or 0.0) - (run[0].timestamp or 0.0)) > gap_s:
            yield run[0].timestamp or time.time(), run
            run = []
        run.append(f)
    if run:
        yield run[0].timestamp or time.time(), run


def pack_late(records: Iterable[tuple[float, bytes]]) -> bytes:
    """Buffered messages (time they left the leg's bus, their packed frames) as one late payload."""
    out = bytearray()
    for at, frames in records:
        out += LATE_RECORD.pack(at, len(frames) // FRAME.size) + frames
    return bytes(out)


def unpack_late(payload: bytes) -> list[tuple[float, list[can.Message]]]:
    """The records of a late payload, each (time, frames) with the frames stamped at that time; ValueError (nothing
    returned) for a payload that is not whole records."""
    out, offset = [], 0
    while offset < len(payload):
        if len(payload) - offset < LATE_RECORD.size:
            raise ValueError(f"a late payload ends inside a record header at byte {offset}")
        at, count = LATE_RECORD.unpack_from(payload, offset)
        offset += LATE_RECORD.size
        end = offset + count * FRAME.size
        if count == 0 or end > len(payload):
            raise ValueError(f"a late record at byte {offset} claims {count} frames past the payload's end")
        frames = unpack_frames(payload[offset:end])
        for f in frames:
            f.timestamp = at
        out.append((at, frames))
        offset = end
    return out


# A leg's time stamps are its bridge's clock, not the server's: the server never lets one decide whether it hears the
# leg. A record stamped more than CLOCK_AHEAD_S after it arrived (a bridge clock set ahead, or a forged time) is taken
# at its arrival time and counted: less than the host's STALE_STATUS_S (1 s), so no time a leg sends can make its real
# statuses look more than a second late (one status 2 s ahead made them "stale" for 98 s). A time that is not a finite
# number, or older than OLDEST_RECORD_S (no buffer keeps a record that long), is refused and counted.
CLOCK_AHEAD_S = 0.5
OLDEST_RECORD_S = 30 * 24 * 3600.0


def checked_records(records: list[tuple[float, list[can.Message]]], arrived_s: float
                    ) -> tuple[list[tuple[float, list[can.Message]]], int, int]:
    """(the records a server may use, how many were refused for their time, how many were taken at their arrival
    time instead of a time ahead of it): see :data:`CLOCK_AHEAD_S`. Frames are stamped with their record's time."""
    kept, refused, clamped = [], 0, 0
    for at, frames in records:
        if not math.isfinite(at) or at < arrived_s - OLDEST_RECORD_S:
            refused += 1
            continue
        if at > arrived_s + CLOCK_AHEAD_S:
            at, clamped = arrived_s, clamped + 1
            for f in frames:
                f.timestamp = at
        kept.append((float(at), frames))
    return kept, refused, clamped


@dataclass(frozen=True)
class BrokerAddress:
    """``mqtts://HOST:PORT`` (TLS, the deployment) or ``mqtt://HOST:PORT`` (plain: only with ``insecure=True``, for a
    bench on an isolated network)."""

    host: str
    port: int
    tls: bool

    @classmethod
    def parse(cls, url: str) -> BrokerAddress:
        parts = urlsplit(url)
        if parts.scheme not in ("mqtts", "mqtt") or not parts.hostname:
            raise ValueError(f"broker must be mqtts://HOST:PORT (or mqtt:// on an isolated bench), got {url!r}")
        return cls(parts.hostname, parts.port or (8883 if parts.scheme == "mqtts" else 1883), parts.scheme == "mqtts")


def identity_name(role: str, name: str) -> str:
    """An identity's user name at the broker, which is also its one client id: ``device-{device id}`` for a leg's
    bridge, ``server-{name}`` for an API instance. The prefix is the namespace: a leg's identity can never be named
    like a server's or the broker's admin (whose name is in neither), so issuing a leg's credentials cannot replace
    theirs. The broker binds the client id to the identity when it is made
    (:meth:`~device_bridge.broker_admin.BrokerAdmin.add_device`), so no identity can connect under another's client
    id and inherit its session, its subscriptions or knock it off the broker."""
    if role not in ("device", "server"):
        raise ValueError(f"an identity's role is 'device' or 'server', got {role!r}")
    return f"{role}-{name}"


def broker_client(broker: str, client_id: str, username: str, password: str, ca_file: str | None = None,
                  insecure: bool = False, clean_session: bool = True) -> tuple[mqtt.Client, BrokerAddress]:
    """A paho client (MQTT 3.1.1) for ``broker`` with this identity, TLS against ``ca_file`` (None: the system's CAs),
    not yet connected, and the broker's address. ValueError for a plain ``mqtt://`` address unless ``insecure`` (a
    bench on an isolated network): every link to the broker, the legs', the servers' and the admin's, is TLS."""
    address = BrokerAddress.parse(broker)
    if not address.tls and not insecure:
        raise ValueError("the broker link is TLS only (mqtts://); a plain mqtt:// link needs insecure=True and an "
                         "isolated network")
    client = mqtt.Client(CallbackAPIVersion.VERSION2, client_id=client_id, clean_session=clean_session,
                         protocol=mqtt.MQTTv311)
    client.username_pw_set(username, password)
    if address.tls:
        client.tls_set(ca_certs=ca_file, cert_reqs=ssl.CERT_REQUIRED, tls_version=ssl.PROTOCOL_TLS_CLIENT)
    return client, address


class MqttBus(can.BusABC):
    """One device's frames through the broker, seen from the server (``role="server"``) or from the leg's bridge
    (``role="device"``).

    Args:
        channel: the device id.
        broker: ``mqtts://HOST:PORT``.
        username, password: this client's identity at the broker (the device's, or the server's).
        ca_file: the CA that signed the broker's certificate (QuasiTune's own); None for the system's.
        instance: unused by a bus of its own (its client id is its identity's user name, :func:`identity_name`: several
            instances each need an identity of their own, as each keeps a session of its own and reads every frame).
        connect_timeout_s: how long the constructor waits for the first connection before it fails loudly.
        late_buffer: the leg's side only: where its messages wait while the broker is out of reach (see the module);
            None: paho keeps them in memory and sends them on reconnection as if they were new.
        connection: the server's side: an instance's one :class:`~device_bridge.mqtt_connection.MqttConnection`
            shared by all its legs (then ``broker``, the identity and ``instance`` are the connection's); None: a
            client of this bus's own.

    Attributes:
        on_late: the server's side: called (from paho's thread, or the shared connection's dispatch thread) with each
            late message's records, (time, frames); unset, late messages are counted in :attr:`late_unclaimed` and
            dropped.
        on_frames: with a shared connection, called with each message's frames (see :attr:`delivers_frames`).
    """

    # how long a push waits for the leg's acknowledgement before asking again (s): a TLS round trip through a broker
    # across the internet, not a CAN bus's millisecond (device_bridge.host.DeviceLink reads it)
    round_trip_s = 0.25
    # the server's heartbeat period through a broker (s): four beats in the leg's 200 ms watchdog, a fifth of the
    # messages of the CAN bus's 20 ms (50 legs at 20 ms were as many messages as their telemetry)
    heartbeat_period_s = 0.05

    def __init__(self, channel: str, broker: str | None = None, username: str | None = None,
                 password: str | None = None, role: Role = "server", ca_file: str | None = None,
                 instance: str | None = None, insecure: bool = False, connect_timeout_s: float = 10.0,
                 late_buffer: LateBuffer | None = None, connection: SharedConnection | None = None,
                 **kwargs: object) -> None:
        if role not in ("server", "device"):
            raise ValueError(f"role must be 'server' or 'device', got {role!r}")
        if connection is not None and role != "server":
            raise ValueError("only the server's side shares a connection among legs")
        self.device_id, self.role = channel, role
        self._send_topic = topic(channel, "down" if role == "server" else "up")
        self._recv_topic = topic(channel, "up" if role == "server" else "down")
        self._late_topic = topic(channel, "late")
        self._late_buffer = late_buffer if role == "device" else None
        self.on_late: Callable[[list[tuple[float, list[can.Message]]]], None] | None = None
        self.on_frames: Callable[[list[can.Message]], None] | None = None
        self.late_unclaimed = 0
        self.late_delivered = 0   # the leg's side: buffered messages the broker acknowledged
        self._rx: queue.Queue[can.Message] = queue.Queue()
        self._connected = threading.Event()
        self.malformed = 0
        self.oversized = 0          # messages over MAX_MESSAGE_BYTES, dropped unread
        self.refused_times = 0      # the leg's records refused for an impossible time (checked_records)
        self.clamped_times = 0      # … taken at their arrival time instead of a time ahead of it
        self.refused: str | None = None
        self._connection = connection
        self._client: mqtt.Client | None = None
        if connection is not None:
            self.channel_info = f"mqtt server {channel} @ {connection.description}"
            connection.attach(self)
        else:
            if broker is None or username is None or password is None:
                raise ValueError("a broker link needs the broker's address and an identity (or a shared connection)")
            self._client, address = broker_client(broker, username, username, password, ca_file,
                                                  insecure, clean_session=False)
            self.channel_info = f"mqtt {role} {channel} @ {address.host}:{address.port}"
            self._start_client(address)
        if not self._connected.wait(connect_timeout_s):
            if connection is not None:
                connection.detach(self)
            else:
                self._client.loop_stop()
            why = self.refused or "no answer"
            raise can.CanInitializationError(f"{self.channel_info}: could not connect ({why})")
        super().__init__(channel=channel, **kwargs)
        self._drain_stop = threading.Event()
        self._drainer: threading.Thread | None = None
        if self._late_buffer is not None:
            self._drainer = threading.Thread(target=self._drain, name=f"mqtt-late-{channel}", daemon=True)
            self._drainer.start()

    def _start_client(self, address: BrokerAddress) -> None:
        """Connect this leg's own client (the bridge's side; a server serving one leg) in the background."""
        client = self._client
        client.reconnect_delay_set(min_delay=1, max_delay=8)
        client.max_queued_messages_set(0)
        client.on_connect = self._on_connect
        client.on_disconnect = self._on_disconnect
        client.on_message = self._on_message
        client.on_subscribe = self._on_subscribe
        client.connect_async(address.host, address.port, keepalive=5)
        client.loop_start()

    @property
    def delivers_frames(self) -> bool:
        """True when the frames come through :attr:`on_frames`, called from a shared connection's dispatch thread
        (:class:`~device_bridge.mqtt_connection.MqttConnection`), instead of :meth:`recv`: a reader then needs no
        thread of its own."""
        return self._connection is not None

    def link_up(self) -> None:
        """(the shared connection) The leg's topics are read again: frames may be sent."""
        self._connected.set()

    def link_down(self) -> None:
        """(the shared connection) The broker is out of reach: nothing is sent until :meth:`link_up`."""
        self._connected.clear()

    # paho's callbacks (its network thread)
    def _on_connect(self, client, _userdata, _flags, reason_code, _properties) -> None:
        if reason_code.is_failure:
            self.refused = str(reason_code)
            return
        self.refused = None
        wanted = [(self._recv_topic, 1)] + ([(self._late_topic, 1)] if self.role == "server" else [])
        client.subscribe(wanted)

    def _on_subscribe(self, _client, _userdata, _mid, reason_codes, _properties) -> None:
        if any(rc.is_failure for rc in reason_codes):     # the broker's rules refused this client the topic
            self.refused = f"not allowed to read {self._recv_topic}"
            return
        self._connected.set()     # connected and reading: nothing sent to it from now on is missed

    def _on_disconnect(self, _client, _userdata, _flags, reason_code, _properties) -> None:
        self._connected.clear()
        if reason_code.is_failure:
            self.refused = str(reason_code)

    def _on_message(self, _client, _userdata, message) -> None:
        self.deliver("late" if message.topic == self._late_topic else "frames", message.payload)

    def deliver(self, direction: str, payload: bytes) -> None:
        """One message from the broker: a late one (``direction`` ``late``) to :attr:`on_late`, else its frames to
        :attr:`on_frames` or the receive queue (the leg's stamped with the time they left its bus); a malformed one is
        counted and dropped whole."""
        if len(payload) > MAX_MESSAGE_BYTES:
            self.oversized += 1
            return
        try:
            if direction == "late" or self.role == "server":   # the leg's: records of (when they left its bus, frames)
                records, refused, clamped = checked_records(unpack_late(payload), time.time())
                self.refused_times += refused
                self.clamped_times += clamped
                frames = [f for _, run in records for f in run]
            else:
                frames = unpack_frames(payload)
        except ValueError:
            self.malformed += 1
            return
        if direction == "late":
            if not records:
                return
            if self.on_late is None:
                self.late_unclaimed += 1
            else:
                self.on_late(records)
            return
        if not frames:
            return
        if self.on_frames is not None:
            self.on_frames(frames)
            return
        for f in frames:
            self._rx.put(f)

    @property
    def connected(self) -> bool:
        return self._connected.is_set()

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        self.send_batch([msg])

    def send_batch(self, frames: list[can.Message]) -> None:
        """Frames in one message (up: QoS 1; down: QoS 0, see the module). While the link is down: the leg's side keeps
        them in its late buffer (without one, paho keeps them in memory and sends them on reconnection); the server's
        side refuses them (CanOperationError): a heartbeat, a command or a push frame from minutes ago must not reach
        the leg."""
        bursts = [(at, pack_frames(burst)) for at, burst in _bursts(frames)] if self.role == "device" else []
        payload = pack_late(bursts) if self.role == "device" else pack_frames(frames)
        if not self._connected.is_set():
            if self.role == "server":
                raise can.CanOperationError(f"{self.channel_info}: the link to the broker is down; not sent")
            if self._late_buffer is not None:     # one record per burst, each at the time it left the leg's bus
                for at, packed in bursts:
                    self._late_buffer.append(at, packed)
                return
        qos = 1 if self.role == "device" else 0
        info = self._client.publish(self._send_topic, payload, qos=qos) if self._connection is None else \
            self._connection.publish(self._send_topic, payload, qos)
        if info.rc not in (mqtt.MQTT_ERR_SUCCESS, mqtt.MQTT_ERR_NO_CONN):
            raise can.CanOperationError(f"{self.channel_info}: publish refused ({mqtt.error_string(info.rc)})")

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        try:
            return self._rx.get(timeout=timeout), False
        except queue.Empty:
            return None, False

    def _drain(self) -> None:
        """The leg's side: write the buffer to disk every few tenths of a second and, while the link is up, deliver
        it oldest first; a chunk is forgotten only once the broker acknowledged it (a chunk delivered twice, after a
        cut at the wrong moment, is joined once by the server on its sequence numbers)."""
        buffer = self._late_buffer
        assert buffer is not None
        while not self._drain_stop.wait(WRITE_PERIOD_S):
            buffer.write_pending()
            while self._connected.is_set() and not self._drain_stop.is_set():
                chunk = buffer.oldest(LATE_CHUNK_BYTES)
                if not chunk:
                    break
                info = self._client.publish(self._late_topic, pack_late((at, p) for _, at, p in chunk), qos=1)
                try:
                    info.wait_for_publish(timeout=5.0)
                except (RuntimeError, ValueError):
                    break
                if not info.is_published():
                    break
                buffer.forget_through(chunk[-1][0])
                self.late_delivered += len(chunk)

    def shutdown(self) -> None:
        self._drain_stop.set()
        if self._drainer is not None:
            self._drainer.join(timeout=10.0)
        if self._late_buffer is not None:
            self._late_buffer.close()
        if self._connection is not None:
            self._connection.detach(self)
        else:
            self._client.disconnect()
            self._client.loop_stop()
        super().shutdown()
