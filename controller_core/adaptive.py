"""The adaptive leg: the four-state machine with rows blended from an envelope at the task the leg estimates.

Once per stride, at heel strike (the machine's entry into stance flexion), :class:`AdaptiveController` takes the
task estimator's new estimate (:mod:`controller_core.task_estimator`), moves the task it runs at towards it by at
most ``max_speed_step_mps`` and ``max_incline_step_deg`` (the per-stride rate limit), blends the envelope there
(:mod:`controller_core.envelope_blend`) and loads the result. **Within the stride**, once the stance's own foot-flat
window is long enough to read the slope it stands on (:meth:`~controller_core.task_estimator.TaskEstimator.provisional`),
the rows of the states still to come in that stride (stance extension's if not yet entered, the swing rows, their
thresholds) are blended at that slope, by at most one stride's rate limit; a row never changes under the state that
runs it, and stance flexion's always comes from the heel strike. Only the incline is taken within the stride, and only
when this stride's own reading is confident and differs from the running incline by more than the estimate's
resolution: the slope comes from the foot's pitch and is the thing a ramp needs at once, while one window's speed is
noisier than the two-stride mean (taking it too made the `speed` course worse). At heel strike speed
and incline are followed separately: where the estimate of one is not confident (or there is none yet) its target is
the envelope's nominal value, approached at the same rate, so the leg stays on, or returns to, the nominal node
without a jump. (The incline comes from the foot's orientation, which stays readable when a leg on the wrong table
for a ramp lets its foot slide and spoils the speed reading.) A target outside the envelope is clamped to its edge,
and the status says so.

Pure, like the machine it wraps: :meth:`AdaptiveController.step` takes one sensor sample and returns one torque
command; the per-stride history is kept for telemetry and scoring.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field, replace
from typing import Literal

from controller_core.envelope_blend import Blend, EnvelopeBlender
from controller_core.fsm import (
    ActuatorLimits,
    GaitState,
    Impedance,
    SensorSample,
    StateMachineController,
    TorqueCommand,
)
from controller_core.task_estimator import (
    INCLINE_RESOLUTION_DEG,
    SPEED_RESOLUTION_MPS,
    StrideTask,
    TaskEstimate,
    TaskEstimator,
)
from controller_core.units import require_positive

AdaptiveMode = Literal["nominal", "partial", "adaptive", "clamped"]


@dataclass(frozen=True, slots=True)
class StrideDecision:
    """What the leg decided at one heel strike.

    Attributes:
        time_s: the heel strike (s).
        estimate: the estimator's estimate then (None before the first stride closed).
        target_speed_mps, target_incline_deg: where it wanted to go (the estimate, or the nominal task).
        speed_mps, incline_deg: the task it runs at for the next stride (after the rate limit and clamping).
        mode: ``adaptive`` (following a confident estimate of both), ``partial`` (one of them not confident: that
            one towards its nominal value), ``nominal`` (neither confident: towards the nominal task) or
            ``clamped`` (following, but the target lies outside the envelope by more than the estimate's resolution:
            held at its edge).
    """

    time_s: float
    estimate: TaskEstimate | None
    target_speed_mps: float
    target_incline_deg: float
    speed_mps: float
    incline_deg: float
    mode: AdaptiveMode


def _towards(current: float, target: float, step: float) -> float:
    return current + max(-step, min(step, target - current))


@dataclass
class AdaptiveController:
    """State machine + task estimator + envelope blender (see the module docstring).

    Args:
        blender: the envelope, already checked (building a blender is the check).
        estimator: the task estimator (segment lengths of this patient and leg).
        nominal: (speed m/s, incline deg) to run when the estimate is not confident.
        limits: actuator limits.
        max_speed_step_mps, max_incline_step_deg: the most the task may move per stride.
        history_strides: how many stride decisions are kept (the oldest are dropped: a leg walks for hours).
        within_stride: also blend the rows still to come in a stride at the stride's own foot-flat slope (module
            docstring); False: rows change at heel strike only.

    Attributes:
        machine_: the wrapped state machine.
        speed_mps_, incline_deg_: the task the current rows were blended at.
        blend_: the current blend.
        mode_: the current mode.
        decisions_: one :class:`StrideDecision` per heel strike, the last ``history_strides``.
    """

    blender: EnvelopeBlender
    estimator: TaskEstimator
    nominal: tuple[float, float]
    limits: ActuatorLimits = field(default_factory=ActuatorLimits)
    max_speed_step_mps: float = 0.15
    max_incline_step_deg: float = 3.0
    history_strides: int = 2000
    within_stride: bool = True
    machine_: StateMachineController = field(init=False)
    speed_mps_: float = field(init=False)
    incline_deg_: float = field(init=False)
    blend_: Blend = field(init=False)
    mode_: AdaptiveMode = field(init=False, default="nominal")
    decisions_: deque[StrideDecision] = field(init=False)
    within_done_: bool = field(init=False, default=True)      # this stride's own estimate has been used

    def __post_init__(self) -> None:
        require_positive(self, ("max_speed_step_mps", "max_incline_step_deg"))
        if not (isinstance(self.history_strides, int) and self.history_strides >= 1):
            raise ValueError(f"history_strides must be a positive integer, got {self.history_strides!r}")
        self.decisions_ = deque(maxlen=self.history_strides)
        self.blend_ = self.blender.at(*self.nominal)
        self.nominal = (self.blend_.speed_mps, self.blend_.incline_deg)
        self.machine_ = StateMachineController(self.blend_.schedule, self.limits)
        self.speed_mps_, self.incline_deg_ = self.nominal

    # the state machine's counters, so a walk can log either controller alike
    @property
    def transitions_(self) -> int:
        return self.machine_.transitions_

    @property
    def guard_transitions_(self) -> int:
        return self.machine_.guard_transitions_

    @property
    def state_(self) -> GaitState:
        return self.machine_.state_

    def impedance(self) -> Impedance:
        """The blended rows' spring and damper each joint runs now (:meth:`StateMachineController.impedance`)."""
        return self.machine_.impedance()

    def use_drive_friction(self, ankle_Nm: float) -> None:
        """The ankle drive's friction (N·m), compensated in swing (:meth:`StateMachineController.use_drive_friction`)."""
        self.machine_.use_drive_friction(ankle_Nm)
        self.limits = self.machine_.limits

    def use_forefoot(self, forefoot_m: float | None) -> None:
        """The foot's forefoot distance (m) for the machine's early landing on the toe
        (:meth:`StateMachineController.use_forefoot`)."""
        self.machine_.use_forefoot(forefoot_m)

    def stand(self) -> None:
        """A person stands on the leg now (:meth:`~controller_core.fsm.StateMachineController.stand`)."""
        self.machine_.stand()

    def reset(self, state: GaitState | None = None) -> None:
        """A new walk (or a new envelope): back to the nominal task, the estimator and history cleared, the machine
        in ``state`` (its initial state by default)."""
        self.estimator.reset()
        self.blend_ = self.blender.at(*self.nominal)
        self.speed_mps_, self.incline_deg_ = self.nominal
        self.mode_ = "nominal"
        self.within_done_ = True          # a stride's own reading is looked for from its heel strike on
        self.decisions_.clear()
        self.machine_.load(self.blend_.schedule)
        self.machine_.reset(state)

    def step(self, x: SensorSample) -> TorqueCommand:
        """Advance one sample; at a heel strike, pick the next stride's rows (used from the next sample on)."""
        before = self.machine_.state_
        cmd = self.machine_.step(x)
        stance = cmd.state in (GaitState.STANCE_FLEXION, GaitState.STANCE_EXTENSION)
        estimate = self.estimator.update(x, stance)
        if cmd.state == GaitState.STANCE_FLEXION and before in (GaitState.SWING_FLEXION, GaitState.SWING_EXTENSION):
            self._at_heel_strike(x.time_s, estimate if estimate is not None else self.estimator.last_)
            self.within_done_ = not self.within_stride
        elif stance and not self.within_done_:
            own = self.estimator.provisional(x.time_s)
            if own is not None:
                self.within_done_ = True
                self._within_stride(own, cmd.state)
        return cmd

    def _within_stride(self, own: StrideTask, state: GaitState) -> None:
        """The stride's own foot-flat estimate is in: the rows of the states after the current one blended at its
        slope (module docstring), by at most one stride's rate limit from where the stride began; nothing when this
        stride's reading is unsure or within the estimate's resolution of the running incline."""
        confident = own.valid and own.incline_quality >= self.estimator.confidence_threshold
        if not confident or abs(own.incline_deg - self.incline_deg_) <= INCLINE_RESOLUTION_DEG:
            return                         # unsure, or no change this estimate can tell from noise
        speed = self.speed_mps_
        incline = _towards(self.incline_deg_, own.incline_deg, self.max_incline_step_deg)
        if (speed, incline) == (self.speed_mps_, self.incline_deg_):
            return
        blend = self.blender.at(speed, incline)
        ran = int(state)                   # rows up to the current state's stay as they were
        old, new = self.machine_.schedule, blend.schedule
        rows = {name: tuple(getattr(old, name)[i] if i <= ran else getattr(new, name)[i] for i in range(4))
                for name in ("knee_k", "knee_theta_e", "knee_b", "ankle_k", "ankle_theta_e", "ankle_b")}
        self.machine_.load(replace(new, **rows))
        self.blend_ = blend
        self.speed_mps_, self.incline_deg_ = blend.speed_mps, blend.incline_deg

    def _at_heel_strike(self, now_s: float, estimate: TaskEstimate | None) -> None:
        follow_speed = estimate is not None and estimate.speed_confident
        follow_incline = estimate is not None and estimate.incline_confident
        target = (estimate.speed_mps if follow_speed and estimate is not None else self.nominal[0],
                  estimate.incline_deg if follow_incline and estimate is not None else self.nominal[1])
        speed = _towards(self.speed_mps_, target[0], self.max_speed_step_mps)
        incline = _towards(self.incline_deg_, target[1], self.max_incline_step_deg)
        blend = self.blender.at(speed, incline)
        mode: AdaptiveMode
        if not (follow_speed or follow_incline):
            mode = "nominal"
        elif not self.blender.contains(*target, SPEED_RESOLUTION_MPS, INCLINE_RESOLUTION_DEG):
            mode = "clamped"   # beyond the edge by more than the estimate can resolve (at the edge is inside)
        else:
            mode = "adaptive" if follow_speed and follow_incline else "partial"
        self.blend_, self.mode_ = blend, mode
        self.speed_mps_, self.incline_deg_ = blend.speed_mps, blend.incline_deg
        self.machine_.load(blend.schedule)
        self.decisions_.append(StrideDecision(now_s, estimate, target[0], target[1], blend.speed_mps,
                                              blend.incline_deg, mode))
