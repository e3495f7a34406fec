"""Saved models: what an older QuasiTune wrote is refused with a reason."""

from __future__ import annotations

import copy

import pytest


def test_a_saved_model_from_before_the_swing_settings_is_refused_with_a_reason(model, tmp_path):
    from controller_core.model_io import load_model, save_model

    old = copy.copy(model)
    del old.swing_rule                      # what a model pickled by an older QuasiTune looks like
    save_model(old, tmp_path / "old")
    with pytest.raises(ValueError, match=r"older QuasiTune.*swing_rule.*quasitune train"):
        load_model(tmp_path / "old")
    save_model(model, tmp_path / "new")
    assert load_model(tmp_path / "new").propose(1.2, 0.0, 75.0).table == model.propose(1.2, 0.0, 75.0).table
