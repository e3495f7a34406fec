"""The simulated leg walking behind the device node."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from controller_core.walking_reference import level_walking_reference
from device_bridge.host import TelemetrySample
from device_bridge.protocol import Mode
from device_bridge.sim.course import Course, Segment
from device_bridge.sim.walker import SimWalker
from tests.helpers.device import pair, until


def test_the_walking_simulated_leg_streams_telemetry_without_gaps(tables):
    walker = SimWalker()
    got: list[TelemetrySample] = []
    lock = threading.Lock()

    def on_telemetry(sample: TelemetrySample) -> None:
        with lock:
            got.append(sample)

    node, link = pair(leg=walker, on_telemetry=on_telemetry)
    try:
        link.push(tables[0], version=3)
        walker.start(level_walking_reference(1.2), 75.0)
        until(lambda: len(got) >= 300, timeout_s=10.0, clock=link.clock)
    finally:
        link.close()
        node.close()
    seqs = [s.seq for s in got]
    assert seqs == list(range(seqs[0], seqs[0] + len(seqs)))
    knee = [s.knee_angle_rad for s in got]
    assert max(knee) - min(knee) > 0.2   # the knee moves (a second of standing, then 11° or more of swing in 2 s)
    assert {s.mode for s in got} == {Mode.ACTIVE} and {s.fsm_state for s in got} >= {0, 1}


def test_a_walk_starts_from_standing_and_its_chunks_continue_the_benchs_walk_exactly(model):
    """The simulated patient walks a task as the bench does (a second of standing, the first steps, walking): 25 s
    of it in three 10 s chunks read what one bench walk from standing reads, tick for tick."""
    from controller_core.fsm import ImpedanceSchedule, StateMachineController
    from device_bridge.bench.task_reference import task_reference
    from device_bridge.sim.simulate import run_walk

    ref = task_reference(1.2, -6.0, model, 75.0)
    schedule = ImpedanceSchedule.from_table(model.propose(1.2, -6.0, 75.0).table)
    bench = run_walk(StateMachineController(schedule), ref, 75.0, 25.0).channels
    walker, leg = SimWalker(), StateMachineController(schedule)
    walker.start(ref, 75.0)
    leg.reset()
    leg.stand()
    knee, state = [], []
    for _ in range(25_000):
        x = walker.sample()
        cmd = leg.step(x)
        knee.append(x.knee_angle_rad)
        state.append(int(cmd.state))
        walker.step(cmd.knee_torque_Nm, cmd.ankle_torque_Nm)
    assert np.allclose(knee, bench["knee_angle_rad"], atol=1e-9) and state == bench["state"].astype(int).tolist()
    assert np.ptp(bench["knee_angle_rad"][:900]) < np.radians(2.0)      # it stood first


def test_a_course_is_walked_once_at_its_true_task_and_the_patient_then_stands():
    course = Course("short", (Segment(2.5, 1.0, 0.0), Segment(1.5, 1.0, 6.0)), transition_s=1.0)   # from standing
    walker = SimWalker()
    walker.start_course(course, 75.0)
    assert walker.walking and walker.course == "short" and walker.task == (1.0, 0.0)
    steps = 0
    while walker.walking:
        sample = walker.sample()
        assert sample is not None and np.isfinite(sample.thigh_angle_rad)   # the socket IMU the estimator reads
        walker.step(0.0, 0.0)
        steps += 1
        if steps == 3900:
            assert walker.task == pytest.approx((1.0, 6.0))        # the ramp, after the transition
    assert steps == round(course.duration_s / 0.001) and walker.task is None
    # the course walked, the patient stands on the leg: live readings of quiet stance (about half the body weight,
    # knee near extension, swaying slowly), not "no data"
    assert walker.state == "standing"
    loads, ankles = [], []
    for _ in range(4000):                                          # one sway period, 4 s
        sample = walker.sample()
        loads.append(sample.load_N)
        ankles.append(np.degrees(sample.ankle_angle_rad))
        walker.step(0.0, 0.0)
    weight = 75.0 * 9.81
    assert 0.4 * weight < min(loads) < max(loads) < 0.6 * weight and np.ptp(ankles) > 0.5
    assert np.degrees(walker.sample().knee_angle_rad) < 10.0
    walker.stop()
    assert walker.state == "not_worn" and walker.sample() is None


def test_standing_refuses_a_body_mass_out_of_range_and_a_walk_ends_the_stance():
    walker = SimWalker()
    with pytest.raises(ValueError, match="mass_kg"):
        walker.stand(float("nan"))
    walker.stand(80.0)
    assert walker.state == "standing" and walker.sample() is not None
    walker.start(level_walking_reference(1.2), 80.0)
    assert walker.state == "walking"


def test_the_readings_keep_one_clock_from_standing_to_walking_and_back():
    """A real leg's clock never jumps back; a walk's physics starting at 0 s again would freeze the state machine
    (its dwell time negative) after the patient had stood a while."""
    walker = SimWalker()
    walker.stand(75.0)
    times = []
    for _ in range(500):
        times.append(walker.sample().time_s)
        walker.step(0.0, 0.0)
    walker.start(level_walking_reference(1.2), 75.0)
    for _ in range(500):
        times.append(walker.sample().time_s)
        walker.step(0.0, 0.0)
    walker.stand(75.0)
    times.append(walker.sample().time_s)
    steps = np.diff(times)
    assert np.all(steps > 0) and np.allclose(steps, 0.001, atol=1e-6)


def test_the_simulated_device_walks_the_leg_it_is_given():
    from device_bridge.sim.leg_file import load_leg

    leg = load_leg("heavy_foot")
    walker = SimWalker(leg)
    walker.start(level_walking_reference(1.2), 75.0)
    plant = walker._leg
    assert plant is not None and plant.geometry == leg
    assert plant.model.body("foot").mass[0] == pytest.approx(leg.foot_mass_kg)
    walker.start_course(Course("short", (Segment(4.0, 1.0, 0.0),)), 75.0)
    assert walker._leg.geometry == leg


def test_the_simulated_legs_firmware_is_set_for_its_own_leg():
    """The server's simulated device runs its firmware with its leg's description, as a real leg does: the task
    estimate's lengths and forefoot, the ankle drive's friction (before: the nominal leg's, whatever leg it walked)."""
    from device_bridge.sim.leg_file import load_leg

    short, stiff = load_leg("short_person"), load_leg("stiff_geared")
    cfg = SimWalker(short).firmware_config()
    assert (cfg.thigh_length_m, cfg.shank_length_m, cfg.forefoot_m) == (short.thigh_m, short.shank_m,
                                                                        short.toe_forward_m)
    assert cfg.thigh_length_m < SimWalker().firmware_config().thigh_length_m
    assert SimWalker(stiff).firmware_config().actuator.ankle_friction_Nm == stiff.ankle_friction_Nm > 0.0
