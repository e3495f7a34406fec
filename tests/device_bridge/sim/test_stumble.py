"""The bench's stumbles (issue 53): a block that catches the toe in mid-swing and a platform the foot lands on early,
placed where the same walk without them put the foot; strides scored clean or not; and what the state machine's
stumble support changes."""

from __future__ import annotations

import dataclasses
import math

import pytest

from controller_core.fsm import ImpedanceSchedule, StateMachineController
from device_bridge.bench.task_reference import task_reference
from device_bridge.sim.leg_model import LegGeometry
from device_bridge.sim.stumble import FloorWithObstacle, run_stumble


def test_the_obstacle_stands_on_the_tilted_floor():
    floor = FloorWithObstacle(incline_deg=-6.0, start_m=2.0, length_m=0.05, height_m=0.03)
    points = dict(floor.polyline())
    slope = math.tan(math.radians(-6.0))
    assert points[2.0] == pytest.approx(2.0 * slope)                      # the plane up to the block
    top = [(x, z) for x, z in floor.polyline() if 2.0 < x < 2.05]
    assert top and all(z == pytest.approx(x * slope + 0.03) for x, z in top)
    assert points[2.05] == pytest.approx(2.05 * slope)                    # and the plane after it


def _table_walker(model, speed: float, incline: float, support: bool):
    schedule = ImpedanceSchedule.from_table(model.propose(speed, incline, 75.0).table)
    if not support:   # the stumble support switched off: no stall is ever seen, no fold is fast enough, no landing
        schedule = dataclasses.replace(schedule, stumble_knee_margin_rad=math.inf, fold_knee_rate_rad_s=math.inf,
                                       early_landing_fraction=0.0)        # is early enough to be one on the toe
    return lambda: StateMachineController(schedule)


def test_a_caught_toe_is_a_stumble_the_bench_sees_and_the_stumble_support_brings_clean_strides_back(model):
    """1.0 m/s −6°, nominal leg, the toe caught in mid-swing after 6 s: the foot touches the block and the stride it
    happens in is not clean. Without the stumble support the leg jams (the toe down in swing extension, heel strike
    never seen) to the end of the walk; with it, clean strides again before the walk ends, and no more falls."""
    ref = task_reference(1.0, -6.0, model, 75.0)
    runs = {support: run_stumble(_table_walker(model, 1.0, -6.0, support), ref, 75.0, "toe_catch",
                                 geometry=LegGeometry()) for support in (False, True)}
    for r in runs.values():
        assert r["disturbed"] and r["obstacle"]["height_m"] > 0.015
    assert runs[False]["strides_to_recover"] is None                   # jammed: no clean strides to the end
    assert not runs[True]["clean"][0] and runs[True]["strides_to_recover"] is not None
    assert all(runs[True]["clean"][runs[True]["strides_to_recover"]:])
    assert runs[True]["falls"] <= runs[False]["falls"], {k: v["falls"] for k, v in runs.items()}


def test_an_unknown_obstacle_is_refused(model):
    ref = task_reference(1.2, 0.0, model, 75.0)
    with pytest.raises(ValueError, match="kind must be one of"):
        run_stumble(_table_walker(model, 1.2, 0.0, True), ref, 75.0, "banana peel", seconds=8.0)


@pytest.mark.parametrize("kind", ["toe_catch", "early_landing"])
def test_the_learned_table_comes_through_a_stumble_without_a_fall_with_the_persons_recovery_step(model, kind):
    """The acceptance of issue 53 on the nominal leg at 1.2 m/s level: the obstacle is met, no fall, clean strides
    again within three; the person's recovery step is listed and its stride is not clean."""
    ref = task_reference(1.2, 0.0, model, 75.0)
    r = run_stumble(_table_walker(model, 1.2, 0.0, True), ref, 75.0, kind, geometry=LegGeometry())
    assert r["disturbed"] and not r["clean"][0]
    assert r["falls"] == 0, r["fall_events"]
    assert r["strides_to_recover"] is not None and r["strides_to_recover"] <= 3, r["clean"]
    assert all(t > r["obstacle"]["met_s"] for t in r["recovery_steps"])      # the person stepped for the trip only
    assert r["loaded_knee_bound_deg"] >= 40.0
