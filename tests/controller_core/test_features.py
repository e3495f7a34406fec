"""Target features on real curves: one test per feature, robust windows, sub-sample refinement."""

from __future__ import annotations

import numpy as np
import pytest

from controller_core.features import (
    FEATURES,
    FEATURES_BY_NAME,
    FeatureNotFoundError,
    estimate_toe_off,
    find_extremum,
    record_features,
)


def _by_speed(reference):
    recs = sorted(reference.records, key=lambda r: r.task["speed_mps"])
    return recs, [record_features(r) for r in recs]


def test_knee_stance_flexion_peak(reference):
    _recs, feats = _by_speed(reference)
    vals = [np.degrees(f["knee_stance_flexion_peak"][1]) for f in feats]
    phases = [f["knee_stance_flexion_peak"][0] for f in feats]
    assert all(0.08 < p < 0.2 for p in phases)
    assert vals[0] < vals[2] < vals[4] and vals[0] > 10 and vals[4] < 35  # rises with speed (Bovi)


def test_knee_heel_strike_angle_is_the_curve_at_heel_strike_and_rises_up_a_ramp(reference):
    from controller_core.phase_table import load_shipped_ramps

    for rec in reference.records:
        phase, value = record_features(rec)["knee_heel_strike_angle"]
        assert phase == 0.0 and value == rec.mean["knee_angle"][0] and 0 < np.degrees(value) < 20
    ramps = {r.task["incline_deg"]: record_features(r)["knee_heel_strike_angle"][1] for r in load_shipped_ramps().records}
    assert np.degrees(ramps[10.0] - ramps[0.0]) > 20            # the knee lands flexed on the way up


def test_knee_swing_flexion_peak(reference):
    _, feats = _by_speed(reference)
    for f in feats:
        p, v = f["knee_swing_flexion_peak"]
        assert 0.65 < p < 0.78 and 55 < np.degrees(v) < 70


def test_ankle_dorsiflexion_peak(reference):
    _, feats = _by_speed(reference)
    for f in feats:
        p, v = f["ankle_dorsiflexion_peak"]
        assert 0.2 < p < 0.55 and 5 < np.degrees(v) < 16
    # the fastest condition peaks early (about 27 %), which the window must still find
    assert feats[-1]["ankle_dorsiflexion_peak"][0] < 0.32


def test_ankle_plantarflexion_peak(reference):
    _, feats = _by_speed(reference)
    vals = [np.degrees(f["ankle_plantarflexion_peak"][1]) for f in feats]
    assert all(-30 < v < -12 for v in vals)
    assert vals[-1] < vals[0]  # more plantarflexion when walking fast


def test_knee_extensor_moment_peak(reference):
    _, feats = _by_speed(reference)
    vals = [f["knee_extensor_moment_peak"][1] for f in feats]
    assert all(v < 0 for v in vals)  # extensor moments are negative in the project convention
    assert vals[-1] < vals[0] - 0.3  # about -0.28 at 0.84 m/s, -0.85 at 1.95 m/s


def test_knee_flexor_moment_peak(reference):
    _, feats = _by_speed(reference)
    for f in feats:
        p, v = f["knee_flexor_moment_peak"]
        assert 0.88 < p < 0.99 and 0.05 < v < 0.4


def test_ankle_plantarflexor_moment_peak(reference):
    _, feats = _by_speed(reference)
    for f in feats:
        p, v = f["ankle_plantarflexor_moment_peak"]
        assert 0.4 < p < 0.52 and -1.5 < v < -1.1


def test_ankle_dorsiflexor_moment_peak(reference):
    _, feats = _by_speed(reference)
    for f in feats:
        p, v = f["ankle_dorsiflexor_moment_peak"]
        assert 0.0 < p < 0.1 and 0.0 < v < 0.15


def test_toe_off_uses_published_event_and_estimate_is_close(reference):
    for rec in reference.records:
        assert record_features(rec)["toe_off"] == (rec.toe_off_phase, rec.toe_off_phase)
        assert abs(estimate_toe_off(rec.phase, rec.mean["ankle_moment"]) - rec.toe_off_phase) < 0.03


def test_features_found_on_other_sources():
    from controller_core.reference import load_shipped_reference

    ref = load_shipped_reference(datasets=("winter1987", "schwartz2008"), populations=("adult", "children"),
                                 require_speed=False)
    for rec in ref.records:
        assert set(record_features(rec)) == {f.name for f in FEATURES}


def test_monotonic_window_raises_instead_of_returning_the_edge(reference):
    rec = reference.records[2]
    spec = FEATURES_BY_NAME["knee_swing_flexion_peak"]
    rising = np.linspace(0, 1, rec.phase.size)
    with pytest.raises(FeatureNotFoundError, match="knee_swing_flexion_peak"):
        find_extremum(rec.phase, rising, spec)  # synthetic ramp (test input only)


def test_parabolic_refinement_is_sub_sample():
    phase = np.linspace(0, 1, 101)
    curve = -((phase - 0.4237) ** 2)  # synthetic parabola (test input only)
    spec = FEATURES_BY_NAME["ankle_dorsiflexion_peak"]
    p, v = find_extremum(phase, curve, spec)
    assert abs(p - 0.4237) < 1e-9 and abs(v) < 1e-12
