"""One walk on the simulated bench (``quasitune simulate``): the learned table proposed for the task, or the fixed
FSMIC literature table (:mod:`controller_core.fsmic`) tuned once at the nominal task, on the same four-state
machine (:class:`controller_core.fsm.StateMachineController`)."""

from __future__ import annotations

from pathlib import Path

from backend.experiments.reference import task_reference
from controller_core.fsm import ImpedanceSchedule, StateMachineController
from controller_core.fsmic import fsmic_table
from controller_core.model import QuasiStiffnessModel
from controller_core.task import validate_task
from device_bridge.sim.simulate import WalkScore, run_walk, score_walk
from device_bridge.sim.video import VideoRecorder

CONTROLLERS: tuple[str, ...] = ("quasi-stiffness", "fsmic")


def make_controller(name: str, speed_mps: float, incline_deg: float, mass_kg: float,
                    model: QuasiStiffnessModel | None = None) -> StateMachineController:
    """A fresh state machine with the table of controller ``name`` for the task.

    Raises:
        ValueError: an unknown controller name (or a quasi-stiffness request without a model).
        SafetyLimitError: the table fails the safety limits (checked again here, as the device does).
    """
    if name == "fsmic":
        table = fsmic_table(mass_kg)
    elif name == "quasi-stiffness":
        if model is None:
            raise ValueError("the quasi-stiffness controller needs a trained model")
        table = model.propose(speed_mps, incline_deg, mass_kg).table
    else:
        raise ValueError(f"unknown controller {name!r}; choose one of {', '.join(CONTROLLERS)}")
    return StateMachineController(ImpedanceSchedule.from_table(table))


def simulate(controller: str, speed_mps: float, incline_deg: float = 0.0, seconds: float = 20.0,
             mass_kg: float = 75.0, model: QuasiStiffnessModel | None = None, record: Path | None = None,
             video: Path | None = None) -> WalkScore:
    """Walk one controller at one task; optionally save the trajectories and a video."""
    validate_task(speed_mps, incline_deg, mass_kg)
    ref = task_reference(speed_mps, incline_deg, model, mass_kg)
    ctrl = make_controller(controller, speed_mps, incline_deg, mass_kg, model)
    recorder = VideoRecorder(video) if video is not None else None
    log = run_walk(ctrl, ref, mass_kg, seconds, frame_callback=recorder, frame_every=recorder.every if recorder else 0)
    if recorder is not None:
        recorder.close()
    score = score_walk(log, ref)
    score.summary["controller"] = controller
    if record is not None:
        frame = log.to_frame()
        if record.suffix == ".parquet":
            frame.to_parquet(record, index=False)
        else:
            frame.to_csv(record, index=False, float_format="%.6g")
        score.summary["record"] = str(record)
    if video is not None:
        score.summary["video"] = str(video)
    return score
