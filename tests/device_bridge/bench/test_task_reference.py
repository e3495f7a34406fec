"""The bench's reference at any task says what it is: measured level walking, the measured ramp trend, or the
model's prediction."""

from __future__ import annotations

import pytest

from device_bridge.bench.task_reference import task_reference


def test_measured_where_the_data_reach_and_the_model_beyond(model):
    assert task_reference(1.2, 0.0).kind == "measured"
    assert task_reference(1.2, 6.0).kind == "measured_ramp_trend"       # no model needed there
    steep = task_reference(1.2, 14.0, model)
    assert steep.kind == "model_prediction" and "model's prediction at +14°" in steep.source
    with pytest.raises(ValueError, match="needs the model"):
        task_reference(1.2, -14.0)
