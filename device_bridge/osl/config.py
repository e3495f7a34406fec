"""The leg's configuration: one TOML file with its actuators, joint maps, load cell, loop rate and link.

Example (``docs/leg.example.toml``)::

    rate_hz = 500
    link = "socketcan:can0"          # or "mqtt:leg-17" through the clinic's broker
    torque_mode = "current"          # QuasiTune computes the torque; the actuator runs its current loop
    ankle_friction_Nm = 0.0          # the ankle drive's Coulomb friction (N·m), measured: swing compensates it

    [knee]
    actuator = "knee"                # an actuator's tag
    encoder = "knee_joint"           # a joint encoder's tag, or leave out: the actuator's output position
    gear_ratio = 41.4999

    [ankle]
    actuator = "ankle"
    gear_ratio = 41.4999

    [actuators.knee]                 # the SDK class and its constructor's arguments (the tag is the table's key)
    kind = "DephyActuator"
    options = { port = "/dev/ttyACM0", gear_ratio = 41.4999, frequency = 500 }

    [sensors.loadcell]
    kind = "DephyLoadcellAmplifier"

    [geometry]                       # with a thigh sensor: the lengths the leg's task estimate needs (m)
    thigh_length_m = 0.43            # the patient's hip to knee axis (residual limb and socket), measured
    shank_length_m = 0.43            # this leg's knee axis to ankle axis
    forefoot_m = 0.13                # the foot's forefoot rocker ahead of the ankle axis

    [calibration]                    # written by the calibration steps; the defaults mean "not calibrated"

Every field is checked when the file is read, and a bad one is named with its reason (:func:`load_config`).
Angles in rad inside, like the rest of the leg side; the calibration's offsets in the sensors' own units.
"""

from __future__ import annotations

import json
import math
import tomllib
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from controller_core.fsm import MAX_DRIVE_FRICTION_NM

Sign = Literal[1, -1]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class JointCalibration(_Strict):
    """How one joint's sensors read the joint (QuasiTune's convention: knee flexion and ankle dorsiflexion +).

    joint angle = ``sign`` × (reading − ``zero_rad``), where reading is the joint encoder's, or the actuator's output
    position when the joint has no encoder; the actuator's torque is sent as ``torque_sign`` × the joint torque.
    """

    sign: Sign = 1
    zero_rad: float = 0.0
    torque_sign: Sign = 1
    calibrated: bool = False


class LoadcellCalibration(_Strict):
    """How the pylon load cell reads the leg: load (N, compression +) = ``fz_sign`` × (fz − ``fz_zero_N``); sagittal
    moment (N·m, dorsiflexion +) = ``my_sign`` × (my − ``my_zero_Nm``)."""

    fz_sign: Sign = 1
    fz_zero_N: float = 0.0
    my_sign: Sign = 1
    my_zero_Nm: float = 0.0
    calibrated: bool = False


class Calibration(_Strict):
    knee: JointCalibration = JointCalibration()
    ankle: JointCalibration = JointCalibration()
    loadcell: LoadcellCalibration = LoadcellCalibration()


# the SDK classes a leg may name, and where the SDK keeps them (``bench``: ours, the MuJoCo bench behind the SDK's
# interfaces: device_bridge.osl.bench_sdk, for a dry run without hardware)
DEVICE_KINDS = {
    "DephyActuator": "opensourceleg.actuators.dephy", "MoteusActuator": "opensourceleg.actuators.moteus",
    "TMotorServoActuator": "opensourceleg.actuators.tmotor", "AS5048B": "opensourceleg.sensors.encoder",
    "DephyLoadcellAmplifier": "opensourceleg.sensors.loadcell", "NBLoadcellDAQ": "opensourceleg.sensors.loadcell",
    "bench": "device_bridge.osl.bench_sdk",
}


class DeviceConfig(_Strict):
    """One actuator or sensor: the SDK class (:data:`DEVICE_KINDS`) and its constructor's keyword arguments."""

    kind: str
    # scalars, or a matrix (a load cell's calibration matrix: rows of numbers, handed to the SDK as a numpy array)
    options: dict[str, str | int | float | bool | list[list[float]]] = Field(default_factory=dict)

    @field_validator("kind")
    @classmethod
    def _known(cls, v: str) -> str:
        if v not in DEVICE_KINDS:
            raise ValueError(f"kind must be one of {', '.join(DEVICE_KINDS)}, got {v!r}")
        return v


class Geometry(_Strict):
    """The lengths the leg's task estimate needs (m; :class:`~controller_core.task_estimator.TaskEstimator`): the
    speed comes from the hip's path over the planted ankle (thigh and shank), the heel-up rule from where the foot's
    forefoot rocker lies. Measured on the patient and on this leg: the firmware's defaults are the simulated bench's
    leg, not anyone's."""

    thigh_length_m: float = Field(ge=0.2, le=0.7, description="the patient's hip to knee axis (residual limb, socket)")
    shank_length_m: float = Field(ge=0.2, le=0.7, description="this leg's knee axis to ankle axis")
    forefoot_m: float = Field(ge=0.03, le=0.3, description="the foot's forefoot rocker ahead of the ankle axis")


class JointConfig(_Strict):
    actuator: str = Field(min_length=1, description="the actuator's tag")
    encoder: str | None = Field(default=None, description="a joint encoder's tag; none: the actuator's output")
    gear_ratio: float = Field(gt=0.0, le=500.0)


class LegConfig(_Strict):
    """The leg (see the module docstring)."""

    rate_hz: float = Field(default=500.0, ge=50.0, le=2000.0, description="control loop rate (Hz)")
    overruns_to_safe: int = Field(default=5, ge=1, le=1000,
                                  description="this many late ticks in a row put the leg in safe mode")
    link: str = Field(default="virtual:quasitune", min_length=3, description="INTERFACE:CHANNEL of the clinic's link")
    # "current"/"torque": QuasiTune computes every torque, the actuator runs its current (Dephy) or torque (Moteus,
    # T-Motor) loop; "dephy_impedance": the actuator runs the spring and damper QuasiTune's state asks for
    # (device_bridge/osl/leg.py), its joints read from the actuators themselves
    torque_mode: Literal["current", "torque", "dephy_impedance"] = "current"
    knee: JointConfig
    ankle: JointConfig
    loadcell: str = Field(default="loadcell", min_length=1, description="the pylon load cell's tag")
    thigh: str | None = Field(default=None, description="the socket's angle sensor (an IMU's pitch), if any")
    geometry: Geometry | None = Field(default=None, description="the task estimate's lengths; needed with a thigh")
    ankle_friction_Nm: float = Field(default=0.0, ge=0.0, le=MAX_DRIVE_FRICTION_NM,
                                     description="the ankle drive's Coulomb friction (N·m), compensated in swing")
    actuators: dict[str, DeviceConfig] = Field(default_factory=dict)
    sensors: dict[str, DeviceConfig] = Field(default_factory=dict)
    calibration: Calibration = Calibration()

    @field_validator("link")
    @classmethod
    def _interface_and_channel(cls, v: str) -> str:
        if ":" not in v or not all(v.split(":", 1)):
            raise ValueError(f"link must be INTERFACE:CHANNEL (socketcan:can0, mqtt:leg-17), got {v!r}")
        return v

    @model_validator(mode="after")
    def _impedance_reads_the_actuators(self) -> LegConfig:
        if self.torque_mode == "dephy_impedance" and (self.knee.encoder or self.ankle.encoder):
            raise ValueError("torque_mode dephy_impedance: the actuator's spring acts on its own output position, so "
                             "each joint must be read from its actuator (no joint encoder)")
        return self

    @model_validator(mode="after")
    def _a_task_estimate_needs_the_legs_lengths(self) -> LegConfig:
        if self.thigh is not None and self.geometry is None:
            raise ValueError("geometry: a leg with a thigh sensor estimates its walking speed and slope from the "
                             "thigh, knee and ankle angles, which needs this patient's and this leg's lengths: add "
                             "[geometry] with thigh_length_m, shank_length_m and forefoot_m (m)")
        return self

    @property
    def period_s(self) -> float:
        return 1.0 / self.rate_hz


class LegConfigError(ValueError):
    """A configuration file that cannot be used; the message names every bad field and why."""


def parse_config(data: object, source: str = "leg configuration") -> LegConfig:
    try:
        return LegConfig.model_validate(data)
    except ValidationError as exc:
        lines = [f"{'.'.join(str(p) for p in e['loc']) or '(file)'}: {e['msg']}" for e in exc.errors()]
        raise LegConfigError(f"{source}: " + "; ".join(lines)) from None


def calibration_path(config_path: Path | str) -> Path:
    """Where a leg's calibration is kept: beside its file (``leg.toml`` → ``leg.calibration.json``)."""
    return Path(config_path).with_suffix(".calibration.json")


def load_config(path: Path | str) -> LegConfig:
    """Read and check a leg's TOML configuration (LegConfigError naming each bad field, or the TOML error's line), with
    the calibration kept beside it (:func:`calibration_path`) when there is one: it replaces the file's own."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise LegConfigError(f"{path}: not TOML: {exc}") from None
    kept = calibration_path(path)
    if kept.exists():
        try:
            data["calibration"] = json.loads(kept.read_text())
        except json.JSONDecodeError as exc:
            raise LegConfigError(f"{kept}: not JSON: {exc}") from None
    return parse_config(data, str(path))


def save_calibration(config_path: Path | str, calibration: Calibration) -> Path:
    """Keep ``calibration`` beside the leg's file (written whole, then renamed over the old one: never half a file)."""
    target = calibration_path(config_path)
    tmp = target.with_suffix(".json.tmp")
    tmp.write_text(calibration.model_dump_json(indent=2) + "\n")
    tmp.replace(target)
    return target


def finite(value: float, what: str) -> float:
    """``value`` if finite, else a ValueError naming ``what`` (a sensor that reads NaN is a fault, not a number)."""
    if not math.isfinite(value):
        raise ValueError(f"{what} read {value!r}")
    return value
