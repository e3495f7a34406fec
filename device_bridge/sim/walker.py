"""The simulated patient: walks the MuJoCo bench at a task for as long as asked, in 10-second chunks.

:class:`SimWalker` is the leg a :class:`device_bridge.device_node.DeviceNode` drives when there is no hardware.
While stopped there are no sensor readings (the patient is not wearing the leg); :meth:`SimWalker.start` plans the
bench for a task (the able-bodied hip trajectory and load at that speed and incline) and from then on every
:meth:`SimWalker.step` advances the physics by one millisecond; the next chunk of the trajectory continues the
previous one exactly, so a session can last any length of time. :meth:`SimWalker.start_course` walks a varying-task
course (:mod:`device_bridge.sim.course`) once instead, on its own floor, and stops at its end.
"""

from __future__ import annotations

import threading

import numpy as np

from controller_core.fsm import SensorSample
from controller_core.walking_reference import WalkingReference
from device_bridge.sim.bench_trajectory import plan_bench_trajectory
from device_bridge.sim.course import Course, CourseTrajectory
from device_bridge.sim.course_walk import course_leg
from device_bridge.sim.plant import SimulatedLeg

CHUNK_S = 10.0


class SimWalker:
    """A bench that walks on request (thread-safe start/stop; stepping from one thread)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._leg: SimulatedLeg | None = None
        self._ref: WalkingReference | None = None
        self._mass = 0.0
        self._chunk_end_tick = 0
        self._ticks = 0
        self._sample: SensorSample | None = None
        self._course: tuple[Course, CourseTrajectory] | None = None

    @property
    def walking(self) -> bool:
        return self._leg is not None

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
        """Start walking at the reference's task (restarts from late swing if already walking)."""
        if not (np.isfinite(mass_kg) and 20.0 <= mass_kg <= 200.0):
            raise ValueError(f"mass_kg must be within [20, 200] kg, got {mass_kg!r}")
        leg = SimulatedLeg(incline_deg=reference.incline_deg)
        traj = plan_bench_trajectory(reference, leg.geometry, mass_kg, CHUNK_S, leg.timestep_s)
        s0 = traj.phase[0]
        sample = leg.reset(traj, float(np.interp(s0, reference.phase, reference.knee_angle_rad)),
                           float(np.interp(s0, reference.phase, reference.ankle_angle_rad)))
        with self._lock:
            self._leg, self._ref, self._mass, self._course = leg, reference, float(mass_kg), None
            self._chunk_end_tick, self._ticks, self._sample = traj.time_s.shape[0], 0, sample

    def start_course(self, course: Course, mass_kg: float) -> None:
        """Walk ``course`` once from late swing at its first task, on its floor; walking stops at its end."""
        if not (np.isfinite(mass_kg) and 20.0 <= mass_kg <= 200.0):
            raise ValueError(f"mass_kg must be within [20, 200] kg, got {mass_kg!r}")
        traj, leg, angles = course_leg(course, mass_kg)
        sample = leg.reset(traj.bench, *angles)
        with self._lock:
            self._leg, self._ref, self._mass, self._course = leg, None, float(mass_kg), (course, traj)
            self._chunk_end_tick, self._ticks, self._sample = traj.bench.time_s.shape[0], 0, sample

    def stop(self) -> None:
        with self._lock:
            self._leg, self._ref, self._sample, self._course = None, None, None, None

    def sample(self) -> SensorSample | None:
        """The sensors now, or None while not walking."""
        return self._sample

    def step(self, knee_torque_Nm: float, ankle_torque_Nm: float) -> None:
        """Apply the torques for one timestep (nothing while not walking)."""
        with self._lock:
            leg = self._leg
            if leg is None:
                return
            self._ticks += 1
            if self._ticks >= self._chunk_end_tick and self._course is not None:   # the course is walked
                self._leg, self._sample, self._course = None, None, None
                return
            if self._ticks >= self._chunk_end_tick:
                assert self._ref is not None
                t0 = self._chunk_end_tick * leg.timestep_s
                leg.continue_with(plan_bench_trajectory(self._ref, leg.geometry, self._mass, CHUNK_S, leg.timestep_s,
                                                        t0_s=t0))
                self._chunk_end_tick += round(CHUNK_S / leg.timestep_s)
            self._sample = leg.step(knee_torque_Nm, ankle_torque_Nm)
