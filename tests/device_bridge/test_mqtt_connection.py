"""One API instance's shared connection to the broker: each leg's frames to its own bus, in order; a leg the identity
may not read refused by name; every leg down while the broker is, nothing sent then, and all back after it."""

from __future__ import annotations

import itertools
import time

import can
import pytest

from device_bridge.mqtt_bus import MqttBus
from device_bridge.mqtt_connection import MqttConnection
from tests.helpers.device import until
from tests.helpers.mosquitto import admin_of, running_broker

pytestmark = [pytest.mark.broker, pytest.mark.wallclock, pytest.mark.live]   # one test starts a broker of its own

_ids = itertools.count()


def _frame(i: int) -> can.Message:
    return can.Message(arbitration_id=i, data=b"\x01", is_extended_id=False)


def _legs(broker, admin, n: int) -> list[MqttBus]:
    """``n`` legs' bridges (device role, each its own identity), connected."""
    out = []
    for _ in range(n):
        device_id = f"shared-leg-{next(_ids)}"
        out.append(MqttBus(device_id, broker.url, *admin.add_device(device_id), role="device",
                           ca_file=broker.ca_file))
    return out


def _connection(broker, admin) -> MqttConnection:
    name = f"shared-server-{next(_ids)}"
    return MqttConnection(broker.url, *admin.add_server(name), ca_file=broker.ca_file, instance=name)


def test_one_connection_serves_several_legs_each_on_its_own_bus(broker, broker_admin):
    far = _legs(broker, broker_admin, 2)
    conn = _connection(broker, broker_admin)
    got: dict[str, list[int]] = {leg.device_id: [] for leg in far}
    near = []
    try:
        for leg in far:
            bus = MqttBus(leg.device_id, role="server", connection=conn)
            bus.on_frames = lambda frames, d=leg.device_id: got[d].extend(f.arbitration_id for f in frames)
            near.append(bus)
        assert all(bus.delivers_frames and bus.connected for bus in near)
        far[0].send_batch([_frame(0x300), _frame(0x301)])
        far[1].send_batch([_frame(0x310)])
        far[0].send_batch([_frame(0x302)])
        until(lambda: len(got[far[0].device_id]) == 3 and len(got[far[1].device_id]) == 1)
        assert got == {far[0].device_id: [0x300, 0x301, 0x302], far[1].device_id: [0x310]}
        near[1].send(_frame(0x100))                      # down: to that leg only
        back = far[1].recv(5)
        assert back is not None and back.arbitration_id == 0x100
        assert far[0].recv(0.3) is None
        near[1].shutdown()                               # that leg no longer read; the other still is
        far[1].send_batch([_frame(0x311)])
        far[0].send_batch([_frame(0x303)])
        until(lambda: got[far[0].device_id][-1:] == [0x303])
        assert got[far[1].device_id] == [0x310]
        with pytest.raises(ValueError, match="shares a connection"):
            MqttBus("leg", role="device", connection=conn)
    finally:
        for bus in near[:1]:
            bus.shutdown()
        conn.close()
        for leg in far:
            leg.shutdown()


def test_a_legs_identity_cannot_read_any_leg_through_a_servers_connection(broker, broker_admin):
    """A leg's credentials used as a server's connection (to read other legs' frames): the broker lets the leg in
    under its own client id only, and refuses it every leg's ``up`` topic, its own included: attaching a leg fails
    loudly, saying so."""
    mine = f"shared-leg-{next(_ids)}"
    conn = MqttConnection(broker.url, *broker_admin.add_device(mine), ca_file=broker.ca_file,
                          instance=f"as-a-leg-{next(_ids)}", connect_timeout_s=3.0)
    try:
        for leg in (mine, "someone-else"):
            with pytest.raises(can.CanInitializationError, match="not allowed to read"):
                MqttBus(leg, connection=conn, connect_timeout_s=2.0)
    finally:
        conn.close()


def test_every_leg_is_down_while_the_broker_is_and_back_after_it():
    with running_broker() as broker, admin_of(broker) as admin:
        far = _legs(broker, admin, 2)
        conn = _connection(broker, admin)
        got: list[int] = []
        near = [MqttBus(leg.device_id, role="server", connection=conn) for leg in far]
        near[0].on_frames = lambda frames: got.extend(f.arbitration_id for f in frames)
        try:
            broker.stop()
            until(lambda: not any(bus.connected for bus in near), timeout_s=15.0)
            with pytest.raises(can.CanOperationError, match="down"):
                near[0].send(_frame(0x100))             # a frame from now must not reach the leg later
            broker.start()
            until(lambda: all(bus.connected for bus in near) and far[0].connected, timeout_s=30.0)
            far[0].send_batch([_frame(0x320)])
            until(lambda: got == [0x320], timeout_s=10.0)
            near[1].send(_frame(0x101))
            deadline = time.monotonic() + 5
            back = None
            while back is None and time.monotonic() < deadline:
                back = far[1].recv(0.5)
            assert back is not None and back.arbitration_id == 0x101
        finally:
            for bus in near:
                bus.shutdown()
            conn.close()
            for leg in far:
                leg.shutdown()


def test_live_messages_go_first_and_late_ones_take_turns_per_leg_within_a_share(monkeypatch):
    """One leg's backlog of late messages never delays another leg's live status, nor its own late turn; beyond a
    leg's share its late messages are dropped and counted (300 late messages of one leg kept another offline 28.6 s)."""
    from device_bridge import mqtt_connection
    from device_bridge.mqtt_bus import topic
    from device_bridge.mqtt_connection import LegMailbox

    monkeypatch.setattr(mqtt_connection, "LATE_QUEUED_PER_LEG", 3)
    box = LegMailbox()
    for i in range(5):
        box.put(topic("leg-2", "late"), b"late-2-%d" % i)             # a flood of one leg's backlog …
    box.put(topic("leg-3", "late"), b"late-3-0")
    box.put(topic("leg-1", "up"), b"status-1")                         # … then another leg's live status
    assert box.dropped == {"leg-2": 2}
    taken = [box.take(0) for _ in range(5)]
    assert taken == [("leg-1", "up", b"status-1"), ("leg-2", "late", b"late-2-0"), ("leg-3", "late", b"late-3-0"),
                     ("leg-2", "late", b"late-2-1"), ("leg-2", "late", b"late-2-2")]
    assert box.take(0) is None                                          # nothing left
    box.close()
    assert box.take() is None


def test_a_legs_late_messages_are_handed_over_within_its_budget_and_live_ones_never_wait(monkeypatch):
    """A leg's late bytes are handed over at most LATE_BYTES_PER_S_PER_LEG (after a burst of one large message): a
    flood of them cannot take the dispatch thread from the other legs, whose live messages and own late turn come
    first; the flood's messages wait their turn, none is lost. Time here is the mailbox's own clock, moved by hand."""
    from device_bridge import mqtt_connection
    from device_bridge.mqtt_bus import topic
    from device_bridge.mqtt_connection import LegMailbox

    monkeypatch.setattr(mqtt_connection, "LATE_BYTES_PER_S_PER_LEG", 100_000)
    monkeypatch.setattr(mqtt_connection, "LATE_BURST_BYTES", 60_000)
    now = [0.0]
    box = LegMailbox(clock=lambda: now[0])
    for i in range(3):
        box.put(topic("leg-2", "late"), bytes([i]) * 50_000)            # 150 kB of one leg's backlog
    assert box.take(0)[2][0] == 0                                       # the burst: the first at once
    assert box.take(0) is None                                          # the second waits for its budget …
    box.put(topic("leg-1", "up"), b"status-1")
    box.put(topic("leg-3", "late"), b"late-3")
    assert box.take(0) == ("leg-1", "up", b"status-1")                  # … never another leg's live message
    assert box.take(0) == ("leg-3", "late", b"late-3")                  # … nor another leg's late turn
    now[0] += 0.39
    assert box.take(0) is None                                          # 49 kB of budget: not yet
    now[0] += 0.02
    assert box.take(0)[2][0] == 1                                       # 50 kB after 0.41 s
    now[0] += 0.5
    assert box.take(0)[2][0] == 2 and box.take(0) is None and box.dropped == {}
