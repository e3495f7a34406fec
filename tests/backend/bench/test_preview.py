"""The dashboard's simulated preview of a table."""

from __future__ import annotations

import pytest

from backend.bench import preview as preview_module
from backend.bench.node_previews import NodeWalks
from backend.bench.preview import BenchmarkWalks, preview_table
from controller_core.fsmic import fsmic_table
from controller_core.table import SafetyLimitError
from device_bridge.sim.course import Course, Segment


def test_a_table_preview_walks_the_table_and_the_fsmic_with_their_difference(model):
    table = model.propose(1.2, 0.0, 75.0).table
    p = preview_table(table, 1.2, 0.0, 75.0, model, seconds=5.0)
    assert len(p["phase_grid"]) == 101 and set(p["controllers"]) == {"table", "fsmic"}
    t, f = p["controllers"]["table"], p["controllers"]["fsmic"]
    assert t["vs_fsmic"]["knee_angle_rmse_difference_deg"] == pytest.approx(
        t["knee_angle_rmse_deg"] - f["knee_angle_rmse_deg"])
    assert len(t["mean_curves"]["knee_angle_deg"]) == 101 and "vs_fsmic" not in f
    same = preview_table(fsmic_table(75.0), 1.2, 0.0, 75.0, model, seconds=5.0)["controllers"]["table"]
    assert same["vs_fsmic"]["knee_angle_rmse_difference_deg"] == pytest.approx(0.0, abs=1e-9)


def test_a_table_preview_walks_the_fsmic_once_per_task_and_body_mass(model):
    benchmark = BenchmarkWalks()
    proposed, fsmic = model.propose(1.2, 0.0, 75.0).table, fsmic_table(75.0)
    a = preview_table(proposed, 1.2, 0.0, 75.0, model, seconds=5.0, benchmark=benchmark)
    b = preview_table(fsmic, 1.2, 0.0, 75.0, model, seconds=5.0, benchmark=benchmark)
    assert (benchmark.at_task.cache_info().hits, benchmark.at_task.cache_info().misses) == (1, 1)
    assert a["controllers"]["fsmic"] == b["controllers"]["fsmic"]
    assert b["controllers"]["table"]["vs_fsmic"]["knee_angle_rmse_difference_deg"] == pytest.approx(0.0, abs=1e-9)
    # the kept walk is the walk walked afresh; another task or body mass walks its own
    fresh = preview_table(proposed, 1.2, 0.0, 75.0, model, seconds=5.0)["controllers"]["fsmic"]
    kept = dict(a["controllers"]["fsmic"])
    assert kept.pop("real_time_factor") > 0 and fresh.pop("real_time_factor") > 0   # the machine's speed, not the walk
    assert fresh == kept
    preview_table(proposed, 1.2, 0.0, 90.0, model, seconds=5.0, benchmark=benchmark)
    preview_table(proposed, 1.0, 0.0, 75.0, model, seconds=5.0, benchmark=benchmark)
    assert benchmark.at_task.cache_info().misses == 3


def test_an_unsafe_table_is_never_walked(model):
    table = model.propose(1.2, 0.0, 75.0).table
    row = table.rows[0]
    bad = table.model_copy(update={"rows": [row.model_copy(update={"k_Nm_per_rad": 50.0}), *table.rows[1:]]})
    with pytest.raises(SafetyLimitError):
        preview_table(bad, 1.2, 0.0, 75.0, model, seconds=5.0)


def test_the_benchmark_walks_a_course_once_per_body_mass_and_every_envelope_preview_reuses_it(model, monkeypatch):
    walked: list[tuple[str, float]] = []
    real_walk = preview_module.walk_course

    def counting_walk(controller, course, model_, mass_kg, *args, **kwargs):
        walked.append((controller, mass_kg))
        return real_walk(controller, course, model_, mass_kg, *args, **kwargs)

    monkeypatch.setattr(preview_module, "walk_course", counting_walk)
    course = Course("short", (Segment(6.0, 1.0, 0.0), Segment(6.0, 1.2, 0.0)))
    benchmark, nodes = BenchmarkWalks(), NodeWalks()      # the node walks are kept too: not what is counted
    first = model.propose_envelope([0.8, 1.4], [-4.0, 4.0], 75.0)
    second = model.propose_envelope([0.9, 1.5], [-4.0, 4.0], 75.0)
    a = preview_module.preview_envelope(first, model, course, benchmark=benchmark, nodes=nodes)
    b = preview_module.preview_envelope(second, model, course, benchmark=benchmark, nodes=nodes)
    assert walked == [("fsmic", 75.0), ("adaptive", 75.0), ("adaptive", 75.0)]   # the benchmark once, each envelope
    assert a["controllers"]["fsmic"] == b["controllers"]["fsmic"]
    assert a["controllers"]["envelope"] != b["controllers"]["envelope"]
    # the benchmark is the same walk as walked afresh, and another body mass walks its own
    fresh = preview_module.preview_envelope(second, model, course, nodes=nodes)["controllers"]["fsmic"]
    kept = b["controllers"]["fsmic"]
    assert kept.pop("real_time_factor") > 0 and fresh.pop("real_time_factor") > 0   # the machine's speed, not the walk
    assert fresh == kept
    heavier = model.propose_envelope([0.9, 1.5], [-4.0, 4.0], 90.0)
    preview_module.preview_envelope(heavier, model, course, benchmark=benchmark, nodes=nodes)
    assert walked[-2:] == [("fsmic", 90.0), ("adaptive", 90.0)]


def test_a_version_walked_before_is_not_walked_again_and_its_kept_walk_is_the_walk(model, monkeypatch):
    """The same content at the same task, body mass, leg and model (an edit undone, the same version asked for again)
    reuses its walk; another content or body mass walks its own, and a kept walk equals one walked afresh."""
    walks: list[float] = []
    real_walk = preview_module.run_walk
    monkeypatch.setattr(preview_module, "run_walk", lambda *a, **k: walks.append(a[2]) or real_walk(*a, **k))
    benchmark = BenchmarkWalks()
    proposed = model.propose(1.2, 0.0, 75.0).table
    firmer = model.propose(1.2, 0.0, 90.0).table
    a = preview_table(proposed, 1.2, 0.0, 75.0, model, seconds=5.0, benchmark=benchmark)
    b = preview_table(proposed.model_copy(deep=True), 1.2, 0.0, 75.0, model, seconds=5.0, benchmark=benchmark)
    assert a == b and benchmark.version_walks == 1 and len(walks) == 2          # the table once, the FSMIC once
    preview_table(firmer, 1.2, 0.0, 75.0, model, seconds=5.0, benchmark=benchmark)
    preview_table(proposed, 1.2, 0.0, 90.0, model, seconds=5.0, benchmark=benchmark)
    assert benchmark.version_walks == 3
    fresh = preview_table(proposed, 1.2, 0.0, 75.0, model, seconds=5.0)["controllers"]["table"]
    kept = dict(a["controllers"]["table"])
    assert kept.pop("real_time_factor") > 0 and fresh.pop("real_time_factor") > 0
    assert fresh == kept
