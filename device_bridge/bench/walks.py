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
from device_bridge.sim.course import Course, Segment
from device_bridge.sim.course_walk import CourseScore, run_course, score_course
from device_bridge.sim.leg_model import LegGeometry
from device_bridge.sim.simulate import WalkScore, run_walk, score_walk
from device_bridge.sim.video import VideoRecorder

STARTS = ("standing", "level", "swing")
LEVEL_LEAD_S = 6.0       # level walking before the change to the task (a few strides after the first steps)
LEVEL_SETTLE_S = 1.0     # strides scored from this long after the change to the task is complete


def level_lead_in(speed_mps: float, incline_deg: float, seconds: float, lead_s: float = LEVEL_LEAD_S) -> Course:
    """A walk that reaches the task from level walking: from standing, ``lead_s`` level at the task's speed, the
    course's raised-cosine change to the incline (its first 2 s), then the rest of ``seconds`` at the task."""
    return Course(f"level lead-in to {speed_mps:g} m/s {incline_deg:+g}°",
                  (Segment(lead_s, speed_mps, 0.0), Segment(seconds, speed_mps, incline_deg)))


def simulate(controller: str, speed_mps: float, incline_deg: float = 0.0, seconds: float = 20.0,
             mass_kg: float = 75.0, model: QuasiStiffnessModel | None = None, record: Path | None = None,
             video: Path | None = None, table: ImpedanceTable | None = None, skip_limits: bool = False,
             geometry: LegGeometry | None = None, start: str = "standing") -> WalkScore:
    """Walk one controller at one task (``quasi-stiffness``: the model's table at that task; ``table``: the given
    table, with ``skip_limits`` unchecked for bench studies) on the leg ``geometry`` (default the nominal bench),
    from ``start``: ``standing`` (quiet standing, then the first steps into the task), ``level`` (the same, then
    level walking that changes to the task: :func:`level_lead_in`; strides scored after the change) or ``swing`` (the
    bench's first start, in late swing at belt speed); optionally save the trajectories (.csv or .parquet) and a
    video."""
    validate_task(speed_mps, incline_deg, mass_kg)
    if start not in STARTS:
        raise ValueError(f"start must be one of {', '.join(STARTS)}, got {start!r}")
    ref = task_reference(speed_mps, incline_deg, model, mass_kg)
    ctrl = make_controller(controller, mass_kg, model, (speed_mps, incline_deg), table=table, skip_limits=skip_limits,
                           geometry=geometry)
    recorder = VideoRecorder(video) if video is not None else None
    frames = {"frame_callback": recorder, "frame_every": recorder.every if recorder else 0}
    settle_s = 2.0
    if start == "level":    # reached from level walking: a course of the level lead-in, the change, then the task
        lead = level_lead_in(speed_mps, incline_deg, seconds)
        log, _ = run_course(ctrl, lead, mass_kg, geometry, start="standing", **frames)
        settle_s = lead.change_times_s[-1] + lead.transition_s + LEVEL_SETTLE_S
    else:
        log = run_walk(ctrl, ref, mass_kg, seconds, geometry, start=start, **frames)
    if recorder is not None:
        recorder.close()
    score = score_walk(log, ref, settle_s=settle_s)
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
