"""Loaders: the shipped published curves and the standard phase-indexed table format (real rows)."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from controller_core.phase_table import load_phase_table, phase_table_to_reference, reference_to_phase_table
from controller_core.reference import bovi_ankle_offset_deg, load_shipped_reference


def test_default_reference_is_bovi_adult_level_walking(reference):
    speeds = sorted(r.task["speed_mps"] for r in reference.records)
    assert [round(s, 2) for s in speeds] == [0.84, 1.19, 1.2, 1.49, 1.95]
    assert all(r.dataset == "bovi2011" and r.task["incline_deg"] == 0.0 for r in reference.records)
    assert reference.phase.shape == (101,) and reference.phase[0] == 0.0 and reference.phase[-1] == 1.0
    assert len(reference.data_sha256) == 64


def test_angles_are_si_and_ankle_offset_is_derived_from_data(reference):
    natural = next(r for r in reference.records if "Natural" in r.name)
    # knee swing peak about 63 deg, stored in rad
    assert 1.0 < natural.mean["knee_angle"].max() < 1.2
    raw = load_shipped_reference(correct_bovi_ankle=False)
    raw_nat = next(r for r in raw.records if "Natural" in r.name)
    shift = np.degrees(natural.mean["ankle_angle"] - raw_nat.mean["ankle_angle"])
    assert np.allclose(shift, shift[0]) and 18.0 < shift[0] < 21.0
    assert math.isclose(shift[0], reference.provenance["bovi_ankle_offset_deg"], rel_tol=1e-9)
    # after correction the ankle is near neutral at heel strike, as in the other adult source
    assert abs(np.degrees(natural.mean["ankle_angle"][0])) < 5.0


def test_offset_uses_winter_and_bovi_natural():
    d = dict(np.load(__import__("controller_core.reference", fromlist=["data_dir"]).data_dir()
                     / "gait_reference_speed_conditions.npz"))
    assert 18.0 < bovi_ankle_offset_deg(d) < 21.0


def test_other_sources_load_without_speed():
    ref = load_shipped_reference(datasets=("winter1987", "schwartz2008"), populations=("adult", "children"),
                                 require_speed=False)
    assert len(ref.records) == 8
    assert all(math.isnan(r.task["speed_mps"]) for r in ref.records)


def test_standard_format_round_trip_csv_and_parquet(reference, tmp_path):
    table = reference_to_phase_table(reference)
    assert len(table) == 5 * 101
    for name in ("data.csv", "data.parquet"):
        path = tmp_path / name
        table.to_csv(path, index=False) if name.endswith(".csv") else table.to_parquet(path)
        back = load_phase_table(path)
        assert len(back.records) == 5
        for a in back.records:
            b = min(reference.records, key=lambda r: abs(r.task["speed_mps"] - a.task["speed_mps"]))
            assert np.allclose(a.mean["knee_angle"], b.mean["knee_angle"], atol=1e-9)
            assert np.allclose(a.mean["ankle_moment"], b.mean["ankle_moment"], atol=1e-9)


def test_standard_format_averages_strides_and_flips_signs(reference):
    table = reference_to_phase_table(reference.subset([1, 2]))  # Bovi S and Natural as two 'strides'
    table["speed_m_s"] = 1.2
    table["ankle_moment_Nm_per_kg"] *= -1.0           # plantarflexor-positive source convention
    table["knee_moment_Nm_per_kg"] *= -1.0
    ref = phase_table_to_reference(table, moment_sign=-1.0)
    assert len(ref.records) == 1 and ref.records[0].n == 2
    expected = (reference.records[1].mean["ankle_moment"] + reference.records[2].mean["ankle_moment"]) / 2
    assert np.allclose(ref.records[0].mean["ankle_moment"], expected)
    assert np.all(np.isfinite(ref.records[0].sd["knee_angle"]))


@pytest.mark.parametrize(
    ("mutate", "message"),
    [
        (lambda t: t.rename(columns={"knee_angle_deg": "knee_angle_grad"}), "unknown unit 'grad'"),
        (lambda t: t.drop(columns=["phase"]), "missing phase column"),
        (lambda t: t.assign(speed_m_s=np.nan), "speed_m_s"),
        (lambda t: t.assign(speed_m_s=-1.0), "speeds must be > 0"),
        (lambda t: t.assign(phase=t["phase"] * 100), "within [0, 1]"),
        (lambda t: t.drop(columns=["ankle_moment_Nm_per_kg"]), "missing column for ankle moment"),
    ],
)
def test_standard_format_refuses_malformed_tables(reference, mutate, message):
    table = mutate(reference_to_phase_table(reference))
    with pytest.raises(ValueError, match=message.replace("[", r"\[").replace("]", r"\]")):
        phase_table_to_reference(table)


def test_unknown_file_format(tmp_path):
    p = tmp_path / "data.xlsx"
    p.write_text("x")
    with pytest.raises(ValueError, match="unknown format"):
        load_phase_table(p)
    assert isinstance(pd.DataFrame(), pd.DataFrame)
