"""Which devices a server talks to: ``sim`` (the simulated leg on an in-process virtual bus), ``none``, or a
python-can ``INTERFACE:CHANNEL`` for a real leg (``socketcan:can0``, ``pcan:PCAN_USBBUS1`` …; ``mqtt:DEVICE_ID``: the
leg with that id, through the broker of the settings); several, comma-separated (``mqtt:leg-1,mqtt:leg-2``)."""

from __future__ import annotations

import itertools
import os
import re
from dataclasses import dataclass

from device_bridge.buses import parse_bus_spec

SIM_DEVICE_ID = "sim-leg-1"
_sim_counter = itertools.count()


@dataclass(frozen=True)
class DeviceSpec:
    """One configured device: its id, kind (``simulated`` or ``can``) and python-can interface and channel."""

    device_id: str
    kind: str
    interface: str
    channel: str


def parse_device_spec(text: str) -> DeviceSpec | None:
    """``sim`` / ``none`` / ``INTERFACE:CHANNEL`` → a spec (None for ``none``); ValueError with the reason."""
    text = text.strip()
    if text == "none":
        return None
    if text == "sim":   # a virtual bus exists only inside one process: a channel of this process's own
        channel = f"quasitune-sim-{os.getpid()}-{next(_sim_counter)}"
        return DeviceSpec(SIM_DEVICE_ID, "simulated", "virtual", channel)
    try:
        interface, channel = parse_bus_spec(text)
    except ValueError as exc:
        raise ValueError(f"device must be 'sim', 'none' or {str(exc).removeprefix('expected ')}") from None
    if interface == "mqtt":     # a leg through the broker is known by its own id there
        if not re.fullmatch(r"[A-Za-z0-9._-]{1,64}", channel):
            raise ValueError(f"a device id at the broker is 1-64 letters, digits, '.', '_' or '-', got {channel!r}")
        return DeviceSpec(channel, "can", interface, channel)
    device_id = re.sub(r"[^A-Za-z0-9._-]", "-", f"{interface}-{channel}")[:64]
    return DeviceSpec(device_id, "can", interface, channel)


def parse_device_specs(text: str) -> list[DeviceSpec]:
    """A comma-separated list of specs (``mqtt:leg-1,mqtt:leg-2``: several legs served by one instance); ``none``
    alone is no device. ValueError naming the spec for a bad one, ``none`` among others, or a device named twice."""
    parts = [p.strip() for p in text.split(",")]
    if len(parts) > 1 and "none" in parts:
        raise ValueError(f"device list {text!r}: 'none' is a device list of its own, not one of several")
    specs = [spec for spec in (parse_device_spec(p) for p in parts) if spec is not None]
    ids = [spec.device_id for spec in specs]
    twice = sorted({i for i in ids if ids.count(i) > 1})
    if twice:
        raise ValueError(f"device list {text!r} names {', '.join(twice)} more than once")
    return specs
