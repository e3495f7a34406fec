"""The four-state impedance machine on scripted samples: transitions, guards, holds, the torque law."""

from __future__ import annotations

import dataclasses
import math

import pytest

from controller_core.fsm import ActuatorLimits, GaitState, ImpedanceSchedule, SensorSample, StateMachineController
from controller_core.table import SafetyLimitError

SF, SE, WF, WE = (GaitState.STANCE_FLEXION, GaitState.STANCE_EXTENSION, GaitState.SWING_FLEXION,
                  GaitState.SWING_EXTENSION)


def schedule(**over) -> ImpedanceSchedule:
    base = dict(knee_k=(-100.0, -50.0, -20.0, -10.0), knee_theta_e=(0.1, 0.05, 1.0, 0.1), knee_b=(2.0, 2.0, 1.0, 1.0),
                ankle_k=(-80.0, -120.0, -10.0, -10.0), ankle_theta_e=(0.0, -0.3, 0.0, 0.0), ankle_b=(1.0, 1.0, 0.5, 0.5),
                sf_to_se_ankle_moment_Nm=-5.0, se_to_wf_load_N=40.0, wf_to_we_knee_angle_rad=math.radians(50.0),
                we_to_sf_load_N=110.0, min_state_time_s=0.05, max_state_time_s=1.5, event_hold_s=0.0)
    base.update(over)
    return ImpedanceSchedule(**base)


def sample(t: float, load: float = 0.0, moment: float = 0.0, knee: float = 0.1, knee_v: float = 0.0,
           ankle: float = 0.0, ankle_v: float = 0.0) -> SensorSample:
    return SensorSample(time_s=t, knee_angle_rad=knee, knee_velocity_rad_s=knee_v, ankle_angle_rad=ankle,
                        ankle_velocity_rad_s=ankle_v, load_N=load, ankle_moment_Nm=moment)


def test_walks_through_the_four_states_in_order_on_a_scripted_stride():
    c = StateMachineController(schedule())
    assert c.step(sample(0.0)).state == WE
    assert c.step(sample(0.10, load=500.0)).state == SF                     # heel strike
    assert c.step(sample(0.20, load=600.0, moment=-2.0)).state == SF        # moment not yet past −5 N·m
    assert c.step(sample(0.30, load=600.0, moment=-6.0)).state == SE        # sagittal moment threshold
    assert c.step(sample(0.50, load=300.0, moment=-60.0)).state == SE
    assert c.step(sample(0.60, load=20.0)).state == WF                      # toe-off: load below 40 N
    assert c.step(sample(0.70, knee=math.radians(55.0), knee_v=3.0)).state == WF   # past 50° but still flexing
    assert c.step(sample(0.75, knee=math.radians(60.0), knee_v=0.0)).state == WE   # past 50° and slowing
    assert c.step(sample(0.95, load=150.0)).state == SF
    assert c.transitions_ == 5 and c.guard_transitions_ == 0


def test_missed_heel_strike_is_caught_by_the_max_time_guard():
    c = StateMachineController(schedule(max_state_time_s=1.0))
    c.step(sample(0.0))                                   # swing extension, the load never rises
    assert c.step(sample(0.99)).state == WE
    assert c.step(sample(1.00)).state == SF               # guard: 1.0 s in swing extension
    assert c.guard_transitions_ == 1


def test_no_transition_before_the_minimum_state_time():
    c = StateMachineController(schedule(min_state_time_s=0.2), initial_state=SE)
    c.step(sample(0.0, load=600.0))
    assert c.step(sample(0.1, load=10.0)).state == SE     # toe-off load, but only 0.1 s in state
    assert c.step(sample(0.2, load=10.0)).state == WF


def test_a_swinging_foot_moment_without_load_does_not_end_stance_flexion():
    c = StateMachineController(schedule(), initial_state=SF)
    c.step(sample(0.0, load=500.0))
    assert c.step(sample(0.2, load=10.0, moment=-30.0)).state == SF
    assert c.step(sample(0.3, load=500.0, moment=-30.0)).state == SE


def test_an_event_fires_only_after_its_condition_has_held_uninterrupted():
    c = StateMachineController(schedule(event_hold_s=0.02), initial_state=SE)
    c.step(sample(0.0, load=600.0))
    assert c.step(sample(0.100, load=20.0)).state == SE     # one low load sample (a ringing load cell) ...
    assert c.step(sample(0.101, load=400.0)).state == SE    # ... then loaded again: the hold restarts
    assert c.step(sample(0.200, load=20.0)).state == SE
    assert c.step(sample(0.210, load=20.0)).state == SE     # 10 ms below the toe-off load: not yet
    assert c.step(sample(0.220, load=20.0)).state == WF     # 20 ms: toe-off
    assert c.transitions_ == 1 and c.event_since_s_ is None  # the hold is forgotten with the state


def test_the_max_time_guard_does_not_wait_for_the_event_hold():
    c = StateMachineController(schedule(event_hold_s=0.02, max_state_time_s=1.0), initial_state=SE)
    c.step(sample(0.0, load=600.0))
    assert c.step(sample(0.995, load=10.0)).state == SE    # toe-off seen, 5 ms held
    assert c.step(sample(1.000, load=10.0)).state == WF    # the guard moves on at 1.0 s regardless
    assert c.guard_transitions_ == 1


def _loaded(c: StateMachineController, t0: float, ms: int, load: float = 800.0) -> list[GaitState]:
    return [c.step(sample(t0 + i / 1000.0, load=load)).state for i in range(ms)]


def test_heel_strike_in_swing_extension_is_recognised_in_5_ms_without_waiting_for_the_minimum_time():
    c = StateMachineController(schedule(event_hold_s=0.02, min_state_time_s=0.05))
    c.step(sample(0.0))                                    # swing extension entered just now
    states = _loaded(c, 0.010, 10)                         # foot contact 10 ms into swing extension
    assert states[:5] == [WE] * 5 and states[5] == SF, states   # stance from the 6th loaded millisecond
    assert c.transitions_ == 1 and c.guard_transitions_ == 0


def test_a_single_loaded_sample_in_swing_is_not_a_heel_strike():
    c = StateMachineController(schedule(event_hold_s=0.02))
    c.step(sample(0.0))
    assert _loaded(c, 0.100, 3) == [WE] * 3                # 3 ms of load (a knock) ...
    assert c.step(sample(0.103, load=5.0)).state == WE     # ... then none: the hold restarts
    assert _loaded(c, 0.104, 5) == [WE] * 5


def test_heel_strike_in_swing_flexion_goes_straight_to_stance():
    c = StateMachineController(schedule(event_hold_s=0.02, min_state_time_s=0.05), initial_state=WF)
    c.step(sample(0.0, knee=0.5, knee_v=3.0))              # swing flexion, the knee still flexing
    states = _loaded(c, 0.300, 10)                         # the foot lands before the knee reached swing extension
    assert states[:5] == [WF] * 5 and states[5] == SF and WE not in states, states


def test_a_leg_loaded_again_just_after_a_false_toe_off_returns_to_stance_in_5_ms():
    c = StateMachineController(schedule(event_hold_s=0.02, min_state_time_s=0.05), initial_state=SE)
    c.step(sample(0.0, load=600.0))
    for i in range(21):                                    # the load dips in mid-stance for 20 ms: a false toe-off
        state = c.step(sample(0.100 + i / 1000.0, load=10.0)).state
    assert state == WF
    states = _loaded(c, 0.121, 8, load=1500.0)             # loaded at once: no waiting for the minimum time
    assert states[5] == SF, states


def test_torque_law_and_clipping():
    sch = schedule()
    c = StateMachineController(sch, limits=ActuatorLimits(knee_torque_Nm=30.0, ankle_torque_Nm=200.0), initial_state=SF)
    x = sample(0.0, load=500.0, knee=0.3, knee_v=0.5, ankle=0.05, ankle_v=-0.2)
    cmd = c.step(x)
    knee_expected = -100.0 * (0.3 - 0.1) - 2.0 * 0.5        # −21 N·m, inside the 30 N·m limit
    ankle_expected = -80.0 * (0.05 - 0.0) - 1.0 * (-0.2)    # −3.8 N·m
    assert cmd.knee_torque_Nm == pytest.approx(knee_expected)
    assert cmd.ankle_torque_Nm == pytest.approx(ankle_expected)
    assert not cmd.saturated
    cmd = c.step(sample(0.01, load=500.0, knee=0.8))         # −70 N·m asked, 30 N·m allowed
    assert cmd.knee_torque_Nm == pytest.approx(-30.0) and cmd.saturated


def test_torque_that_drives_a_joint_past_its_range_end_is_refused():
    lim = ActuatorLimits()
    c = StateMachineController(schedule(knee_theta_e=(2.5, 0.05, 1.0, 0.1)), limits=lim, initial_state=SF)
    cmd = c.step(sample(0.0, load=500.0, knee=lim.knee_range_rad[1] + 0.01))   # θe beyond 120°: pushes flexion
    assert cmd.knee_torque_Nm == 0.0 and cmd.saturated
    cmd = c.step(sample(0.01, load=500.0, knee=1.0))                            # inside the range: applied
    assert cmd.knee_torque_Nm > 0.0


def test_actuator_limits_refuse_nonsense():
    with pytest.raises(ValueError, match="knee_torque_Nm"):
        ActuatorLimits(knee_torque_Nm=float("nan"))
    with pytest.raises(ValueError, match="ankle_range_rad"):
        ActuatorLimits(ankle_range_rad=(0.5, -0.5))


def test_a_loaded_knee_that_extends_ends_stance_flexion_when_the_table_asks_for_it():
    # the ankle moment never reaches its threshold (−5 N·m): a fast, flexed landing
    for speed, expect in ((0.0, SF), (0.2, SE)):                   # 0 = off: the FSMIC's moment-only rule
        c = StateMachineController(schedule(sf_to_se_knee_extension_rad_s=speed), initial_state=SF)
        c.step(sample(0.0, load=500.0, moment=-1.0, knee_v=1.0))     # flexing into the landing
        assert c.step(sample(0.1, load=500.0, moment=-1.0, knee_v=-0.1)).state == SF   # slower than 0.2 rad/s
        assert c.step(sample(0.2, load=500.0, moment=-1.0, knee_v=-0.5)).state == expect
    c = StateMachineController(schedule(sf_to_se_knee_extension_rad_s=0.2), initial_state=SF)
    c.step(sample(0.0, load=500.0))
    assert c.step(sample(0.2, load=10.0, knee_v=-2.0)).state == SF     # unloaded: a swinging shank, not stance


def test_schedule_from_table_rechecks_safety_limits(model):
    table = model.propose(1.2, 0.0, 75.0).table
    sch = ImpedanceSchedule.from_table(table)
    assert sch.knee_k[0] == pytest.approx(table.row("knee", "stance_flexion").k_Nm_per_rad)
    assert sch.wf_to_we_knee_angle_rad == pytest.approx(math.radians(table.thresholds.wf_to_we_knee_angle_deg))
    assert sch.sf_to_se_knee_extension_rad_s == pytest.approx(
        math.radians(table.thresholds.sf_to_se_knee_extension_deg_per_s)) and sch.sf_to_se_knee_extension_rad_s > 0
    rows = [r.model_copy(update={"k_Nm_per_rad": 900.0}) if r.subphase == "swing_flexion" else r for r in table.rows]
    bad = table.model_copy(update={"rows": rows})
    with pytest.raises(SafetyLimitError, match=r"swing_flexion\.k_Nm_per_rad"):
        ImpedanceSchedule.from_table(bad)


def test_a_leg_still_in_stance_stands_and_holds_its_knee_until_it_moves_or_is_lifted():
    """Standing: entered after standing_enter_s still and loaded in stance; no event nor guard moves the state; the
    knee is held against flexion where standing found it (free to extend, the hold following it); left on knee
    motion (back to stance flexion) or on unloading (a step: swing flexion)."""
    sch = schedule(standing_enter_s=0.5, standing_blend_s=0.0)
    c = StateMachineController(sch, initial_state=SE)
    t = 0.0
    while t < 0.49:
        assert c.step(sample(t, load=400.0, knee=0.05)).state == SE and not c.standing_
        t = round(t + 0.01, 6)
    c.step(sample(0.5, load=400.0, knee=0.05))
    assert c.standing_ and c.standing_knee_rad_ == 0.05
    cmd = c.step(sample(3.0, load=400.0, knee=0.07))                    # past the 1.5 s guard: still standing
    assert cmd.state == SE and c.standing_ and c.guard_transitions_ == 0
    assert cmd.knee_torque_Nm == pytest.approx(sch.knee_k[0] * 0.02)      # held against flexion, the SF stiffness
    c.step(sample(3.01, load=400.0, knee=0.03, knee_v=-0.1))             # extends: the hold follows
    assert c.standing_knee_rad_ == 0.03
    moved = c.step(sample(3.02, load=400.0, knee=0.03, knee_v=1.0))      # moves: on in the state it stood in
    assert moved.state == SE and not c.standing_ and c.state_entry_time_s_ == 3.02
    d = StateMachineController(sch, initial_state=SF)
    for k in range(60):
        d.step(sample(k * 0.01, load=400.0))
    assert d.standing_
    assert d.step(sample(0.7, load=10.0, knee_v=0.5)).state == WF and not d.standing_   # lifted, bending: a step
    e = StateMachineController(sch, initial_state=SF)
    for k in range(60):
        e.step(sample(k * 0.01, load=400.0))
    assert e.step(sample(0.7, load=10.0)).state == WE        # lifted on a straight knee: nothing to flex first


def test_the_guard_never_puts_a_leg_carrying_the_heel_strike_load_into_swing():
    c = StateMachineController(schedule(max_state_time_s=1.0), initial_state=SE)
    c.step(sample(0.0, load=600.0, knee=0.3, knee_v=1.0))               # moving: never standing
    assert c.step(sample(1.2, load=600.0, knee=0.3, knee_v=1.0)).state == SE and c.guard_transitions_ == 0
    assert c.step(sample(1.3, load=60.0, knee=0.3, knee_v=1.0)).state == WF     # below it, the guard may act
    assert c.guard_transitions_ == 1


def test_told_a_person_stands_on_it_the_machine_stands_from_the_next_sample():
    """stand(): standing at once (stance extension, the joints held where found), not the walking rows first; an
    unloaded leg is taken for lifted only once the person's weight has come onto it."""
    sch = schedule(standing_blend_s=0.2)
    c = StateMachineController(sch)
    c.reset()
    c.stand()
    first = c.step(sample(0.0, load=20.0, knee=0.05))                  # the weight not yet on it: not a lift
    assert first.state == SE and c.standing_ and first.knee_torque_Nm == pytest.approx(0.0)   # no blend: held
    assert c.step(sample(0.05, load=20.0, knee=0.05)).state == SE and c.standing_
    c.step(sample(0.1, load=400.0, knee=0.05))                          # the person's weight comes
    assert c.step(sample(0.2, load=10.0, knee=0.05, knee_v=0.5)).state == WF and not c.standing_   # then a step


def _to_swing_extension(c: StateMachineController) -> float:
    """A scripted stride up to swing extension (heel strike at 0.1 s, toe-off at 0.7 s); returns the time there."""
    c.step(sample(0.0))
    c.step(sample(0.10, load=500.0))
    c.step(sample(0.30, load=600.0, moment=-6.0))
    c.step(sample(0.70, load=20.0))
    c.step(sample(0.80, knee=math.radians(60.0), knee_v=0.0))
    assert c.state_ == WE
    return 0.80


def test_a_swing_knee_held_flexed_by_the_floor_gets_stance_support_at_once():
    """A toe caught in late swing: the knee, 40° above swing extension's equilibrium, stops extending while the pylon
    reads too little axial load for a heel strike. After the state's minimum time the machine goes to stance flexion,
    recovering, and stays there while the ankle moment says "late stance"; it leaves when the knee is back near stance
    flexion's equilibrium. The next heel strike is an ordinary one."""
    c = StateMachineController(schedule())
    t = _to_swing_extension(c)
    knee = math.radians(45.0)                                  # θe 0.1 rad ≈ 5.7°: 39° above it
    assert c.step(sample(t + 0.02, load=60.0, knee=knee, knee_v=-0.2)).state == WE    # before the minimum time
    assert c.step(sample(t + 0.06, load=60.0, knee=knee, knee_v=-0.2)).state == SF    # stalled: the floor holds it
    assert c.recovering_ and c.guard_transitions_ == 0
    assert c.step(sample(t + 0.20, load=600.0, moment=-60.0, knee=knee)).state == SF  # the moment does not end it
    assert c.step(sample(t + 0.30, load=600.0, moment=-60.0, knee=math.radians(18.0))).state == SE  # back within 15°
    c.step(sample(t + 0.50, load=20.0))                                                # toe-off
    assert c.state_ == WF
    c.step(sample(t + 0.60, knee=math.radians(60.0)))
    assert c.step(sample(t + 0.80, load=500.0)).state == SF and not c.recovering_     # an ordinary heel strike


def test_a_free_swing_knee_that_extends_is_not_taken_for_a_stumble():
    c = StateMachineController(schedule())
    t = _to_swing_extension(c)
    for k in range(1, 10):                                     # extending at 3 rad/s from 60°
        knee = math.radians(60.0) - 3.0 * 0.02 * k
        assert c.step(sample(t + 0.02 * k, knee=max(knee, 0.1), knee_v=-3.0)).state == WE
    assert c.step(sample(t + 0.30, knee=0.12, knee_v=0.0)).state == WE    # extended and still: waits for the heel


def test_a_loaded_knee_giving_way_early_in_stance_goes_back_to_stance_flexion_but_pre_swing_does_not():
    """Stance extension entered while the knee still flexes under the body: flexing faster than 1.5 rad/s (a
    downhill knee yields slower), loaded, within half the last stance, it returns to stance flexion (recovering). The
    same flexion late in stance is pre-swing's and changes nothing."""
    c = StateMachineController(schedule())
    c.step(sample(0.0))
    c.step(sample(0.10, load=500.0))                            # heel strike: stance begins
    c.step(sample(0.30, load=600.0, moment=-6.0))
    c.step(sample(0.80, load=20.0))                             # toe-off: this stance lasted 0.7 s
    c.step(sample(0.90, knee=math.radians(60.0)))
    c.step(sample(1.20, load=500.0))                            # heel strike at 1.2 s
    c.step(sample(1.30, load=800.0, moment=-6.0))               # stance extension at 1.3 s
    assert c.state_ == SE
    yielding = dict(load=800.0, moment=-40.0, knee=math.radians(30.0), knee_v=1.0)
    assert c.step(sample(1.31, **yielding)).state == SE          # a downhill knee yielding under load: the table's
    fold = dict(load=800.0, moment=-40.0, knee=math.radians(35.0), knee_v=2.5)
    assert c.step(sample(1.32, **fold)).state == SF and c.recovering_      # (the event hold is 0 here)
    late = StateMachineController(schedule())
    for x in (sample(0.0), sample(0.10, load=500.0), sample(0.30, load=600.0, moment=-6.0), sample(0.80, load=20.0),
              sample(0.90, knee=math.radians(60.0)), sample(1.20, load=500.0), sample(1.30, load=800.0, moment=-6.0)):
        late.step(x)
    assert late.step(sample(1.60, **fold)).state == SE          # 0.4 s into a 0.7 s stance: pre-swing
    assert late.step(sample(1.62, **fold)).state == SE and not late.recovering_


@pytest.mark.parametrize("ankle_deg", [-20.0, -3.0, -0.5, 0.0, 0.5, 3.0, 20.0])
@pytest.mark.parametrize("ankle_v", [-4.0, 0.0, 4.0])
def test_the_swing_ankle_compensates_its_drives_friction_as_a_spring_and_stance_does_not(ankle_deg, ankle_v):
    """With the ankle drive's friction f known, a swing state's ankle torque is its row's plus ½f·tanh(spring / 1 N·m):
    in the spring's direction, at most f/2, nothing at the equilibrium and the same whatever the velocity (a function
    of the angle alone: still a spring, no energy injected). Stance states and the knee run their rows unchanged."""
    friction = 3.0
    x = sample(0.0, ankle=math.radians(ankle_deg), ankle_v=ankle_v, knee=0.4, knee_v=1.0)
    for state in GaitState:
        plain = StateMachineController(schedule(), initial_state=state).step(x)
        machine = StateMachineController(schedule(), initial_state=state)
        machine.use_drive_friction(friction)
        drive = machine.step(x)
        assert drive.state == plain.state == state and drive.knee_torque_Nm == plain.knee_torque_Nm
        added = drive.ankle_torque_Nm - plain.ankle_torque_Nm
        if state in (SF, SE):
            assert added == 0.0
            continue
        spring = schedule().ankle_k[int(state)] * (x.ankle_angle_rad - schedule().ankle_theta_e[int(state)])
        assert added == pytest.approx(0.5 * friction * math.tanh(spring / 1.0))
        assert abs(added) <= friction / 2 and (added == 0.0 or math.copysign(1.0, added) == math.copysign(1.0, spring))


def test_a_drive_friction_beyond_what_a_drive_has_is_refused():
    with pytest.raises(ValueError, match="ankle_friction_Nm"):
        ActuatorLimits(ankle_friction_Nm=40.0)
    with pytest.raises(ValueError, match="ankle_friction_Nm"):
        ActuatorLimits(ankle_friction_Nm=math.nan)


def _hold(c: StateMachineController, t0: float, t1: float, **signals) -> GaitState:
    """The same signals every 2 ms from ``t0`` up to ``t1`` (the machine's holds need more than one sample)."""
    state, t = c.state_, t0
    while t < t1 - 1e-9:
        state = c.step(sample(t, **signals)).state
        t += 0.002
    return state


def _stride(c: StateMachineController, t: float, swing_s: float) -> float:
    """A stance of 0.6 s from ``t`` (heel strike, then stance extension on the moment), then a swing of ``swing_s``;
    returns when the swing ends."""
    _hold(c, t, t + 0.2, load=600.0)
    assert _hold(c, t + 0.2, t + 0.6, load=600.0, moment=-6.0) == SE
    assert _hold(c, t + 0.6, t + 0.7, load=20.0, knee=math.radians(30.0), knee_v=3.0) == WF
    assert _hold(c, t + 0.7, t + 0.6 + swing_s, knee=math.radians(60.0), knee_v=-3.0) == WE   # extending
    return t + 0.6 + swing_s


FIRM_ANKLE = schedule(ankle_k=(-400.0, -120.0, -10.0, -10.0))   # a stance-flexion ankle row firmer than the cap


@pytest.mark.parametrize(("swing_s", "cop_m", "withheld"), [
    (0.25, 0.10, True),      # an early landing on the toe: the toe-down torque capped while the weight is on the toe
    (0.40, 0.10, False),     # an ordinary swing landing on the toe (a fast gait's flat landing): the row as it is
    (0.25, 0.02, False),     # early but on the heel or the whole foot: the row as it is
])
def test_an_early_landing_on_the_toe_lets_the_heel_come_down(swing_s, cop_m, withheld):
    """The foot lands before its swing is over (three quarters of the last one's length here, under the rule's
    0.8) with the centre of pressure far forward (0.10 m of a 0.13 m forefoot): stance flexion's ankle row would push
    the toe down (56 N·m here); the machine gives no more plantarflexion torque than a centre of pressure at the
    threshold needs (half the forefoot × the load: 39 N·m) until the centre of pressure moves back, and keeps the
    row's dorsiflexion torque. An ordinary-length swing, or a landing under the heel, runs the row unchanged; a
    machine that does not know its foot never does this."""
    c = StateMachineController(FIRM_ANKLE, forefoot_m=0.13)
    plain = StateMachineController(FIRM_ANKLE)
    for m in (c, plain):
        m.step(sample(0.0))
        t = _stride(m, 0.002, 0.40)
        t = _stride(m, t, 0.40)                                             # the last ordinary swing: 0.4 s
        _stride(m, t, swing_s)                                              # this one lands after swing_s
    t_land = t + 0.6 + swing_s
    load = 600.0
    moment = -cop_m * load                                                  # centre of pressure cop_m ahead of the ankle
    ankle = math.radians(8.0)                                               # dorsiflexed: the row pushes the toe down
    cmd = c.step(sample(t_land, load=load, moment=moment, ankle=ankle))
    ref = plain.step(sample(t_land, load=load, moment=moment, ankle=ankle))
    assert cmd.state == ref.state == SF and ref.ankle_torque_Nm < 0.0
    assert c.early_landing_ == (swing_s < 0.8 * 0.40)
    if withheld:
        assert cmd.ankle_torque_Nm == pytest.approx(-0.5 * 0.13 * load) and ref.ankle_torque_Nm < -0.5 * 0.13 * load
        later = c.step(sample(t_land + 0.1, load=load, moment=-0.01 * load, ankle=ankle))   # the heel is down
        assert later.ankle_torque_Nm == pytest.approx(plain.step(sample(t_land + 0.1, load=load, moment=-0.01 * load,
                                                                         ankle=ankle)).ankle_torque_Nm)
        plantarflexed = c.step(sample(t_land + 0.2, load=load, moment=moment, ankle=math.radians(-20.0)))
        assert plantarflexed.ankle_torque_Nm > 0.0            # the row's dorsiflexion torque is never withheld
    else:
        assert cmd.ankle_torque_Nm == pytest.approx(ref.ankle_torque_Nm)
    with pytest.raises(ValueError, match="forefoot_m"):
        StateMachineController(schedule(), forefoot_m=-0.1)


@pytest.mark.parametrize(("early_pct", "forefoot_pct", "withheld"), [
    (80.0, 50.0, True),      # the table's defaults: a swing of 0.3 of 0.4 s, weight 0.10 m along a 0.13 m forefoot
    (70.0, 50.0, False),     # the table says early is under 70 % of the last swing: 75 % is not
    (80.0, 85.0, False),     # the table says on the toe is beyond 85 % of the forefoot: 77 % is not
])
def test_the_early_landing_trigger_is_the_tables(early_pct, forefoot_pct, withheld):
    """The two shares that make a landing early and on the toe come from the table the leg runs (its thresholds
    ``early_landing_swing_pct`` and ``forefoot_landing_pct``), not from the machine."""
    sch = dataclasses.replace(FIRM_ANKLE, early_landing_fraction=early_pct / 100.0,
                              forefoot_landing_fraction=forefoot_pct / 100.0)
    c = StateMachineController(sch, forefoot_m=0.13)
    c.step(sample(0.0))
    t = _stride(c, _stride(c, 0.002, 0.40), 0.40)
    _stride(c, t, 0.30)
    cmd = c.step(sample(t + 0.9, load=600.0, moment=-0.10 * 600.0, ankle=math.radians(8.0)))
    capped = -forefoot_pct / 100.0 * 0.13 * 600.0
    assert cmd.state == SF and (cmd.ankle_torque_Nm == pytest.approx(capped)) == withheld


def test_the_toe_landings_release_is_held_so_the_ankle_does_not_chatter():
    """Withholding the plantarflexion torque moves the centre of pressure, so a release decided on each sample beat
    against it at half the control rate (on the bench the load alternated between two-thirds and an eighth of body
    weight every millisecond). The release waits until the centre of pressure has stayed back for the event hold."""
    c = StateMachineController(dataclasses.replace(FIRM_ANKLE, event_hold_s=0.02), forefoot_m=0.13)
    plain = StateMachineController(dataclasses.replace(FIRM_ANKLE, event_hold_s=0.02))
    for m in (c, plain):
        m.step(sample(0.0))
        t = _stride(m, _stride(m, 0.002, 0.40), 0.40)
        _stride(m, t, 0.25)                                              # an early landing
    t, ankle = t + 0.85, math.radians(8.0)
    for m in (c, plain):                                                 # the landing, on the toe
        _hold(m, t, t + 0.008, load=600.0, moment=-60.0, ankle=ankle)
    t += 0.008
    for i in range(20):                                                  # forward, back, forward … every millisecond
        load, moment = (600.0, -60.0) if i % 2 == 0 else (100.0, -4.0)
        cmd = c.step(sample(t + 0.001 * i, load=load, moment=moment, ankle=ankle))
        plain.step(sample(t + 0.001 * i, load=load, moment=moment, ankle=ankle))
        assert cmd.ankle_torque_Nm == pytest.approx(-0.5 * 0.13 * load), i      # capped throughout
    assert c.state_ == SF and c.toe_landing_
    assert plain.step(sample(t + 0.020, load=600.0, moment=-4.0, ankle=ankle)).ankle_torque_Nm < 0.0   # the row pushes
    for i in range(30):                                                  # back, and held there: the heel is down
        cmd = c.step(sample(t + 0.021 + 0.001 * i, load=600.0, moment=-4.0, ankle=ankle))
    assert not c.toe_landing_ and cmd.ankle_torque_Nm < 0.0             # the row's own torque again


@pytest.mark.parametrize(("caught", "knee_v", "capped"), [
    (True, 1.0, False),     # a toe caught in swing, then the weight on it and the knee giving way: the ankle's row
    (True, -0.5, True),     # caught, the knee at its limit but extending (or holding): the cap, the heel comes down
    (False, 1.0, True),     # an early landing on the toe without a catch (a fast steep descent): the cap
])
def test_a_caught_toe_under_a_knee_that_gives_way_keeps_the_ankles_row(caught, knee_v, capped):
    """A toe caught in swing (the knee stalls, flexed, with too little load for a heel strike: stance flexion at once)
    and then the weight on the forefoot: the knee's row asks more than its drive gives (a knee far behind the foot
    under half the body's weight: 120 N·m on the bench's toe catch at 1.0 m/s downhill) and it flexes on. Then the
    ankle's plantarflexion torque is not capped: pushing on the forefoot turns the shank back under the knee, the one
    thing still extending it. Holding or extending, or landing early on the toe without a catch, the cap stands (tall
    legs' fast steep descents land so, and their grid fell more without the cap there: docs/results.md)."""
    sch = dataclasses.replace(FIRM_ANKLE, knee_k=(-300.0, -50.0, -20.0, -10.0))
    c, plain = StateMachineController(sch, forefoot_m=0.13), StateMachineController(sch)
    knee, ankle = math.radians(60.0), math.radians(8.0)
    for m in (c, plain):
        m.step(sample(0.0))
        t = _stride(m, _stride(m, 0.002, 0.40), 0.40)
        _stride(m, t, 0.25)                                              # in swing extension, 0.25 s after toe-off
        if caught:                                                       # stalled, flexed, the pylon barely loaded
            assert m.step(sample(t + 0.86, load=60.0, knee=knee, knee_v=-0.2)).state == SF
    land = sample(t + 0.87, load=600.0, moment=-0.10 * 600.0, knee=knee, knee_v=knee_v, ankle=ankle)
    cmd, ref = c.step(land), plain.step(land)
    assert c.caught_ == caught and c.early_landing_                      # landed before its swing was over
    assert cmd.state == SF and c.toe_landing_ and cmd.knee_torque_Nm == -c.limits.knee_torque_Nm   # at the limit
    assert ref.ankle_torque_Nm < -0.5 * 0.13 * 600.0                     # the row pushes harder than the cap
    assert cmd.ankle_torque_Nm == pytest.approx(-0.5 * 0.13 * 600.0 if capped else ref.ankle_torque_Nm)
