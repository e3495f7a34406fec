"""The simulated leg: the MuJoCo bench behind a sensor-in, torque-out interface.

:class:`SimulatedLeg` owns one MuJoCo model and data. Each :meth:`SimulatedLeg.step` applies what the person does
this tick (:class:`device_bridge.sim.person.Person`: progression, hip torque, the other leg's push) and the commanded
knee and ankle torques (N·m), advances the physics by one timestep and returns the sensor sample the controller reads
next. Everything the firmware would see comes from the model's sensors (joint encoders, the six-axis load cell above
the ankle; the socket's angle from the vertical and its rate, which an IMU on the socket gives, read from the socket's
hinge), converted to the controller's conventions: load positive in compression, sagittal moment positive in the
dorsiflexion direction.
"""

from __future__ import annotations

import math
from typing import Protocol

import mujoco
import numpy as np

from controller_core.fsm import SensorSample
from device_bridge.sim.bench_trajectory import BenchTrajectory
from device_bridge.sim.leg_model import LegGeometry, build_mjcf
from device_bridge.sim.person import Person


class FloorProfile(Protocol):
    """A floor as straight pieces: a course's :class:`~device_bridge.sim.course.Terrain`, or a plane with an obstacle
    (:class:`~device_bridge.sim.stumble.FloorWithObstacle`)."""

    def polyline(self) -> tuple[tuple[float, float], ...]: ...


class SimulatedLeg:
    """A knee-ankle prosthesis carrying a body on a (tilted) floor, stepped at the model timestep.

    Args:
        geometry: segment lengths and masses.
        incline_deg: floor incline (deg, + uphill); ignored with ``terrain``.
        timestep_s: physics and control period (s); 0.001 for the 1 kHz controller.
        terrain: a floor profile (a course's, or a plane with an obstacle) instead of the tilted plane.
        person: the person around the prosthesis (their mass, hip and other leg); default a 75 kg
            :class:`device_bridge.sim.person.Person`.

    Attributes:
        model, data: the MuJoCo model and data (read-only use outside this class).
        support_N: what the person added this tick beyond the other leg's reference share (N, up +): their
            compensation for what the prosthesis did not carry.
        hip_torque_Nm: the person's hip torque this tick (N·m).
    """

    def __init__(self, geometry: LegGeometry | None = None, incline_deg: float = 0.0, timestep_s: float = 0.001,
                 terrain: FloorProfile | None = None, person: Person | None = None) -> None:
        if not (math.isfinite(incline_deg) and abs(incline_deg) <= 20.0):
            raise ValueError(f"incline_deg must be within ±20 deg, got {incline_deg!r}")
        self.geometry = geometry or LegGeometry()
        self.person = person or Person(75.0)
        self.incline_deg = float(incline_deg)
        xml = build_mjcf(self.geometry, incline_deg, timestep_s, () if terrain is None else terrain.polyline(),
                         self.person.mass_kg, (self.person.progression_stiffness_N_per_m,
                                               self.person.progression_damping_N_s_per_m))
        self.model = mujoco.MjModel.from_xml_string(xml)
        self.data = mujoco.MjData(self.model)
        self.timestep_s = float(self.model.opt.timestep)
        m = self.model
        self._q = {name: int(m.joint(name).qposadr[0]) for name in ("hip_x", "hip_z", "hip", "knee", "ankle")}
        self._v = {name: int(m.joint(name).dofadr[0]) for name in ("hip_x", "hip_z", "hip", "knee", "ankle")}
        self._a = {m.actuator(i).name: i for i in range(m.nu)}
        a = self._a
        self._a_bench = (a["hip_x_pos"], a["hip_x_vel"], a["hip_z_push"], a["hip_torque"])
        self._a_knee, self._a_ankle = a["knee"], a["ankle"]
        self._qv_bench = (self._q["hip_z"], self._v["hip_z"], self._q["hip"], self._v["hip"])
        adr = {m.sensor(i).name: int(m.sensor_adr[i]) for i in range(m.nsensor)}
        self._s_knee, self._s_kneev = adr["knee_angle"], adr["knee_velocity"]
        self._s_ankle, self._s_anklev = adr["ankle_angle"], adr["ankle_velocity"]
        self._s_force, self._s_torque = adr["load_cell_force"], adr["load_cell_torque"]
        colliding = {m.geom(i).name for i in range(m.ngeom) if m.geom_contype[i] or m.geom_conaffinity[i]}
        if not all(name in ("heel", "toe") or name.startswith("floor") for name in colliding):
            raise ValueError(f"only the foot and the floor may collide (foot_contact_force sums every contact): "
                             f"{sorted(colliding)}")
        self.support_N = 0.0
        self.hip_torque_Nm = 0.0
        self._tick = 0
        self._recovering, self._planned_down_seen = False, False
        self.recovery_step_times_s: list[float] = []
        self._traj: BenchTrajectory | None = None
        self._rows: list[tuple] = []    # the trajectory per tick as Python floats: the loop reads one row a tick
        self._force6 = np.zeros(6)   # scratch for mj_contactForce (called every tick in contact)
        # MjData's arrays are views of its own buffers for its whole life (mj_resetData rewrites them in place):
        # held once here, the loop does not make a new view of each every tick
        d = self.data
        self._qpos, self._qvel, self._ctrl, self._sensordata = d.qpos, d.qvel, d.ctrl, d.sensordata
        self._q_hip, self._v_hip = self._q["hip"], self._v["hip"]
        self._q_hip_x, self._q_hip_z = self._q["hip_x"], self._q["hip_z"]

    def reset(self, trajectory: BenchTrajectory, knee_rad: float, ankle_rad: float) -> SensorSample:
        """Place the socket at the trajectory's first sample and the joints at the given angles (rad)."""
        mujoco.mj_resetData(self.model, self.data)
        self._use(trajectory)
        self._tick = 0
        self._recovering, self._planned_down_seen = False, False
        self.recovery_step_times_s = []
        q, v = self.data.qpos, self.data.qvel
        q[self._q["hip_x"]], q[self._q["hip_z"]] = trajectory.x_m[0], trajectory.z_m[0]
        q[self._q["hip"]], q[self._q["knee"]], q[self._q["ankle"]] = trajectory.hip_rad[0], knee_rad, ankle_rad
        v[self._v["hip_x"]], v[self._v["hip_z"]] = trajectory.xd_m_s[0], trajectory.zd_m_s[0]
        v[self._v["hip"]] = trajectory.hipd_rad_s[0]
        self._apply_bench(0)
        mujoco.mj_forward(self.model, self.data)
        return self.sample()

    def continue_with(self, trajectory: BenchTrajectory) -> None:
        """Carry on walking along ``trajectory``, the chunk that starts one timestep after the current one ends."""
        if self._traj is None:
            raise RuntimeError("reset() the leg with a bench trajectory before continuing it")
        self._use(trajectory)
        self._tick = -1   # step() applies the new chunk's first sample next

    def _use(self, tr: BenchTrajectory) -> None:
        self._traj = tr
        self._rows = list(zip(tr.x_m.tolist(), tr.xd_m_s.tolist(), tr.z_m.tolist(), tr.zd_m_s.tolist(),
                              tr.hip_rad.tolist(), tr.hipd_rad_s.tolist(), tr.other_foot_down.tolist(),
                              tr.other_leg_N.tolist(), strict=True))

    def _apply_bench(self, i: int) -> None:
        """The person at tick ``i``: the walk's progression, the hip's torque on the thigh, the other leg's push
        (its reference share plus the person's compensation, :class:`device_bridge.sim.person.Person`)."""
        x, xd, z, zd, hip, hipd, other_down, other_N = self._rows[i]
        d, person = self.data, self.person
        c, q, v = self._ctrl, self._qpos.tolist(), self._qvel.tolist()   # Python floats: the person's arithmetic per tick
        a_x, a_xd, a_push, a_hip = self._a_bench
        q_z, v_z, q_hip, v_hip = self._qv_bench
        c[a_x], c[a_xd] = x, xd
        other_down = bool(other_down)
        if person.recovery_steps:
            other_down = self._recovery_step(other_down, z - q[q_z], d.time)
        self.support_N = person.compensation_N(z - q[q_z], zd - v[v_z], other_down, float(other_N))
        c[a_push] = other_N + self.support_N
        self.hip_torque_Nm = person.hip_torque_Nm(hip - q[q_hip], hipd - v[v_hip], d.ncon > 0)
        c[a_hip] = self.hip_torque_Nm

    def _recovery_step(self, scripted_down: bool, sink_m: float, time_s: float) -> bool:
        """Whether the other foot is down this tick when the person steps to save themselves
        (:attr:`Person.recovery_steps`): once the hip is :attr:`Person.recovery_step_sink_m` below its path while the
        other foot is up, it comes down at once and stays down to the end of its next planned stance."""
        if self._recovering:
            if scripted_down:
                self._planned_down_seen = True
            elif self._planned_down_seen:
                self._recovering = False
            return self._recovering or scripted_down
        if not scripted_down and sink_m > self.person.recovery_step_sink_m:
            self._recovering, self._planned_down_seen = True, False
            self.recovery_step_times_s.append(round(time_s, 3))
            return True
        return scripted_down

    def sample(self) -> SensorSample:
        """The sensors as the controller reads them now."""
        sd = self._sensordata.tolist()
        # the force/torque sensors give what the shank exerts on the load-cell subtree, in the site frame
        # (z up along the shank, y the joint axes): compression pushes it down (−z), and the moment about
        # +y is a plantarflexion moment in this model's axes (the ankle axis is −y), hence the signs
        return SensorSample(
            time_s=self.data.time,
            knee_angle_rad=sd[self._s_knee], knee_velocity_rad_s=sd[self._s_kneev],
            ankle_angle_rad=sd[self._s_ankle], ankle_velocity_rad_s=sd[self._s_anklev],
            load_N=-sd[self._s_force + 2], ankle_moment_Nm=-sd[self._s_torque + 1],
            thigh_angle_rad=float(self._qpos[self._q_hip]), thigh_velocity_rad_s=float(self._qvel[self._v_hip]))

    def step(self, knee_torque_Nm: float, ankle_torque_Nm: float) -> SensorSample:
        """Apply the joint torques (N·m) for one timestep and return the next sensor sample."""
        if self._traj is None:
            raise RuntimeError("reset() the leg with a bench trajectory before stepping it")
        self._tick += 1
        self._apply_bench(min(self._tick, len(self._rows) - 1))
        c = self._ctrl
        c[self._a_knee] = knee_torque_Nm
        c[self._a_ankle] = ankle_torque_Nm
        mujoco.mj_step(self.model, self.data)
        return self.sample()

    def foot_contact_force(self) -> float:
        """Total normal force between the foot's contacts and the floor now (N): ground truth for metrics. Every
        contact is one (the model lets only the heel, the toe and the floor collide: checked when it is built)."""
        total = 0.0
        f6, m, d = self._force6, self.model, self.data
        for j in range(d.ncon):
            mujoco.mj_contactForce(m, d, j, f6)
            total += abs(f6[0])
        return total

    def hip_position_m(self) -> tuple[float, float]:
        """The socket's (x, z) position in the world (m)."""
        q = self._qpos
        return float(q[self._q_hip_x]), float(q[self._q_hip_z])
