"""Walks on the bench: one controller at one task (``quasitune simulate``), or over a varying-task course.

At one task the walk is scored against the reference at that task (:mod:`device_bridge.bench.task_reference`); on a
course each stride is scored against the reference at its own true task (:mod:`device_bridge.sim.course_walk`).
"""

from __future__ import annotations

from pathlib import Path

from controller_core.envelope import Envelope
from controller_core.model import QuasiStiffnessModel
from controller_core.table import ImpedanceTable
from controller_core.task import validate_task
from device_bridge.bench.controllers import NOMINAL_TASK, make_controller
from device_bridge.bench.task_reference import task_reference
from device_bridge.sim.course import Course
from device_bridge.sim.course_walk import CourseScore, run_course, score_course
from device_bridge.sim.leg_model import LegGeometry
from device_bridge.sim.simulate import WalkScore, run_walk, score_walk
from device_bridge.sim.video import VideoRecorder


def simulate(controller: str, speed_mps: float, incline_deg: float = 0.0, seconds: float = 20.0,
             mass_kg: float = 75.0, model: QuasiStiffnessModel | None = None, record: Path | None = None,
             video: Path | None = None, table: ImpedanceTable | None = None, skip_limits: bool = False,
             geometry: LegGeometry | None = None, start: str = "standing") -> WalkScore:
    """Walk one controller at one task (``quasi-stiffness``: the model's table at that task; ``table``: the given
    table, with ``skip_limits`` unchecked for bench studies) on the leg ``geometry`` (default the nominal bench),
    from ``start`` (``swing`` or ``standing``: :func:`~device_bridge.sim.simulate.run_walk`); optionally save the
    trajectories (.csv or .parquet) and a video."""
    validate_task(speed_mps, incline_deg, mass_kg)
    ref = task_reference(speed_mps, incline_deg, model, mass_kg)
    ctrl = make_controller(controller, mass_kg, model, (speed_mps, incline_deg), table=table, skip_limits=skip_limits)
    recorder = VideoRecorder(video) if video is not None else None
    log = run_walk(ctrl, ref, mass_kg, seconds, geometry, frame_callback=recorder,
                   frame_every=recorder.every if recorder else 0, start=start)
    if recorder is not None:
        recorder.close()
    score = score_walk(log, ref)
    score.summary["controller"] = controller
    score.summary["leg"] = (geometry or LegGeometry()).name
    score.summary["start"] = start
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


def walk_course(controller: str, course: Course, model: QuasiStiffnessModel | None, mass_kg: float = 75.0,
                envelope: Envelope | None = None, task: tuple[float, float] = NOMINAL_TASK,
                video: Path | None = None, geometry: LegGeometry | None = None, start: str = "standing") -> CourseScore:
    """Walk one controller over the course on the leg ``geometry`` (default the nominal bench) from ``start``
    (:func:`~device_bridge.sim.course_walk.course_leg`) and score it (the adaptive one also for its task
    estimates)."""
    geometry = geometry or LegGeometry()
    ctrl = make_controller(controller, mass_kg, model, task, envelope=envelope, geometry=geometry)
    recorder = VideoRecorder(video) if video is not None else None
    log, traj = run_course(ctrl, course, mass_kg, geometry, frame_callback=recorder,
                           frame_every=recorder.every if recorder else 0, start=start)
    if recorder is not None:
        recorder.close()
    score = score_course(log, traj, course, getattr(ctrl, "decisions_", None))
    score.summary["controller"] = controller
    score.summary["leg"] = geometry.name
    score.summary["start"] = start
    if controller == "quasi-stiffness":
        score.summary["table_task"] = {"speed_mps": task[0], "incline_deg": task[1]}
    if video is not None:
        score.summary["video"] = str(video)
    return score
