"""The leg's devices, made from its configuration: each actuator and sensor is the SDK class the file names, built with
the file's options (the SDK refuses what it cannot use, loudly); ``kind = "bench"`` builds the MuJoCo bench behind
the SDK's interfaces instead (:mod:`device_bridge.osl.bench_sdk`), for a dry run of the whole leg side without
hardware."""

from __future__ import annotations

import importlib
from pathlib import Path
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


def sdk_log_folder(folder: Path | str) -> Path:
    """Where the SDK writes its log (its ``LOGGER`` singleton, which otherwise writes ``logger_<time>.log`` into the
    working directory at its first message): ``folder``, made if missing."""
    from opensourceleg.logging.logger import Logger  # the SDK: only on the leg's computer

    path = Path(folder)
    path.mkdir(parents=True, exist_ok=True)
    Logger(log_path=str(path))     # the singleton takes the folder; its file is opened at the first message
    return path


def build_devices(config: LegConfig, log_folder: Path | str | None = None) -> tuple[dict[str, Any], dict[str, Any], Any]:
    """(actuators by tag, sensors by tag, the bench if any device is ``bench``, else None); the SDK's log goes to
    ``log_folder`` (:func:`sdk_log_folder`) where one is given."""
    if log_folder is not None:
        sdk_log_folder(log_folder)
    bench = None
    if any(d.kind == "bench" for d in (*config.actuators.values(), *config.sensors.values())):
        from device_bridge.osl.bench_sdk import BenchLeg  # MuJoCo: the dry run only

        bench = BenchLeg(period_s=config.period_s)
    actuators = {tag: _build(tag, d, bench) for tag, d in config.actuators.items()}
    sensors = {tag: _build(tag, d, bench) for tag, d in config.sensors.items()}
    return actuators, sensors, bench
