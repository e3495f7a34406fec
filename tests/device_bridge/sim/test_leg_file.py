"""Leg files: the simulated leg and person as JSON."""

from __future__ import annotations

import json

import pytest

from device_bridge.sim.leg_file import LEGS_DIR, load_leg, parse_leg
from device_bridge.sim.leg_model import LegGeometry


def test_an_empty_leg_file_is_the_nominal_bench():
    assert parse_leg({}) == LegGeometry()


def test_every_field_of_the_contract_is_read():
    body = {"name": "test leg", "body_height_m": 1.6, "socket_mass_kg": 2.5, "shank_mass_kg": 3.1,
            "ankle_unit_mass_kg": 2.0, "foot_mass_kg": 1.1, "heel_back_m": 0.06, "contact_radius_m": 0.018,
            "knee_armature_kg_m2": 0.08, "ankle_armature_kg_m2": 0.05, "knee_friction_Nm": 2.0,
            "ankle_friction_Nm": 1.0, "knee_damping_Nm_s_per_rad": 0.3, "ankle_damping_Nm_s_per_rad": 0.2}
    g = parse_leg(body)
    assert {k: getattr(g, k) for k in body} == body


@pytest.mark.parametrize(("body", "words"), [
    ({"knee_friction": 1.0}, "knee_friction: unknown field"),
    ({"foot_mass_kg": -0.5}, "foot_mass_kg: Input should be greater than or equal to 0.2"),
    ({"body_height_m": 2.5}, "body_height_m: Input should be less than or equal to 2.1"),
    ({"knee_armature_kg_m2": "heavy"}, "knee_armature_kg_m2: Input should be a valid number"),
    ([1, 2], "a leg file is a JSON object"),
])
def test_an_unknown_field_or_a_value_out_of_range_is_refused_with_the_field_and_the_reason(body, words):
    with pytest.raises(ValueError, match=words):
        parse_leg(body)


def test_the_repository_legs_load_by_name_and_by_path(tmp_path):
    names = sorted(p.stem for p in LEGS_DIR.glob("*.json"))
    assert {"stiff_geared", "heavy_foot", "short_person"} <= set(names)
    for name in names:
        assert load_leg(name) == load_leg(LEGS_DIR / f"{name}.json") != LegGeometry()
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(ValueError, match="not JSON"):
        load_leg(bad)
    with pytest.raises(ValueError, match=r"the repository's legs: .*stiff_geared"):
        load_leg(tmp_path / "missing.json")
    good = tmp_path / "light.json"
    good.write_text(json.dumps({"foot_mass_kg": 0.5}))
    assert load_leg(good).foot_mass_kg == 0.5
