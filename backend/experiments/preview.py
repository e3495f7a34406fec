"""The dashboard's simulated preview: a given (proposed or edited) table and the FSMIC walked on the bench."""

from __future__ import annotations

import numpy as np

from backend.experiments.comparison import against_fsmic
from backend.experiments.reference import task_reference
from controller_core.fsm import ImpedanceSchedule, StateMachineController
from controller_core.fsmic import fsmic_table
from controller_core.gait_metrics import PHASE_GRID, reference_curves
from controller_core.model import QuasiStiffnessModel
from controller_core.table import ImpedanceTable
from controller_core.task import validate_task
from device_bridge.sim.simulate import run_walk, score_walk


def preview_table(table: ImpedanceTable, speed_mps: float, incline_deg: float, mass_kg: float,
                  model: QuasiStiffnessModel | None = None, seconds: float = 10.0) -> dict[str, object]:
    """Walk a given (e.g. proposed or edited) table and the FSMIC benchmark on the bench at a task.

    The dashboard's "simulated preview": same plant, same reference, same metrics as ``quasitune simulate``.
    Returns JSON-ready data: ``phase_grid`` (101 points), ``reference_curves`` and, per controller
    (``table``, ``fsmic``), its summary and stride-averaged ``mean_curves`` (deg, N·m/kg); the table's entry
    also carries ``vs_fsmic`` (:func:`against_fsmic`: its RMSEs minus the FSMIC's, with 95 % intervals).

    Raises:
        SafetyLimitError: a table fails the safety limits (checked again, as the device does).
    """
    def rounded(curves: dict[str, np.ndarray]) -> dict[str, list[float]]:
        return {k: [round(float(v), 3) for v in c] for k, c in curves.items()}

    validate_task(speed_mps, incline_deg, mass_kg)
    ref = task_reference(speed_mps, incline_deg, model, mass_kg)
    scores = {name: score_walk(run_walk(StateMachineController(ImpedanceSchedule.from_table(tab)), ref, mass_kg,
                                        seconds), ref)
              for name, tab in (("table", table), ("fsmic", fsmic_table(mass_kg)))}
    controllers: dict[str, object] = {name: {**score.summary, "mean_curves": rounded(score.mean_curves)}
                                      for name, score in scores.items()}
    controllers["table"]["vs_fsmic"] = against_fsmic(scores["table"], scores["fsmic"])
    return {"seconds": seconds, "phase_grid": [round(float(s), 3) for s in PHASE_GRID],
            "reference_curves": rounded(reference_curves(ref)), "controllers": controllers}
