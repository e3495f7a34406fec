"""Gait metrics on known signals: RMSE, stride bootstrap, state-entry delays."""

from __future__ import annotations

import numpy as np
import pytest

from controller_core.gait_metrics import (
    bootstrap_rmse,
    heel_strikes,
    percentile_interval,
    rmse,
    rmse_difference,
    state_entry_delays,
    stride_curves,
    strided_errors,
)


def test_gait_metrics_on_a_known_signal():
    contact = np.zeros(1000)
    for start in (100, 400, 700):
        contact[start:start + 150] = 500.0
    strikes = heel_strikes(contact, 20.0, 50)
    assert strikes.tolist() == [100, 400, 700]
    curves = stride_curves(np.arange(1000.0), strikes)
    assert curves.shape == (2, 101)
    assert curves[0, 0] == 100 and curves[0, -1] == 400
    assert rmse(np.ones(5), np.zeros(5)) == 1.0


def test_state_entry_delays_on_a_scripted_machine():
    # synthetic, labelled: a machine that enters state 0 five samples after the first event, two samples before
    # the second, and never within the third event's stride (it enters only after the fourth event)
    states = np.full(100, 3)
    states[15:30] = 0
    states[48:60] = 0
    states[95:] = 0
    events = np.array([10, 50, 70, 90])
    delays = state_entry_delays(states, 0, events, lead_samples=3)
    assert delays[:2].tolist() == [5.0, -2.0]
    assert np.isnan(delays[2])               # the entry at 95 belongs to the event at 90, not to 70
    assert delays[3] == 5.0
    # without the lead, an entry before the event is not this event's: the next one is after the next event
    assert np.isnan(state_entry_delays(states, 0, events, lead_samples=0)[1])
    with pytest.raises(ValueError, match="lead_samples"):
        state_entry_delays(states, 0, events, lead_samples=-1)


def test_per_stride_rmse_counts_errors_that_cancel_in_the_stride_average():
    # synthetic, labelled: strides alternately 2 deg above and below the reference
    ref = np.sin(np.linspace(0, 2 * np.pi, 101))
    strides = np.array([ref + 2.0, ref - 2.0, ref + 2.0, ref - 2.0])
    _, errors = strided_errors({"knee_angle_deg": strides}, ["knee_angle_deg"], {"knee_angle_deg": ref},
                               per_stride=True)
    assert errors["knee_angle_rmse_deg"] == pytest.approx(0.0, abs=1e-12)
    assert errors["knee_angle_per_stride_rmse_deg"] == pytest.approx(2.0)
    _, plain = strided_errors({"knee_angle_deg": strides}, ["knee_angle_deg"], {"knee_angle_deg": ref})
    assert "knee_angle_per_stride_rmse_deg" not in plain


def test_stride_bootstrap_brackets_the_rmse_and_tells_a_real_difference_from_stride_noise():
    # synthetic strides (a sine "reference" plus offsets and noise), only to check the statistics
    rng = np.random.default_rng(7)
    grid = np.linspace(0.0, 1.0, 101)
    ref = 10.0 * np.sin(2 * np.pi * grid)
    same = np.tile(ref + 2.0, (12, 1))                  # every stride identical: no stride-to-stride spread
    boots = bootstrap_rmse(same, ref)
    assert np.allclose(boots, 2.0)
    noisy = ref + 2.0 + rng.normal(0.0, 1.5, (12, 101)) + rng.normal(0.0, 1.0, (12, 1))
    lo, hi = percentile_interval(bootstrap_rmse(noisy, ref))
    assert lo < rmse(noisy.mean(axis=0), ref) < hi and hi - lo > 0.1
    wider = ref + 2.0 + rng.normal(0.0, 1.5, (12, 101)) + rng.normal(0.0, 4.0, (12, 1))
    lo_w, hi_w = percentile_interval(bootstrap_rmse(wider, ref))
    assert hi_w - lo_w > hi - lo                        # more stride-to-stride variation, a wider interval

    better = ref + 0.5 + rng.normal(0.0, 0.5, (12, 101))
    d = rmse_difference(better, noisy, ref)
    assert d["verdict"] == "A lower" and d["difference"] < 0 and d["interval"][1] < 0
    assert rmse_difference(noisy, better, ref)["verdict"] == "B lower"
    twin = ref + 2.0 + rng.normal(0.0, 1.5, (12, 101)) + rng.normal(0.0, 1.0, (12, 1))
    assert rmse_difference(twin, noisy, ref)["verdict"] == "not resolved"   # same process, different strides
    with pytest.raises(ValueError, match="two strides"):
        bootstrap_rmse(same[:1], ref)
    with pytest.raises(ValueError, match="grid points"):
        bootstrap_rmse(same[:, :50], ref)
    with pytest.raises(ValueError, match="level"):
        percentile_interval(boots, 1.5)
