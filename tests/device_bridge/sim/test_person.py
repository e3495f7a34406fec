"""The person around the prosthesis: a hip with a person's strength, a leg that pushes and never pulls."""

from __future__ import annotations

import math

import pytest

from device_bridge.sim.person import Person


def test_the_hip_places_the_swinging_leg_freely_but_adds_only_its_strength_with_the_foot_down():
    p = Person(80.0)
    big = p.hip_torque_Nm(0.5, 0.0, foot_down=False)
    assert big == pytest.approx(0.5 * p.hip_stiffness_Nm_per_rad)
    assert p.hip_torque_Nm(0.5, 0.0, foot_down=True) == pytest.approx(80.0 * p.hip_strength_Nm_per_kg)
    assert p.hip_torque_Nm(-0.5, 0.0, foot_down=True) == pytest.approx(-80.0 * p.hip_strength_Nm_per_kg)


def test_the_other_leg_pushes_harder_when_the_hip_is_low_and_never_pulls_below_nothing():
    p = Person(75.0)
    share = 300.0
    low = p.compensation_N(0.05, 0.0, other_foot_down=True, other_share_N=share)
    assert low > 0.05 * p.other_leg_stiffness_N_per_m                       # the leg and the stabiliser push up
    high = p.compensation_N(-0.2, 0.0, other_foot_down=True, other_share_N=share)
    stabiliser = -0.2 * p.stabiliser_bw_per_0_1m * p.weight_N / 0.1
    assert high == pytest.approx(-share + stabiliser)                        # the leg lets go of its share, no more
    airborne = p.compensation_N(0.05, 0.0, other_foot_down=False, other_share_N=0.0)
    assert airborne == pytest.approx(0.05 * p.stabiliser_bw_per_0_1m * p.weight_N / 0.1)   # only the weak stabiliser


@pytest.mark.parametrize("bad", [{"mass_kg": 0.0}, {"mass_kg": math.nan}, {"hip_strength_Nm_per_kg": -1.0}])
def test_nonsense_people_are_refused(bad):
    with pytest.raises(ValueError):
        Person(**{"mass_kg": 75.0, **bad})
