"""The shipped reference curves: selection, SI units, the Bovi ankle offset derived from the data."""

from __future__ import annotations

import math

import numpy as np

from controller_core.reference import bovi_ankle_offset_deg, interp_rows, load_shipped_reference


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


def test_rows_are_interpolated_exactly_as_np_interp_does_column_by_column():
    """Random rows (said here), speeds with repeats, queries between, on, below and above them."""
    rng = np.random.default_rng(7)
    for _ in range(300):
        xs = np.sort(np.round(rng.uniform(0.0, 3.0, rng.integers(2, 7)), 1))
        rows = rng.normal(size=(len(xs), 4))
        for x in (float(rng.choice(xs)), float(np.round(rng.uniform(-0.5, 3.5), 2)), float(xs[0]), float(xs[-1])):
            expected = np.array([np.interp(x, xs, rows[:, p]) for p in range(rows.shape[1])])
            assert np.array_equal(interp_rows(x, xs, rows), expected), (x, xs)
    assert np.isnan(interp_rows(math.nan, np.array([1.0, 2.0]), np.ones((2, 3)))).all()
