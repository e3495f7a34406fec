"""Each node of an envelope walked at its own task: what the leg runs when its estimate sits on that node.

The envelope's course preview (``mixed``) never visits the grid's corners (0.6 m/s, ±10°), so every node is also
walked alone, its table on the four-state machine at the node's task, twice:

* ``standing``: from quiet standing, the first steps and :data:`NODE_WALK_S` of walking at the task (starting to walk
  on a slope is something patients do);
* ``level``: reached from level walking: :data:`NODE_LEVEL_LEAD_S` of level walking at the node's speed on the
  envelope's most level node at that speed, the course's change to the node's incline, and the node's own table from
  the first heel strike after the change begins (the leg changes rows at heel strike), then :data:`NODE_WALK_S` at
  the task.

Each walk reports the safety figures of :func:`~device_bridge.sim.simulate.score_walk` (falls and toe catches over
the whole walk, stance entry and the body's carriage over the strides after it settles); a walk depends only on its
two tables, the task, the body mass and the leg, so callers cache it by that content.
"""

from __future__ import annotations

from dataclasses import dataclass

from controller_core.fsm import GaitState, ImpedanceSchedule, SensorSample, StateMachineController, TorqueCommand
from controller_core.table import ImpedanceTable
from controller_core.walking_reference import WalkingReference
from device_bridge.bench.walks import LEVEL_SETTLE_S, level_lead_in
from device_bridge.sim.course import Course
from device_bridge.sim.course_walk import run_course
from device_bridge.sim.leg_model import LegGeometry
from device_bridge.sim.simulate import run_walk, score_walk

NODE_STARTS = ("standing", "level")
NODE_WALK_S = 5.0          # scored at the node's task (s): three strides or more from 0.75 m/s, two at 0.6
NODE_LEVEL_LEAD_S = 3.0    # level walking before the change to the node's incline (s): the first steps and a stride
NODE_CHANGE_S = Course.transition_s   # the change from level to the node's incline (s): the courses' raised cosine
NODE_SETTLE_S = 2.0        # from standing, strides scored from here (as every fixed-task walk of the bench)
# the figures a node walk keeps (the safety figures the gate reads, the strides behind them, the two angle errors)
NODE_FIGURES = ("strides", "falls", "fall_events", "toe_catches", "heel_strikes_without_stance",
                "loaded_swing_ms_max_stride", "heel_strike_to_stance_ms_max", "hip_sink_max_mm",
                "support_deficit_max_bw", "stance_knee_flexion_peak_max_deg", "reference_stance_knee_flexion_peak_deg",
                "knee_angle_rmse_deg", "ankle_angle_rmse_deg", "seconds", "settle_s")


class ChangesTableAtHeelStrike(StateMachineController):
    """The four-state machine on ``lead`` rows until ``after_s``, then on ``then`` rows from the next heel strike
    (swing extension → stance flexion), as the leg swaps rows; ``changed_at_s_`` says when (None: not yet)."""

    def __init__(self, lead: ImpedanceSchedule, then: ImpedanceSchedule, after_s: float) -> None:
        super().__init__(lead)
        self.lead, self.then, self.after_s = lead, then, after_s
        self.changed_at_s_: float | None = None

    def reset(self, state: GaitState | None = None) -> None:
        super().reset(state)
        self.load(self.lead)
        self.changed_at_s_ = None

    def step(self, x: SensorSample) -> TorqueCommand:
        before = self.state_
        cmd = super().step(x)
        if self.changed_at_s_ is None and x.time_s >= self.after_s and before == GaitState.SWING_EXTENSION \
                and self.state_ == GaitState.STANCE_FLEXION:
            self.load(self.then)
            self.changed_at_s_ = x.time_s
        return cmd


@dataclass(frozen=True)
class NodeWalk:
    """One walk of a node: ``figures`` (:data:`NODE_FIGURES`), from ``start``; ``changed_at_s``, reached from level:
    when the node's rows took over (None from standing, or when no heel strike came after the change began)."""

    start: str
    figures: dict[str, object]
    changed_at_s: float | None = None

    def to_dict(self) -> dict[str, object]:
        out: dict[str, object] = {"start": self.start, **self.figures}
        if self.start == "level":
            out["node_rows_from_s"] = self.changed_at_s
        return out


def level_to_node(speed_mps: float, incline_deg: float, seconds: float = NODE_WALK_S) -> Course:
    """The course of a node reached from level walking: the lead-in, then the change to the node's incline and
    ``seconds`` scored at the task after it settles."""
    return level_lead_in(speed_mps, incline_deg, NODE_CHANGE_S + LEVEL_SETTLE_S + seconds, lead_s=NODE_LEVEL_LEAD_S)


def simulated_s(start: str, seconds: float = NODE_WALK_S) -> float:
    """How long a node walk from ``start`` lasts on the bench (s)."""
    return NODE_SETTLE_S + seconds if start == "standing" else level_to_node(1.0, 0.0, seconds).duration_s


def walk_node(table: ImpedanceTable, reference: WalkingReference, mass_kg: float, start: str,
              level_table: ImpedanceTable | None = None, geometry: LegGeometry | None = None,
              seconds: float = NODE_WALK_S) -> NodeWalk:
    """Walk a node's ``table`` at the ``reference``'s task (:func:`~device_bridge.bench.task_reference.task_reference`)
    from ``start`` (module docstring); ``level_table``: the rows of the level walking it is reached from
    (``start="level"``; default the node's own). Tables are checked against the safety limits, as the device does.

    Raises:
        ValueError: an unknown start.
        SafetyLimitError: a table outside the limits.
    """
    if start not in NODE_STARTS:
        raise ValueError(f"start must be one of {', '.join(NODE_STARTS)}, got {start!r}")
    ref = reference
    speed_mps, incline_deg = ref.speed_mps, ref.incline_deg
    node = ImpedanceSchedule.from_table(table)
    if start == "standing":
        log = run_walk(StateMachineController(node), ref, mass_kg, NODE_SETTLE_S + seconds, geometry, start="standing")
        score = score_walk(log, ref, settle_s=NODE_SETTLE_S)
        return NodeWalk(start, _kept(score.summary))
    lead = ImpedanceSchedule.from_table(level_table) if level_table is not None else node
    course = level_to_node(speed_mps, incline_deg, seconds)
    change_s = course.change_times_s[-1]
    ctrl = ChangesTableAtHeelStrike(lead, node, change_s)
    log, _ = run_course(ctrl, course, mass_kg, geometry, start="standing")
    score = score_walk(log, ref, settle_s=change_s + course.transition_s + LEVEL_SETTLE_S)
    return NodeWalk(start, _kept(score.summary), ctrl.changed_at_s_)


def _kept(summary: dict[str, object]) -> dict[str, object]:
    return {k: summary.get(k) for k in NODE_FIGURES}
