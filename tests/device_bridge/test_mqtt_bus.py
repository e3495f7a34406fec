"""The leg's link through an MQTT broker over TLS: frames unchanged end to end, a device identity that reads and sends
only its own, revocation at once, and the CAN protocol catching what a broker or bridge alters."""

from __future__ import annotations

import itertools
import ssl
import threading

import can
import paho.mqtt.client as mqtt
import pytest
from paho.mqtt.enums import CallbackAPIVersion

from device_bridge.broker_admin import Identity
from device_bridge.device_node import DeviceNode
from device_bridge.envelope_wire import table_wire
from device_bridge.gateway import Gateway
from device_bridge.host import DeviceLink, PushError
from device_bridge.mqtt_bus import MqttBus, pack_frames, topic, unpack_frames
from device_bridge.protocol import frame_id
from tests.helpers.device import until
from tests.helpers.mosquitto import connect_as

_ids = itertools.count()


def _frame(i: int, data: bytes = b"\x01\x02\x03") -> can.Message:
    return can.Message(arbitration_id=i, data=data, is_extended_id=False)


def _leg(broker_admin, name: str) -> tuple[str, Identity]:
    device_id = f"{name}-{next(_ids)}"
    return device_id, broker_admin.add_device(device_id)


@pytest.fixture
def server_identity(broker_admin) -> Identity:
    return broker_admin.add_server(f"{next(_ids)}")


def test_frames_travel_whole_and_a_payload_that_is_not_whole_frames_is_refused():
    frames = [_frame(0x300, bytes(range(8))), _frame(0x100, b""), _frame(0x7FF, b"\xff")]
    back = unpack_frames(pack_frames(frames))
    assert [(f.arbitration_id, bytes(f.data)) for f in back] == [(f.arbitration_id, bytes(f.data)) for f in frames]
    with pytest.raises(ValueError, match="whole number of 11-byte frames"):
        unpack_frames(pack_frames(frames)[:-1])
    with pytest.raises(ValueError, match="classic 11-bit"):
        pack_frames([can.Message(arbitration_id=0x1FFFFFFF, is_extended_id=True)])
    with pytest.raises(ValueError, match="without '/'"):
        topic("leg/1", "up")


def test_the_link_is_tls_only_unless_a_bench_says_otherwise(broker):
    with pytest.raises(ValueError, match="TLS only"):
        MqttBus("leg", broker.url.replace("mqtts", "mqtt"), "u", "p")


def test_server_and_leg_exchange_frames_batched_both_ways(broker, broker_admin, server_identity):
    device_id, identity = _leg(broker_admin, "leg")
    server = MqttBus(device_id, broker.url, *server_identity, role="server", ca_file=broker.ca_file)
    leg = MqttBus(device_id, broker.url, *identity, role="device", ca_file=broker.ca_file)
    try:
        server.send(_frame(0x100))
        got = leg.recv(5)
        assert got is not None and got.arbitration_id == 0x100 and bytes(got.data) == b"\x01\x02\x03"
        leg.send_batch([_frame(0x300 + k) for k in range(4)])          # one telemetry sample, one message
        assert [server.recv(5).arbitration_id for _ in range(4)] == [0x300, 0x301, 0x302, 0x303]
    finally:
        server.shutdown()
        leg.shutdown()


def _raw_client(broker, username: str, password: str) -> tuple[mqtt.Client, list, threading.Event]:
    """A plain paho client with a leg's identity (and so its one bound client id)."""
    received, subscribed = [], threading.Event()
    c = mqtt.Client(CallbackAPIVersion.VERSION2, client_id=username)
    c.username_pw_set(username, password)
    c.tls_set(ca_certs=broker.ca_file, cert_reqs=ssl.CERT_REQUIRED, tls_version=ssl.PROTOCOL_TLS_CLIENT)
    c.on_message = lambda _c, _u, m: received.append(m.topic)
    c.on_subscribe = lambda _c, _u, _m, codes, _p: (received.extend(str(r) for r in codes if r.is_failure),
                                                    subscribed.set())
    c.connect("127.0.0.1", broker.port)
    c.loop_start()
    return c, received, subscribed


def test_a_device_reads_only_its_own_commands_and_cannot_send_any(broker, broker_admin, server_identity):
    a, a_id = _leg(broker_admin, "leg-a")
    b, b_id = _leg(broker_admin, "leg-b")
    server = MqttBus(a, broker.url, *server_identity, role="server", ca_file=broker.ca_file)
    leg_a = MqttBus(a, broker.url, *a_id, role="device", ca_file=broker.ca_file)
    spy, seen, subscribed = _raw_client(broker, *b_id)     # leg b's identity, trying a's topics
    try:
        spy.subscribe(topic(a, "down"), qos=1)
        assert subscribed.wait(5)
        spy.publish(topic(a, "down"), pack_frames([_frame(0x080, b"\x01")]), qos=1).wait_for_publish(5)
        spy.publish(topic(b, "down"), pack_frames([_frame(0x080, b"\x01")]), qos=1).wait_for_publish(5)
        server.send(_frame(0x100, b"\x07"))
        first = leg_a.recv(5)
        assert first is not None and first.arbitration_id == 0x100      # the server's frame arrives …
        assert leg_a.recv(0.5) is None                                   # … and nothing b tried to send as a command
        assert [t for t in seen if t.startswith("quasitune/")] == []     # b read none of a's commands
        assert any("authori" in t.lower() or "unspecified" in t.lower() or "0x80" in t for t in seen), seen
    finally:
        spy.loop_stop()
        spy.disconnect()
        server.shutdown()
        leg_a.shutdown()


def test_no_identity_connects_under_another_identitys_client_id(broker, broker_admin, server_identity):
    """Each identity's client id is bound at the broker: a leg's credentials under the server's client id (which would
    inherit its persistent session and subscriptions, and knock it off once a second) or under another leg's are
    refused, and the server's link is not disturbed."""
    a, a_id = _leg(broker_admin, "leg-a")
    b, b_id = _leg(broker_admin, "leg-b")
    server = MqttBus(a, broker.url, *server_identity, role="server", ca_file=broker.ca_file)
    clients = []
    try:
        for stolen in (server_identity.username, a_id.username, f"raw-{next(_ids)}"):
            accepted, c = connect_as(broker, *b_id, stolen)
            clients.append(c)
            assert not accepted, f"{b} connected as {stolen}"
        accepted, c = connect_as(broker, *b_id, b_id.username)
        clients.append(c)
        assert accepted                                                   # its own client id works
        assert server.connected and server._client.is_connected()         # never knocked off
    finally:
        for c in clients:
            c.loop_stop()
            c.disconnect()
        server.shutdown()


def test_a_revoked_device_is_disconnected_at_once_and_refused_afterwards(broker, broker_admin):
    device_id, identity = _leg(broker_admin, "leg")
    leg = MqttBus(device_id, broker.url, *identity, role="device", ca_file=broker.ca_file)
    try:
        assert leg.connected
        broker_admin.revoke_device(device_id)
        until(lambda: not leg.connected, 5.0, poll_s=0.05)
    finally:
        leg.shutdown()
    with pytest.raises(can.CanInitializationError, match="could not connect"):
        MqttBus(device_id, broker.url, *identity, role="device", ca_file=broker.ca_file,
                connect_timeout_s=2)


def test_a_replaced_password_shuts_the_old_one_out(broker, broker_admin):
    device_id, old = _leg(broker_admin, "leg")
    new = broker_admin.replace_device(device_id)
    with pytest.raises(can.CanInitializationError):
        MqttBus(device_id, broker.url, *old, role="device", ca_file=broker.ca_file, connect_timeout_s=2)
    MqttBus(device_id, broker.url, *new, role="device", ca_file=broker.ca_file).shutdown()


class _Tamper(can.BusABC):
    """A bridge that alters one byte of every ENVELOPE_ROW frame it forwards while ``active`` (a broker or bridge gone
    bad)."""

    def __init__(self, inner: MqttBus) -> None:
        self.inner, self.altered, self.active = inner, 0, True
        super().__init__(channel=inner.channel_info)

    def send_batch(self, frames: list[can.Message]) -> None:
        self.inner.send_batch(frames)

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        self.inner.send(msg)

    def _recv_internal(self, timeout):
        msg = self.inner.recv(timeout)
        if self.active and msg is not None and msg.arbitration_id == frame_id("ENVELOPE_ROW"):
            data = bytearray(msg.data)
            data[3] ^= 0x01
            msg = can.Message(arbitration_id=msg.arbitration_id, data=bytes(data), is_extended_id=False)
            self.altered += 1
        return msg, False

    def shutdown(self) -> None:
        self.inner.shutdown()
        super().shutdown()


def _bridged(broker, broker_admin, server_identity, tamper: bool = False):
    """A simulated leg on its own virtual bus, its bridge to the broker, and the server's link through the broker."""
    device_id, identity = _leg(broker_admin, "leg")
    leg_bus = f"test-mqtt-leg-{next(_ids)}"
    node = DeviceNode(can.Bus(interface="virtual", channel=leg_bus)).start()
    far = MqttBus(device_id, broker.url, *identity, role="device", ca_file=broker.ca_file)
    gateway = Gateway(can.Bus(interface="virtual", channel=leg_bus), _Tamper(far) if tamper else far).start()
    link = DeviceLink(MqttBus(device_id, broker.url, *server_identity, role="server", ca_file=broker.ca_file)).start()
    return node, gateway, link


def test_a_push_is_acknowledged_with_its_crc_through_the_broker(broker, broker_admin, server_identity, tables):
    node, gateway, link = _bridged(broker, broker_admin, server_identity)
    try:
        result = link.push(tables[0], version=5)
        assert result.crc32 == table_wire(tables[0]).crc32() == node.snapshot().staged_or_active_crc32()
        # the bridge counts a frame once sent, and the host may read the acknowledgement before the count is made
        until(lambda: gateway.forwarded["b_to_a"] >= 12 and gateway.forwarded["a_to_b"] > 0, 5.0, poll_s=0.05)
    finally:
        link.close()
        gateway.close()
        node.close()


def test_a_frame_altered_in_transit_never_yields_a_mixed_table(broker, broker_admin, server_identity, tables):
    """The broker link adds no check of its own: the CRC read-back catches a bridge that alters a row, the push fails,
    and the leg keeps the table it had, whole."""
    node, gateway, link = _bridged(broker, broker_admin, server_identity, tamper=True)
    tamper = gateway.b
    try:
        tamper.active = False
        link.push(tables[0], version=5)
        held = node.snapshot().staged_or_active_crc32()
        tamper.active = True
        with pytest.raises(PushError):
            link.push(tables[1], version=6, timeout_s=2.0)
        assert tamper.altered > 0
        assert node.snapshot().staged_or_active_crc32() == held == table_wire(tables[0]).crc32()
    finally:
        link.close()
        gateway.close()
        node.close()


def test_two_server_instances_both_read_one_legs_frames(broker, broker_admin, tables):
    """Each API instance has its own session at the broker: both see the leg's status (and telemetry)."""
    device_id, identity = _leg(broker_admin, "leg")
    leg_bus = f"test-mqtt-leg-{next(_ids)}"
    node = DeviceNode(can.Bus(interface="virtual", channel=leg_bus)).start()
    far = MqttBus(device_id, broker.url, *identity, role="device", ca_file=broker.ca_file)
    gateway = Gateway(can.Bus(interface="virtual", channel=leg_bus), far).start()
    links = []
    try:
        for instance in ("one", "two"):
            bus = MqttBus(device_id, broker.url, *broker_admin.add_server(f"{instance}-{next(_ids)}"), role="server",
                          ca_file=broker.ca_file, instance=instance)
            links.append(DeviceLink(bus).start())
        until(lambda: all(link.status is not None for link in links), 5.0, poll_s=0.05)
        links[0].push(tables[0], version=9)           # pushed through one instance, seen running by both
        until(lambda: [link.status.active_version for link in links] == [9, 9], 5.0, poll_s=0.05)
    finally:
        for link in links:
            link.close()
        gateway.close()
        node.close()


def test_a_batch_kept_while_disconnected_is_one_record_per_burst_at_its_own_time():
    """The bridge's 50 ms messages hold several samples: each is kept with the time it left the leg's bus."""
    from device_bridge.mqtt_bus import _bursts

    frames = [_frame(0x300), _frame(0x301), _frame(0x300), _frame(0x301), _frame(0x080)]
    for f, at in zip(frames, (10.000, 10.001, 10.010, 10.0105, 10.040), strict=True):
        f.timestamp = at
    runs = [(at, [f.arbitration_id for f in run]) for at, run in _bursts(frames)]
    assert runs == [(10.000, [0x300, 0x301]), (10.010, [0x300, 0x301]), (10.040, [0x080])]


def test_a_legs_time_stamps_never_decide_whether_the_server_hears_it():
    """A record stamped ahead of its arrival (a bridge clock set forward, or a forged time) is taken at its arrival
    time, counted; a time that is not finite or older than any buffer keeps is refused, counted; the rest pass as sent.
    Before, one status stamped 2 s ahead made every real status look stale for 98 s, and 1e300 stopped recording."""
    from device_bridge.mqtt_bus import CLOCK_AHEAD_S, OLDEST_RECORD_S, checked_records, pack_late, unpack_late

    now = 1_800_000_000.0
    sent = [now - 0.5, now + CLOCK_AHEAD_S + 1.0, float("inf"), float("nan"), 1e300, -1e300,
            now - OLDEST_RECORD_S - 1.0, now + 0.3, now - 3600.0]
    payload = pack_late((at, pack_frames([_frame(0x100 + i)])) for i, at in enumerate(sent))
    kept, refused, clamped = checked_records(unpack_late(payload), now)
    assert refused == 4 and clamped == 2                # inf, nan, -1e300 and the too old; +1.5 s and 1e300 clamped
    assert [at for at, _ in kept] == [now - 0.5, now, now, now + 0.3, now - 3600.0]
    assert all(f.timestamp == at for at, frames in kept for f in frames)
    assert [frames[0].arbitration_id for _, frames in kept] == [0x100, 0x101, 0x104, 0x107, 0x108]


def test_an_oversized_message_is_refused_at_the_broker_and_never_reaches_the_server(broker, broker_admin,
                                                                                     server_identity):
    """The broker's max_packet_size (64 KiB, above any late chunk) disconnects a client that sends more, before the
    message reaches anyone; the server's link stays up (a 10 MB message sent another leg offline for 5 s)."""
    b, b_id = _leg(broker_admin, "leg-big")
    server = MqttBus(b, broker.url, *server_identity, role="server", ca_file=broker.ca_file)
    accepted, c = connect_as(broker, *b_id, b_id.username)
    gone = threading.Event()
    c.on_disconnect = lambda *_: gone.set()
    try:
        assert accepted
        c.publish(topic(b, "up"), b"\0" * 100_000, qos=1)
        assert gone.wait(5)                                                # the sender is cut off
        assert server.recv(0.5) is None and server.malformed == 0 and server.oversized == 0
        assert server.connected
    finally:
        c.loop_stop()
        c.disconnect()
        server.shutdown()
