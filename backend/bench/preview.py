"""The dashboard's simulated preview of a version: its table (or envelope) and the FSMIC walked on the bench.

A table walks at its task for ten seconds; an envelope walks the mixed course (the leg estimating its task and
adapting), both against the FSMIC on the same plant, reference and metrics as ``quasitune simulate``, and every node of
the envelope walks alone at its own task, from standing and reached from level walking
(:mod:`backend.bench.node_previews`).
"""

from __future__ import annotations

import functools
import threading
from collections import OrderedDict
from collections.abc import Callable, Hashable
from typing import TypeVar

import numpy as np

from backend.bench.node_previews import NodeWalks, content_sha256
from controller_core.envelope import Envelope
from controller_core.gait_metrics import PHASE_GRID, reference_curves
from controller_core.model import QuasiStiffnessModel
from controller_core.table import ImpedanceTable
from controller_core.task import validate_task
from device_bridge.bench.controllers import make_controller
from device_bridge.bench.node_walks import NODE_LEVEL_LEAD_S, NODE_WALK_S
from device_bridge.bench.task_reference import task_reference
from device_bridge.bench.versus import against_fsmic, versus
from device_bridge.bench.walks import walk_course
from device_bridge.sim.course import Course
from device_bridge.sim.course_walk import CourseScore
from device_bridge.sim.leg_model import LegGeometry
from device_bridge.sim.simulate import WalkScore, run_walk, score_walk

T = TypeVar("T")
PREVIEW_COURSE = "mixed"
NODE_WALKS_SAID = {
    "seconds_at_task": NODE_WALK_S, "level_lead_s": NODE_LEVEL_LEAD_S,
    "starts": {"standing": "from quiet standing: the first steps, then walking at the node's task",
               "level": "reached from level walking at the node's speed (the envelope's most level node), the node's "
                        "rows from the first heel strike after the slope begins (the most level nodes: their walk from "
                        "standing is their level walking)"},
    "controller": "the node's own table on the four-state machine: what the leg runs when its estimate sits on the node",
    "bounds": "the same bounds as every bench walk, without the FSMIC-relative one (the FSMIC is not walked per node)"}


class BenchmarkWalks:
    """The walks a preview reuses, kept for the life of the server: the FSMIC's per (course, body mass, leg, model) and
    per (task, body mass, seconds, leg, model), and a version's own per its content and the same conditions.

    A walk on the bench depends only on what walks and where (deterministic), so every preview after the first at a
    body mass (and, for a table, at a task) reuses the benchmark's walk, and a version whose content was walked before
    (an edit undone, a refinement that changed nothing, the same envelope asked for again) reuses its own: an edit's
    preview then costs the new content's walk alone. ``maxsize`` bounds the memory of each kind. The scores returned
    are shared: read them, never change them.
    """

    def __init__(self, maxsize: int = 32) -> None:
        self.maxsize = maxsize
        self.score = functools.lru_cache(maxsize=maxsize)(self._walk)
        self.at_task = functools.lru_cache(maxsize=maxsize)(self._walk_at_task)
        self._versions: OrderedDict[Hashable, object] = OrderedDict()
        self._lock = threading.Lock()
        self.version_walks = 0           # versions' walks walked (not found kept)

    @staticmethod
    def _walk(course: Course, mass_kg: float, geometry: LegGeometry, model: QuasiStiffnessModel) -> CourseScore:
        return walk_course("fsmic", course, model, mass_kg, geometry=geometry)

    @staticmethod
    def _walk_at_task(speed_mps: float, incline_deg: float, mass_kg: float, seconds: float, geometry: LegGeometry,
                      model: QuasiStiffnessModel | None) -> WalkScore:
        ref = task_reference(speed_mps, incline_deg, model, mass_kg)
        return score_walk(run_walk(make_controller("fsmic", mass_kg), ref, mass_kg, seconds, geometry), ref)

    def version(self, key: Hashable, walk: Callable[[], T]) -> T:
        """The version's walk kept under ``key`` (its content hash and the walk's conditions); ``walk()`` the first
        time. Two previews of one content at once may both walk; one result is kept."""
        with self._lock:
            if key in self._versions:
                self._versions.move_to_end(key)
                return self._versions[key]
        score = walk()
        with self._lock:
            self.version_walks += 1
            self._versions[key] = score
            while len(self._versions) > self.maxsize:
                self._versions.popitem(last=False)
        return score


def preview_table(table: ImpedanceTable, speed_mps: float, incline_deg: float, mass_kg: float,
                  model: QuasiStiffnessModel | None = None, seconds: float = 10.0,
                  geometry: LegGeometry | None = None, benchmark: BenchmarkWalks | None = None) -> dict[str, object]:
    """Walk a given (e.g. proposed or edited) table and the FSMIC benchmark (from ``benchmark`` when it holds that
    walk) on the bench at a task.

    Returns JSON-ready data: ``phase_grid`` (101 points), ``reference_curves`` and, per controller (``table``,
    ``fsmic``), its summary and stride-averaged ``mean_curves`` (deg, N·m/kg); the table's entry also carries
    ``vs_fsmic`` (its RMSEs minus the FSMIC's, with 95 % intervals).

    Raises:
        SafetyLimitError: a table fails the safety limits (checked again, as the device does).
    """
    def rounded(curves: dict[str, np.ndarray]) -> dict[str, list[float]]:
        return {k: [round(float(v), 3) for v in c] for k, c in curves.items()}

    validate_task(speed_mps, incline_deg, mass_kg)
    geometry = geometry or LegGeometry()
    ref = task_reference(speed_mps, incline_deg, model, mass_kg)
    benchmark = benchmark or BenchmarkWalks(maxsize=1)
    key = ("table", content_sha256(table), speed_mps, incline_deg, mass_kg, seconds, geometry, model)
    scores = {"table": benchmark.version(key, lambda: score_walk(run_walk(
                  make_controller("table", mass_kg, table=table), ref, mass_kg, seconds, geometry), ref)),
              "fsmic": benchmark.at_task(speed_mps, incline_deg, mass_kg, seconds, geometry, model)}
    controllers: dict[str, object] = {name: {**score.summary, "mean_curves": rounded(score.mean_curves)}
                                      for name, score in scores.items()}
    controllers["table"]["vs_fsmic"] = against_fsmic(scores["table"], scores["fsmic"])
    return {"seconds": seconds, "leg": geometry.name, "phase_grid": [round(float(s), 3) for s in PHASE_GRID],
            "reference_curves": rounded(reference_curves(ref)), "controllers": controllers}


def preview_envelope(envelope: Envelope, model: QuasiStiffnessModel, course: Course,
                     geometry: LegGeometry | None = None,
                     benchmark: BenchmarkWalks | None = None,
                     nodes: NodeWalks | None = None) -> dict[str, object]:
    """The envelope's preview for its page: the course walked with the envelope (the leg estimating its task and
    adapting) and with the FSMIC (from ``benchmark`` when it holds that walk), at the envelope's body mass. Per
    controller its summary (safety figures, errors by segment, estimation accuracy for the envelope);
    ``envelope_minus_fsmic``: per channel the mean per-stride RMSE difference with its 95 % interval and verdict;
    ``nodes``: every node walked alone at its task (from ``nodes``' kept walks where it has them), its figures and
    flags; ``node_walks``: what those walks are."""
    geometry = geometry or LegGeometry()
    walked_nodes = (nodes or NodeWalks()).walk(envelope, model, geometry)
    benchmark = benchmark or BenchmarkWalks(maxsize=1)
    fsmic = benchmark.score(course, envelope.mass_kg, geometry, model)
    key = ("envelope", content_sha256(envelope), course, envelope.mass_kg, geometry, model)
    scores = {"envelope": benchmark.version(key, lambda: walk_course("adaptive", course, model, envelope.mass_kg,
                                                                     envelope, geometry=geometry)),
              "fsmic": fsmic}
    return {"course": course.to_json(), "mass_kg": envelope.mass_kg, "leg": geometry.name,
            "controllers": {name: s.to_dict() for name, s in scores.items()},
            "envelope_minus_fsmic": versus(scores["envelope"], scores["fsmic"], "envelope", "FSMIC"),
            "nodes": walked_nodes, "node_walks": NODE_WALKS_SAID}
