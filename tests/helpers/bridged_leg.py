"""A simulated leg behind its own bridge to a broker, as at a patient's home: the firmware and the bench on a virtual
bus of their own, ``quasitune bridge``'s gateway with its store-and-forward buffer, and the leg's identity at the
broker; plus an API app that reaches the leg only through the broker."""

from __future__ import annotations

import itertools
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import can

from device_bridge.broker_admin import Identity
from device_bridge.device_node import DeviceNode
from device_bridge.gateway import Gateway
from device_bridge.late_buffer import LateBuffer
from device_bridge.mqtt_bus import MqttBus
from device_bridge.sim.walker import SimWalker
from tests.helpers.api import Api, make_api

_ids = itertools.count()


@dataclass
class BridgedLeg:
    device_id: str
    node: DeviceNode
    walker: SimWalker
    far: MqttBus
    gateway: Gateway
    identity: Identity                 # the leg's at the broker (a red team uses it as a stolen one)


@contextmanager
def bridged_leg(broker, admin, folder: Path, device_id: str = "home-leg", mass_kg: float = 80.0
                ) -> Iterator[BridgedLeg]:
    """The leg (a patient of ``mass_kg`` standing on it) and its bridge, connected to ``broker`` as ``device_id``."""
    identity = admin.add_device(device_id)
    channel = f"bridged-{device_id}-{next(_ids)}"
    walker = SimWalker()
    walker.stand(mass_kg)
    node = DeviceNode(can.Bus(interface="virtual", channel=channel), leg=walker).start()
    far = MqttBus(device_id, broker.url, *identity, role="device", ca_file=broker.ca_file,
                  late_buffer=LateBuffer(folder / f"{device_id}-late.sqlite"))
    gateway = Gateway.to_broker(can.Bus(interface="virtual", channel=channel), far).start()
    try:
        yield BridgedLeg(device_id, node, walker, far, gateway, identity)
    finally:
        gateway.close()
        node.close()


@contextmanager
def broker_app(broker, admin, folder: Path, model, template: Path, device_id: str, instance: str = "one"
               ) -> Iterator[Api]:
    """An API instance whose one device is ``mqtt:device_id``, with a server identity of its own at the broker."""
    server = admin.add_server(f"{instance}-{next(_ids)}")
    api, client = make_api(folder / instance, lambda: model, template=template, device=f"mqtt:{device_id}",
                           broker_url=broker.url, broker_username=server.username, broker_password=server.password,
                           broker_ca_file=broker.ca_file, instance_name=instance)
    with client:     # the app's lifespan opens the broker link and closes it
        yield api
