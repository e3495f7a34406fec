"""The tasks the model knows: the data's range plus a margin chosen where the uncertainty stops meaning anything."""

from __future__ import annotations

import numpy as np
import pytest

from controller_core.known_range import INCLINE_MARGIN_DEG, SPEED_MARGIN_MPS, known_range, speed_uncertainty_ratio


def test_the_speed_margin_ends_where_the_features_sd_reaches_half_the_training_spread(model):
    """The statement in the module (and the README) holds for the shipped model: inside the data the median feature
    SD is a small part of the training spread; at the margin it has grown to about half of it, on both sides."""
    known = known_range(model)
    lo, hi = known.data_speed_mps
    inside = speed_uncertainty_ratio(model, np.linspace(lo, hi, 12))
    edges = speed_uncertainty_ratio(model, np.array([lo - SPEED_MARGIN_MPS, hi + SPEED_MARGIN_MPS]))
    assert inside.max() < 0.35
    assert np.all((edges > 0.4) & (edges < 0.6)), edges
    far = speed_uncertainty_ratio(model, np.array([lo - SPEED_MARGIN_MPS - 0.2, hi + SPEED_MARGIN_MPS + 0.2]))
    assert np.all(far > edges)


def test_beyond_names_the_value_and_the_range_the_model_knows(model):
    known = known_range(model)
    assert known.data_incline_deg == (-10.0, 10.0) and known.incline_deg == (-10.0 - INCLINE_MARGIN_DEG,
                                                                              10.0 + INCLINE_MARGIN_DEG)
    assert known.beyond(1.2, 0.0) is None and known.beyond(known.speed_mps[0], known.incline_deg[1]) is None
    why = known.beyond(0.15, -19.0)
    assert why is not None and "0.15 m/s and -19°" in why and "0.84–1.95 m/s" in why
    assert known.to_json()["speed_mps"] == [pytest.approx(known.data_speed_mps[0] - 0.35, abs=0.01),
                                            pytest.approx(known.data_speed_mps[1] + 0.35, abs=0.01)]
