"""The OSL leg's loud failures: a configuration naming a device the leg lacks, a sensor that reads NaN, an impedance
mode that cannot work."""

from __future__ import annotations

import math

import pytest

from device_bridge.osl.bench_sdk import BenchActuator, BenchLoadcell, BenchWorld, Mounting
from device_bridge.osl.config import LegConfigError, parse_config
from device_bridge.osl.leg import OSLLeg
from tests.leg.bench import bench_leg, config


def test_a_device_the_leg_does_not_have_is_named():
    world = BenchWorld()
    with pytest.raises(ValueError, match="the load cell 'loadcell', which the leg does not have"):
        OSLLeg(config(), {"knee": BenchActuator("knee", world, "knee"), "ankle": BenchActuator("ankle", world, "ankle")},
               {"thigh": BenchLoadcell("thigh", world)})


def test_a_sensor_that_reads_nan_gives_no_sample_and_a_reason_for_the_firmware():
    leg, world = bench_leg(config(), Mounting(fz_offset_N=math.nan))
    from controller_core.fsm import SensorSample

    world.observe(SensorSample(0.0, 0.1, 0.0, 0.0, 0.0, 500.0, 0.0))
    assert leg.sample() is None
    kind, reason = leg.take_fault()
    assert kind == "sensor" and "the load cell's fz read nan" in reason
    assert leg.take_fault() is None                       # taken once


def test_impedance_mode_needs_joints_read_from_their_actuators_and_the_firmwares_impedance():
    with pytest.raises(LegConfigError, match="dephy_impedance: the actuator's spring acts on its own output"):
        parse_config({**config(knee_encoder=True).model_dump(), "torque_mode": "dephy_impedance"})
    world = BenchWorld()
    actuators = {"knee": BenchActuator("knee", world, "knee"), "ankle": BenchActuator("ankle", world, "ankle")}
    cfg = config().model_copy(update={"torque_mode": "dephy_impedance"})
    with pytest.raises(ValueError, match="needs the impedance the firmware runs"):
        OSLLeg(cfg, actuators, {"loadcell": BenchLoadcell("loadcell", world), "thigh": BenchLoadcell("thigh", world)})


def test_a_leg_file_option_the_sdk_class_does_not_take_is_refused_by_name():
    from device_bridge.osl.hardware import build_devices

    cfg = parse_config({**config().model_dump(), "actuators": {
        "knee": {"kind": "bench", "options": {"part": "knee_actuator", "colour": "red"}}}})
    with pytest.raises(ValueError, match=r"knee: bench: .*unexpected keyword argument 'colour'"):
        build_devices(cfg)
