"""Safe mode holds a loaded knee against flexion, lets it extend, extends it in swing and holds the ankle near neutral;
passive throughout (what it gives back it was given)."""

from __future__ import annotations

import math

import pytest

from controller_core.fsm import GaitState, SensorSample
from controller_core.safe_mode import SafeModeController, SafeModeParameters


def _x(knee: float, knee_v: float = 0.0, load: float = 700.0, ankle: float = 0.0, ankle_v: float = 0.0,
       t: float = 0.0) -> SensorSample:
    return SensorSample(time_s=t, knee_angle_rad=knee, knee_velocity_rad_s=knee_v, ankle_angle_rad=ankle,
                        ankle_velocity_rad_s=ankle_v, load_N=load, ankle_moment_Nm=0.0)


def test_a_loaded_knee_is_held_where_the_load_found_it_and_may_extend_freely():
    p = SafeModeParameters()
    safe = SafeModeController(p)
    first = safe.step(_x(0.2))                                   # loaded at 0.2 rad: held there
    assert first.state == GaitState.STANCE_FLEXION and first.knee_torque_Nm == 0.0 and safe.knee_hold_rad_ == 0.2
    flexing = safe.step(_x(0.25, 0.5))                           # folding further: spring and strong damper against
    assert flexing.knee_torque_Nm == pytest.approx(-p.knee_hold_k_Nm_per_rad * 0.05 - p.knee_flexion_b_Nm_s_per_rad * 0.5)
    extending = safe.step(_x(0.1, -0.5))                         # extending: only lightly damped, the hold follows
    assert extending.knee_torque_Nm == pytest.approx(p.knee_extension_b_Nm_s_per_rad * 0.5)
    assert safe.knee_hold_rad_ == 0.1
    again = safe.step(_x(0.15, 0.2))                             # and holds from there
    assert again.knee_torque_Nm == pytest.approx(-p.knee_hold_k_Nm_per_rad * 0.05 - p.knee_flexion_b_Nm_s_per_rad * 0.2)


def test_load_has_hysteresis_and_an_unloaded_knee_is_extended_for_the_next_step():
    p = SafeModeParameters()
    safe = SafeModeController(p)
    assert not safe.loaded_ and safe.step(_x(0.5, load=p.loaded_on_N - 1)).state == GaitState.SWING_EXTENSION
    assert safe.step(_x(0.5, load=p.loaded_on_N + 1)).state == GaitState.STANCE_FLEXION
    assert safe.step(_x(0.5, load=p.loaded_off_N + 1)).state == GaitState.STANCE_FLEXION     # between: still loaded
    swing = safe.step(_x(0.5, 1.0, load=p.loaded_off_N - 1))
    assert swing.state == GaitState.SWING_EXTENSION and safe.knee_hold_rad_ is None and safe.transitions_ == 2
    assert swing.knee_torque_Nm == pytest.approx(-p.knee_swing_k_Nm_per_rad * (0.5 - p.knee_swing_theta_rad)
                                                 - p.knee_swing_b_Nm_s_per_rad * 1.0)
    ankle = safe.step(_x(0.5, load=0.0, ankle=0.1, ankle_v=0.5)).ankle_torque_Nm
    assert ankle == pytest.approx(-p.ankle_k_Nm_per_rad * 0.1 - p.ankle_b_Nm_s_per_rad * 0.5)


def test_safe_mode_injects_no_energy_into_a_loaded_knee():
    """A loaded knee flexed and extended back to where it started, any number of times: the work safe mode does on it
    is never positive (it resists and gives back at most what it stored)."""
    safe, dt, work = SafeModeController(), 0.001, 0.0
    for cycle in range(3):
        for k in range(400):
            phase = k / 400
            v = 1.0 * math.sin(2 * math.pi * phase)                # out and back: flex, then extend
            theta = 0.2 + (1.0 / (2 * math.pi)) * (1 - math.cos(2 * math.pi * phase)) * 0.4
            tau = safe.step(_x(theta, v, t=cycle + k * dt)).knee_torque_Nm
            work += tau * v * dt
            assert work <= 1e-9
    assert work < 0.0


def test_torques_stay_within_the_actuator_and_parameters_are_checked():
    safe = SafeModeController()
    safe.step(_x(0.1))
    assert abs(safe.step(_x(1.5, 20.0)).knee_torque_Nm) <= safe.limits.knee_torque_Nm
    with pytest.raises(ValueError, match="loaded_off_N"):
        SafeModeParameters(loaded_on_N=50.0, loaded_off_N=60.0)
    with pytest.raises(ValueError, match="knee_hold_k_Nm_per_rad"):
        SafeModeParameters(knee_hold_k_Nm_per_rad=math.nan)
