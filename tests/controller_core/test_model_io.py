"""Saved models: what an older QuasiTune wrote is refused with a reason."""

from __future__ import annotations

import copy

import pytest


def test_a_saved_model_from_before_the_swing_settings_is_refused_with_a_reason(model, tmp_path):
    from controller_core.model_io import load_model, save_model

    old = copy.copy(model)
    old.table_rules_ = copy.copy(model.table_rules_)
    del old.table_rules_.swing_rule         # what a model pickled by an older QuasiTune looks like
    save_model(old, tmp_path / "old")
    with pytest.raises(ValueError, match=r"older QuasiTune.*swing_rule.*quasitune train"):
        load_model(tmp_path / "old")
    save_model(model, tmp_path / "new")
    assert load_model(tmp_path / "new").propose(1.2, 0.0, 75.0).table == model.propose(1.2, 0.0, 75.0).table


def test_a_saved_model_from_before_the_model_was_split_in_parts_is_refused_with_a_reason(model, tmp_path):
    from controller_core.model_io import load_model, save_model

    old = copy.copy(model)
    del old.feature_model_                  # one class held everything before the feature model was a part
    save_model(old, tmp_path / "old")
    with pytest.raises(ValueError, match=r"older QuasiTune.*feature_model_.*quasitune train"):
        load_model(tmp_path / "old")
