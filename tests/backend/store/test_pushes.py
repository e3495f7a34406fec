"""Push bookkeeping: which table a device runs, or will run from its next heel strike."""

from __future__ import annotations

import pytest
from sqlalchemy.exc import IntegrityError

from backend.errors import ConflictError
from backend.services import pushes as push_views
from backend.store import devices, pushes
from backend.store.users import User
from tests.helpers.sql import sql


def _pushes(api, n: int, outcomes: list[str | None] | None = None
            ) -> tuple[object, list[int], list[int], list[int]]:
    """``n`` pushes to one leg, one after the other as a device takes them: each finished with its outcome (None: left
    ``sending``, only the last may be) before the next is recorded."""
    outcomes = outcomes or [None] * n
    assert None not in outcomes[:-1], "one push on its way per device"
    patient = api.new_patient()
    proposal_ids = [api.propose(patient["id"], speed=1.0 + 0.1 * i)["id"] for i in range(n)]
    conn = api.db()
    devices.register_device(conn, "leg", "simulated", "virtual", "x")
    push_ids, versions = [], []
    for pid, outcome in zip(proposal_ids, outcomes, strict=True):
        push_id, version = pushes.begin_push(conn, ("proposal", pid), "leg", 0xABC0 + pid, _actor(conn))
        if outcome is not None:
            pushes.finish_push(conn, push_id, outcome, 1, 3.0, None if outcome == "acknowledged" else outcome)
        push_ids.append(push_id)
        versions.append(version)
    return conn, proposal_ids, push_ids, versions


def _current(conn) -> dict | None:
    """What the leg runs or will run from its next heel strike, by the records: its newest push that is ``active`` or
    ``acknowledged`` (a CRC read back but no status frame reporting it yet)."""
    found = sql(conn, "SELECT id FROM pushes WHERE device_id = 'leg' AND status IN ('active', 'acknowledged') "
                "ORDER BY id DESC").first()
    return None if found is None else push_views.get_push(conn, found[0])


def _actor(conn) -> User:
    user_id = sql(conn, "SELECT id FROM users WHERE username = 'prosthetist'").scalar_one()
    return User(id=user_id, username="prosthetist", role="prosthetist")


def test_acknowledged_push_is_current_before_the_device_reports_it(api):
    conn, proposal_ids, (push_id,), _versions = _pushes(api, 1)
    assert _current(conn) is None                    # still sending: nothing on the leg yet
    pushes.finish_push(conn, push_id, "acknowledged", 1, 3.0, None)
    assert _current(conn)["proposal_id"] == proposal_ids[0]


def test_running_a_table_supersedes_older_acknowledged_pushes(api):
    conn, proposal_ids, push_ids, versions = _pushes(api, 3, ["acknowledged"] * 3)
    changed = pushes.reconcile(conn, "leg", (versions[1], 0xABC0 + proposal_ids[1]), versions[2], set())
    statuses = [push_views.get_push(conn, i)["status"] for i in push_ids]
    assert statuses == ["superseded", "active", "acknowledged"]        # the newest is still to be run
    assert set(changed) == {("proposal", proposal_ids[0]), ("proposal", proposal_ids[1])}
    assert _current(conn)["id"] == push_ids[2]
    # what each version's page says about where it runs
    states = [pushes.deployment_state(conn, ("proposal", p)) for p in proposal_ids]
    assert states == ["replaced", "active_on_device", "pushed"]


def test_a_device_kind_outside_the_schema_is_refused_not_ignored(api):
    conn = api.db()
    with pytest.raises(IntegrityError, match=r"(?i)check"):
        devices.register_device(conn, "leg", "bluetooth", "virtual", "x")
    devices.register_device(conn, "leg", "can", "socketcan", "can0")
    devices.register_device(conn, "leg", "can", "socketcan", "can1")             # a restart keeps the first
    assert sql(conn, "SELECT channel FROM devices WHERE id = 'leg'").scalar_one() == "can0"


def test_the_table_version_is_the_devices_own_counter_and_wraps_past_16_bits(api):
    conn, proposal_ids, push_ids, versions = _pushes(api, 2, ["failed"] * 2)
    assert versions == [1, 2]                                          # not the proposal ids
    sql(conn, "UPDATE devices SET last_wire_version = 65534 WHERE id = 'leg'")
    wrapped = []
    for _ in range(3):
        push_id, version = pushes.begin_push(conn, ("proposal", proposal_ids[0]), "leg", 0x1234, _actor(conn))
        pushes.finish_push(conn, push_id, "failed", 1, 3.0, "refused")
        wrapped.append(version)
    assert wrapped == [65535, 1, 2]
    # a reused number still names the newest push of that version and CRC
    assert push_views.push_of_version(conn, "leg", 2, 0x1234)["id"] > push_ids[1]
    assert push_views.push_of_version(conn, "leg", 2, 0xABC0 + proposal_ids[1])["id"] == push_ids[1]


def test_the_records_follow_what_the_device_reports_after_a_restart(api):
    """A server killed mid-push, a device that came back with no table: nothing stays active or sending."""
    conn, proposal_ids, push_ids, versions = _pushes(api, 3, ["acknowledged", "acknowledged", None])
    # the first runs, the second is staged for the next heel strike, the third was left 'sending' by a killed server
    pushes.reconcile(conn, "leg", (versions[0], 0xABC0 + proposal_ids[0]), versions[1], {push_ids[2]})
    assert pushes.interrupted_pushes(conn, ["another-leg"]) == 0     # another instance's device: left to it
    assert pushes.interrupted_pushes(conn, ["leg"]) == 1
    assert push_views.get_push(conn, push_ids[2])["status"] == "unconfirmed"
    pushes.reconcile(conn, "leg", None, None, set())                          # the leg restarted: no table
    statuses = [push_views.get_push(conn, i)["status"] for i in push_ids]
    assert statuses == ["lost", "lost", "failed"]
    assert "no table" in push_views.get_push(conn, push_ids[0])["error"]
    assert _current(conn) is None
    assert [pushes.deployment_state(conn, ("proposal", p)) for p in proposal_ids] == ["not_on_device"] * 2 + [
        "push_failed"]


def test_an_unconfirmed_push_is_decided_by_the_devices_next_status(api):
    conn, proposal_ids, push_ids, versions = _pushes(api, 2, ["unconfirmed"] * 2)
    assert [push_views.get_push(conn, i)["status"] for i in push_ids] == ["unconfirmed", "unconfirmed"]
    assert pushes.deployment_state(conn, ("proposal", proposal_ids[0])) == "unconfirmed"
    # the device runs the first (its acknowledgement was lost as it switched) and never got the second
    pushes.reconcile(conn, "leg", (versions[0], 0xABC0 + proposal_ids[0]), None, set())
    assert [push_views.get_push(conn, i)["status"] for i in push_ids] == ["active", "failed"]


def test_a_push_in_flight_is_left_to_its_sender_and_a_staged_one_is_kept(api):
    conn, _proposal_ids, push_ids, versions = _pushes(api, 2, ["acknowledged", None])
    pushes.reconcile(conn, "leg", None, versions[0], {push_ids[1]})
    assert [push_views.get_push(conn, i)["status"] for i in push_ids] == ["acknowledged", "sending"]


def test_a_device_running_a_table_this_server_did_not_send_supersedes_ours(api):
    conn, proposal_ids, push_ids, versions = _pushes(api, 1)
    pushes.finish_push(conn, push_ids[0], "acknowledged", 1, 3.0, None)
    pushes.reconcile(conn, "leg", (versions[0], 0xABC0 + proposal_ids[0]), None, set())
    pushes.reconcile(conn, "leg", (999, 0xDEADBEEF), None, set())
    push = push_views.get_push(conn, push_ids[0])
    assert push["status"] == "superseded" and "version 999, CRC deadbeef" in push["error"]


def test_a_push_the_device_reports_running_is_active_even_while_its_sender_finishes(api):
    conn, proposal_ids, push_ids, versions = _pushes(api, 1)
    pushes.reconcile(conn, "leg", (versions[0], 0xABC0 + proposal_ids[0]), None, {push_ids[0]})
    assert push_views.get_push(conn, push_ids[0])["status"] == "active"
    pushes.finish_push(conn, push_ids[0], "acknowledged", 1, 3.0, None)     # the sender's answer keeps it active
    assert push_views.get_push(conn, push_ids[0])["status"] == "active"


def test_one_push_on_its_way_per_device_is_the_databases_rule(conn, prosthetist, draft):
    """Two instances pushing to one leg at once: the second push's record is refused by the database itself (a
    partial unique index), whichever instance records it; once the first is finished the next may go."""
    devices.register_device(conn, "leg", "simulated", "virtual", "x")
    first, _ = pushes.begin_push(conn, ("proposal", draft()), "leg", 0x1234, prosthetist)
    with pytest.raises(ConflictError, match="another push to device leg is still in progress"):
        pushes.begin_push(conn, ("proposal", draft()), "leg", 0x5678, prosthetist)
    assert sql(conn, "SELECT count(*) FROM pushes").scalar_one() == 1     # nothing of the refused one
    pushes.finish_push(conn, first, "acknowledged", 1, 3.0, None)
    pushes.begin_push(conn, ("proposal", draft()), "leg", 0x5678, prosthetist)


def test_a_push_an_instance_left_sending_blocks_the_others_only_while_it_beats(conn, prosthetist, draft):
    """An instance killed mid-push leaves its record ``sending``: while the instance beats (it may still be sending),
    every other instance's push is refused; once it has missed its beats for ``DEAD_AFTER_S``, the next push from
    any instance makes it ``unconfirmed`` at once (the device's next status decides it) and goes ahead (it blocked
    them for a minute or until that instance restarted)."""
    import time

    from backend.store.instance_beats import DEAD_AFTER_S, beat

    devices.register_device(conn, "leg", "simulated", "virtual", "x")
    beat(conn, "api1")
    beat(conn, "api2")
    dead, _ = pushes.begin_push(conn, ("proposal", draft()), "leg", 0x1234, prosthetist, instance_name="api1")
    with pytest.raises(ConflictError, match="still in progress"):             # api1 beats: it may be sending
        pushes.begin_push(conn, ("proposal", draft()), "leg", 0x5678, prosthetist, instance_name="api2")
    beat(conn, "api1", at_unix=time.time() - DEAD_AFTER_S - 1.0)              # api1 stopped beating
    fresh, _ = pushes.begin_push(conn, ("proposal", draft()), "leg", 0x5678, prosthetist, instance_name="api2")
    left = push_views.get_push(conn, dead)
    assert left["status"] == "unconfirmed" and "instance that stopped" in left["error"]
    assert push_views.get_push(conn, fresh)["status"] == "sending"
    changed = pushes.reconcile(conn, "leg", (2, 0x5678), None, set())          # the leg reports the new one running
    assert push_views.get_push(conn, dead)["status"] == "failed" and changed


def test_a_push_recorded_without_its_instance_is_left_for_a_minute(conn, prosthetist, draft):
    """Pushes recorded before they named their instance: their age decides (a minute), as it did."""
    from sqlalchemy import update

    from backend.store.tables import pushes as table

    devices.register_device(conn, "leg", "simulated", "virtual", "x")
    old, _ = pushes.begin_push(conn, ("proposal", draft()), "leg", 0x1234, prosthetist)
    with pytest.raises(ConflictError, match="still in progress"):
        pushes.begin_push(conn, ("proposal", draft()), "leg", 0x5678, prosthetist)
    conn.execute(update(table).where(table.c.id == old).values(requested_at="2026-01-01T00:00:00.000Z"))
    conn.commit()
    pushes.begin_push(conn, ("proposal", draft()), "leg", 0x5678, prosthetist)
    assert push_views.get_push(conn, old)["status"] == "unconfirmed"
