"""One API instance's connection to the broker, shared by every leg it serves.

A server that opened one MQTT client per leg ran a network thread, a receive thread and a heartbeat thread for each:
at 10 legs an instance spent more than half a core switching between them (``python -m benchmarks fleet``). Here one
paho client subscribes to the ``up`` and ``late`` topics of each attached leg (:class:`~device_bridge.mqtt_bus.MqttBus`
with ``connection=``) and one dispatch thread hands each message to its leg: paho's network thread only queues
what arrives, so a slow callback of one leg (a database write on a status) never holds back the network, the
acknowledgements of the QoS 1 messages or the heartbeats the instance sends.

The client id is its identity's, ``server-{name}`` (bound to the identity at the broker, :func:`client_id_of`), with a
persistent session when the instance is named, so each instance (each with an identity of its own) reads every frame of
its legs and the broker keeps the QoS 1 frames that arrive while it reconnects.
"""

from __future__ import annotations

import logging
import queue
import threading

import paho.mqtt.client as mqtt

from device_bridge.mqtt_bus import TOPIC_PREFIX, MqttBus, broker_client, client_id_of, topic

log = logging.getLogger(__name__)


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
        self._client, address = broker_client(broker, client_id_of("server", username), username, password,
                                              ca_file, insecure, clean_session=not instance)
        self.description = f"mqtt server{f' {instance}' if instance else ''} @ {address.host}:{address.port}"
        self._buses: dict[str, MqttBus] = {}
        self._pending: dict[int, MqttBus] = {}     # subscription message id -> the leg it subscribes
        self._lock = threading.Lock()
        self._connected = threading.Event()
        self.refused: str | None = None
        self._inbox: queue.SimpleQueue[tuple[str, bytes] | None] = queue.SimpleQueue()
        self._client.reconnect_delay_set(min_delay=1, max_delay=8)
        self._client.max_queued_messages_set(0)
        self._client.on_connect = self._on_connect
        self._client.on_disconnect = self._on_disconnect
        self._client.on_subscribe = self._on_subscribe
        self._client.on_message = lambda _c, _u, m: self._inbox.put((m.topic, m.payload))
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
        """Each message to its leg, in arrival order (one thread for all legs: see the module)."""
        prefix = TOPIC_PREFIX + "/"
        while (item := self._inbox.get()) is not None:
            name, payload = item
            device_id, _, direction = name.removeprefix(prefix).rpartition("/")
            bus = self._buses.get(device_id)
            if bus is None:
                continue
            try:
                bus.deliver(direction, payload)
            except Exception:     # one leg's failing callback must not stop the others' frames
                log.exception("broker link: delivering a message of %s failed", device_id)

    def close(self) -> None:
        self._inbox.put(None)
        self._dispatcher.join(timeout=5.0)
        self._client.disconnect()
        self._client.loop_stop()
