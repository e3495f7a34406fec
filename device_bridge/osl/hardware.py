"""The leg's devices, made from its configuration: each actuator and sensor is the SDK class the file names, built with
the file's options (the SDK refuses what it cannot use, loudly); ``kind = "bench"`` builds the MuJoCo bench behind
the SDK's interfaces instead (:mod:`device_bridge.osl.bench_sdk`), for a dry run of the whole leg side without
hardware."""

from __future__ import annotations

import importlib
from typing import Any

import numpy as np

from device_bridge.osl.config import DEVICE_KINDS, DeviceConfig, LegConfig


def _build(tag: str, device: DeviceConfig, bench: Any) -> Any:
    try:
        module = importlib.import_module(DEVICE_KINDS[device.kind])
    except ImportError as exc:   # the SDK's extra for this hardware (e.g. opensourceleg[dephy]) is not installed
        raise ValueError(f"{tag}: {device.kind} needs {exc.name or 'a package'}, which is not installed: {exc}") from exc
    options = {k: np.asarray(v, dtype=float) if isinstance(v, list) else v for k, v in device.options.items()}
    try:
        if device.kind != "bench":
            return getattr(module, device.kind)(tag=tag, **options)
        return bench.device(tag, **options)
    except TypeError as exc:     # an option the SDK's class does not take, or one it needs and did not get
        raise ValueError(f"{tag}: {device.kind}: {exc}") from exc


def build_devices(config: LegConfig) -> tuple[dict[str, Any], dict[str, Any], Any]:
    """(actuators by tag, sensors by tag, the bench if any device is ``bench``, else None)."""
    bench = None
    if any(d.kind == "bench" for d in (*config.actuators.values(), *config.sensors.values())):
        from device_bridge.osl.bench_sdk import BenchLeg  # MuJoCo: the dry run only

        bench = BenchLeg(period_s=config.period_s)
    actuators = {tag: _build(tag, d, bench) for tag, d in config.actuators.items()}
    sensors = {tag: _build(tag, d, bench) for tag, d in config.sensors.items()}
    return actuators, sensors, bench
