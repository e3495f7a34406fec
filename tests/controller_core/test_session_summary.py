"""A session's summary from its telemetry: strides the leg walked off its table are counted, not scored."""

from __future__ import annotations

import numpy as np
import pytest

from controller_core.session_summary import device_times, session_strikes, summarize_session
from controller_core.walking_reference import level_walking_reference


def _summary(log, running=None) -> dict:
    c = log.channels
    return summarize_session(c["time_s"], c["knee_angle_rad"], c["ankle_angle_rad"], c["knee_torque_Nm"],
                             c["ankle_torque_Nm"], c["load_N"], log.mass_kg, level_walking_reference(1.2),
                             running_table=running)


def test_strides_off_the_table_are_counted_and_left_out_of_the_errors(quasi_stiffness_walk):
    log, _score = quasi_stiffness_walk
    everything = _summary(log)
    assert everything["strides_off_table"] == 0 and everything["strides_scored"] == everything["strides"] >= 4
    t = log.channels["time_s"]
    running = ~((t >= 3.0) & (t < 3.3))                       # 0.3 s in safe mode in the middle of the walk
    marked = _summary(log, running)
    assert marked["strides"] == everything["strides"]          # walked is walked
    assert 1 <= marked["strides_off_table"] <= 2                # the stride(s) holding those samples
    assert marked["strides_scored"] == marked["strides"] - marked["strides_off_table"]
    assert abs(marked["off_table_s"] - 0.3) < 0.01
    assert marked["knee_angle_rmse_deg"] != everything["knee_angle_rmse_deg"]   # scored over other strides
    nothing = _summary(log, np.zeros_like(t, dtype=bool))
    assert nothing["strides_scored"] == 0 and nothing["knee_angle_rmse_deg"] is None
    assert nothing["mean_curves"]["knee_angle_deg"] is None and nothing["cadence_steps_per_min"] is None


def test_the_cadence_is_of_the_strides_on_the_table_not_of_a_flickering_load_in_safe_mode(quasi_stiffness_walk):
    """Synthetic flicker (test data): in safe mode the load crosses the heel-strike threshold many times a second; those
    "strides" are left out of the cadence as they are of the errors, so the counts and the cadence agree."""
    log, _score = quasi_stiffness_walk
    c = dict(log.channels)
    t = c["time_s"]
    walked = _summary(log)
    flicker = (t >= t[-1] - 2.0)                                  # the last 2 s: safe mode, the load flickering at 2.5 Hz
    load = np.where(flicker, np.where(np.sin(2 * np.pi * 2.5 * t) > 0, 600.0, 0.0), c["load_N"])
    summary = summarize_session(t, c["knee_angle_rad"], c["ankle_angle_rad"], c["knee_torque_Nm"],
                                c["ankle_torque_Nm"], load, log.mass_kg, level_walking_reference(1.2),
                                running_table=~flicker)
    assert summary["strides"] > walked["strides"] and summary["strides_off_table"] >= 4     # counted as recorded
    assert summary["strides_scored"] + summary["strides_off_table"] == summary["strides"]
    assert summary["cadence_steps_per_min"] == pytest.approx(walked["cadence_steps_per_min"], rel=0.1)   # not 200+


def test_bursty_receive_times_do_not_split_strides_on_the_devices_clock():
    """Scripted telemetry (synthetic load, not gait data): a 1.2 s stride, 60 % stance, at 100 Hz; the server got the
    samples in bursts of 25, each burst within a millisecond."""
    seq = np.arange(1200)
    phase = (seq * 0.01 / 1.2) % 1.0
    load = np.where(phase < 0.6, 600.0, 0.0) + np.where(seq % 37 == 0, 40.0, 0.0)   # noise below the 10 % threshold
    received = 1000.0 + (seq // 25) * 0.25 + (seq % 25) * 1e-5
    on_device = device_times(seq, received, 0.01)
    assert np.allclose(np.diff(on_device), 0.01)
    strikes = session_strikes(on_device, load, 75.0)
    assert len(strikes) == 9 and np.allclose(np.diff(on_device[strikes]), 1.2)
    assert len(session_strikes(received, load, 75.0)) != 9        # the receive times miscount strides


def test_a_short_session_whose_first_second_arrived_late_keeps_its_stride_time():
    """Scripted telemetry (synthetic load, not gait data): 3 s of 1.1 s strides at 100 Hz; the server was busy as the
    session began and got its first second of samples in one burst, a second late. A rate taken from the receive
    times would make the strides 1.5 times shorter; the device's period keeps them."""
    seq = np.arange(300) + 5000
    load = np.where(((seq - 5000) * 0.01 / 1.1 + 0.7) % 1.0 < 0.6, 600.0, 0.0)
    received = np.where(seq < 5100, 1001.0 + (seq - 5000) * 1e-5, 1000.0 + (seq - 5000) * 0.01)
    on_device = device_times(seq, received, 0.01)
    strikes = session_strikes(on_device, load, 75.0)
    assert len(strikes) == 3 and np.allclose(np.diff(on_device[strikes]), 1.1, atol=0.011)   # ± one sample
    with pytest.raises(ValueError, match="period_s"):
        device_times(seq, received, 0.0)


def test_standing_is_counted_apart_from_walking():
    """Synthetic loads (test data): three strides, a 4.2 s pause standing on the leg, one more stride. Walking is the
    strides; the pause and the ends of the recording are standing."""
    t = np.arange(0.0, 10.0, 0.01)
    strikes_s = [0.5, 1.6, 2.7, 3.8, 8.0, 9.1]
    load = np.zeros_like(t)
    for a, b in zip(strikes_s, [*strikes_s[1:], 10.0], strict=True):
        load[(t >= a) & (t < a + 0.6 * min(b - a, 1.1))] = 700.0     # stance, then swing unloaded
    load[(t >= 3.8) & (t < 7.7)] = 700.0                             # standing on the leg through the pause
    zeros = np.zeros_like(t)
    s = summarize_session(t, zeros, zeros, zeros, zeros, load, 75.0, level_walking_reference(1.2))
    assert s["strides"] == 5
    assert s["walking_s"] == pytest.approx(4 * 1.1, abs=0.02)                  # the pause is not a stride
    assert s["standing_s"] == pytest.approx(s["duration_s"] - s["walking_s"], abs=1e-6) and s["standing_s"] > 5.0
    assert s["cadence_steps_per_min"] is not None
