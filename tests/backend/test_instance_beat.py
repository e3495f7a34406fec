"""An API instance beats in the database while it serves, and names itself on the pushes it sends: the other
instances know it is alive, and when it is not."""

from __future__ import annotations

import time

from sqlalchemy import select

from backend.instance_beat import InstanceBeat
from backend.store.tables import instance_beats


def _beats(api) -> dict[str, float]:
    with api.db() as conn:
        return {r.name: r.beat_at_unix for r in conn.execute(select(instance_beats))}


def test_a_serving_instance_beats_and_one_that_closed_falls_silent(api):
    name = api.client.app.state.settings.instance_name
    assert time.time() - _beats(api)[name] < 10.0                 # the first beat is written before it serves
    beat = InstanceBeat(api.client.app.state.db, "other", period_s=0.05).start()
    try:
        first = _beats(api)["other"]
        deadline = time.monotonic() + 5.0
        while _beats(api)["other"] == first and time.monotonic() < deadline:
            time.sleep(0.02)
        assert _beats(api)["other"] > first                       # it goes on beating
    finally:
        beat.close()
    last = _beats(api)["other"]
    time.sleep(0.2)
    assert _beats(api)["other"] == last                           # closed: silent
