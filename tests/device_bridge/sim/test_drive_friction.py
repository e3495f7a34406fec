"""A leg whose drives have friction (issue 53's hidden legs): the swing ankle compensates its drive's friction
(controller_core/fsm.py, "Drive friction"), which the bench's leg firmware knows from the leg's description.

Measured before it: with 3 N·m of ankle friction (and 2.5 N·m at the knee) the learned table's foot stayed
plantarflexed after push-off at 0.85 m/s level and caught its toe in most strides, and fell."""

from __future__ import annotations

from dataclasses import replace

from controller_core.fsm import ImpedanceSchedule, StateMachineController
from device_bridge.bench.task_reference import task_reference
from device_bridge.sim.leg_model import LegGeometry
from device_bridge.sim.simulate import run_walk, score_walk

MASS_KG = 75.0
FRICTION_LEG = replace(LegGeometry(), knee_friction_Nm=2.5, ankle_friction_Nm=3.0)


class IgnoresItsDrive(StateMachineController):
    """The same machine without the compensation: what the leg did before it."""

    def use_drive_friction(self, ankle_Nm: float) -> None:
        pass


def _walk(machine_class, model):
    table = model.propose(0.85, 0.0, MASS_KG).table
    ref = task_reference(0.85, 0.0, model, MASS_KG)
    machine = machine_class(ImpedanceSchedule.from_table(table))
    return machine, score_walk(run_walk(machine, ref, MASS_KG, 20.0, FRICTION_LEG), ref)


def test_the_learned_table_walks_a_leg_with_drive_friction_without_catching_its_toe(model):
    machine, score = _walk(StateMachineController, model)
    assert machine.limits.ankle_friction_Nm == 3.0                # the bench's leg told its firmware
    assert score.summary["falls"] == 0 and score.summary["toe_catches"] == 0, score.summary["fall_events"]
    _, before = _walk(IgnoresItsDrive, model)
    assert before.summary["toe_catches"] >= 5 and before.summary["falls"] >= 1
