"""The simulated patient: walks the MuJoCo bench at a task for as long as asked, in 10-second chunks.

:class:`SimWalker` is the leg a :class:`device_bridge.device_node.DeviceNode` drives when there is no hardware.
While stopped there are no sensor readings (the patient is not wearing the leg); :meth:`SimWalker.start` plans the
bench for a task (quiet standing, the first steps, then the able-bodied hip trajectory and load at that speed and
incline) and from then on every :meth:`SimWalker.step` advances the physics by one millisecond; the next chunk of
the trajectory continues the previous one exactly, so a session can last any length of time.
:meth:`SimWalker.start_course` walks a varying-task course (:mod:`device_bridge.sim.course`) once instead, on its own
floor, and stops at its end.

Between walks a patient who wears the leg **stands** (:meth:`SimWalker.stand`; after a course, on its own): the
sensors then read a quiet stance, half the body weight through the pylon with the knee near extension and the foot
flat, swaying slowly (0.25 Hz: about ±0.5° at the ankle and ±5 % body weight, the order of quiet-standing sway). The
bench has no physics of standing: these readings do not answer the leg's torques, they give the leg and the monitor
what a standing patient's sensors show, so that the clinic sees live signals whenever the leg is worn.
"""

from __future__ import annotations

import threading
from dataclasses import replace

import numpy as np

from controller_core.fsm import ActuatorLimits, SensorSample
from controller_core.units import G_MPS2
from controller_core.walking_reference import WalkingReference
from device_bridge.firmware import FirmwareConfig
from device_bridge.sim.bench_trajectory import (
    STAND_S,
    STANDING_START_PHASE,
    plan_bench_trajectory,
    plan_standing_start,
    standing_pose_rad,
)
from device_bridge.sim.course import Course, CourseTrajectory
from device_bridge.sim.course_walk import course_leg
from device_bridge.sim.leg_model import LegGeometry
from device_bridge.sim.person import Person
from device_bridge.sim.plant import SimulatedLeg

CHUNK_S = 10.0
STANDING_TIMESTEP_S = 0.001           # one reading per control tick, as while walking
STANDING_LOAD_FRACTION = 0.5          # of body weight, through the prosthesis
STANDING_SWAY_HZ = 0.25
STANDING_KNEE_DEG, STANDING_ANKLE_DEG = 3.0, 1.0
STANDING_SWAY_ANKLE_DEG, STANDING_SWAY_LOAD_FRACTION = 0.5, 0.05


class SimWalker:
    """A bench that walks on request (thread-safe start/stop; stepping from one thread)."""

    def __init__(self, geometry: LegGeometry | None = None) -> None:
        self.geometry = geometry or LegGeometry()   # the leg and person walked (a leg file's, or the nominal bench)
        self._lock = threading.Lock()
        self._leg: SimulatedLeg | None = None
        self._ref: WalkingReference | None = None
        self._mass = 0.0
        self._chunk_end_tick = 0
        self._ticks = 0
        self._sample: SensorSample | None = None
        self._course: tuple[Course, CourseTrajectory] | None = None
        self._standing_kg: float | None = None   # body mass of the patient standing on the leg, or None
        self._standing_ticks = 0
        # one clock for every reading, as a real leg's: each walk's physics starts at 0 s, so its readings are shifted
        # to follow the last one given (a clock that jumped back would freeze the state machine's dwell times)
        self._offset_s = 0.0
        self._last_s = 0.0
        self._walk_from_s = 0.0    # a fixed-task walk's first step, on its physics clock (s)

    def firmware_config(self) -> FirmwareConfig:
        """The firmware's settings for this leg, as a real leg's firmware has them from its own description: the task
        estimate's thigh, shank and forefoot, and the ankle drive's friction (compensated in swing)."""
        g = self.geometry
        return FirmwareConfig(thigh_length_m=g.thigh_m, shank_length_m=g.shank_m, forefoot_m=g.toe_forward_m,
                              actuator=ActuatorLimits(ankle_friction_Nm=g.ankle_friction_Nm))

    @property
    def walking(self) -> bool:
        return self._leg is not None

    @property
    def state(self) -> str:
        """``walking``, ``standing`` (worn, between walks) or ``not_worn`` (no sensor readings)."""
        return "walking" if self._leg is not None else "standing" if self._standing_kg is not None else "not_worn"

    def stand(self, mass_kg: float) -> None:
        """The patient of ``mass_kg`` stands on the leg (ends a walk)."""
        if not (np.isfinite(mass_kg) and 20.0 <= mass_kg <= 200.0):
            raise ValueError(f"mass_kg must be within [20, 200] kg, got {mass_kg!r}")
        with self._lock:
            self._leg, self._ref, self._sample, self._course = None, None, None, None
            self._standing_kg, self._standing_ticks = float(mass_kg), 0
            self._offset_s = self._last_s + STANDING_TIMESTEP_S

    def _standing_sample(self) -> SensorSample:
        """Quiet standing at the current tick (see the module docstring)."""
        t = self._offset_s + self._standing_ticks * STANDING_TIMESTEP_S
        w = 2.0 * np.pi * STANDING_SWAY_HZ
        sway, rate = float(np.sin(w * t)), float(w * np.cos(w * t))
        weight = float(self._standing_kg or 0.0) * G_MPS2
        ankle = np.radians(STANDING_ANKLE_DEG + STANDING_SWAY_ANKLE_DEG * sway)
        return SensorSample(time_s=t, knee_angle_rad=float(np.radians(STANDING_KNEE_DEG)), knee_velocity_rad_s=0.0,
                            ankle_angle_rad=float(ankle),
                            ankle_velocity_rad_s=float(np.radians(STANDING_SWAY_ANKLE_DEG) * rate),
                            load_N=weight * (STANDING_LOAD_FRACTION + STANDING_SWAY_LOAD_FRACTION * sway),
                            ankle_moment_Nm=0.0, thigh_angle_rad=0.0, thigh_velocity_rad_s=0.0)

    @property
    def course(self) -> str | None:
        """The course's name while walking one."""
        course = self._course
        return None if course is None else course[0].name

    @property
    def task(self) -> tuple[float, float] | None:
        """The true (speed m/s, incline deg) now, while walking."""
        course, ref = self._course, self._ref
        if course is not None:
            i = min(self._ticks, course[1].speed_mps.shape[0] - 1)
            return float(course[1].speed_mps[i]), float(course[1].incline_deg[i])
        return None if ref is None else (ref.speed_mps, ref.incline_deg)

    def start(self, reference: WalkingReference, mass_kg: float) -> None:
        """Start walking at the reference's task from quiet standing (a second of it, then the first steps into the
        task, as every walk of the bench begins: :func:`~device_bridge.sim.bench_trajectory.plan_standing_start`);
        a walk under way starts again from standing."""
        if not (np.isfinite(mass_kg) and 20.0 <= mass_kg <= 200.0):
            raise ValueError(f"mass_kg must be within [20, 200] kg, got {mass_kg!r}")
        leg = SimulatedLeg(self.geometry, incline_deg=reference.incline_deg, person=Person(mass_kg))
        traj = plan_standing_start(reference, leg.geometry, mass_kg, CHUNK_S, leg.timestep_s)
        _, knee0, ankle0 = standing_pose_rad(reference.incline_deg)
        sample = leg.reset(traj, knee0, ankle0)
        with self._lock:
            self._standing_kg = None
            self._offset_s = self._last_s + leg.timestep_s - sample.time_s
            self._leg, self._ref, self._mass, self._course = leg, reference, float(mass_kg), None
            self._chunk_end_tick, self._ticks, self._sample = traj.time_s.shape[0], 0, sample
            self._walk_from_s = round(STAND_S / leg.timestep_s) * leg.timestep_s   # the walk's time 0 on the leg's

    def start_course(self, course: Course, mass_kg: float) -> None:
        """Walk ``course`` once on its floor from standing (a second of it, then the first steps into its first task);
        walking stops at its end."""
        if not (np.isfinite(mass_kg) and 20.0 <= mass_kg <= 200.0):
            raise ValueError(f"mass_kg must be within [20, 200] kg, got {mass_kg!r}")
        traj, leg, angles = course_leg(course, mass_kg, self.geometry, start="standing")
        sample = leg.reset(traj.bench, *angles)
        with self._lock:
            self._standing_kg = None
            self._offset_s = self._last_s + leg.timestep_s - sample.time_s
            self._leg, self._ref, self._mass, self._course = leg, None, float(mass_kg), (course, traj)
            self._chunk_end_tick, self._ticks, self._sample = traj.bench.time_s.shape[0], 0, sample

    def stop(self) -> None:
        """Nobody wears the leg: no walk, no stance, no readings."""
        with self._lock:
            self._leg, self._ref, self._sample, self._course = None, None, None, None
            self._standing_kg = None

    def sample(self) -> SensorSample | None:
        """The sensors now: walking, standing, or None while nobody wears the leg (on one monotonic clock)."""
        if self._leg is None and self._standing_kg is not None:
            out = self._standing_sample()
        elif self._sample is None:
            return None
        else:
            out = replace(self._sample, time_s=self._sample.time_s + self._offset_s)
        self._last_s = out.time_s
        return out

    def step(self, knee_torque_Nm: float, ankle_torque_Nm: float) -> None:
        """Apply the torques for one timestep (nothing while not walking)."""
        with self._lock:
            leg = self._leg
            if leg is None:
                self._standing_ticks += 1
                return
            self._ticks += 1
            if self._ticks >= self._chunk_end_tick and self._course is not None:   # the course is walked: stand
                self._leg, self._sample, self._course = None, None, None
                self._standing_kg, self._standing_ticks = self._mass, 0
                return
            if self._ticks >= self._chunk_end_tick:
                assert self._ref is not None
                t0 = self._chunk_end_tick * leg.timestep_s - self._walk_from_s    # on the walk's own clock
                leg.continue_with(plan_bench_trajectory(self._ref, leg.geometry, self._mass, CHUNK_S, leg.timestep_s,
                                                        start_phase=STANDING_START_PHASE, t0_s=t0))
                self._chunk_end_tick += round(CHUNK_S / leg.timestep_s)
            self._sample = leg.step(knee_torque_Nm, ankle_torque_Nm)
