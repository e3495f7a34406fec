"""The server's devices: the CAN link to each configured prosthesis (:mod:`backend.devices.manager`), the live
telemetry fan-out to WebSocket clients (:mod:`backend.devices.fanout`) and the recording of walking sessions into
SQLite (:mod:`backend.devices.recorder`)."""

from backend.devices.manager import DeviceManager, ManagedDevice
from backend.devices.specs import SIM_DEVICE_ID, DeviceSpec, parse_device_spec, parse_device_specs

__all__ = ["SIM_DEVICE_ID", "DeviceManager", "DeviceSpec", "ManagedDevice", "parse_device_spec", "parse_device_specs"]
