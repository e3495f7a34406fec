"""The bench's geometry and its MuJoCo model."""

from __future__ import annotations

import math

import mujoco
import pytest

from device_bridge.sim.leg_model import LegGeometry, build_mjcf


def test_segments_follow_winters_proportions_of_the_patients_height():
    g = LegGeometry(body_height_m=1.80)
    assert g.thigh_m == pytest.approx(0.245 * 1.80) and g.shank_m == pytest.approx(0.246 * 1.80)
    assert g.prosthesis_mass_kg == pytest.approx(2.9 + 1.6 + 0.9) and g.moving_mass_kg == pytest.approx(3.0 + 5.4)
    assert g.toe_forward_m > 0.1


@pytest.mark.parametrize("bad", [{"body_height_m": 0.0}, {"foot_mass_kg": -1.0}, {"knee_armature_kg_m2": math.nan},
                                 {"ankle_friction_Nm": -0.1}, {"knee_damping_Nm_s_per_rad": math.inf}])
def test_a_non_physical_geometry_is_refused_by_name(bad):
    with pytest.raises(ValueError, match=f"{next(iter(bad))} must be a (positive )?finite number"):
        LegGeometry(**bad)


def test_each_joint_gets_its_own_armature_friction_and_damping():
    g = LegGeometry(knee_armature_kg_m2=0.1, ankle_armature_kg_m2=0.05, knee_friction_Nm=3.0, ankle_friction_Nm=1.5,
                    knee_damping_Nm_s_per_rad=0.4, ankle_damping_Nm_s_per_rad=0.2)
    model = mujoco.MjModel.from_xml_string(build_mjcf(g))
    knee, ankle = model.joint("knee"), model.joint("ankle")
    assert model.dof_armature[knee.dofadr[0]] == pytest.approx(0.1)
    assert model.dof_armature[ankle.dofadr[0]] == pytest.approx(0.05)
    assert model.dof_frictionloss[knee.dofadr[0]] == pytest.approx(3.0)
    assert model.dof_frictionloss[ankle.dofadr[0]] == pytest.approx(1.5)
    assert model.dof_damping[knee.dofadr[0]] == pytest.approx(0.4)
    assert model.dof_damping[ankle.dofadr[0]] == pytest.approx(0.2)


def test_the_model_loads_with_the_joints_sensors_and_a_tilted_floor():
    g = LegGeometry()
    model = mujoco.MjModel.from_xml_string(build_mjcf(g, incline_deg=8.0))
    assert {model.joint(i).name for i in range(model.njnt)} >= {"hip_x", "hip_z", "hip", "knee", "ankle"}
    sensors = {model.sensor(i).name for i in range(model.nsensor)}
    assert {"knee_angle", "ankle_angle", "load_cell_force", "load_cell_torque"} <= sensors
    assert model.opt.timestep == pytest.approx(0.001)
    knee = model.joint("knee")
    assert math.degrees(knee.range[1]) == pytest.approx(120.0, abs=0.5)
