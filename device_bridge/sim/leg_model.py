"""The MuJoCo model of a hip-driven knee-ankle prosthesis bench (planar, sagittal plane).

Frame: x forward (walking direction), z up, rotations about y. The floor is a plane tilted by the incline
(uphill rises towards +x). A treadmill belt at constant speed is an inertial frame, so the bench walks the
socket forward over a fixed floor at the belt speed: the same physics with nothing moving under the foot. On a
varying-task course (:mod:`device_bridge.sim.course`) the floor is a chain of boxes following the course's ramps.
Friction uses elliptic cones with ``impratio`` 10: with MuJoCo's default pyramidal cones the loaded foot crept
down an 8° ramp at about 0.13 m/s (soft-contact slip), which a shoe on a ramp does not do.

Bodies:

* ``pelvis`` — the rest of the body (body mass less the socket and prosthesis), on two slides: ``hip_x`` (m, driven
  forward at belt speed by the person's progression servo) and ``hip_z`` (m, free: the body's weight acts on it, the
  prosthesis and the person's other leg hold it up; :mod:`device_bridge.sim.person`).
* ``socket`` — residual thigh and socket on the ``hip`` hinge (rad, flexion +: the knee moves forward), turned by
  the person's hip (:class:`device_bridge.sim.person.Person`).
* ``shank`` — knee actuator, frame and pylon; ``knee`` hinge (rad, flexion +), range 0–120°.
* ``load_cell`` — welded to the bottom of the shank with its sensing site at the ankle axis: a six-axis
  load cell between pylon and foot (the ankle actuator sits on the shank above it); its force and torque
  sensors read what the foot exchanges with the shank.
* ``foot`` — ``ankle`` hinge (rad, dorsiflexion +), range ±30°; heel and toe contact spheres.

Masses: total prosthesis 5.4 kg (the Open Source Leg class the issue names), split by us between knee unit
and shank frame (2.9 kg), ankle actuator on the lower shank (1.6 kg) and foot (0.9 kg); segment lengths
from Winter's anthropometric proportions of body height (thigh 0.245 H, shank 0.246 H, foot length 0.152 H,
ankle height 0.039 H: Winter DA, Biomechanics and Motor Control of Human Movement, 4th ed., 2009, Table 4.1).
Each joint has an armature standing for the reflected inertia of a geared actuator (an assumption of
0.03 kg·m², of the order of belt/screw drives on such legs), a small viscous damping (0.05 N·m·s/rad) and no
Coulomb friction by default; a leg file (:mod:`device_bridge.sim.leg_file`) sets each per joint for a leg that is not
the nominal one.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

from controller_core.units import require_positive

KNEE_RANGE_DEG = (0.0, 120.0)
FOREFOOT_ROCKER = 0.75   # metatarsal heads, as a fraction of foot length from the back of the heel
ANKLE_RANGE_DEG = (-30.0, 30.0)


@dataclass(frozen=True)
class LegGeometry:
    """Segment lengths (m), masses (kg) and contact geometry of the bench and prosthesis.

    Args:
        body_height_m: patient height (m); sets the segment lengths by Winter's proportions.
        socket_mass_kg: residual thigh and socket moved by the bench (kg).
        shank_mass_kg: knee actuator and shank frame (kg).
        ankle_unit_mass_kg: ankle actuator on the lower shank (kg).
        foot_mass_kg: foot (kg).
        contact_radius_m: radius of the heel and toe contact spheres (m).
        heel_back_m: heel contact centre behind the ankle axis (m).
        knee_armature_kg_m2, ankle_armature_kg_m2: reflected actuator inertia per joint (kg·m²).
        knee_friction_Nm, ankle_friction_Nm: Coulomb friction per joint (N·m; MuJoCo's ``frictionloss``), ≥ 0.
        knee_damping_Nm_s_per_rad, ankle_damping_Nm_s_per_rad: viscous damping per joint on top of the controller's
            b (N·m·s/rad), ≥ 0.
        name: what the leg is called in outputs.
    """

    body_height_m: float = 1.75
    socket_mass_kg: float = 3.0
    shank_mass_kg: float = 2.9
    ankle_unit_mass_kg: float = 1.6
    foot_mass_kg: float = 0.9
    contact_radius_m: float = 0.02
    heel_back_m: float = 0.05
    knee_armature_kg_m2: float = 0.03
    ankle_armature_kg_m2: float = 0.03
    knee_friction_Nm: float = 0.0
    ankle_friction_Nm: float = 0.0
    knee_damping_Nm_s_per_rad: float = 0.05
    ankle_damping_Nm_s_per_rad: float = 0.05
    name: str = "nominal"

    def __post_init__(self) -> None:
        require_positive(self, POSITIVE_FIELDS)
        for field in NON_NEGATIVE_FIELDS:
            v = getattr(self, field)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise ValueError(f"{field} must be a finite number ≥ 0, got {v!r}")

    @property
    def thigh_m(self) -> float:
        """Hip to knee axis (m)."""
        return 0.245 * self.body_height_m

    @property
    def shank_m(self) -> float:
        """Knee to ankle axis (m)."""
        return 0.246 * self.body_height_m

    @property
    def ankle_height_m(self) -> float:
        """Ankle axis above the sole (m)."""
        return 0.039 * self.body_height_m

    @property
    def toe_forward_m(self) -> float:
        """Forefoot contact centre ahead of the ankle axis (m): the rocker at the metatarsal heads, 75 % of the foot
        length (Winter: 0.152 × height) from the back of the heel; the toes bend beyond it and carry little, and a
        prosthetic foot's keel rolls over the same point. A rigid foot touching at the toe tip would lengthen the
        lever the ankle must hold the body on by about half."""
        return FOREFOOT_ROCKER * 0.152 * self.body_height_m - self.heel_back_m - self.contact_radius_m

    @property
    def prosthesis_mass_kg(self) -> float:
        """Mass below the socket (kg)."""
        return self.shank_mass_kg + self.ankle_unit_mass_kg + self.foot_mass_kg

    @property
    def moving_mass_kg(self) -> float:
        """Everything the bench moves (kg)."""
        return self.socket_mass_kg + self.prosthesis_mass_kg


NON_NEGATIVE_FIELDS = ("knee_friction_Nm", "ankle_friction_Nm", "knee_damping_Nm_s_per_rad",
                       "ankle_damping_Nm_s_per_rad")
POSITIVE_FIELDS = ("body_height_m", "socket_mass_kg", "shank_mass_kg", "ankle_unit_mass_kg", "foot_mass_kg",
                   "contact_radius_m", "heel_back_m", "knee_armature_kg_m2", "ankle_armature_kg_m2")


def _rod_inertia(mass: float, length: float) -> float:
    return mass * length * length / 12.0


def _floor(incline_deg: float, terrain: tuple[tuple[float, float], ...] = ()) -> str:
    """The floor's geoms: a plane tilted by the incline, or, for a course, a chain of thin boxes whose top faces follow
    the polyline ``terrain`` ((x, z) vertices, m): box–sphere contact is as exact as plane–sphere contact (a height
    field's prism contacts made the same walk fall where the plane did not)."""
    contact = 'material="grid" contype="1" conaffinity="1" friction="1.0 0.005 0.0001"'
    if not terrain:
        return (f'<geom name="floor" type="plane" size="200 1 0.1" euler="0 {-math.radians(incline_deg):.9f} 0" '
                f'{contact}/>')
    out = []
    half_thick = 0.1
    for k, ((x0, z0), (x1, z1)) in enumerate(itertools.pairwise(terrain)):
        length = math.hypot(x1 - x0, z1 - z0)
        slope = math.atan2(z1 - z0, x1 - x0)
        cx = 0.5 * (x0 + x1) + half_thick * math.sin(slope)   # the box's centre: half its thickness below the top face
        cz = 0.5 * (z0 + z1) - half_thick * math.cos(slope)
        out.append(f'<geom name="floor{k}" type="box" size="{0.5 * length:.6f} 1 {half_thick}" pos="{cx:.6f} 0 {cz:.6f}" '
                   f'euler="0 {-slope:.9f} 0" {contact}/>')
    return "\n    ".join(out)


def build_mjcf(geometry: LegGeometry, incline_deg: float = 0.0, timestep_s: float = 0.001,
               terrain: tuple[tuple[float, float], ...] = (), body_mass_kg: float = 75.0,
               progression: tuple[float, float] = (20000.0, 2300.0)) -> str:
    """The bench as an MJCF string (see the module docstring for bodies, joints and sensors); with ``terrain`` (a
    course's floor polyline) the floor follows it instead of the tilted plane (see :func:`_floor`). The body rides on
    the socket (``body_mass_kg``), driven forward by a servo of ``progression`` (stiffness N/m, damping N·s/m)."""
    g = geometry
    lt, ls, ha = g.thigh_m, g.shank_m, g.ankle_height_m
    r, heel, toe = g.contact_radius_m, g.heel_back_m, g.toe_forward_m
    lc_len = 0.08   # the load-cell body spans the last 8 cm above the ankle
    zc = -ha + r    # contact sphere centres relative to the ankle axis
    deg = math.pi / 180.0
    foot_len = heel + toe
    i_long = _rod_inertia(g.foot_mass_kg, foot_len)
    foot_inertia = f"{_rod_inertia(g.foot_mass_kg, 0.05):.6g} {i_long:.6g} {i_long:.6g}"
    floor = _floor(incline_deg, terrain)
    rest = body_mass_kg - g.moving_mass_kg
    if not (math.isfinite(rest) and rest > 0.0):
        raise ValueError(f"body_mass_kg must exceed the bench's moving mass ({g.moving_mass_kg:g} kg), "
                         f"got {body_mass_kg!r}")
    return f"""
<mujoco model="quasitune_hip_driven_bench">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="{timestep_s}" integrator="implicitfast" gravity="0 0 -9.81" cone="elliptic" impratio="10"/>
  <visual><global offwidth="1280" offheight="720"/><headlight diffuse="0.7 0.7 0.7"/></visual>
  <asset>
    <texture name="grid" type="2d" builtin="checker" width="256" height="256" rgb1="0.82 0.84 0.86"
             rgb2="0.72 0.74 0.76"/>
    <material name="grid" texture="grid" texrepeat="20 2"/>
  </asset>
  <default>
    <geom contype="0" conaffinity="0" rgba="0.35 0.45 0.6 1"/>
  </default>
  <worldbody>
    <light pos="0 -3 4" dir="0 0.6 -0.8"/>
    {floor}
    <body name="pelvis">
      <joint name="hip_x" type="slide" axis="1 0 0"/>
      <joint name="hip_z" type="slide" axis="0 0 1"/>
      <geom name="trunk" type="sphere" pos="0 0 0.3" size="0.12" mass="{rest:.6g}" rgba="0.6 0.6 0.6 0.3"/>
    <body name="socket">
      <joint name="hip" type="hinge" axis="0 -1 0"/>
      <geom name="thigh" type="capsule" fromto="0 0 0 0 0 {-lt:.6f}" size="0.06" mass="{g.socket_mass_kg}"
            rgba="0.85 0.7 0.6 0.6"/>
      <body name="shank" pos="0 0 {-lt:.6f}">
        <joint name="knee" type="hinge" axis="0 1 0" range="{KNEE_RANGE_DEG[0] * deg:.9f} {KNEE_RANGE_DEG[1] * deg:.9f}"
               armature="{g.knee_armature_kg_m2}" damping="{g.knee_damping_Nm_s_per_rad}"
               frictionloss="{g.knee_friction_Nm}" solreflimit="0.004 1"/>
        <geom name="shank" type="capsule" fromto="0 0 0 0 0 {-(ls - lc_len):.6f}" size="0.035" mass="{g.shank_mass_kg}"/>
        <geom name="ankle_unit" type="capsule" fromto="0 0 {-ls + 0.03:.6f} 0 0 {-ls + lc_len:.6f}" size="0.04"
              mass="{g.ankle_unit_mass_kg}" rgba="0.25 0.3 0.4 1"/>
        <body name="load_cell" pos="0 0 {-ls:.6f}">
          <site name="load_cell" pos="0 0 0" size="0.015"/>
          <geom name="load_cell" type="cylinder" fromto="0 0 0.005 0 0 0.025" size="0.03" mass="0.05"
                rgba="0.6 0.6 0.2 1"/>
          <body name="foot">
            <joint name="ankle" type="hinge" axis="0 -1 0"
                   range="{ANKLE_RANGE_DEG[0] * deg:.9f} {ANKLE_RANGE_DEG[1] * deg:.9f}"
                   armature="{g.ankle_armature_kg_m2}" damping="{g.ankle_damping_Nm_s_per_rad}"
               frictionloss="{g.ankle_friction_Nm}" solreflimit="0.004 1"/>
            <inertial pos="{(toe - heel) / 3:.6f} 0 {zc:.6f}" mass="{g.foot_mass_kg}" diaginertia="{foot_inertia}"/>
            <geom name="sole" type="capsule" fromto="{-heel:.6f} 0 {zc:.6f} {toe:.6f} 0 {zc:.6f}" size="{r * 0.9:.6f}"
                  mass="0" rgba="0.2 0.2 0.2 1"/>
            <geom name="heel" type="sphere" pos="{-heel:.6f} 0 {zc:.6f}" size="{r}" mass="0" contype="1" conaffinity="1"
                  friction="1.0 0.005 0.0001" solref="0.01 1" rgba="0.8 0.3 0.3 1"/>
            <geom name="toe" type="sphere" pos="{toe:.6f} 0 {zc:.6f}" size="{r}" mass="0" contype="1" conaffinity="1"
                  friction="1.0 0.005 0.0001" solref="0.01 1" rgba="0.8 0.3 0.3 1"/>
          </body>
        </body>
      </body>
    </body>
    </body>
  </worldbody>
  <actuator>
    <position name="hip_x_pos" joint="hip_x" kp="{progression[0]:g}"/>
    <velocity name="hip_x_vel" joint="hip_x" kv="{progression[1]:g}"/>
    <motor name="hip_z_push" joint="hip_z" ctrlrange="-50000 50000"/>
    <motor name="hip_torque" joint="hip" ctrlrange="-10000 10000"/>
    <motor name="knee" joint="knee" ctrlrange="-1000 1000"/>
    <motor name="ankle" joint="ankle" ctrlrange="-1000 1000"/>
  </actuator>
  <sensor>
    <jointpos name="knee_angle" joint="knee"/>
    <jointvel name="knee_velocity" joint="knee"/>
    <jointpos name="ankle_angle" joint="ankle"/>
    <jointvel name="ankle_velocity" joint="ankle"/>
    <force name="load_cell_force" site="load_cell"/>
    <torque name="load_cell_torque" site="load_cell"/>
  </sensor>
</mujoco>
"""
