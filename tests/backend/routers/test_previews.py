"""The simulated preview of a proposal."""

from __future__ import annotations

import pytest

from backend.bench.safety_figures import safety_flags
from tests.helpers.sql import sql


def test_preview_walks_the_table_and_the_fsmic_once_and_keeps_it(api):
    prop = api.propose(api.new_patient()["id"], speed=1.2)
    c, viewer = api.client, api.as_("viewer")
    r = c.get(f"/api/proposals/{prop['id']}/preview", headers=viewer)
    assert r.status_code == 200, r.text
    first = r.json()
    assert first["table_sha256"] == prop["table_sha256"]
    assert set(first["controllers"]) == {"table", "fsmic"}
    for run in first["controllers"].values():
        assert run["seconds"] == pytest.approx(10.0, abs=0.01)
        assert set(run["mean_curves"]) <= set(first["reference_curves"])
    assert first["controllers"]["fsmic"]["strides"] >= 3   # the benchmark walks at its nominal task
    # how sure: each RMSE has its interval over strides, and the table's difference from the FSMIC its verdict
    table = first["controllers"]["table"]
    lo, hi = table["knee_angle_rmse_ci95_deg"]
    assert lo <= table["knee_angle_rmse_deg"] <= hi
    vs = table["vs_fsmic"]
    assert vs["knee_angle_rmse_difference_deg"] == pytest.approx(
        table["knee_angle_rmse_deg"] - first["controllers"]["fsmic"]["knee_angle_rmse_deg"])
    lo, hi = vs["ankle_angle_rmse_difference_ci95_deg"]
    d = vs["ankle_angle_rmse_difference_deg"]
    assert lo <= d <= hi and vs["ankle_angle_verdict"] == ("learned lower" if hi < 0 else "FSMIC lower" if lo > 0
                                                           else "not resolved")
    for key in ("hip_sink_max_mm", "support_deficit_max_bw", "stance_knee_flexion_peak_deg"):
        assert table[key] is not None and first["controllers"]["fsmic"][key] is not None
    assert table["heel_strikes_without_stance"] == 0 and table["heel_strike_to_stance_ms_median"] >= 5.0   # its hold
    assert table["loaded_swing_ms_max_stride"] >= table["loaded_swing_ms_per_stride"]
    assert len(first["phase_grid"]) == 101
    # the safety figures are flagged on their own bounds (rules in test_safety_figures), with words to read
    assert first["safety"] == safety_flags(table, first["controllers"]["fsmic"])
    assert all(f["message"] and f["severity"] in {"bad", "warn"} for f in first["safety"])
    again = c.get(f"/api/proposals/{prop['id']}/preview", headers=viewer).json()
    assert again == first   # stored, not re-simulated (same created_at)
    with api.db() as conn:
        assert sql(conn, "SELECT count(*) FROM previews").scalar_one() == 1
    assert c.get("/api/proposals/999/preview", headers=viewer).status_code == 404


def test_preview_made_from_another_table_is_refused(api):
    prop = api.propose(api.new_patient()["id"], speed=1.2)
    c, viewer = api.client, api.as_("viewer")
    assert c.get(f"/api/proposals/{prop['id']}/preview", headers=viewer).status_code == 200
    with api.db() as conn:
        sql(conn, "UPDATE previews SET content_sha256 = :sha", sha="0" * 64)
    r = c.get(f"/api/proposals/{prop['id']}/preview", headers=viewer)
    assert r.status_code == 409 and "another table" in r.json()["detail"]


def test_a_server_started_with_a_leg_file_previews_on_that_leg(tmp_path, model):
    from device_bridge.sim.leg_file import LEGS_DIR
    from tests.helpers.api import make_api

    api, client = make_api(tmp_path, lambda: model, bench_leg=LEGS_DIR / "short_person.json")
    with client:
        patient = api.new_patient()
        prop = api.propose(patient["id"])
        r = client.get(f"/api/proposals/{prop['id']}/preview", headers=api.as_("viewer"))
        assert r.status_code == 200, r.text
        assert r.json()["leg"] == "short person (1.58 m)"


def test_one_walk_per_version_however_many_pages_ask_at_once():
    """A page redrawn while its preview walks asks again; five asks at once make one walk on the bench's queue (the
    others wait for it and read what it stored), never five, nor a 429 for the user's share."""
    import threading

    import anyio

    from backend.routers import previews as router
    from backend.threads import BENCH_PER_USER, bench_queue

    walks, release, stored = [], threading.Event(), {}

    def preview(key: str, walk: bool = True) -> dict | None:
        if key in stored or not walk:
            return stored.get(key)
        walks.append(key)
        release.wait(10)
        stored[key] = {"walked": key}
        return stored[key]

    async def main() -> list[dict]:
        got: list[dict] = []

        async def ask() -> None:
            got.append(await router._walk_once(("proposal", 7), "dana", preview, "v7"))

        async with anyio.create_task_group() as tg:
            for _ in range(BENCH_PER_USER + 3):
                tg.start_soon(ask)
            with anyio.fail_after(5):
                while not walks:
                    await anyio.sleep(0.01)
            assert bench_queue() == {"dana": 1}                   # one walk queued for the user, not five
            release.set()
        return got

    out: list = []       # on a thread of its own: a test before may have left an event loop in this one
    runner = threading.Thread(target=lambda: out.append(anyio.run(main)))
    runner.start()
    runner.join(30)
    [got] = out
    assert walks == ["v7"] and got == [{"walked": "v7"}] * (BENCH_PER_USER + 3) and router._walks == {}
