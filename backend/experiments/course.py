"""Walks over a varying-task course (``quasitune simulate --course`` and ``quasitune compare --course``).

Three controllers meet the same course: the adaptive envelope (the leg estimates its task and blends the envelope's
rows there, :mod:`controller_core.adaptive`), the model's fixed table at one task (the nominal 1.2 m/s level table
by default) and the FSMIC (:mod:`controller_core.fsmic`), all on the same four-state machine. Each stride is scored
against the reference at its own true task (:mod:`device_bridge.sim.course_walk`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from controller_core.adaptive import AdaptiveController
from controller_core.envelope import Envelope
from controller_core.envelope_blend import EnvelopeBlender
from controller_core.fsm import ImpedanceSchedule, StateMachineController
from controller_core.fsmic import fsmic_table
from controller_core.gait_metrics import GAIT_CHANNELS, bootstrap_means, percentile_interval, verdict
from controller_core.model import QuasiStiffnessModel
from controller_core.task_estimator import TaskEstimator
from device_bridge.as_run import as_run
from device_bridge.sim.course import Course
from device_bridge.sim.course_walk import CourseScore, run_course, score_course
from device_bridge.sim.leg_model import LegGeometry
from device_bridge.sim.video import VideoRecorder

COURSE_CONTROLLERS: tuple[str, ...] = ("adaptive", "quasi-stiffness", "fsmic")
DEFAULT_ENVELOPE_SPEEDS_MPS = tuple(np.linspace(0.6, 1.6, 5).round(3))
DEFAULT_ENVELOPE_INCLINES_DEG = tuple(np.linspace(-10.0, 10.0, 5).round(3))
NOMINAL_TASK = (1.2, 0.0)


def default_envelope(model: QuasiStiffnessModel, mass_kg: float) -> Envelope:
    """The 5 × 5 envelope over 0.6–1.6 m/s × ±10° the course comparison uses, nominal 1.2 m/s level."""
    return model.propose_envelope(DEFAULT_ENVELOPE_SPEEDS_MPS, DEFAULT_ENVELOPE_INCLINES_DEG, mass_kg, NOMINAL_TASK)


def make_course_controller(name: str, model: QuasiStiffnessModel | None, mass_kg: float, geometry: LegGeometry,
                           envelope: Envelope | None = None, task: tuple[float, float] = NOMINAL_TASK):
    """A fresh controller for a course walk (``quasi-stiffness``: the model's fixed table at ``task``).

    Raises:
        ValueError: an unknown name, or a learned controller without a model.
        SafetyLimitError: a table or envelope node fails the limits (checked again here, as the device does).
    """
    if name == "fsmic":
        return StateMachineController(ImpedanceSchedule.from_table(fsmic_table(mass_kg)))
    if name not in COURSE_CONTROLLERS:
        raise ValueError(f"unknown controller {name!r}; choose one of {', '.join(COURSE_CONTROLLERS)}")
    if model is None:
        raise ValueError(f"the {name} controller needs a trained model")
    if name == "quasi-stiffness":
        return StateMachineController(ImpedanceSchedule.from_table(model.propose(task[0], task[1], mass_kg).table))
    env = envelope or default_envelope(model, mass_kg)
    return AdaptiveController(EnvelopeBlender(env.speeds_mps, env.inclines_deg, env.tables(), steps=env.neighbour_steps),
                              TaskEstimator(geometry.thigh_m, geometry.shank_m),
                              (env.nominal_speed_mps, env.nominal_incline_deg))


def walk_course(controller: str, course: Course, model: QuasiStiffnessModel | None, mass_kg: float = 75.0,
                envelope: Envelope | None = None, task: tuple[float, float] = NOMINAL_TASK,
                video: Path | None = None) -> CourseScore:
    """Walk one controller over the course and score it (the adaptive one also for its task estimates)."""
    geometry = LegGeometry()
    ctrl = make_course_controller(controller, model, mass_kg, geometry, envelope, task)
    recorder = VideoRecorder(video) if video is not None else None
    log, traj = run_course(ctrl, course, mass_kg, geometry, frame_callback=recorder,
                           frame_every=recorder.every if recorder else 0)
    if recorder is not None:
        recorder.close()
    score = score_course(log, traj, course, getattr(ctrl, "decisions_", None))
    score.summary["controller"] = controller
    if controller == "quasi-stiffness":
        score.summary["table_task"] = {"speed_mps": task[0], "incline_deg": task[1]}
    if video is not None:
        score.summary["video"] = str(video)
    return score


def mean_difference(a: np.ndarray, b: np.ndarray, n_boot: int = 2000, seed: int = 0) -> dict[str, object]:
    """Mean of A minus mean of B (per-stride RMSEs of two independent walks), with a 95 % bootstrap interval and a
    verdict: ``A lower``/``B lower`` when the interval excludes zero, else ``not resolved``."""
    rng = np.random.default_rng(seed)
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if a.size < 2 or b.size < 2:
        return {"difference": None, "interval": None, "verdict": None}
    interval = percentile_interval(bootstrap_means(a, n_boot, rng) - bootstrap_means(b, n_boot, rng))
    return {"difference": float(a.mean() - b.mean()), "interval": list(interval), "verdict": verdict(interval)}


def compare_course(model: QuasiStiffnessModel, course: Course, mass_kg: float = 75.0,
                   envelope: Envelope | None = None) -> dict[str, object]:
    """All three controllers over the course, and the adaptive one's per-stride errors against each other's."""
    env = envelope or default_envelope(model, mass_kg)
    scores = {name: walk_course(name, course, model, mass_kg, env) for name in COURSE_CONTROLLERS}
    versus: dict[str, dict[str, object]] = {}
    for other in ("quasi-stiffness", "fsmic"):
        rows: dict[str, object] = {}
        for channel in GAIT_CHANNELS:
            d = mean_difference(scores["adaptive"].stride_rmse[channel], scores[other].stride_rmse[channel])
            words = {"A lower": "adaptive lower", "B lower": f"{other} lower"}.get(str(d["verdict"]), d["verdict"])
            rows[channel] = {"rmse_difference": d["difference"], "ci95": d["interval"], "verdict": words}
        versus[other] = rows
    return {"course": course.to_json(),
            "envelope": {"speeds_mps": env.speeds_mps, "inclines_deg": env.inclines_deg,
                         "wire_crc32": as_run(env).wire_crc32,
                         "nominal": [env.nominal_speed_mps, env.nominal_incline_deg]},
            "rows": [scores[name].to_dict() for name in COURSE_CONTROLLERS],
            "adaptive_minus": versus}


PREVIEW_COURSE = "mixed"


def preview_envelope(envelope: Envelope, model: QuasiStiffnessModel, course: Course) -> dict[str, object]:
    """The envelope's preview for its page: the course walked with the envelope (the leg estimating its task and
    adapting) and with the FSMIC, at the envelope's body mass. Per controller its summary (safety figures, errors by
    segment, estimation accuracy for the envelope); ``envelope_minus_fsmic``: per channel the mean per-stride RMSE
    difference with its 95 % interval and verdict."""
    scores = {"envelope": walk_course("adaptive", course, model, envelope.mass_kg, envelope),
              "fsmic": walk_course("fsmic", course, model, envelope.mass_kg)}
    versus: dict[str, object] = {}
    for channel in GAIT_CHANNELS:
        d = mean_difference(scores["envelope"].stride_rmse[channel], scores["fsmic"].stride_rmse[channel])
        words = {"A lower": "envelope lower", "B lower": "FSMIC lower"}.get(str(d["verdict"]), d["verdict"])
        versus[channel] = {"rmse_difference": d["difference"], "ci95": d["interval"], "verdict": words}
    return {"course": course.to_json(), "mass_kg": envelope.mass_kg,
            "controllers": {name: s.to_dict() for name, s in scores.items()}, "envelope_minus_fsmic": versus}
