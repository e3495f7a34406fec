"""The SDK's real Dephy actuator class, exercised without hardware: its own mode checks and unit conversions under the
OSL leg, with only flexsea's calls to the device recorded instead of sent.

``DephyActuator(offline=True)`` replaces every hardware method by a no-op (its conversions and checks with them), so
the actuator here is built offline and then given back the class's own methods but for opening, reading and closing
the device (flexsea's C library, fetched on first connect); what would go to the device over
flexsea (``set_gains``, ``command_motor_impedance``, ``command_motor_current``) is recorded. What reaches the wire is
then the SDK's arithmetic on what the leg asked, and the SDK's refusals (a negative stiffness, a call in the wrong
control mode) are its own.
"""

from __future__ import annotations

import math

import pytest
from opensourceleg.actuators import dephy  # opensourceleg[dephy] (flexsea): the leg's test environment has it
from opensourceleg.logging.exceptions import ControlModeException

from device_bridge.osl.bench_sdk import BenchLoadcell, BenchWorld
from device_bridge.osl.config import Calibration, JointCalibration, LoadcellCalibration, parse_config
from device_bridge.osl.leg import OSLLeg
from tests.leg import bench  # noqa: F401  (the SDK's log goes to a temporary folder)

GEAR = 41.4999
CONNECTION = ("start", "stop", "update", "home")     # open, close and read the device: offline stubs stay


def wired_dephy(tag: str) -> tuple[dephy.DephyActuator, list[tuple[str, object]]]:
    """A DephyActuator with its own methods, whose flexsea calls are recorded in the returned list."""
    a = dephy.DephyActuator(tag=tag, port="/dev/null", gear_ratio=GEAR, frequency=500, offline=True)
    wire: list[tuple[str, object]] = []
    for name in a._OFFLINE_METHODS:     # the class's own methods again, but for the connection's (flexsea's C library)
        if name not in CONNECTION:
            a.__dict__.pop(name, None)
    a._is_offline = False
    a.set_gains = lambda **gains: wire.append(("gains", gains))
    a.command_motor_impedance = lambda value: wire.append(("impedance_counts", value))
    a.command_motor_current = lambda value: wire.append(("current_mA", value))
    a._original_methods = {}
    a._set_original_methods()
    a._set_mutated_methods()
    return a, wire


def _leg(torque_mode: str, impedance=None, knee_sign: int = 1, knee_torque_sign: int = 1) -> tuple[OSLLeg, dict]:
    cal = Calibration(knee=JointCalibration(sign=knee_sign, zero_rad=0.2, torque_sign=knee_torque_sign, calibrated=True),
                      ankle=JointCalibration(calibrated=True), loadcell=LoadcellCalibration(calibrated=True))
    config = parse_config({"torque_mode": torque_mode, "knee": {"actuator": "knee", "gear_ratio": GEAR},
                           "ankle": {"actuator": "ankle", "gear_ratio": GEAR}, "calibration": cal.model_dump()})
    (knee, knee_wire), (ankle, ankle_wire) = wired_dephy("knee"), wired_dephy("ankle")
    leg = OSLLeg(config, {"knee": knee, "ankle": ankle}, {"loadcell": BenchLoadcell("loadcell", BenchWorld())},
                 impedance=impedance)
    return leg, {"knee": knee_wire, "ankle": ankle_wire}


def test_in_impedance_mode_the_sdk_gets_the_rows_spring_in_its_units_and_its_equilibrium_in_motor_counts():
    """The knee's row k = −80 N·m/rad, θe 25°, b 2 N·m·s/rad: the Dephy class turns K = 80 at the joint into whole motor
    units (what ``quantised_`` reports), the equilibrium into motor counts from the knee's zero; a row that pushes
    (k > 0, the ankle's here) goes as K = 0, never as the negative stiffness the SDK refuses."""
    rows = ((-80.0, math.radians(25.0), 2.0), (15.0, 0.0, 1.0))
    leg, wire = _leg("dephy_impedance", impedance=lambda: rows)
    leg.start()
    wire["knee"].clear()
    leg.send_impedance()
    knee = leg.actuators["knee"]
    gains = [g for kind, g in wire["knee"] if kind == "gains"][-1]
    assert gains["k"] == int(80.0 / GEAR**2 * knee.NM_PER_RAD_TO_MOTOR_UNITS)
    assert gains["b"] == int(2.0 / GEAR**2 * knee.NM_S_PER_RAD_TO_MOTOR_UNITS)
    asked, runs = leg.quantised_["knee"]
    assert asked == 80.0 and runs == pytest.approx(gains["k"] * GEAR**2 / knee.NM_PER_RAD_TO_MOTOR_UNITS)
    assert 0 < asked - runs < 0.5                    # the SDK's whole units: under 0.5 N·m/rad lost at 41.5:1
    counts = [v for kind, v in wire["knee"] if kind == "impedance_counts"][-1]
    equilibrium = 0.2 + math.radians(25.0)           # the actuator's own output angle: zero + sign × θe
    assert counts == int((equilibrium * GEAR + knee.motor_zero_position) / knee.MOTOR_CONSTANTS.RAD_PER_COUNT)
    ankle_gains = [g for kind, g in wire["ankle"] if kind == "gains"][-1]
    assert ankle_gains["k"] == 0 and leg.clamped_ == 1
    with pytest.raises(ValueError, match="cannot be negative"):     # what the leg's conversion keeps from happening
        knee.set_output_impedance(k=-1.0, b=1.0)


def test_in_current_mode_the_sdk_gets_the_joint_torque_as_motor_current_with_the_calibrated_sign():
    leg, wire = _leg("current", knee_torque_sign=-1)
    leg.start()
    leg.step(10.0, -5.0)
    leg.step(20.0, -5.0)
    knee = leg.actuators["knee"]
    first, second = [v for kind, v in wire["knee"] if kind == "current_mA"][-2:]
    per_Nm = 1.0 / GEAR / knee.MOTOR_CONSTANTS.NM_PER_MILLIAMP
    assert first == int(-10.0 * per_Nm) and second == int(-20.0 * per_Nm) and first < 0   # the linkage reverses it
    assert [v for kind, v in wire["ankle"] if kind == "current_mA"][-1] == int(-5.0 * per_Nm)


def test_a_leg_whose_actuators_were_never_put_in_their_mode_fails_loudly():
    """The SDK's own mode check: torque asked of an actuator still idle (the leg not started) raises, never a silent
    no-op."""
    leg, _ = _leg("current")
    with pytest.raises(ControlModeException, match="IDLE"):
        leg.step(1.0, 1.0)
