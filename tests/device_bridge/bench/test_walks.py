"""Walks on the bench at one task."""

from __future__ import annotations

import pandas as pd
import pytest

from device_bridge.bench.stance_response import with_knee_stance_k as _knee
from device_bridge.bench.walks import simulate


def test_a_given_table_walks_as_the_model_table_at_its_task(model, tmp_path):
    table = model.propose(1.2, 0.0, 75.0).table
    given = simulate("table", 1.2, 0.0, seconds=5.0, mass_kg=75.0, table=table, record=tmp_path / "walk.csv")
    learned = simulate("quasi-stiffness", 1.2, 0.0, seconds=5.0, mass_kg=75.0, model=model)
    assert given.summary["controller"] == "table" and learned.summary["controller"] == "quasi-stiffness"
    assert given.summary["knee_angle_rmse_deg"] == pytest.approx(learned.summary["knee_angle_rmse_deg"])
    frame = pd.read_csv(tmp_path / "walk.csv")
    assert {"time_s", "knee_angle_deg", "state"} <= set(frame.columns) and frame["time_s"].iloc[-1] == pytest.approx(4.999)


def test_a_bad_task_is_refused_before_walking(model):
    with pytest.raises(ValueError, match="speed"):
        simulate("fsmic", -1.0, 0.0, seconds=1.0)


def test_a_knee_with_no_stance_support_lets_the_body_fall_where_the_learned_table_carries_it(model):
    """Downhill (1.2 m/s −10°), where the stance knee must yield under the body and hold it. On the level the bench's
    person walks a limp knee straight-legged about as well as the table (sink 27 against 25 mm at 1.2 m/s from
    standing, as passive-knee users do); the old late-swing start's bent-knee landing made it fall there too."""
    table = model.propose(1.2, -10.0, 75.0).table
    soft = _knee(table, stance_flexion=-1.0, stance_extension=-1.0)
    limp = simulate("table", 1.2, -10.0, seconds=12.0, mass_kg=75.0, table=soft, skip_limits=True).summary
    assert limp["falls"] >= 1                                           # the bench is not blind in stance
    carried = simulate("table", 1.2, -10.0, seconds=12.0, mass_kg=75.0, table=table).summary
    assert carried["falls"] == 0
    # the hip lower, more of the person's push, the loaded knee further flexed (docs/results.md)
    assert carried["hip_sink_max_mm"] < limp["hip_sink_max_mm"]
    assert carried["support_deficit_max_bw"] < limp["support_deficit_max_bw"]
    assert carried["stance_knee_flexion_peak_max_deg"] < limp["stance_knee_flexion_peak_max_deg"]
    with pytest.raises(ValueError, match="stance support floor"):    # and the unsafe table needs skip_limits
        simulate("table", 1.2, 0.0, seconds=1.0, mass_kg=75.0, table=soft)


def test_the_stance_knee_flexes_more_on_a_softer_stance_flexion_row():
    from controller_core.fsmic import fsmic_table

    base = fsmic_table(75.0)   # its stance-flexion row holds through the loading response
    peaks = {k: simulate("table", 1.2, 0.0, seconds=12.0, mass_kg=75.0, table=_knee(base, stance_flexion=k),
                         skip_limits=True).summary["stance_knee_flexion_peak_deg"] for k in (-50.0, -300.0)}
    assert peaks[-50.0] >= peaks[-300.0] + 3.0


def test_a_task_reached_from_level_walking_is_scored_after_the_change(model):
    """The second start: from standing, 6 s of level walking at the task's speed, the 2 s change to −10°, then the
    task; the strides scored are the task's (after the change and a second), a fall anywhere would count. The table
    for −10° walks it without a fall (the table's level lead-in included)."""
    summary = simulate("quasi-stiffness", 1.0, -10.0, seconds=8.0, mass_kg=75.0, model=model, start="level").summary
    assert summary["start"] == "level" and summary["settle_s"] == pytest.approx(9.0)
    assert summary["seconds"] == pytest.approx(14.0) and summary["falls"] == 0
    assert 3 <= summary["strides"] <= 5                      # 5 s of the task at about 1.1 s a stride
    with pytest.raises(ValueError, match="start must be one of"):
        simulate("fsmic", 1.2, 0.0, seconds=2.0, start="running")
