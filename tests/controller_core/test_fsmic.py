"""The FSMIC benchmark table: the literature values in our units and signs."""

from __future__ import annotations

import math

import pytest

from controller_core.fsm import GaitState
from controller_core.fsmic import OSL_EXAMPLE_IMPEDANCE, SOURCE_MASS_KG, fsmic_table
from controller_core.units import G_MPS2 as G

SF, SE, WF, WE = (GaitState.STANCE_FLEXION, GaitState.STANCE_EXTENSION, GaitState.SWING_FLEXION,
                  GaitState.SWING_EXTENSION)


def test_fsmic_table_is_the_literature_table_in_our_units_and_signs():
    t = fsmic_table(90.0)
    scale = 90.0 / SOURCE_MASS_KG
    for joint, states in OSL_EXAMPLE_IMPEDANCE.items():
        for sub, (K, B, theta_e) in states.items():
            row = t.row(joint, sub)
            assert row.k_Nm_per_rad == pytest.approx(-K * scale)      # restoring = negative here
            assert row.b_Nm_s_per_rad == pytest.approx(B * scale)
            assert row.theta_e_deg == theta_e
    k_es, _, th_es = OSL_EXAMPLE_IMPEDANCE["ankle"]["stance_flexion"]
    assert t.thresholds.sf_to_se_ankle_moment_Nm == pytest.approx(-k_es * scale * math.radians(6.0 - th_es))
    assert t.provenance.source == "literature"


def test_event_load_thresholds_are_the_published_pair_the_fsmic_uses(model):
    for mass in (60.0, 90.0):
        learned, benchmark = model.propose(1.2, 0.0, mass).table.thresholds, fsmic_table(mass).thresholds
        assert learned.se_to_wf_load_N == pytest.approx(0.15 * mass * G) == benchmark.se_to_wf_load_N
        assert learned.we_to_sf_load_N == pytest.approx(0.40 * mass * G) == benchmark.we_to_sf_load_N
