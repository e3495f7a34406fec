"""``quasitune leg --config leg.toml``: the leg side on the leg's own computer.

Builds the leg's devices from the file (:mod:`device_bridge.osl.hardware`), starts them, opens the link to the clinic
(CAN, or the broker as ``mqtt:LEG_ID``), and runs the firmware in the control loop on the main thread at the file's
rate (:mod:`device_bridge.osl.loop`); the link's receive thread runs beside it. Overruns in a row put the leg in safe
mode. A leg not yet calibrated gives no torque until it is: the clinic's device page can guide its calibration
(:mod:`device_bridge.remote_calibration`), kept beside the leg file as ``--calibrate`` keeps it. Ctrl-C (or SIGTERM)
stops the loop, commands zero torque and stops every device. Prints the loop's figures at the end. Imports only what
the leg installs (``.[leg]``).
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

from device_bridge.osl.config import LegConfig, LegConfigError, load_config

if TYPE_CHECKING:
    from device_bridge.firmware import FirmwareConfig


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--config", required=True, help="the leg's TOML file (docs/leg.example.toml)")
    p.add_argument("--seconds", type=float, default=None, help="stop after this long (default: until Ctrl-C)")
    p.add_argument("--bench-walk", type=float, default=None, metavar="SPEED",
                   help="a leg file of bench devices: the simulated patient walks on the level at SPEED m/s")
    p.add_argument("--calibrate", action="store_true",
                   help="the guided calibration (prompts on this terminal), kept beside the leg file; then exit")
    p.add_argument("--mass", type=float, default=None, help="the patient's body mass (kg), for --calibrate")


def run(args: argparse.Namespace) -> int:
    from device_bridge.buses import open_bus
    from device_bridge.device_node import DeviceNode
    from device_bridge.osl.config import save_calibration
    from device_bridge.osl.hardware import build_devices
    from device_bridge.osl.leg import OSLLeg
    from device_bridge.osl.loop import ControlLoop
    from device_bridge.protocol import Fault

    config = load_config(args.config)
    # the SDK's log beside the leg file (not wherever the command was started)
    actuators, sensors, bench = build_devices(config, log_folder=Path(args.config).resolve().parent / "logs")
    if args.calibrate:
        return calibrate(args, config, actuators, sensors)
    if args.bench_walk is not None:
        if bench is None:
            raise ValueError("--bench-walk needs a leg file whose devices are kind = \"bench\"")
        bench.walk(args.bench_walk)
    leg = OSLLeg(config, actuators, sensors, clock=time.monotonic, require_calibration=bench is None)
    if not leg.drives:
        print("quasitune leg: this leg is not calibrated: it gives no torque until it is (a reversed sensor would turn "
              "every torque against the joint); calibrate it from the clinic's device page, or with "
              f"quasitune leg --config {args.config} --calibrate --mass KG", file=sys.stderr)
    leg.start()
    port = leg.calibration_port(lambda cal: save_calibration(args.config, cal))
    node = DeviceNode(open_bus(config.link), leg=leg, config=firmware_config(config), control_thread=False,
                      calibration=port)
    loop = ControlLoop(config.period_s, node.tick, config.overruns_to_safe,
                       on_overruns=lambda n: node.overrun(n, time.monotonic()))
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: loop.stop_event.set())
    ticks = None if args.seconds is None else max(round(args.seconds / config.period_s), 1)
    node.start()
    try:
        stats = loop.run(max_ticks=ticks)
    finally:
        try:
            leg.stop()
        finally:
            node.close()
    faults = node.firmware.faults_      # why the leg is where it is (a dry run has no host: HEARTBEAT_LOST, NO_TABLE)
    print(json.dumps({"rate_hz": config.rate_hz, "ticks": stats.ticks, "overruns": stats.overruns,
                      "longest_late_ms": round(1000 * stats.longest_late_s, 3), "mode": node.firmware.mode_.name,
                      "faults": [f.name for f in Fault if f in faults], "hardware_fault": node.firmware.hardware_fault_}))
    return 0


def firmware_config(config: LegConfig) -> FirmwareConfig:
    """The firmware's settings as this leg's file sets them: its task estimate's lengths (the defaults for a leg without
    a thigh sensor, which estimates no task) and its ankle drive's friction."""
    from controller_core.fsm import ActuatorLimits
    from device_bridge.firmware import FirmwareConfig

    drive = ActuatorLimits(ankle_friction_Nm=config.ankle_friction_Nm)
    g = config.geometry
    if g is None:
        return FirmwareConfig(actuator=drive)
    return FirmwareConfig(thigh_length_m=g.thigh_length_m, shank_length_m=g.shank_length_m, forefoot_m=g.forefoot_m,
                          actuator=drive)


def calibrate(args: argparse.Namespace, config, actuators, sensors) -> int:
    """The guided calibration (:mod:`device_bridge.osl.calibration_guide`), kept beside the leg file."""
    from device_bridge.osl.calibration_guide import guided_calibration
    from device_bridge.osl.config import save_calibration
    from device_bridge.osl.leg import OSLLeg

    if args.mass is None:
        raise ValueError("--calibrate needs the patient's --mass (kg): the load cell's sign is read from their weight")
    leg = OSLLeg(config, actuators, sensors, clock=time.monotonic)
    leg.start()
    leg.step(0.0, 0.0)                               # the joints are moved by hand: no torque
    try:
        calibration = guided_calibration(leg, args.mass, ask=lambda prompt: input(f"{prompt} Then press Enter. "),
                                         say=lambda words: print(f"  {words}"))
    finally:
        leg.stop()
    print(f"kept in {save_calibration(args.config, calibration)}")
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="quasitune leg", description=__doc__.splitlines()[0])
    add_arguments(parser)
    args = parser.parse_args(argv)
    try:
        return run(args)
    except (LegConfigError, ValueError, FileNotFoundError) as exc:
        print(f"quasitune leg: error: {str(exc).splitlines()[0]}", file=sys.stderr)
        return 2
