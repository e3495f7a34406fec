"""Revision 0021 (one version), on both databases: a database at 0020, as the code before it left one (tables and
envelopes, an edit of each, previews, sign-offs, a withdrawal, refinements, pushes, sessions and their audit), carries
every row into ``versions`` and ``version_id``, and the application reads it back as it read it before."""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterator
from contextlib import contextmanager
from datetime import UTC, datetime
from pathlib import Path

import pytest
from sqlalchemy import Connection, MetaData, create_engine, func, select, text

from backend.db import connect, database_url
from backend.errors import ConflictError, MovedError, NotFoundError
from backend.migrate import migrate
from backend.refinement import of_version as refinement_of
from backend.services import pushes as push_views
from backend.services import sessions as session_views
from backend.store import previews as previews_store
from backend.store import signoffs, versions, withdrawals
from backend.store.tables import legacy_ids
from backend.store.users import User
from controller_core.envelope import Envelope
from controller_core.table import ParameterTable

DATA = Path(__file__).parents[1] / "leg" / "data"
TABLE = json.loads((DATA / "table_1.2mps_level_75kg.json").read_text())      # stored by the code before, as it was
ENVELOPE = json.loads((DATA / "envelope_default_75kg.json").read_text())
AT = "2026-11-29T10:00:00.000Z"
WHY = "the bench flags a figure we have looked at and accept"


def _text(value: object) -> str:
    return json.dumps(value, sort_keys=True, separators=(",", ":"))


def _sha(body: str) -> str:
    return hashlib.sha256(body.encode()).hexdigest()


EDITED = {**TABLE, "rows": [{**TABLE["rows"][0], "theta_e_deg": TABLE["rows"][0]["theta_e_deg"] + 1.0},
                            *TABLE["rows"][1:]]}
T1, T2 = _text(TABLE), _text(EDITED)
E1 = _text(ENVELOPE)
E2 = _text({**ENVELOPE, "neighbour_steps": {**ENVELOPE.get("neighbour_steps", {}), "load_N": 140.0}})


@contextmanager
def _writing(target: str | Path) -> Iterator[tuple[Connection, dict, object]]:
    """A transaction on ``target`` with its tables as they are (reflected) and a time in the form its columns take."""
    engine = create_engine(database_url(target))
    at = datetime(2026, 11, 29, 10, tzinfo=UTC) if engine.dialect.name == "postgresql" else AT
    try:
        with engine.begin() as conn:
            md = MetaData()
            md.reflect(conn)
            yield conn, md.tables, at
    finally:
        engine.dispose()


def _fill_0020(target: str | Path) -> None:
    """What the code before revision 0021 stored, row by row (its tables as they were at 0020)."""
    with _writing(target) as (conn, tables, at):
        def add(table: str, **values: object) -> None:
            conn.execute(tables[table].insert().values(**values))

        decided = {"status": "approved", "decided_by": 1, "decided_at": at, "decision_comment": "looked at it"}
        add("users", id=1, username="dana", role="prosthetist", password_hash="h", created_at=at)
        add("users", id=2, username="kim", role="prosthetist", password_hash="h", created_at=at)
        add("patients", id=1, code_name="P-1", body_mass_kg=75.0, side="left", created_by=1, created_at=at,
            updated_at=at)
        for pid, version, parent, body, extra in ((1, 1, None, T1, decided), (2, 2, 1, T2, {}), (3, 3, None, T1, {})):
            add("proposals", id=pid, patient_id=1, version=version, parent_id=parent,
                source="model" if parent is None else "edit", speed_mps=1.2, incline_deg=0.0, body_mass_kg=75.0,
                extrapolation=False, safety_ok=True, model_json=_text({"model": {"version": "m"}, "features": []}),
                table_json=body, table_sha256=_sha(T2 if pid == 3 else body),    # 3: altered in storage
                created_by=1, created_at=at, **extra)
        for eid, version, parent, body, extra in ((1, 1, None, E1, decided), (2, 2, 1, E2, {})):
            add("envelopes", id=eid, patient_id=1, version=version, parent_id=parent,
                source="model" if parent is None else "edit", body_mass_kg=75.0, n_speeds=5, n_inclines=5,
                extrapolation=False, safety_ok=True, envelope_json=body, envelope_sha256=_sha(body),
                wire_crc32=4000000000 + eid, created_by=1, created_at=at, **extra)
        add("devices", id="leg", kind="simulated", interface="virtual", channel="c", registered_at=at, patient_id=1,
            last_wire_version=2)
        add("pushes", id=1, proposal_id=1, device_id="leg", table_version=1, crc32=5, status="superseded",
            requested_by=1, requested_at=at)
        add("pushes", id=2, envelope_id=1, device_id="leg", table_version=2, crc32=6, status="active",
            requested_by=1, requested_at=at)
        session = {"patient_id": 1, "device_id": "leg", "speed_mps": 1.2, "incline_deg": 0.0, "body_mass_kg": 75.0,
                   "status": "stopped", "started_by": 1, "started_at": at, "stopped_at": at, "summary_json": "{}"}
        add("walking_sessions", id=1, proposal_id=1, table_version=1, table_crc32=5, **session)
        add("walking_sessions", id=2, envelope_id=2, course="mixed", **session)
        add("walking_sessions", id=3, **session)
        add("proposal_previews", proposal_id=1, table_sha256=_sha(T1), seconds=10.0, created_at=at,
            result_json='{"walk": 1}')
        add("proposal_previews", proposal_id=2, table_sha256="0" * 64, seconds=10.0, created_at=at,
            result_json='{"walk": 2}')       # made from other content: refused before, refused after
        add("envelope_previews", envelope_id=1, envelope_sha256=_sha(E1), course="mixed", created_at=at,
            result_json='{"course": {"name": "mixed"}, "nodes": []}')
        add("gate_signoffs", proposal_id=1, content_sha256=_sha(T1), user_id=1, reason=WHY, signed_at=at)
        add("gate_signoffs", envelope_id=2, content_sha256=_sha(E2), user_id=2, reason=WHY, signed_at=at)
        add("withdrawals", envelope_id=1, user_id=1, reason=WHY, withdrawn_at=at)
        add("refinements", envelope_id=2, parent_id=1, session_ids_json="[2]", evidence_json='{"nodes": []}',
            created_by=1, created_at=at)
        add("refinements", proposal_id=2, parent_id=1, session_ids_json="[1]", evidence_json="{}", created_by=1,
            created_at=at)
        add("audit_log", at=at, actor_id=1, actor_name="dana", action="envelope.create", entity="envelope",
            entity_id=1)


@pytest.fixture(params=["sqlite", "postgresql"])
def at_0020(request, tmp_path):
    """A database at revision 0020 holding what the code before stored."""
    if request.param == "sqlite":
        target: str | Path = tmp_path / "q.sqlite"
        migrate(target, to="0020")
        _fill_0020(target)
        yield target
        return
    with request.getfixturevalue("postgres").new_database() as url:
        migrate(url, to="0020")
        _fill_0020(url)
        yield url


def test_every_row_is_carried_to_one_version_and_read_back_as_before(at_0020):
    assert migrate(at_0020) == ["0021"]
    conn = connect(at_0020)
    try:
        # one id space: tables keep their ids, envelopes move up past the largest id of either kind (3)
        assert [(r.id, r.kind, r.version) for r in conn.execute(text("SELECT id, kind, version FROM versions "
                                                                     "ORDER BY id"))] == \
            [(1, "table", 1), (2, "table", 2), (3, "table", 3), (4, "envelope", 1), (5, "envelope", 2)]
        assert sorted(tuple(r) for r in conn.execute(select(legacy_ids))) == [
            ("envelope", 1, 4), ("envelope", 2, 5), ("proposal", 1, 1), ("proposal", 2, 2), ("proposal", 3, 3)]
        assert versions.moved_to(conn, "envelope", 1) == 4 and versions.moved_to(conn, "proposal", 1) is None

        # the content: a table as the envelope of its one node, its values as they were; an envelope as it was
        t1, t2 = versions.get_row(conn, "proposal", 1), versions.get_row(conn, "proposal", 2)
        assert versions.stored_table(t1) == ParameterTable.model_validate(TABLE)
        assert versions.stored_table(t2) == ParameterTable.model_validate(EDITED)
        assert (t1["status"], t1["decided_by_name"], t1["n_speeds"], t1["n_inclines"]) == ("approved", "dana", 1, 1)
        assert (t2["parent_id"], t2["parent_version"], json.loads(t1["model_json"])["model"]) == (1, 1,
                                                                                               {"version": "m"})
        e1, e2 = versions.get_row(conn, "envelope", 4), versions.get_row(conn, "envelope", 5)
        assert versions.stored_envelope(e1) == Envelope.from_json(ENVELOPE) and e1["content_sha256"] == _sha(E1)
        assert (e2["parent_id"], e2["parent_version"], e2["wire_crc32"]) == (4, 1, 4000000002)
        assert (e1["speed_mps"], e1["incline_deg"]) == (ENVELOPE["nominal_speed_mps"], ENVELOPE["nominal_incline_deg"])
        with pytest.raises(MovedError, match="envelope 1 is now version 4"):    # an old envelope link moves on
            versions.get_row(conn, "envelope", 1)
        with pytest.raises(NotFoundError, match="version 4 is an envelope"):   # the API's kinds stay apart
            versions.get_row(conn, "proposal", 4)
        with pytest.raises(ConflictError, match="does not match its sha256"):   # altered before: still refused
            versions.stored_table(versions.get_row(conn, "proposal", 3))

        # what names a version: previews and sign-offs follow a table's new content hash, the rest its new id
        assert previews_store.get_preview(conn, "proposal", 1, t1["content_sha256"])["walk"] == 1
        with pytest.raises(ConflictError, match="another table"):
            previews_store.get_preview(conn, "proposal", 2, t2["content_sha256"])
        assert previews_store.get_preview(conn, "envelope", 4, _sha(E1))["course"]["name"] == "mixed"
        assert [s["by"] for s in signoffs.signoffs(conn, "proposal", 1, t1["content_sha256"])] == ["dana"]
        assert [s["by"] for s in signoffs.signoffs(conn, "envelope", 5, _sha(E2))] == ["kim"]
        assert withdrawals.withdrawal(conn, "envelope", 4)["reason"] == WHY
        assert withdrawals.withdrawal(conn, "proposal", 1) is None
        refined = refinement_of(conn, 5)
        assert (refined["envelope_id"], refined["proposal_id"], refined["parent_id"]) == (5, None, 4)
        assert refinement_of(conn, 2)["parent_id"] == 1
        [p1] = push_views.pushes_of(conn, ("proposal", 1))
        [p2] = push_views.pushes_of(conn, ("envelope", 4))
        assert (p1["kind"], p1["proposal_id"], p1["label"], p1["withdrawal"]) == ("table", 1, "P-1 · table v1", None)
        assert (p2["envelope_id"], p2["label"], p2["withdrawal"]["reason"]) == (4, "P-1 · envelope v1", WHY)
        s1, s2, s3 = (session_views.get_session(conn, i) for i in (1, 2, 3))
        assert (s1["proposal_id"], s1["envelope_id"], s1["table_label"]) == (1, None, "P-1 · table v1")
        assert (s2["proposal_id"], s2["envelope_id"], s2["table_label"]) == (None, 5, "P-1 · envelope v2")
        assert (s3["proposal_id"], s3["envelope_id"], s3["table_label"]) == (None, None, None)
        assert conn.execute(select(func.count()).select_from(text("audit_log"))).scalar_one() == 1

        # the rules moved with the rows, and a new version is numbered and named after the old ones
        conn.rollback()
        for statement, words in [("UPDATE versions SET content_json = '{}' WHERE id = 1", "immutable"),
                                 ("UPDATE versions SET status = 'rejected' WHERE id = 4", "already been approved"),
                                 ("DELETE FROM versions WHERE id = 3", "never deleted"),
                                 ("UPDATE walking_sessions SET course = 'x' WHERE id = 1", "final"),
                                 ("DELETE FROM refinements", "never deleted"),
                                 ("UPDATE withdrawals SET reason = 'x'", "kept as written"),
                                 ("UPDATE legacy_ids SET version_id = 1", "kept as written")]:
            with pytest.raises(Exception, match=words), conn.begin():
                conn.execute(text(statement))
        with conn.begin():
            row = versions.insert_row(conn, 1, None, ParameterTable.model_validate(TABLE), None, True, None,
                                      User(1, "dana", "prosthetist"))
        assert (row["id"], row["kind"], row["version"]) == (6, "table", 4)
    finally:
        conn.close()


@pytest.fixture(params=["sqlite", "postgresql"])
def many_at_0020(request, tmp_path):
    """A database at 0020 with more tables than the migration copies at a time (its ``BATCH``, 200) and an envelope."""
    target: str | Path
    if request.param == "sqlite":
        target = tmp_path / "q.sqlite"
        yield from _many(target)
        return
    with request.getfixturevalue("postgres").new_database() as url:
        yield from _many(url)


def _many(target: str | Path):
    migrate(target, to="0020")
    with _writing(target) as (conn, t, at):
        conn.execute(t["users"].insert().values(id=1, username="dana", role="prosthetist", password_hash="h",
                                                created_at=at))
        conn.execute(t["patients"].insert().values(id=1, code_name="P-1", body_mass_kg=75.0, side="left", created_by=1,
                                                   created_at=at, updated_at=at))
        conn.execute(t["proposals"].insert(), [
            {"id": i, "patient_id": 1, "version": i, "parent_id": i - 1 if i > 1 else None,
             "source": "edit" if i > 1 else "model", "speed_mps": 1.2, "incline_deg": 0.0, "body_mass_kg": 75.0,
             "extrapolation": False, "safety_ok": True, "model_json": "{}", "table_json": T1, "table_sha256": _sha(T1),
             "created_by": 1, "created_at": at} for i in range(1, 451)])
        conn.execute(t["envelopes"].insert().values(
            id=1, patient_id=1, version=1, source="model", body_mass_kg=75.0, n_speeds=5, n_inclines=5,
            extrapolation=False, safety_ok=True, envelope_json=E1, envelope_sha256=_sha(E1), created_by=1,
            created_at=at))
    yield target


def test_a_database_larger_than_one_batch_is_carried_whole_in_order(many_at_0020):
    """Versions are copied a batch at a time (memory stays bounded on a large database), each a parent before its
    child: 450 tables in a chain of edits and an envelope arrive whole."""
    assert migrate(many_at_0020) == ["0021"]
    conn = connect(many_at_0020)
    try:
        got = [tuple(r) for r in conn.execute(text("SELECT kind, count(*), min(id), max(id) FROM versions GROUP BY kind "
                                                   "ORDER BY kind"))]
        assert got == [("envelope", 1, 451, 451), ("table", 450, 1, 450)]   # moved past the largest old id (450)
        assert conn.execute(select(func.count()).select_from(legacy_ids)).scalar_one() == 451
        last = versions.get_row(conn, "proposal", 450)
        assert (last["parent_version"], versions.stored_table(last)) == (449, ParameterTable.model_validate(TABLE))
        assert versions.moved_to(conn, "envelope", 1) == 451
    finally:
        conn.close()
