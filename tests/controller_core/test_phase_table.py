"""The standard phase-indexed table format: round trips, stride averaging, sign flips, malformed input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from controller_core.phase_table import load_phase_table, phase_table_to_reference, reference_to_phase_table


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
    with pytest.raises(ValueError, match=r"'data.xlsx': unknown format \(use .csv or .parquet\)"):
        load_phase_table(p)
    with pytest.raises(ValueError, match="does not exist"):
        load_phase_table(tmp_path / "missing.csv")


def test_conditions_group_their_strides_and_missing_samples_are_averaged_over_the_others():
    ramps = load_phase_table(Path(__file__).resolve().parents[2] / "controller_core/data/vielemeyer2025_ref01_ramps.csv")
    by_name = {r.name.split("/")[2].split(" ")[0]: r for r in ramps.records}
    assert set(by_name) == {"level_down", "level_up", "ramp_10_down", "ramp_10_up"}
    down = by_name["ramp_10_down"]
    assert down.n == 12 and down.task["incline_deg"] == -10.0
    assert 1.10 < down.task["speed_mps"] < 1.15                    # the mean of its strides' own speeds
    assert np.all(np.isfinite(down.mean["knee_moment"]))           # the force-plate gap at heel strike filled
    assert "hip_angle" in down.mean                                # kept for the simulated bench


def test_a_phase_point_most_strides_miss_is_refused():
    # synthetic (test-only) table: three strides of one condition, two of them missing the first 5 points
    rows = []
    for stride in range(3):
        for pct in range(101):
            missing = stride > 0 and pct < 5
            rows.append({"condition": "c", "stride": stride, "speed_m_s": 1.2, "incline_deg": 0.0, "phase_pct": pct,
                         "knee_angle_deg": 10.0, "ankle_angle_deg": 0.0, "ankle_moment_Nm_per_kg": -1.0,
                         "knee_moment_Nm_per_kg": np.nan if missing else 0.1})
    with pytest.raises(ValueError, match="knee_moment is missing at phase 0 % in more than half the strides"):
        phase_table_to_reference(pd.DataFrame(rows))
