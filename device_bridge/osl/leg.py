"""An Open Source Leg as a leg of the device stack: readings from the SDK's sensors, torques to its actuators.

:class:`OSLLeg` is the seam the simulated leg uses (``sample()``, ``step(knee_Nm, ankle_Nm)``), so QuasiTune's firmware
(state machine, torque clipping, safe mode, adaptive controller) stays in charge on every actuator: the actuators run
their current (or torque) loop only. Each reading goes through the leg's calibration
(:class:`~device_bridge.osl.config.Calibration`): joint angle = sign × (reading − zero), load and moment likewise.

Faults are loud: a thermal or I²t exception from an actuator's ``update()`` (the SDK raises them after reading the
actuator, so the reading stands) is kept as :attr:`OSLLeg.fault_` with its reason and handed to the firmware, which
goes to safe mode and raises the over-temperature flag (:meth:`device_bridge.firmware.DeviceFirmware.hardware_fault`);
a sensor that cannot be read, or reads NaN, gives no sample (the firmware then commands no torque). Every torque is
scaled by the actuator's thermal scaling factor where it has one (Dephy's thermal model), and :attr:`OSLLeg.derating_`
reports the smallest factor applied.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from typing import Any

from controller_core.fsm import Impedance, SensorSample
from device_bridge.osl.calibration_session import DEFAULT_SAMPLES
from device_bridge.osl.config import Calibration, JointCalibration, LegConfig, finite
from device_bridge.protocol import LegTorqueMode
from device_bridge.remote_calibration import CalibrationPort

THERMAL_EXCEPTIONS = ("ThermalLimitException", "I2tLimitException")   # opensourceleg.math's, matched by name


class OSLLeg:
    """The leg (module docstring) over SDK objects named by the configuration's tags.

    Args:
        config: the leg's configuration (which tags are which joint, its calibration, the torque mode).
        actuators: SDK actuators by tag (``opensourceleg.actuators`` subclasses).
        sensors: SDK sensors by tag: joint encoders, the load cell, the socket's angle sensor.
        clock: the leg's monotonic clock (s).
        impedance: what the firmware runs as a spring and damper (Dephy impedance mode).
        require_calibration: give no torque until every sensor is calibrated (a reversed sensor would turn every
            torque against its joint); False only for bench devices, which read the bench as QuasiTune does.
    """

    def __init__(self, config: LegConfig, actuators: Mapping[str, Any], sensors: Mapping[str, Any],
                 clock: Callable[[], float] = time.monotonic, impedance: Callable[[], Impedance] | None = None,
                 require_calibration: bool = True) -> None:
        def need(pool: Mapping[str, Any], tag: str | None, what: str) -> Any:
            if tag is None:
                return None
            if tag not in pool:
                raise ValueError(f"the configuration names {what} {tag!r}, which the leg does not have "
                                 f"(it has {', '.join(sorted(pool)) or 'none'})")
            return pool[tag]

        self.config = config
        self.clock = clock
        self.actuators = {j: need(actuators, getattr(config, j).actuator, f"the {j}'s actuator") for j in ("knee", "ankle")}
        self.encoders = {j: need(sensors, getattr(config, j).encoder, f"the {j}'s encoder") for j in ("knee", "ankle")}
        self.loadcell = need(sensors, config.loadcell, "the load cell")
        self.thigh = need(sensors, config.thigh, "the socket's angle sensor")
        self.fault_: tuple[str, str] | None = None   # the last hardware fault (kind, reason) until the firmware takes it
        self.derating_ = 1.0                    # the smallest thermal scaling applied to the last torques
        self.temperature_degC_: float | None = None
        if config.torque_mode == "dephy_impedance" and impedance is None:
            raise ValueError("torque_mode dephy_impedance needs the impedance the firmware runs (firmware.impedance)")
        self.impedance = impedance
        self.require_calibration = require_calibration
        self.sent_: dict[str, tuple[float, float, float]] = {}     # per joint: (K, B, equilibrium) last sent
        self.quantised_: dict[str, tuple[float, float]] = {}      # per joint: (K asked, K the actuator runs) N·m/rad
        self.clamped_ = 0                                          # rows whose k pushed (k > 0): sent as K = 0

    @property
    def devices(self) -> list[Any]:
        found = [*self.actuators.values(), *self.encoders.values(), self.loadcell, self.thigh]
        return [d for d in found if d is not None]

    def start(self) -> None:
        """Start every device and put the actuators in their torque mode (the SDK raises if one cannot)."""
        from opensourceleg.actuators.base import CONTROL_MODES  # the SDK: only on the leg's computer

        mode = {"current": CONTROL_MODES.CURRENT, "torque": CONTROL_MODES.TORQUE,
                "dephy_impedance": CONTROL_MODES.IMPEDANCE}[self.config.torque_mode]
        for d in self.devices:
            d.start()
        for a in self.actuators.values():
            a.set_control_mode(mode)
            if mode == CONTROL_MODES.CURRENT and hasattr(a, "set_current_gains"):
                a.set_current_gains()  # the SDK's defaults; a Dephy needs gains before its current loop runs

    def stop(self) -> None:
        """Zero torque, then stop every device (errors while stopping are collected, never hidden)."""
        problems = []
        for a in self.actuators.values():
            try:
                a.set_output_torque(0.0)
            except Exception as exc:
                problems.append(f"{a.tag}: {exc}")
        for d in self.devices:
            try:
                d.stop()
            except Exception as exc:
                problems.append(f"{getattr(d, 'tag', d)}: {exc}")
        if problems:
            raise RuntimeError("stopping the leg: " + "; ".join(problems))

    @property
    def calibrated(self) -> bool:
        """Every sensor calibrated (joints and load cell)."""
        cal = self.config.calibration
        return cal.knee.calibrated and cal.ankle.calibrated and cal.loadcell.calibrated

    @property
    def drives(self) -> bool:
        """Whether the leg gives the firmware's torques (else none: not calibrated yet)."""
        return self.calibrated or not self.require_calibration

    def leg_state(self) -> dict[str, int]:
        """What this leg says of itself in DEVICE_LEG: an Open Source Leg, which of its sensors are calibrated, its
        torque mode, and the torque its thermal model allows (%)."""
        cal = self.config.calibration
        return {"hardware": 1, "calibrated": int(cal.knee.calibrated) | int(cal.ankle.calibrated) << 1
                | int(cal.loadcell.calibrated) << 2,
                "torque_mode": int({"current": LegTorqueMode.CURRENT, "torque": LegTorqueMode.TORQUE,
                                    "dephy_impedance": LegTorqueMode.ACTUATOR_IMPEDANCE}[self.config.torque_mode]),
                "derating": round(100.0 * min(max(self.derating_, 0.0), 1.0))}

    def raw_readings(self) -> dict[str, float]:
        """The sensors as they read now, before any calibration (the devices as last updated): each joint's sensor
        and its actuator's output (rad), the load cell's fz (N) and my (N·m); NaN for one that cannot be read. What
        calibration measures (:mod:`device_bridge.osl.calibration_session`)."""
        def read(get: Callable[[], Any]) -> float:
            try:
                return float(get())
            except Exception:
                return float("nan")

        out: dict[str, float] = {}
        for joint in ("knee", "ankle"):
            act, enc = self.actuators[joint], self.encoders[joint]
            out[f"{joint}_actuator"] = read(lambda a=act: a.output_position)
            out[joint] = read(lambda e=enc: e.position) if enc is not None else out[f"{joint}_actuator"]
        out["fz"] = read(lambda: self.loadcell.fz)
        out["my"] = read(lambda: self.loadcell.my)
        return out

    def calibrate(self, calibration: Calibration, save: Callable[[Calibration], object]) -> None:
        """Run from now on with ``calibration``, once ``save`` has kept it (an error saving changes nothing)."""
        save(calibration)
        self.config = self.config.model_copy(update={"calibration": calibration})

    def calibration_port(self, save: Callable[[Calibration], object], samples: int = DEFAULT_SAMPLES) -> CalibrationPort:
        """The firmware's port for calibration from the clinic: this leg's raw readings, and :meth:`calibrate`."""
        return CalibrationPort(self.raw_readings, lambda cal: self.calibrate(cal, save), samples)

    def take_fault(self) -> tuple[str, str] | None:
        """The hardware fault seen since the last call as (``"thermal"`` or ``"sensor"``, its reason), or None; the
        device node hands it to the firmware each tick."""
        fault, self.fault_ = self.fault_, None
        return fault

    def _update(self, device: Any) -> None:
        try:
            device.update()
        except Exception as exc:
            if type(exc).__name__ not in THERMAL_EXCEPTIONS:
                raise
            self.fault_ = ("thermal", f"{getattr(device, 'tag', 'actuator')}: {type(exc).__name__}: {exc}".rstrip(": "))

    def _angle(self, joint: str) -> tuple[float, float]:
        cal: JointCalibration = getattr(self.config.calibration, joint)
        enc = self.encoders[joint]
        if enc is not None:
            raw, rate = enc.position, enc.velocity
        else:
            act = self.actuators[joint]
            raw, rate = act.output_position, act.output_velocity
        angle = cal.sign * (finite(float(raw), f"the {joint}'s angle") - cal.zero_rad)
        return angle, cal.sign * finite(float(rate), f"the {joint}'s velocity")

    def sample(self) -> SensorSample | None:
        """Read every device once and return the sensors in QuasiTune's conventions (None: a sensor failed)."""
        try:
            for d in self.devices:
                self._update(d)
            knee, knee_v = self._angle("knee")
            ankle, ankle_v = self._angle("ankle")
            cal = self.config.calibration.loadcell
            lc = self.loadcell
            load = cal.fz_sign * (finite(float(lc.fz), "the load cell's fz") - cal.fz_zero_N)
            moment = cal.my_sign * (finite(float(lc.my), "the load cell's my") - cal.my_zero_Nm)
            thigh = (float(self.thigh.position), float(self.thigh.velocity)) if self.thigh is not None else (0.0, 0.0)
            temps = [float(t) for a in self.actuators.values() if (t := getattr(a, "case_temperature", None)) is not None]
            self.temperature_degC_ = max(temps) if temps else None
        except Exception as exc:   # the leg cannot be read: no sample, and the reason kept
            self.fault_ = self.fault_ or ("sensor", f"a sensor could not be read: {type(exc).__name__}: {exc}")
            return None
        return SensorSample(time_s=self.clock(), knee_angle_rad=knee, knee_velocity_rad_s=knee_v,
                            ankle_angle_rad=ankle, ankle_velocity_rad_s=ankle_v, load_N=load, ankle_moment_Nm=moment,
                            thigh_angle_rad=thigh[0], thigh_velocity_rad_s=thigh[1])

    def step(self, knee_torque_Nm: float, ankle_torque_Nm: float) -> None:
        """Send the joint torques (N·m), each scaled by its actuator's thermal scaling factor; in Dephy impedance mode,
        the impedance the firmware runs instead (:meth:`send_impedance`)."""
        if self.config.torque_mode == "dephy_impedance":
            self.send_impedance()
            return
        if not self.drives:
            knee_torque_Nm = ankle_torque_Nm = 0.0
        for joint, tau in (("knee", knee_torque_Nm), ("ankle", ankle_torque_Nm)):
            cal: JointCalibration = getattr(self.config.calibration, joint)
            self.actuators[joint].set_output_torque(cal.torque_sign * tau * _thermal_scale(self.actuators[joint]))
        self.derating_ = min(_thermal_scale(a) for a in self.actuators.values())

    def send_impedance(self) -> None:
        """Dephy impedance mode: each joint's spring and damper from the firmware (the row of its state, standing's or
        safe mode's hold), sent when it changes, as the SDK takes it: joint-side stiffness K = −k ≥ 0 (QuasiTune's
        restoring k is negative; a row that pushes, k > 0, is sent as K = 0 and counted in :attr:`clamped_`), damping
        b, and the equilibrium in the actuator's own output angle. :attr:`quantised_` keeps the stiffness the
        actuator will run where it says its unit (Dephy: whole motor units, about 0.4 N·m/rad at 41.5:1). The
        thermal scaling factor cannot scale an impedance: it is kept in :attr:`derating_` for the health report."""
        assert self.impedance is not None
        springs = self.impedance() if self.drives else ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
        for joint, (k, theta_e, b) in zip(("knee", "ankle"), springs, strict=True):
            cal: JointCalibration = getattr(self.config.calibration, joint)
            act = self.actuators[joint]
            stiffness = max(-k, 0.0)
            target = (stiffness, max(b, 0.0), cal.zero_rad + cal.sign * theta_e)
            if self.sent_.get(joint) == target:
                continue
            self.clamped_ += int(k > 0.0)
            act.set_output_impedance(k=target[0], b=target[1])
            act.set_output_position(target[2])
            units = getattr(act, "NM_PER_RAD_TO_MOTOR_UNITS", None)
            if units:
                ratio = act.gear_ratio ** 2
                self.quantised_[joint] = (stiffness, int(stiffness / ratio * units) * ratio / units)
            self.sent_[joint] = target
        self.derating_ = min(_thermal_scale(a) for a in self.actuators.values())


def _thermal_scale(actuator: Any) -> float:
    """The share of its torque an actuator's thermal model allows now, in [0, 1] (1 where it has no such model)."""
    return min(max(float(getattr(actuator, "thermal_scaling_factor", 1.0)), 0.0), 1.0)
