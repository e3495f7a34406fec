"""Published incline features mapped to QuasiTune's features, in SI, with their standard errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controller_core.features import FEATURES_BY_NAME
from controller_core.published_features import (
    RABAGO_MAP,
    incline_table_sha256,
    load_incline_table,
    published_points,
)


def test_every_point_names_a_feature_in_si_with_a_positive_standard_error():
    points = published_points()
    assert {p.source for p in points} == {"rabago2016", "franz2012"}          # Kuster needs the level value
    for p in points:
        assert p.feature in FEATURES_BY_NAME and p.se > 0 and math.isfinite(p.value)
        if FEATURES_BY_NAME[p.feature].quantity == "angle":
            assert abs(p.value) < math.radians(90)                             # radians, not degrees
        if p.feature == "toe_off":
            assert 0.5 < p.value < 0.75                                        # a fraction of the cycle


def test_rabago_angles_become_radians_and_their_se_is_sd_over_root_n():
    df = load_incline_table()
    row = df[(df["source"] == "rabago2016") & (df["feature"] == RABAGO_MAP["knee_heel_strike_angle"][0])].iloc[0]
    [p] = [p for p in published_points() if p.source == "rabago2016" and p.feature == "knee_heel_strike_angle"]
    assert p.value == pytest.approx(math.radians(row["mean"]))
    assert p.se == pytest.approx(math.radians(row["sd"]) / math.sqrt(row["n"])) and p.sd == pytest.approx(
        math.radians(row["sd"]))


def test_the_kuster_point_scales_the_level_value_by_the_published_downhill_ratio():
    level_value = -0.9
    [k] = [p for p in published_points((1.3, level_value)) if p.source == "kuster1993"]
    df = load_incline_table()
    ku = df[(df["source"] == "kuster1993") & (df["feature"] == "knee_moment_extensor_peak_stance")]
    ratio = ku[ku["incline_deg"] < 0]["mean"].iloc[0] / ku[ku["incline_deg"] == 0]["mean"].iloc[0]
    assert k.value == pytest.approx(level_value * ratio) and k.incline_deg < 0 and k.speed_mps == 1.3
    assert np.isfinite(k.sd) and k.sd > k.se > 0


def test_the_table_is_identified_by_its_hash():
    assert len(incline_table_sha256()) == 64 and incline_table_sha256() == incline_table_sha256()
