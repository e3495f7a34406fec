"""A leg's swing inertia (device_bridge/sim/swing_inertia.py), and the learned table proposed for it on the bench."""

from __future__ import annotations

import dataclasses

import pytest

from device_bridge.bench.controllers import make_controller
from device_bridge.bench.task_reference import task_reference
from device_bridge.sim.leg_file import load_leg
from device_bridge.sim.leg_model import LegGeometry
from device_bridge.sim.simulate import run_walk, score_walk
from device_bridge.sim.swing_inertia import swing_inertia_kg_m2, swing_inertia_ratio


def test_the_reference_leg_is_one_and_an_actuator_adds_exactly_its_reflected_inertia():
    assert swing_inertia_ratio(None) == (1.0, 1.0) == swing_inertia_ratio(LegGeometry())
    base = LegGeometry()
    geared = dataclasses.replace(base, knee_armature_kg_m2=base.knee_armature_kg_m2 + 0.05,
                                 ankle_armature_kg_m2=base.ankle_armature_kg_m2 + 0.03)
    (k0, a0), (k1, a1) = swing_inertia_kg_m2(base), swing_inertia_kg_m2(geared)
    assert k1 - k0 == pytest.approx(0.05, abs=1e-9) and a1 - a0 == pytest.approx(0.03, abs=1e-9)


def test_a_heavier_foot_weighs_on_the_knee_more_than_on_the_ankle():
    # the foot's extra mass sits a shank's length below the knee and only centimetres from the ankle's axis
    knee, ankle = swing_inertia_ratio(load_leg("heavy_foot"))
    assert knee > 1.3 and 1.0 < ankle < knee
    short_knee, _ = swing_inertia_ratio(load_leg("short_person"))
    assert short_knee < 1.0                                          # a shorter shank swings less inertia


def test_on_a_heavy_foot_the_table_proposed_for_the_leg_walks_where_the_reference_legs_table_falls(model):
    # 1.6 m/s level from standing: with the reference leg's swing rows the heavy foot overshoots to full extension,
    # lands late, then early on a bent knee (it fell, until the early landing on the toe was supported: now its hip
    # sinks 130 mm of the 150 that are a fall, the loaded knee to 49°); the rows proposed for its inertia walk it
    leg, ref = load_leg("heavy_foot"), task_reference(1.6, 0.0, model, 75.0)
    runs = {}
    for name, geometry in (("for the leg", leg), ("for the reference leg", None)):
        ctrl = make_controller("quasi-stiffness", 75.0, model, (1.6, 0.0), geometry=geometry)
        runs[name] = score_walk(run_walk(ctrl, ref, 75.0, 20.0, leg), ref, settle_s=2.0).summary
    mine, other = runs["for the leg"], runs["for the reference leg"]
    assert mine["falls"] == 0 and mine["hip_sink_max_mm"] < 0.75 * other["hip_sink_max_mm"], runs
    assert mine["stance_knee_flexion_peak_max_deg"] < other["stance_knee_flexion_peak_max_deg"] - 8.0
    assert mine["knee_angle_per_stride_rmse_deg"] < other["knee_angle_per_stride_rmse_deg"]
