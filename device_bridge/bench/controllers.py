"""The one controller factory of the bench: every walk (preview, comparison, course, session) gets its controller here.

* ``table``: a given table (a proposal's, an edit's) on the four-state machine;
* ``quasi-stiffness``: the model's table at one task (default the nominal 1.2 m/s level);
* ``fsmic``: the hand-tuned benchmark table (:mod:`controller_core.fsmic`), one table for every task;
* ``adaptive``: an envelope blended at the leg's own task estimate (:mod:`controller_core.adaptive`).

Every table is checked against the safety limits again here, as the device does.
"""

from __future__ import annotations

import numpy as np

from controller_core.adaptive import AdaptiveController
from controller_core.envelope import Envelope
from controller_core.envelope_blend import EnvelopeBlender
from controller_core.fsm import ImpedanceSchedule, StateMachineController
from controller_core.fsmic import fsmic_table
from controller_core.model import QuasiStiffnessModel
from controller_core.table import ImpedanceTable
from controller_core.task_estimator import TaskEstimator
from device_bridge.sim.leg_model import LegGeometry
from device_bridge.sim.swing_inertia import swing_inertia_ratio

CONTROLLERS: tuple[str, ...] = ("table", "quasi-stiffness", "fsmic", "adaptive")
NOMINAL_TASK = (1.2, 0.0)
DEFAULT_ENVELOPE_SPEEDS_MPS = tuple(np.linspace(0.6, 1.6, 5).round(3))
DEFAULT_ENVELOPE_INCLINES_DEG = tuple(np.linspace(-10.0, 10.0, 5).round(3))


def default_envelope(model: QuasiStiffnessModel, mass_kg: float, geometry: LegGeometry | None = None) -> Envelope:
    """The 5 × 5 envelope over 0.6–1.6 m/s × ±10° that course walks use when given none, nominal 1.2 m/s level, its
    swing rows for ``geometry``'s leg (:mod:`device_bridge.sim.swing_inertia`)."""
    return model.propose_envelope(DEFAULT_ENVELOPE_SPEEDS_MPS, DEFAULT_ENVELOPE_INCLINES_DEG, mass_kg, NOMINAL_TASK,
                                  swing_inertia_ratio=swing_inertia_ratio(geometry))


def make_controller(name: str, mass_kg: float, model: QuasiStiffnessModel | None = None,
                    task: tuple[float, float] = NOMINAL_TASK, table: ImpedanceTable | None = None,
                    envelope: Envelope | None = None, geometry: LegGeometry | None = None,
                    skip_limits: bool = False) -> StateMachineController | AdaptiveController:
    """A fresh controller named ``name`` for a patient of ``mass_kg``.

    Args:
        task: (speed m/s, incline deg) of the ``quasi-stiffness`` table.
        table: the ``table`` controller's table.
        envelope: the ``adaptive`` controller's envelope (default :func:`default_envelope`).
        geometry: the leg: the ``adaptive`` controller's task estimator needs its segments, and the learned tables
            (``quasi-stiffness``, the default envelope) are proposed for its swing inertia.
        skip_limits: walk the ``table`` controller's table without the limit check (bench studies of unsafe tables
            only: ``quasitune simulate --skip-limits``; no path from it reaches a device).

    Raises:
        ValueError: an unknown name, or what the name needs is missing.
        SafetyLimitError: a table or envelope node fails the limits.
    """
    if name not in CONTROLLERS:
        raise ValueError(f"unknown controller {name!r}; choose one of {', '.join(CONTROLLERS)}")
    if name == "fsmic":
        return StateMachineController(ImpedanceSchedule.from_table(fsmic_table(mass_kg)))
    if name == "table":
        if table is None:
            raise ValueError("the table controller needs a table")
        if skip_limits:
            return StateMachineController(ImpedanceSchedule.from_table_unchecked(table))
        return StateMachineController(ImpedanceSchedule.from_table(table))
    if model is None:
        raise ValueError(f"the {name} controller needs a trained model")
    if name == "quasi-stiffness":
        table = model.propose(task[0], task[1], mass_kg, swing_inertia_ratio=swing_inertia_ratio(geometry)).table
        return StateMachineController(ImpedanceSchedule.from_table(table))
    env = envelope or default_envelope(model, mass_kg, geometry)
    geometry = geometry or LegGeometry()
    return AdaptiveController(EnvelopeBlender(env.speeds_mps, env.inclines_deg, env.tables(), steps=env.neighbour_steps),
                              TaskEstimator(geometry.thigh_m, geometry.shank_m, forefoot_m=geometry.toe_forward_m),
                              (env.nominal_speed_mps, env.nominal_incline_deg))
