"""The adaptive machine: rows change at heel strike, and within a stride for the states still to come at that stride's
own slope, at a limited rate, back to nominal without confidence."""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import pytest

from controller_core.adaptive import AdaptiveController
from controller_core.envelope_blend import EnvelopeBlender
from controller_core.fsm import GaitState, SensorSample
from controller_core.task_estimator import StrideTask, TaskEstimate


@pytest.fixture(scope="module")
def blender(model):
    env = model.propose_envelope([0.8, 1.2, 1.6], [-8.0, 0.0, 8.0], 75.0)
    return EnvelopeBlender(env.speeds_mps, env.inclines_deg, env.tables())


@dataclass
class ScriptedEstimator:
    """Stands in for the task estimator: at each heel strike, the next of ``script`` (speed, incline, confident)."""

    script: list[tuple[float, float, bool]]
    last_: TaskEstimate | None = None
    within: list[tuple[float, float, bool]] | None = None   # each stride's own foot-flat estimate, if any
    confidence_threshold: float = 0.5
    _was_stance: bool = False
    _i: int = field(default=0)

    def provisional(self, now_s: float) -> StrideTask | None:
        """This stride's own estimate (the ``within`` script's, for the stride under way), or None."""
        if self.within is None or not self._was_stance or not 0 < self._i <= len(self.within):
            return None
        v, g, ok = self.within[self._i - 1]
        return StrideTask(now_s, v, g, 0.3, 0.001, 0.1, 1.0 if ok else 0.0, 1.0 if ok else 0.0, ok)

    def reset(self) -> None:
        self.last_, self._was_stance, self._i = None, False, 0

    def update(self, x: SensorSample, stance: bool) -> TaskEstimate | None:
        out = None
        if stance and not self._was_stance and self._i < len(self.script):
            v, g, ok = self.script[self._i]
            self._i += 1
            stride = StrideTask(x.time_s, v, g, 0.3, 0.001, 0.1, 1.0 if ok else 0.0, 1.0 if ok else 0.0, ok)
            out = self.last_ = TaskEstimate(x.time_s, v, g, float(ok), float(ok), ok, ok, stride)
        self._was_stance = stance
        return out


def strides(n: int, dt: float = 0.001):
    """Scripted sensor samples: swing (unloaded, knee flexing then extending) then stance (loaded), n times."""
    t = 0.0
    for _ in range(n):
        for k in range(450):                                   # swing: flex to 60° and back
            knee = math.radians(60.0) * math.sin(math.pi * k / 450)
            vel = math.radians(60.0) * math.pi / 0.45 * math.cos(math.pi * k / 450)
            yield SensorSample(t, knee, vel, 0.0, 0.0, 0.0, 0.0)
            t += dt
        for k in range(650):                                   # stance: loaded, the ankle moment falls late
            yield SensorSample(t, math.radians(5.0), 0.0, 0.0, 0.0, 700.0, -80.0 if k > 200 else 10.0)
            t += dt


def test_rows_change_only_at_heel_strike_and_at_most_by_the_rate_limit(blender):
    est = ScriptedEstimator([(1.6, 8.0, True)] * 10)      # no estimate within the stride: heel strikes only
    ctrl = AdaptiveController(blender, est, (1.2, 0.0), max_speed_step_mps=0.15, max_incline_step_deg=3.0)
    ctrl.reset()
    schedule, state = ctrl.machine_.schedule, ctrl.machine_.state_
    changes = 0
    for x in strides(8):
        before = state
        cmd = ctrl.step(x)
        state = cmd.state
        if ctrl.machine_.schedule is not schedule:
            changes += 1
            assert state == GaitState.STANCE_FLEXION and before in (GaitState.SWING_FLEXION, GaitState.SWING_EXTENSION)
            schedule = ctrl.machine_.schedule
    assert changes >= 6
    tasks = [(d.speed_mps, d.incline_deg) for d in ctrl.decisions_]
    prev = (1.2, 0.0)
    for speed, incline in tasks:
        assert abs(speed - prev[0]) <= 0.15 + 1e-9 and abs(incline - prev[1]) <= 3.0 + 1e-9
        prev = (speed, incline)
    assert tasks[-1] == pytest.approx((1.6, 8.0))          # reached in steps, not in one jump
    short = AdaptiveController(blender, ScriptedEstimator([(1.6, 8.0, True)] * 10), (1.2, 0.0), history_strides=3)
    short.reset()
    for x in strides(8):
        short.step(x)
    assert len(short.decisions_) == 3 and short.decisions_[-1].time_s == ctrl.decisions_[-1].time_s
    assert ctrl.decisions_[-1].mode == "adaptive"


def test_without_confidence_the_leg_returns_to_nominal_at_the_same_rate(blender):
    est = ScriptedEstimator([(1.6, 8.0, True)] * 4 + [(math.nan, math.nan, False)] * 6)
    ctrl = AdaptiveController(blender, est, (1.2, 0.0))
    ctrl.reset()
    for x in strides(11):
        ctrl.step(x)
    modes = [d.mode for d in ctrl.decisions_]
    assert modes[:4] == ["adaptive"] * 4 and set(modes[4:]) == {"nominal"}
    away = ctrl.decisions_[3]
    assert (away.speed_mps, away.incline_deg) != (1.2, 0.0)
    back = ctrl.decisions_[-1]
    assert (back.speed_mps, back.incline_deg) == pytest.approx((1.2, 0.0))
    decisions = list(ctrl.decisions_)
    steps = [abs(b.incline_deg - a.incline_deg) for a, b in itertools.pairwise(decisions)]
    assert max(steps) <= 3.0 + 1e-9


@pytest.mark.parametrize(("speed", "mode"), [(2.2, "clamped"), (1.6, "adaptive"), (1.65, "adaptive")])
def test_a_task_beyond_the_envelope_is_followed_to_its_edge_and_called_clamped_only_past_the_estimates_resolution(
        blender, speed, mode):
    """The bench walked exactly 1.60 m/s, the envelope's edge, and the leg once said it was outside the approved
    range: a task the estimate cannot tell from the edge (±0.1 m/s) is inside; 2.2 m/s is clamped."""
    est = ScriptedEstimator([(speed, 0.0, True)] * 8)
    ctrl = AdaptiveController(blender, est, (1.2, 0.0))
    ctrl.reset()
    for x in strides(9):
        ctrl.step(x)
    last = ctrl.decisions_[-1]
    assert last.mode == mode and last.speed_mps == pytest.approx(1.6)


def test_a_speed_estimate_without_confidence_leaves_speed_nominal_while_incline_is_followed(blender):
    @dataclass
    class HalfSure(ScriptedEstimator):
        def update(self, x, stance):
            out = super().update(x, stance)
            if out is not None:
                out = self.last_ = TaskEstimate(out.time_s, 1.6, 8.0, 0.1, 0.9, False, True, out.stride)
            return out

    ctrl = AdaptiveController(blender, HalfSure([(1.6, 8.0, True)] * 6), (1.2, 0.0))
    ctrl.reset()
    for x in strides(7):
        ctrl.step(x)
    last = ctrl.decisions_[-1]
    assert last.mode == "partial" and last.speed_mps == pytest.approx(1.2) and last.incline_deg == pytest.approx(8.0)


def test_within_a_stride_the_rows_still_to_come_follow_that_strides_own_slope(blender):
    """Level at every heel strike so far, then the stride's own foot-flat reading says +6°: from that moment the
    stance-extension and swing rows (and thresholds) are the +3° blend (one stride's rate limit), stance flexion's row
    stays the one it started with; a reading within the estimate's resolution, or an unsure one, changes nothing, and
    neither does a leg with the within-stride blend off."""
    level, ramp = (1.2, 0.0, True), (1.2, 6.0, True)

    def walk(within, on=True):
        est = ScriptedEstimator([level] * 6, within=within)
        ctrl = AdaptiveController(blender, est, (1.2, 0.0), within_stride=on)
        ctrl.reset()
        seen = []                                   # (state when the rows changed, schedule after), within strides
        schedule = ctrl.machine_.schedule
        for x in strides(4):
            before = ctrl.machine_.state_
            cmd = ctrl.step(x)
            if ctrl.machine_.schedule is not schedule:
                if not (cmd.state == GaitState.STANCE_FLEXION and before != GaitState.STANCE_FLEXION):
                    seen.append((cmd.state, schedule, ctrl.machine_.schedule, ctrl.incline_deg_))
                schedule = ctrl.machine_.schedule
        return seen

    seen = walk([level, ramp, ramp])
    assert len(seen) == 2 and all(state == GaitState.STANCE_FLEXION for state, *_ in seen)
    _, old, new, incline = seen[0]
    target = blender.at(1.2, 3.0).schedule
    assert incline == pytest.approx(3.0)
    assert new.knee_k[0] == old.knee_k[0] and new.ankle_theta_e[0] == old.ankle_theta_e[0]      # the running row
    assert new.knee_k[1:] == target.knee_k[1:] and new.ankle_theta_e[3] == target.ankle_theta_e[3]
    assert new.se_to_wf_load_N == target.se_to_wf_load_N
    assert walk([level, (1.2, 1.0, True), (1.2, -1.0, True)]) == []          # within the resolution: noise
    assert walk([level, (1.2, 6.0, False), (1.2, 6.0, False)]) == []         # unsure
    assert walk([level, ramp, ramp], on=False) == []
