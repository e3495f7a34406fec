"""The refinement's sensitivity grid: reading it, blending it over tasks, and what the shipped one says."""

from __future__ import annotations

import numpy as np
import pytest

from controller_core.refine import PARAMETERS
from controller_core.refine_evidence import QUANTITIES
from controller_core.refine_sensitivity import BenchSensitivity, SensitivityError, load_sensitivity

NAMES = dict(parameters=[p.field for p in PARAMETERS], quantities=[q.key for q in QUANTITIES])


def grid_json(values: list[float | None]) -> dict:
    """A made-up 2 × 2 grid (speeds 1.0, 1.4; inclines 0, 5) whose every entry at node k is values[k]."""
    return {"version": 1, **NAMES, "speeds_mps": [1.0, 1.4], "inclines_deg": [0.0, 5.0],
            "jacobians": [[[v] * len(PARAMETERS) for _ in QUANTITIES] for v in values]}


def test_a_task_between_nodes_blends_them_as_the_leg_blends_its_rows():
    grid = BenchSensitivity.from_json(grid_json([1.0, 2.0, 3.0, 4.0]))
    assert grid.at(1.0, 0.0)[0, 0] == pytest.approx(1.0)
    assert grid.at(1.2, 2.5)[0, 0] == pytest.approx(2.5)
    assert grid.at(9.0, 0.0)[0, 0] == pytest.approx(3.0)      # held at the edge, not extrapolated


def test_an_entry_a_node_could_not_resolve_comes_from_the_nodes_that_did():
    grid = BenchSensitivity.from_json(grid_json([None, 2.0, None, 4.0]))
    assert grid.at(1.0, 5.0)[0, 0] == pytest.approx(2.0)
    assert grid.at(1.0, 2.5)[0, 0] == pytest.approx(2.0)      # the resolved corner carries the blend
    assert grid.at(1.0, 0.0)[0, 0] == pytest.approx(3.0)      # none near: the grid's median
    none = BenchSensitivity.from_json(grid_json([None, None, None, None]))
    assert np.all(none.at(1.2, 2.5) == 0.0)


def test_a_node_whose_walk_changed_its_gait_rather_than_responding_is_set_aside():
    grid = BenchSensitivity.from_json(grid_json([1.0, 1.1, 0.9, 30.0]))
    assert grid.outliers() == len(QUANTITIES) * len(PARAMETERS)
    assert grid.at(1.4, 5.0)[0, 0] == pytest.approx(1.05)     # the grid's median, not 30
    assert grid.at(1.2, 2.5)[0, 0] == pytest.approx(1.0)      # the three usable corners


def test_a_file_that_does_not_fit_the_code_is_refused_by_name():
    body = grid_json([1.0, 2.0, 3.0, 4.0])
    with pytest.raises(SensitivityError, match="version"):
        BenchSensitivity.from_json({**body, "version": 99})
    with pytest.raises(SensitivityError, match="2 × 2 grid"):
        BenchSensitivity.from_json({**body, "jacobians": body["jacobians"][:3]})
    grid = BenchSensitivity.from_json({**body, "parameters": list(reversed(body["parameters"]))})
    with pytest.raises(SensitivityError, match="re-measure"):
        grid.check_names(tuple(NAMES["parameters"]), tuple(NAMES["quantities"]))


def test_the_shipped_grid_fits_the_code_and_says_what_the_bench_shows():
    grid = load_sensitivity()
    grid.check_names(tuple(NAMES["parameters"]), tuple(NAMES["quantities"]))
    assert grid.provenance["leg"] == "nominal" and "quasitune sensitivity" in grid.provenance["command"]
    J = grid.at(1.1, 0.0)
    q = {k.key: r for r, k in enumerate(QUANTITIES)}
    p = {k.field: c for c, k in enumerate(PARAMETERS)}
    # a higher swing-flexion equilibrium angle swings the knee further; a lower push-off angle plantarflexes further
    assert J[q["knee_swing_flexion_peak_deg"], p["knee.swing_flexion.theta_e_deg"]] > 0.5
    assert 0.7 < J[q["ankle_plantarflexion_peak_deg"], p["ankle.stance_extension.theta_e_deg"]] < 1.3
    # a knee that lands more flexed (terminal-swing equilibrium angle up) flexes further in stance
    assert J[q["knee_stance_flexion_peak_deg"], p["knee.swing_extension.theta_e_deg"]] > 0.3
