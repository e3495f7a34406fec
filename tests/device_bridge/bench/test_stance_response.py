"""The bench study of the loaded knee's answer to its stance-flexion stiffness, and the person variants it walks."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controller_core.fsm import GaitState
from device_bridge.bench.controllers import make_controller
from device_bridge.bench.stance_response import person_variant, stance_flexion_stays, stance_response
from device_bridge.bench.task_reference import task_reference
from device_bridge.sim.person import Person
from device_bridge.sim.simulate import WalkLog, run_walk


def _damping_ratio(p: Person, body_kg: float) -> float:
    return p.progression_damping_N_s_per_m / (2.0 * math.sqrt(p.progression_stiffness_N_per_m * body_kg))


def test_a_person_variant_changes_only_what_it_names_and_keeps_the_progression_critically_damped():
    stated = Person(75.0)
    body_kg = stated.progression_damping_N_s_per_m ** 2 / (4.0 * stated.progression_stiffness_N_per_m)
    soft = person_variant(75.0, progression_stiffness_N_per_m=2000.0)
    assert soft.progression_stiffness_N_per_m == 2000.0
    assert _damping_ratio(soft, body_kg) == pytest.approx(_damping_ratio(stated, body_kg))
    weak = person_variant(75.0, hip_strength_Nm_per_kg=0.4)
    assert weak.hip_limit_Nm == pytest.approx(30.0)
    assert weak.other_leg_stiffness_N_per_m == stated.other_leg_stiffness_N_per_m
    with pytest.raises(TypeError):
        person_variant(75.0, hip_strenght_Nm_per_kg=0.4)   # a misspelt field is refused, not ignored


def test_a_walk_refuses_a_person_of_another_mass():
    ref = task_reference(1.2, 0.0, None, 75.0)
    with pytest.raises(ValueError, match="person's mass"):
        run_walk(make_controller("fsmic", 75.0), ref, 75.0, 1.0, person=Person(80.0))


def test_stance_flexion_stays_are_read_from_the_state_channel():
    # synthetic log (made up for this test): 3 s at 1 kHz, stance flexion at 2.5-2.6 s and 2.8-2.95 s, one visit
    # before the settling time that must not count, the torque on each visit's last tick known
    n = 3000
    t = np.arange(n) * 0.001
    state = np.full(n, int(GaitState.SWING_EXTENSION))
    torque = np.zeros(n)
    for a, b, tau in ((1000, 1100, -99.0), (2500, 2600, -10.0), (2800, 2950, -30.0)):
        state[a:b] = int(GaitState.STANCE_FLEXION)
        torque[b - 1] = tau
    log = WalkLog(channels={"time_s": t, "state": state, "knee_torque_Nm": torque}, timestep_s=0.001, mass_kg=75.0,
                  wall_time_s=0.0, saturated_ticks=0, guard_transitions=0, transitions=0)
    stay_ms, torque_Nm = stance_flexion_stays(log, settle_s=2.0)
    assert stay_ms == pytest.approx(125.0) and torque_Nm == pytest.approx(-20.0)
    assert stance_flexion_stays(log, settle_s=2.99) == (None, None)


def test_the_study_walks_both_tables_at_both_stiffnesses_and_the_learned_table_without_knee_support(model):
    rows = stance_response(model, seconds=6.0, persons={"the bench's person": {}})
    assert [r["table"] for r in rows] == ["learned", "FSMIC"]
    learned, fsmic = rows
    assert set(learned["by_stance_flexion_k_Nm_per_rad"]) == {"-50", "-300"}
    assert "no_knee_support" in learned and "no_knee_support" not in fsmic
    # the learned row hands over to stance extension near the knee's peak; the FSMIC's holds through the loading
    # response, and a row that acts longer moves the body further (docs/results.md)
    assert (learned["by_stance_flexion_k_Nm_per_rad"]["-50"]["stance_flexion_stay_ms"]
            < fsmic["by_stance_flexion_k_Nm_per_rad"]["-50"]["stance_flexion_stay_ms"])
    assert fsmic["response_deg"] > learned["response_deg"] > 0.0
