"""One API instance's connection to the broker, shared by every leg it serves.

A server that opened one MQTT client per leg ran a network thread, a receive thread and a heartbeat thread for each:
at 10 legs an instance spent more than half a core switching between them (``python -m benchmarks fleet``). Here one
paho client subscribes to the ``up`` and ``late`` topics of each attached leg (:class:`~device_bridge.mqtt_bus.MqttBus`
with ``connection=``) and one dispatch thread hands each message to its leg: paho's network thread only queues
what arrives, so a slow callback of one leg (a database write on a status) never holds back the network, the
acknowledgements of the QoS 1 messages or the heartbeats the instance sends. Live messages go before late ones (what a
bridge kept while its link was down), and late ones are taken one leg at a time in turn, each leg holding at most
:data:`LATE_QUEUED_PER_LEG` (beyond, dropped and counted) and handed over within a budget of bytes per second
(:data:`LATE_BYTES_PER_S_PER_LEG`): one leg's backlog never delays another leg's status (300 late messages of one leg
kept another offline for 28.6 s).

The client id is its identity's user name, ``server-{name}`` (bound to it at the broker, :func:`identity_name`), with a
persistent session when the instance is named, so each instance (each with an identity of its own) reads every frame of
its legs and the broker keeps the QoS 1 frames that arrive while it reconnects.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import Counter, deque
from collections.abc import Callable

import paho.mqtt.client as mqtt

from device_bridge.mqtt_bus import TOPIC_PREFIX, MqttBus, broker_client, topic

log = logging.getLogger(__name__)
LATE_QUEUED_PER_LEG = 512     # late messages of one leg waiting to be handed over (about 24 MB at most)
# late bytes handed over per leg per second: 40 times what a walking leg sends live (about 6.6 kB/s), so a 4-hour
# backlog drains in about 6 minutes, while one leg's flood of late messages takes at most this much of the dispatch
# thread's time (300 late messages of 58 kB, parsed back to back, kept another leg's status stale past a second)
LATE_BYTES_PER_S_PER_LEG = 256 * 1024
LATE_BURST_BYTES = 64 * 1024   # what a leg may hand over at once after a pause (the broker's largest message)


class MqttConnection:
    """The shared connection (see the module).

    Args:
        broker: ``mqtts://HOST:PORT`` (``mqtt://`` only with ``insecure=True``, an isolated bench).
        username, password: this instance's identity at the broker (``quasitune broker add-server``).
        ca_file: the CA that signed the broker's certificate; None for the system's.
        instance: this instance's name; given, the broker keeps its session while it reconnects.
        connect_timeout_s: how long the constructor waits for the connection before it fails loudly.
    """

    def __init__(self, broker: str, username: str, password: str, ca_file: str | None = None,
                 instance: str | None = None, insecure: bool = False, connect_timeout_s: float = 10.0) -> None:
        self._client, address = broker_client(broker, username, username, password,
                                              ca_file, insecure, clean_session=not instance)
        self.description = f"mqtt server{f' {instance}' if instance else ''} @ {address.host}:{address.port}"
        self._buses: dict[str, MqttBus] = {}
        self._pending: dict[int, MqttBus] = {}     # subscription message id -> the leg it subscribes
        self._lock = threading.Lock()
        self._connected = threading.Event()
        self.refused: str | None = None
        self._mailbox = LegMailbox()
        self._client.reconnect_delay_set(min_delay=1, max_delay=8)
        self._client.max_queued_messages_set(0)
        self._client.on_connect = self._on_connect
        self._client.on_disconnect = self._on_disconnect
        self._client.on_subscribe = self._on_subscribe
        self._client.on_message = lambda _c, _u, m: self._mailbox.put(m.topic, m.payload)
        self._client.connect_async(address.host, address.port, keepalive=5)
        self._client.loop_start()
        if not self._connected.wait(connect_timeout_s):
            self._client.loop_stop()
            raise ConnectionError(f"{self.description}: could not connect ({self.refused or 'no answer'})")
        self._dispatcher = threading.Thread(target=self._dispatch, name="mqtt-dispatch", daemon=True)
        self._dispatcher.start()

    @property
    def connected(self) -> bool:
        return self._connected.is_set()

    def attach(self, bus: MqttBus) -> None:
        """Read ``bus``'s leg from now on (its ``up`` and ``late`` topics); the bus is connected once the broker
        granted both."""
        with self._lock:
            if bus.device_id in self._buses:
                raise ValueError(f"device {bus.device_id} is attached to this connection already")
            self._buses[bus.device_id] = bus
            if self._connected.is_set():
                self._subscribe(bus)

    def detach(self, bus: MqttBus) -> None:
        with self._lock:
            if self._buses.get(bus.device_id) is bus:
                del self._buses[bus.device_id]
                self._client.unsubscribe([topic(bus.device_id, "up"), topic(bus.device_id, "late")])

    def publish(self, topic_name: str, payload: bytes, qos: int) -> mqtt.MQTTMessageInfo:
        return self._client.publish(topic_name, payload, qos=qos)

    def _subscribe(self, bus: MqttBus) -> None:
        """(under the lock) Ask for the leg's topics; :meth:`_on_subscribe` marks it connected."""
        result, mid = self._client.subscribe([(topic(bus.device_id, "up"), 1), (topic(bus.device_id, "late"), 1)])
        if result == mqtt.MQTT_ERR_SUCCESS and mid is not None:
            self._pending[mid] = bus

    # paho's callbacks (its network thread)
    def _on_connect(self, _client, _userdata, _flags, reason_code, _properties) -> None:
        if reason_code.is_failure:
            self.refused = str(reason_code)
            return
        self.refused = None
        self._connected.set()
        with self._lock:
            for bus in self._buses.values():
                self._subscribe(bus)

    def _on_subscribe(self, _client, _userdata, mid, reason_codes, _properties) -> None:
        with self._lock:
            bus = self._pending.pop(mid, None)
        if bus is None:
            return
        if any(rc.is_failure for rc in reason_codes):     # the broker's rules refused this identity the leg's topics
            bus.refused = f"not allowed to read {topic(bus.device_id, 'up')}"
            return
        bus.refused = None
        bus.link_up()

    def _on_disconnect(self, _client, _userdata, _flags, reason_code, _properties) -> None:
        self._connected.clear()
        if reason_code.is_failure:
            self.refused = str(reason_code)
        with self._lock:
            buses = list(self._buses.values())
        for bus in buses:
            bus.link_down()

    def _dispatch(self) -> None:
        """Each message to its leg (one thread for all legs: see the module)."""
        while (item := self._mailbox.take()) is not None:
            device_id, direction, payload = item
            bus = self._buses.get(device_id)
            if bus is None:
                continue
            try:
                bus.deliver(direction, payload)
            except Exception:     # one leg's failing callback must not stop the others' frames
                log.exception("broker link: delivering a message of %s failed", device_id)

    @property
    def late_dropped(self) -> Counter[str]:
        """Per leg: late messages beyond its share, dropped."""
        return self._mailbox.dropped

    def close(self) -> None:
        self._mailbox.close()
        self._dispatcher.join(timeout=5.0)
        self._client.disconnect()
        self._client.loop_stop()


class LegMailbox:
    """What the network thread received, for the dispatch thread: live messages first, in arrival order; then late
    ones, one leg at a time in turn, each leg holding at most :data:`LATE_QUEUED_PER_LEG` and handed over at most
    :data:`LATE_BYTES_PER_S_PER_LEG` (see the module). ``clock``: monotonic seconds (the budget's)."""

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self._live: deque[tuple[str, bytes]] = deque()      # up messages, in arrival order
        self._late: dict[str, deque[bytes]] = {}             # late messages per leg
        self._turn: deque[str] = deque()                     # legs with late messages waiting, in turn
        self._budget: dict[str, tuple[float, float]] = {}    # per leg: (bytes it may hand over, when last counted)
        self._clock = clock
        self._arrived = threading.Condition()
        self._closing = False
        self.dropped: Counter[str] = Counter()               # per leg: late messages beyond its share

    def put(self, name: str, payload: bytes) -> None:
        """A message on topic ``name`` (from paho's network thread)."""
        with self._arrived:
            if name.endswith("/late"):
                device_id = name.removeprefix(TOPIC_PREFIX + "/").rpartition("/")[0]
                waiting = self._late.setdefault(device_id, deque())
                if len(waiting) >= LATE_QUEUED_PER_LEG:
                    self.dropped[device_id] += 1
                    return
                if not waiting:
                    self._turn.append(device_id)
                waiting.append(payload)
            else:
                self._live.append((name, payload))
            self._arrived.notify()

    def _wait_for_budget_s(self, device_id: str, size: int) -> float:
        """Seconds until ``device_id`` may hand over ``size`` late bytes (0: now, and they are counted)."""
        now = self._clock()
        has, at = self._budget.get(device_id, (LATE_BURST_BYTES, now))
        has = min(LATE_BURST_BYTES, has + (now - at) * LATE_BYTES_PER_S_PER_LEG)
        cost = min(size, LATE_BURST_BYTES)
        if has < cost:
            self._budget[device_id] = (has, now)
            return (cost - has) / LATE_BYTES_PER_S_PER_LEG
        self._budget[device_id] = (has - cost, now)
        return 0.0

    def _next_late(self) -> tuple[tuple[str, str, bytes] | None, float | None]:
        """(the next late message of a leg within its budget, or None; then how long until one is)."""
        soonest = None
        for _ in range(len(self._turn)):
            device_id = self._turn.popleft()
            waiting = self._late[device_id]
            wait_s = self._wait_for_budget_s(device_id, len(waiting[0]))
            if wait_s == 0.0:
                payload = waiting.popleft()
                if waiting:
                    self._turn.append(device_id)     # its next late message after the other legs' turn
                return (device_id, "late", payload), None
            self._turn.append(device_id)
            soonest = wait_s if soonest is None else min(soonest, wait_s)
        return None, soonest

    def take(self, timeout_s: float | None = None) -> tuple[str, str, bytes] | None:
        """The next message, (device id, direction, payload): a live one if any, else one late message of the next
        leg in turn within its budget; None once closed (or after ``timeout_s`` with nothing to hand over)."""
        deadline = None if timeout_s is None else self._clock() + timeout_s
        with self._arrived:
            while True:
                if self._live:
                    name, payload = self._live.popleft()
                    device_id, _, direction = name.removeprefix(TOPIC_PREFIX + "/").rpartition("/")
                    return device_id, direction, payload
                if self._closing:
                    return None
                late, budget_wait_s = self._next_late()
                if late is not None:
                    return late
                left_s = None if deadline is None else deadline - self._clock()
                if left_s is not None and left_s <= 0:
                    return None
                waits = [w for w in (budget_wait_s, left_s) if w is not None]
                self._arrived.wait(min(waits) if waits else None)

    def close(self) -> None:
        with self._arrived:
            self._closing = True
            self._arrived.notify_all()
