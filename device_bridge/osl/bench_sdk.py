"""The MuJoCo bench behind the Open Source Leg SDK's own interfaces: actuators, joint encoders and a load cell that
are ``opensourceleg`` subclasses, so :class:`~device_bridge.osl.leg.OSLLeg` walks the bench exactly as it drives a
real leg (the SDK has no simulation: its ``offline`` mode returns constants; these are ours).

:class:`BenchWorld` holds the walking bench (:class:`device_bridge.sim.walker.SimWalker`) and what the hardware would
do with it: the torques the actuators were told hold for one control period (two 1 ms physics steps at 500 Hz), and
the first ``update()`` of a new period advances the bench by that period, as time passes between two reads of real
hardware. :class:`Mounting` says how the bench's sensors are mounted (sign and offset of each reading against
QuasiTune's conventions): what calibration must find. A thermal trip makes an actuator's next ``update()`` raise the
SDK's ``ThermalLimitException`` after its reading, as the Dephy actuator does.

Needs the SDK and MuJoCo (the leg's test environment; never the leg's runtime).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from opensourceleg.actuators.base import CONTROL_MODE_CONFIGS, CONTROL_MODES, MOTOR_CONSTANTS, ActuatorBase
from opensourceleg.math.math import ThermalLimitException
from opensourceleg.sensors.base import EncoderBase, LoadcellBase

from controller_core.fsm import GaitState, SensorSample, TorqueCommand
from device_bridge.firmware import DeviceFirmware
from device_bridge.osl.leg import OSLLeg
from device_bridge.sim.walker import SimWalker

PHYSICS_STEP_S = 0.001   # the bench's physics and the simulated leg's control tick
ACTPACK_IMPEDANCE_A, ACTPACK_IMPEDANCE_C = 0.00028444, 0.0007812   # the ActPack's impedance gain scales (Dephy)
BENCH_MOTOR = MOTOR_CONSTANTS(MOTOR_COUNT_PER_REV=16384, NM_PER_AMP=0.1133, MAX_CASE_TEMPERATURE=80.0,
                              MAX_WINDING_TEMPERATURE=110.0)   # a Dephy ActPack's motor, as the SDK states it


@dataclass(frozen=True)
class Mounting:
    """Reading = sign × QuasiTune's value + offset, per sensor; the actuator's output torque = torque sign × the joint's.

    The defaults read the bench as QuasiTune does (no calibration needed)."""

    knee_sign: int = 1
    knee_offset_rad: float = 0.0
    ankle_sign: int = 1
    ankle_offset_rad: float = 0.0
    knee_torque_sign: int = 1
    ankle_torque_sign: int = 1
    fz_sign: int = 1
    fz_offset_N: float = 0.0
    my_sign: int = 1
    my_offset_Nm: float = 0.0

    def torque_sign(self, joint: str) -> int:
        """The actuator of ``joint``'s output torque direction against QuasiTune's."""
        return self.knee_torque_sign if joint == "knee" else self.ankle_torque_sign


@dataclass
class BenchWorld:
    """The bench the SDK objects read and drive (module docstring).

    Attributes:
        walker: the walking bench; None when the bench loop itself steps the physics and hands each tick's readings
            in (:meth:`observe`, :class:`SDKRoute`).
        period_s: the leg's control period (s): what passes between two reads.
        mounting: how the sensors read it.
        held: joint angles (rad) the joints are held at by hand (calibration in a stand): the readings then come
            from these and the unloaded foot, not from a walk.
    """

    walker: SimWalker | None = None
    period_s: float = 0.002
    mounting: Mounting = Mounting()
    held: tuple[float, float] | None = None
    torques: dict[str, float] = field(default_factory=lambda: {"knee": 0.0, "ankle": 0.0})
    springs: dict[str, tuple[float, float, float]] = field(default_factory=dict)   # impedance mode: K, B, rest
    thermal_trip: set[str] = field(default_factory=set)
    time_s: float = 0.0
    _commanded: bool = False
    _sample: SensorSample | None = None

    def joint_torques(self, x: SensorSample) -> tuple[float, float]:
        """The joints' torques (QuasiTune's direction, N·m) at the bench's state ``x``: the torque an actuator was told,
        or, for one running its own spring and damper (impedance mode), that spring's torque on its reading of ``x``:
        computed every physics step, as the actuator's own loop runs faster than the leg's."""
        out = []
        for joint in ("knee", "ankle"):
            spring = self.springs.get(joint)
            if spring is None:
                out.append(self.torques[joint])
                continue
            k, b, rest = spring
            spring_Nm = k * (rest - self.reading(joint, x)) - b * self.reading(f"{joint}_velocity", x)
            out.append(self.mounting.torque_sign(joint) * spring_Nm)
        return out[0], out[1]

    def command(self, joint: str, output_torque_Nm: float) -> None:
        """An actuator's output torque (its own direction, N·m) → the joint's torque (QuasiTune's direction)."""
        self.torques[joint] = self.mounting.torque_sign(joint) * output_torque_Nm
        self._commanded = True

    @property
    def steps_per_period(self) -> int:
        """Physics steps in one control period (2 at 500 Hz)."""
        return max(round(self.period_s / PHYSICS_STEP_S), 1)

    def observe(self, x: SensorSample) -> None:
        """The bench's readings now (when the bench loop steps the physics: ``walker`` is None)."""
        self._sample, self.time_s, self._commanded = x, x.time_s, False

    def sync(self) -> None:
        """Let a control period pass if torques were commanded since the last read (the first read of a period)."""
        if self.walker is None or (self._sample is not None and not self._commanded):
            return
        if self._commanded:
            for _ in range(self.steps_per_period):
                now = self.walker.sample()
                knee, ankle = self.joint_torques(now) if now is not None else (self.torques["knee"],
                                                                             self.torques["ankle"])
                self.walker.step(knee, ankle)
            self.time_s += self.steps_per_period * PHYSICS_STEP_S
            self._commanded = False
        self._sample = self.walker.sample()
        if self._sample is not None:
            self.time_s = self._sample.time_s

    @property
    def truth(self) -> SensorSample | None:
        """What the bench's joints and pylon are doing now, in QuasiTune's conventions."""
        if self.held is not None:
            return SensorSample(self.time_s, self.held[0], 0.0, self.held[1], 0.0, 0.0, 0.0)
        return self._sample

    def reading(self, name: str, x: SensorSample | None = None) -> float:
        """A sensor's raw reading (of the bench now, or of ``x``): ``knee``, ``knee_velocity``, ``ankle``,
        ``ankle_velocity``, ``fz``, ``my``, ``thigh``, ``thigh_velocity``."""
        x, m = (self.truth if x is None else x), self.mounting
        if x is None:
            return math.nan
        return {"knee": m.knee_sign * x.knee_angle_rad + m.knee_offset_rad,
                "knee_velocity": m.knee_sign * x.knee_velocity_rad_s,
                "ankle": m.ankle_sign * x.ankle_angle_rad + m.ankle_offset_rad,
                "ankle_velocity": m.ankle_sign * x.ankle_velocity_rad_s,
                "fz": m.fz_sign * x.load_N + m.fz_offset_N,
                "my": m.my_sign * x.ankle_moment_Nm + m.my_offset_Nm,
                "thigh": x.thigh_angle_rad, "thigh_velocity": x.thigh_velocity_rad_s}[name]


class BenchActuator(ActuatorBase):
    """A joint's actuator on the bench: current (or torque) mode, or impedance mode like a Dephy ActPack's (its own
    spring and damper about an output position, stiffness and damping in whole motor units: the ActPack's conversion,
    about 0.40 N·m/rad and 0.003 N·m·s/rad at the joint at 41.5:1); its output position is the joint's, as the bench's
    mounting reads it; its torque goes to the bench's joint."""

    def __init__(self, tag: str, world: BenchWorld, joint: str, gear_ratio: float = 41.4999,
                 frequency: int = 500) -> None:
        super().__init__(tag=tag, gear_ratio=gear_ratio, motor_constants=BENCH_MOTOR, frequency=frequency)
        self.world, self.joint = world, joint
        self.case_temperature_degC = 30.0
        amp = BENCH_MOTOR.NM_PER_AMP / 1e3          # N·m per mA: the ActPack's impedance gains are in its own units
        self.NM_PER_RAD_TO_MOTOR_UNITS = (2 * math.pi / BENCH_MOTOR.MOTOR_COUNT_PER_REV) / ACTPACK_IMPEDANCE_C / amp
        self.NM_S_PER_RAD_TO_MOTOR_UNITS = (math.pi / 180) / ACTPACK_IMPEDANCE_A / amp
        self._spring: tuple[float, float] | None = None

    def set_output_impedance(self, k: float, b: float) -> None:
        """Joint-side stiffness (N·m/rad) and damping (N·m·s/rad), both ≥ 0 (a negative one raises, as the SDK's),
        truncated to whole motor units as the ActPack takes them."""
        if k < 0 or b < 0:
            raise ValueError(f"{self.tag}: stiffness {k} and damping {b} cannot be negative")
        ratio = self.gear_ratio ** 2
        k_q = int(k / ratio * self.NM_PER_RAD_TO_MOTOR_UNITS) * ratio / self.NM_PER_RAD_TO_MOTOR_UNITS
        b_q = int(b / ratio * self.NM_S_PER_RAD_TO_MOTOR_UNITS) * ratio / self.NM_S_PER_RAD_TO_MOTOR_UNITS
        self._spring = (k_q, b_q)

    def _spring_to(self, rest: float) -> None:
        if self._spring is None:
            raise RuntimeError(f"{self.tag}: set the impedance before its position")
        self.world.springs[self.joint] = (*self._spring, rest)

    @property
    def _CONTROL_MODE_CONFIGS(self) -> CONTROL_MODE_CONFIGS:
        return CONTROL_MODE_CONFIGS()

    def start(self) -> None:
        self._is_open = self._is_streaming = True

    def stop(self) -> None:
        self._is_open = self._is_streaming = False

    def update(self) -> None:
        self.world.sync()
        if self.joint in self.world.thermal_trip:
            raise ThermalLimitException(f"{self.tag}: case {self.case_temperature_degC:.0f} °C over its limit")

    def set_output_torque(self, value: float) -> None:
        self.world.command(self.joint, float(value))

    def set_motor_torque(self, value: float) -> None:
        self.set_output_torque(value * self.gear_ratio)

    def set_motor_current(self, value: float) -> None:
        self.set_motor_torque(value / 1000.0 * self.MOTOR_CONSTANTS.NM_PER_AMP)

    def set_current_gains(self, kp: float = 40, ki: float = 400, kd: float = 0, ff: float = 128) -> None:
        self._current_gains = (kp, ki, kd, ff)   # the bench's current loop is ideal; kept to show they were set

    def _unsupported(self, what: str) -> None:
        raise NotImplementedError(f"{self.tag}: the bench actuator runs current or torque only, not {what}")

    def set_motor_voltage(self, value: float) -> None:
        self._unsupported("voltage")

    def set_motor_position(self, value: float) -> None:
        if self.mode != CONTROL_MODES.IMPEDANCE:
            self._unsupported("position")
        self._spring_to(value / self.gear_ratio)

    def set_position_gains(self, kp: float, ki: float, kd: float, ff: float) -> None:
        self._unsupported("position")

    def _set_impedance_gains(self, k: float, b: float) -> None:
        self._unsupported("impedance gains in raw units (set_output_impedance takes joint units)")

    def home(self, *args: object, **kwargs: object) -> None:
        self._is_homed = True

    @property
    def motor_position(self) -> float:
        return self.world.reading(self.joint) * self.gear_ratio

    @property
    def motor_velocity(self) -> float:
        return self.world.reading(f"{self.joint}_velocity") * self.gear_ratio

    @property
    def motor_voltage(self) -> float:
        return 0.0

    @property
    def motor_current(self) -> float:
        return 1000.0 * self.motor_torque / self.MOTOR_CONSTANTS.NM_PER_AMP

    @property
    def motor_torque(self) -> float:
        return self.world.mounting.torque_sign(self.joint) * self.world.torques[self.joint] / self.gear_ratio

    @property
    def case_temperature(self) -> float:
        return self.case_temperature_degC

    @property
    def winding_temperature(self) -> float:
        return self.case_temperature_degC

    @property
    def thermal_scaling_factor(self) -> float:
        return 1.0


class _BenchSensor:
    """What every bench sensor does: stream once started, and read the bench as it is after the period's physics."""

    world: BenchWorld
    _streaming = False

    def start(self) -> None:
        self._streaming = True

    def stop(self) -> None:
        self._streaming = False

    def update(self) -> None:
        self.world.sync()

    @property
    def is_streaming(self) -> bool:
        return self._streaming


class BenchEncoder(_BenchSensor, EncoderBase):
    """A joint encoder on the bench (or, with ``name="thigh"``, the socket's angle sensor)."""

    def __init__(self, tag: str, world: BenchWorld, name: str) -> None:
        super().__init__(tag=tag)
        self.world, self.name = world, name

    @property
    def data(self) -> tuple[float, float]:
        return self.position, self.velocity

    @property
    def position(self) -> float:
        return self.world.reading(self.name)

    @property
    def velocity(self) -> float:
        return self.world.reading(f"{self.name}_velocity")


class BenchLoadcell(_BenchSensor, LoadcellBase):
    """The pylon's six-axis load cell on the bench (the sagittal plane's two channels; the others read 0)."""

    def __init__(self, tag: str, world: BenchWorld) -> None:
        super().__init__(tag=tag)
        self.world = world

    @property
    def data(self) -> tuple[float, ...]:
        return (self.fx, self.fy, self.fz, self.mx, self.my, self.mz)

    def calibrate(self) -> None:
        raise NotImplementedError("calibrate with device_bridge.osl.calibration: the SDK's zero is not trusted (#221)")

    def reset(self) -> None:
        pass

    @property
    def is_calibrated(self) -> bool:
        return True

    fx = fy = mx = mz = property(lambda self: 0.0)

    @property
    def fz(self) -> float:
        return self.world.reading("fz")

    @property
    def my(self) -> float:
        return self.world.reading("my")


class SDKRoute:
    """A bench controller (:class:`device_bridge.sim.simulate.StepController`) that goes the way of a real leg: the
    bench's readings through the SDK objects and the leg's calibration (:class:`~device_bridge.osl.leg.OSLLeg`), the
    firmware's tick at the leg's rate, the torques back through the actuators, held between ticks (zero-order hold:
    at 500 Hz each holds for two 1 ms physics steps). So :func:`device_bridge.sim.simulate.run_walk` scores a walk of
    the OSL leg exactly as it scores the simulated leg's.

    The firmware must hold a table (installed as pushed); the host's heartbeat is taken as alive.
    """

    def __init__(self, firmware: DeviceFirmware, leg: OSLLeg, world: BenchWorld) -> None:
        self.firmware, self.leg, self.world = firmware, leg, world
        self._every = world.steps_per_period
        self._calls = 0
        self._held = TorqueCommand(GaitState.SWING_EXTENSION, 0.0, 0.0, False)

    @property
    def transitions_(self) -> int:
        return getattr(self.firmware.controller_, "transitions_", 0)

    @property
    def guard_transitions_(self) -> int:
        return getattr(self.firmware.controller_, "guard_transitions_", 0)

    def reset(self) -> None:
        self._calls = 0
        if self.firmware.controller_ is not None:
            self.firmware.controller_.reset()

    def stand(self) -> None:
        if self.firmware.controller_ is not None and hasattr(self.firmware.controller_, "stand"):
            self.firmware.controller_.stand()

    def step(self, x: SensorSample) -> TorqueCommand:
        if self._calls % self._every == 0:
            self.world.observe(x)
            xs = self.leg.sample()
            now = xs.time_s if xs is not None else x.time_s
            self.firmware.last_heartbeat_s_ = now      # the clinic's link is not what this walk is about
            knee, ankle, _ = self.firmware.tick(xs, now)
            self.leg.step(knee, ankle)
            t, ctrl = self.world.torques, self.firmware.controller_    # the joints' torques, as the actuators gave them
            state = GaitState(ctrl.state_) if ctrl is not None else GaitState.SWING_EXTENSION
            self._held = TorqueCommand(state, t["knee"], t["ankle"], False)
        self._calls += 1
        if self.world.springs:        # the actuators' own springs act every physics step, not only at the leg's rate
            knee, ankle = self.world.joint_torques(x)
            return TorqueCommand(self._held.state, knee, ankle, False)
        return self._held


class BenchLeg:
    """A whole bench leg for a dry run (``kind = "bench"`` in a leg file): the walking bench with a patient standing on
    it, and the SDK objects a leg file names by their ``part``: ``knee_actuator``, ``ankle_actuator``,
    ``knee_encoder``, ``ankle_encoder``, ``loadcell``, ``thigh``."""

    def __init__(self, period_s: float = 0.002, mass_kg: float = 75.0, mounting: Mounting | None = None) -> None:
        self.walker = SimWalker()
        self.world = BenchWorld(walker=self.walker, period_s=period_s, mounting=mounting or Mounting())
        self.mass_kg = mass_kg
        self.walker.stand(mass_kg)

    def device(self, tag: str, part: str) -> ActuatorBase | EncoderBase | LoadcellBase:
        w = self.world
        if part in ("knee_actuator", "ankle_actuator"):
            return BenchActuator(tag, w, part.removesuffix("_actuator"), frequency=round(1.0 / w.period_s))
        if part in ("knee_encoder", "ankle_encoder", "thigh"):
            return BenchEncoder(tag, w, part.removesuffix("_encoder"))
        if part == "loadcell":
            return BenchLoadcell(tag, w)
        raise ValueError(f"{tag}: a bench part must be one of knee_actuator, ankle_actuator, knee_encoder, "
                         f"ankle_encoder, loadcell, thigh; got {part!r}")

    def walk(self, speed_mps: float) -> None:
        """The patient walks on the level at ``speed_mps`` (from standing), with the measured reference's pattern."""
        from controller_core.walking_reference import level_walking_reference

        self.walker.start(level_walking_reference(speed_mps), self.mass_kg)
