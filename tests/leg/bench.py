"""An Open Source Leg on the MuJoCo bench, through the SDK's interfaces (device_bridge/osl/bench_sdk.py), for the
leg environment's tests."""

from __future__ import annotations

import tempfile
from collections.abc import Callable

from controller_core.envelope import Envelope, envelope_of_table
from controller_core.table import ParameterTable
from device_bridge.envelope_wire import WireEnvelope, envelope_begin_frame, envelope_commit_frame
from device_bridge.firmware import DeviceFirmware
from device_bridge.osl.bench_sdk import BenchActuator, BenchEncoder, BenchLoadcell, BenchWorld, Mounting
from device_bridge.osl.config import Calibration, LegConfig, parse_config
from device_bridge.osl.hardware import sdk_log_folder
from device_bridge.osl.leg import OSLLeg
from device_bridge.sim.leg_model import LegGeometry
from device_bridge.sim.walker import SimWalker
from tests.leg.fixtures import ENVELOPE, TABLE

sdk_log_folder(tempfile.mkdtemp(prefix="quasitune-leg-tests-sdk-log-"))   # not the working directory


def learned_table() -> ParameterTable:
    return ParameterTable.model_validate_json(TABLE.read_text())


def learned_envelope() -> Envelope:
    return Envelope.model_validate_json(ENVELOPE.read_text())


def config(rate_hz: float = 500.0, calibration: Calibration | None = None, knee_encoder: bool = False) -> LegConfig:
    bench = LegGeometry()         # the bench's leg: its lengths are the task estimate's
    data = {"rate_hz": rate_hz, "thigh": "thigh", "geometry": {
                "thigh_length_m": bench.thigh_m, "shank_length_m": bench.shank_m, "forefoot_m": bench.toe_forward_m},
            "knee": {"actuator": "knee", "gear_ratio": 41.4999, **({"encoder": "knee_joint"} if knee_encoder else {})},
            "ankle": {"actuator": "ankle", "gear_ratio": 41.4999}}
    if calibration is not None:
        data["calibration"] = calibration.model_dump()
    return parse_config(data)


def bench_leg(cfg: LegConfig, mounting: Mounting | None = None, walker: SimWalker | None = None,
              clock: Callable[[], float] | None = None, impedance: Callable | None = None,
              calibrated_only: bool = False) -> tuple[OSLLeg, BenchWorld]:
    """An OSL leg over bench actuators, encoders and a load cell, started (its clock the bench's, or ``clock``);
    ``calibrated_only``: it gives no torque until calibrated, as hardware (the bench's default mounting reads the bench
    as QuasiTune does, so the walks drive it uncalibrated)."""
    world = BenchWorld(walker=walker, period_s=cfg.period_s, mounting=mounting or Mounting())
    actuators = {"knee": BenchActuator("knee", world, "knee"), "ankle": BenchActuator("ankle", world, "ankle")}
    sensors = {"loadcell": BenchLoadcell("loadcell", world), "thigh": BenchEncoder("thigh", world, "thigh"),
               "knee_joint": BenchEncoder("knee_joint", world, "knee")}
    leg = OSLLeg(cfg, actuators, sensors, clock=clock or (lambda: world.time_s), impedance=impedance,
                 require_calibration=calibrated_only)
    leg.start()
    return leg, world


def firmware_with(item: ParameterTable | Envelope) -> DeviceFirmware:
    """A firmware holding ``item`` as pushed (frames through its receiver), active."""
    fw = DeviceFirmware()
    wire = WireEnvelope.from_envelope(item if isinstance(item, Envelope) else envelope_of_table(item))
    frames = [envelope_begin_frame(1, 1, wire.crc32(), wire.shape), *wire.frames(1),
              envelope_commit_frame(1, 1, wire.crc32(), wire.shape)]
    for f in frames:
        fw.receive(f, 0.0)
    fw.tick(None, 0.0)
    assert fw.active_ is not None, fw.faults_
    return fw
