"""One version: tables and envelopes are rows of one ``versions`` table, a table being the envelope of its one node.

* ``versions``: every proposal (``kind`` 'table', 1 × 1) and every envelope (``kind`` 'envelope'), with its task (a
  range's nominal task), its content as the envelope JSON the device runs (a proposal's table becomes the envelope of
  its one node, so its content hash is new; a sign-off or preview made on the table's old hash is carried over to the
  new one; a table whose text no longer matched its hash keeps the old hash, so it is refused at every read as before)
  and, for a table, the model's output it was made from. Numbers stay as they were: a patient's tables and
  envelopes are numbered apart ("table v3", "envelope v3").
* One id space: a proposal keeps its id; an envelope's id moves up by the largest id of either kind before
  (``legacy_ids`` keeps every old id, for the audit rows written before and old envelope links).
* ``previews``, and ``version_id`` in place of ``proposal_id`` / ``envelope_id`` in ``walking_sessions``, ``pushes``,
  ``refinements`` (its ``parent_id`` moved likewise), ``gate_signoffs`` and ``withdrawals``.
* The rules move with the rows: the immutability triggers of the two version tables become the ``versions`` triggers;
  the triggers of the tables that change are read back as the database wrote them and made again, word for word.

SQLite cannot drop a column that a foreign key names, so there each changed table is rebuilt (created anew, the rows
copied, the old one dropped and the new one renamed; the migration runs without foreign-key enforcement); PostgreSQL
alters them in place.

Revision ID: 0021
Revises: 0020
Created: 2026-11-30
"""

from __future__ import annotations

import hashlib
import json

import sqlalchemy as sa
from alembic import op

revision = "0021"
down_revision = "0020"
branch_labels = None
depends_on = None

CHANGED = ("walking_sessions", "pushes", "refinements", "gate_signoffs", "withdrawals")

VERSION_TRIGGERS: list[tuple[str, str, str | None, str]] = [
    ("versions_content_immutable",
     "UPDATE OF patient_id, kind, version, parent_id, source, n_speeds, n_inclines, speed_mps, incline_deg, "
     "body_mass_kg, extrapolation, safety_ok, content_json, content_sha256, wire_crc32, model_json, edit_comment, "
     "created_by, created_at", None, "a version's content is immutable; derive a new version instead"),
    ("versions_decided_once", "UPDATE OF status, decided_by, decided_at, decision_comment, decision_override",
     "OLD.status <> 'draft'", "version has already been approved or rejected"),
    ("versions_never_deleted", "DELETE", None, "versions are never deleted"),
    ("versions_extrapolation_reason_kept", "UPDATE OF extrapolation_reason", None,
     "a version's extrapolation reason is kept as written"),
    ("versions_leg_kept", "UPDATE OF leg_json", None, "the leg a version was made for is kept as written"),
    ("legacy_ids_kept", "UPDATE", None, "an old id is kept as written"),
]


class _Types:
    """A time and a flag as revision 0020 left them: timestamp and boolean on PostgreSQL, text and 0/1 on SQLite."""

    def __init__(self, pg: bool) -> None:
        self.pg = pg
        self.time = sa.TIMESTAMP(timezone=True) if pg else sa.Text()
        self.float = sa.Double() if pg else sa.REAL()
        self.crc = sa.BigInteger() if pg else sa.Integer()

    def flag(self, name: str, nullable: bool = False, column_check: bool = False) -> sa.Column:
        if self.pg:
            return sa.Column(name, sa.Boolean(create_constraint=False), nullable=nullable)
        checks = [sa.CheckConstraint(f"{name} IN (0, 1)")] if column_check else []
        return sa.Column(name, sa.Integer(), *checks, nullable=nullable)

    def checks(self, *sqlite_only: str) -> list[sa.CheckConstraint]:
        """Checks made on SQLite only (JSON's, a flag's 0/1)."""
        return [] if self.pg else [sa.CheckConstraint(c) for c in sqlite_only]


def upgrade() -> None:
    bind = op.get_bind()
    pg = bind.dialect.name == "postgresql"
    t = _Types(pg)
    kept = _read_triggers(bind, pg)
    for table, name, _ in kept:
        op.execute(f'DROP TRIGGER "{name}" ON "{table}"' if pg else f'DROP TRIGGER "{name}"')
    _create_versions(t)
    offset, table_sha = _copy_versions(bind)
    _create_previews(t)
    _copy_previews(bind, offset, table_sha)
    moved = f"COALESCE(proposal_id, envelope_id + {offset})"
    sha = ("CASE WHEN proposal_id IS NULL THEN content_sha256 ELSE COALESCE((SELECT n.new FROM _sha_map n WHERE "
           "n.id = proposal_id AND n.old = content_sha256), content_sha256) END")
    parent = f"CASE WHEN envelope_id IS NULL THEN parent_id ELSE parent_id + {offset} END"
    if pg:
        _alter_pg(moved, sha, parent)
    else:
        _rebuild_sqlite(t, moved, sha, parent)
    op.execute("DROP TABLE _sha_map")
    for table in ("proposal_previews", "envelope_previews", "proposals", "envelopes"):
        op.drop_table(table)
    for _, _, definition in kept:
        op.execute(definition)
    _create_version_triggers(pg)
    if pg:
        op.execute("SELECT setval(pg_get_serial_sequence('versions', 'id'), (SELECT COALESCE(max(id), 0) + 1 "
                   "FROM versions), false)")


def _read_triggers(bind, pg: bool) -> list[tuple[str, str, str]]:
    """(table, name, definition) of every trigger on the tables that change, as the database wrote them."""
    if pg:
        rows = bind.execute(sa.text(
            "SELECT c.relname, t.tgname, pg_get_triggerdef(t.oid) FROM pg_trigger t JOIN pg_class c ON c.oid = t.tgrelid "
            "WHERE NOT t.tgisinternal AND c.relname = ANY(:tables) ORDER BY c.relname, t.tgname"),
            {"tables": list(CHANGED)}).all()
    else:
        rows = bind.execute(sa.text(
            "SELECT tbl_name, name, sql FROM sqlite_master WHERE type = 'trigger' AND tbl_name IN "
            f"({', '.join(repr(x) for x in CHANGED)}) ORDER BY tbl_name, name")).all()
    return [(r[0], r[1], r[2]) for r in rows]


def _create_versions(t: _Types) -> None:
    op.create_table(
        "versions",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("patient_id", sa.Integer(), nullable=False),
        sa.Column("kind", sa.Text(), nullable=False),
        sa.Column("version", sa.Integer(), nullable=False),
        sa.Column("parent_id", sa.Integer(), nullable=True),
        sa.Column("source", sa.Text(), nullable=False),
        sa.Column("n_speeds", sa.Integer(), nullable=False),
        sa.Column("n_inclines", sa.Integer(), nullable=False),
        sa.Column("speed_mps", t.float, nullable=False),
        sa.Column("incline_deg", t.float, nullable=False),
        sa.Column("body_mass_kg", t.float, nullable=False),
        t.flag("extrapolation"),
        t.flag("safety_ok"),
        sa.Column("content_json", sa.Text(), nullable=False),
        sa.Column("content_sha256", sa.Text(), nullable=False),
        sa.Column("wire_crc32", t.crc, nullable=True),
        sa.Column("model_json", sa.Text(), nullable=True),
        sa.Column("edit_comment", sa.Text(), nullable=True),
        sa.Column("created_by", sa.Integer(), nullable=False),
        sa.Column("created_at", t.time, nullable=False),
        sa.Column("status", sa.Text(), server_default="draft", nullable=False),
        sa.Column("decided_by", sa.Integer(), nullable=True),
        sa.Column("decided_at", t.time, nullable=True),
        sa.Column("decision_comment", sa.Text(), nullable=True),
        sa.Column("decision_override", sa.Text(), nullable=True),
        sa.Column("extrapolation_reason", sa.Text(), nullable=True),
        sa.Column("leg_json", sa.Text(), server_default="{}", nullable=False),
        sa.CheckConstraint("kind IN ('table', 'envelope')"),
        sa.CheckConstraint("(kind = 'table' AND n_speeds = 1 AND n_inclines = 1) OR (kind = 'envelope' AND n_speeds "
                           "BETWEEN 2 AND 15 AND n_inclines BETWEEN 2 AND 15 AND n_speeds * n_inclines <= 64)"),
        sa.CheckConstraint("speed_mps > 0 AND speed_mps <= 3"),
        sa.CheckConstraint("incline_deg BETWEEN -20 AND 20"),
        sa.CheckConstraint("version >= 1"),
        sa.CheckConstraint("source IN ('model', 'edit')"),
        sa.CheckConstraint("body_mass_kg BETWEEN 20 AND 200"),
        *t.checks("extrapolation IN (0, 1)", "safety_ok IN (0, 1)"),
        sa.CheckConstraint("status IN ('draft', 'approved', 'rejected')"),
        *t.checks("json_valid(content_json)", "json_valid(leg_json)"),
        sa.ForeignKeyConstraint(["patient_id"], ["patients.id"]),
        sa.ForeignKeyConstraint(["parent_id"], ["versions.id"]),
        sa.ForeignKeyConstraint(["created_by"], ["users.id"]),
        sa.ForeignKeyConstraint(["decided_by"], ["users.id"]),
        sa.PrimaryKeyConstraint("id"),
        sa.UniqueConstraint("patient_id", "kind", "version"),
    )
    op.create_table(
        "legacy_ids",
        sa.Column("kind", sa.Text(), nullable=False),
        sa.Column("old_id", sa.Integer(), nullable=False),
        sa.Column("version_id", sa.Integer(), nullable=False),
        sa.CheckConstraint("kind IN ('proposal', 'envelope')"),
        sa.ForeignKeyConstraint(["version_id"], ["versions.id"]),
        sa.PrimaryKeyConstraint("kind", "old_id"),
        sa.UniqueConstraint("version_id"),
    )


def one_node_envelope(table_json: str) -> str:
    """A stored table as the envelope of its one node, at the task, mass and model its provenance names (the JSON
    ``controller_core.envelope.envelope_of_table`` gives, in the stored canonical form)."""
    table = json.loads(table_json)
    p = table["provenance"]
    envelope = {"format": "quasitune.envelope/1", "speeds_mps": [p["speed_mps"]], "inclines_deg": [p["incline_deg"]],
                "nominal_speed_mps": p["speed_mps"], "nominal_incline_deg": p["incline_deg"],
                "mass_kg": p["patient_mass_kg"], "model_version": p["model_version"], "data_sha256": p["data_sha256"],
                "nodes": [{"speed_mps": p["speed_mps"], "incline_deg": p["incline_deg"], "table": table,
                           "extrapolation": p["extrapolation"], "feature_std": {}, "neighbour_guarded": {}}]}
    return json.dumps(envelope, sort_keys=True, separators=(",", ":"), allow_nan=False)


BATCH = 200     # versions read and written at a time (an envelope's JSON is about 100 kB): memory stays bounded


def _batches(bind, table: sa.Table):
    """The rows of ``table`` in id order, :data:`BATCH` at a time (keyset pages: no cursor held open across writes)."""
    last = 0
    while True:
        rows = bind.execute(sa.select(table).where(table.c.id > last).order_by(table.c.id).limit(BATCH)).mappings().all()
        if not rows:
            return
        yield rows
        last = rows[-1]["id"]


def _copy_versions(bind) -> tuple[int, dict[int, tuple[str, str]]]:
    """Every proposal and envelope into ``versions`` and ``legacy_ids`` (tables, then envelopes, each in id order: a
    parent before its children); returns the envelopes' id offset and each table's (old, new) content hash."""
    old = sa.MetaData()
    proposals = sa.Table("proposals", old, autoload_with=bind)
    envelopes = sa.Table("envelopes", old, autoload_with=bind)
    versions = sa.Table("versions", sa.MetaData(), autoload_with=bind)
    legacy = sa.Table("legacy_ids", sa.MetaData(), autoload_with=bind)
    offset = max(int(bind.execute(sa.select(sa.func.coalesce(sa.func.max(x.c.id), 0))).scalar())
                 for x in (proposals, envelopes))
    shared = ("patient_id", "version", "source", "body_mass_kg", "extrapolation", "safety_ok", "edit_comment",
              "created_by", "created_at", "status", "decided_by", "decided_at", "decision_comment", "decision_override",
              "extrapolation_reason", "leg_json")
    table_sha: dict[int, tuple[str, str]] = {}

    def table(r) -> dict:
        content = one_node_envelope(r["table_json"])
        intact = hashlib.sha256(r["table_json"].encode()).hexdigest() == r["table_sha256"]
        # a table whose stored text no longer gives its hash keeps the hash it had: still refused at every read
        new_sha = hashlib.sha256(content.encode()).hexdigest() if intact else r["table_sha256"]
        table_sha[r["id"]] = (r["table_sha256"], new_sha)
        return {**{k: r[k] for k in shared}, "id": r["id"], "kind": "table", "parent_id": r["parent_id"],
                "n_speeds": 1, "n_inclines": 1, "speed_mps": r["speed_mps"], "incline_deg": r["incline_deg"],
                "content_json": content, "content_sha256": new_sha, "wire_crc32": None, "model_json": r["model_json"]}

    def envelope(r) -> dict:
        body = json.loads(r["envelope_json"])
        return {**{k: r[k] for k in shared}, "id": r["id"] + offset, "kind": "envelope",
                "parent_id": None if r["parent_id"] is None else r["parent_id"] + offset,
                "n_speeds": r["n_speeds"], "n_inclines": r["n_inclines"],
                "speed_mps": body["nominal_speed_mps"], "incline_deg": body["nominal_incline_deg"],
                "content_json": r["envelope_json"], "content_sha256": r["envelope_sha256"],
                "wire_crc32": r["wire_crc32"], "model_json": None}

    for source, make, kind in ((proposals, table, "proposal"), (envelopes, envelope, "envelope")):
        for batch in _batches(bind, source):
            rows = [make(r) for r in batch]
            bind.execute(versions.insert(), rows)
            bind.execute(legacy.insert(), [{"kind": kind, "old_id": r["id"], "version_id": x["id"]}
                                           for r, x in zip(batch, rows, strict=True)])
    op.create_table("_sha_map", sa.Column("id", sa.Integer(), primary_key=True), sa.Column("old", sa.Text()),
                    sa.Column("new", sa.Text()))
    if table_sha:
        bind.execute(sa.table("_sha_map", sa.column("id"), sa.column("old"), sa.column("new")).insert(),
                     [{"id": k, "old": o, "new": n} for k, (o, n) in table_sha.items()])
    return offset, table_sha


def _create_previews(t: _Types) -> None:
    op.create_table(
        "previews",
        sa.Column("version_id", sa.Integer(), autoincrement=False, nullable=False),
        sa.Column("content_sha256", sa.Text(), nullable=False),
        sa.Column("seconds", t.float, nullable=True),
        sa.Column("course", sa.Text(), nullable=True),
        sa.Column("created_at", t.time, nullable=False),
        sa.Column("result_json", sa.Text(), nullable=False),
        sa.CheckConstraint("length(content_sha256) = 64"),
        sa.CheckConstraint("seconds IS NULL OR seconds > 0"),
        *t.checks("json_valid(result_json)"),
        sa.ForeignKeyConstraint(["version_id"], ["versions.id"]),
        sa.PrimaryKeyConstraint("version_id"),
    )


def _copy_previews(bind, offset: int, table_sha: dict[int, tuple[str, str]]) -> None:
    """A table's preview is keyed by its new content hash when it was walked from the content it now has."""
    for r in bind.execute(sa.text("SELECT proposal_id, table_sha256, seconds, created_at, result_json FROM "
                                  "proposal_previews")).mappings():
        old, new = table_sha.get(r["proposal_id"], (None, None))
        bind.execute(sa.text("INSERT INTO previews (version_id, content_sha256, seconds, course, created_at, "
                             "result_json) VALUES (:v, :s, :sec, NULL, :at, :res)"),
                     {"v": r["proposal_id"], "s": new if r["table_sha256"] == old else r["table_sha256"],
                      "sec": r["seconds"], "at": r["created_at"], "res": r["result_json"]})
    op.execute(f"INSERT INTO previews (version_id, content_sha256, seconds, course, created_at, result_json) "
               f"SELECT envelope_id + {offset}, envelope_sha256, NULL, course, created_at, result_json "
               f"FROM envelope_previews")


def _alter_pg(moved: str, sha: str, parent: str) -> None:
    """PostgreSQL: each changed table gets ``version_id`` in place (its old columns, their keys and checks go)."""
    for table, nullable in (("walking_sessions", True), ("pushes", False), ("refinements", False),
                            ("gate_signoffs", False), ("withdrawals", False)):
        op.add_column(table, sa.Column("version_id", sa.Integer(), sa.ForeignKey("versions.id"), nullable=True))
        op.execute(f"UPDATE {table} SET version_id = {moved}")
        if table == "refinements":
            op.execute(f"UPDATE refinements SET parent_id = {parent}")
        if table == "gate_signoffs":
            op.execute(f"UPDATE gate_signoffs SET content_sha256 = {sha}")
        if not nullable:
            op.alter_column(table, "version_id", nullable=False)
        op.drop_column(table, "proposal_id")
        op.drop_column(table, "envelope_id")
    op.create_index("pushes_by_version", "pushes", ["version_id"])
    op.create_unique_constraint("refinements_version_id_key", "refinements", ["version_id"])
    op.create_unique_constraint("gate_signoffs_version_id_user_id_key", "gate_signoffs", ["version_id", "user_id"])
    op.create_unique_constraint("withdrawals_version_id_key", "withdrawals", ["version_id"])


def _rebuild_sqlite(t: _Types, moved: str, sha: str, parent: str) -> None:
    """SQLite: each changed table made anew with ``version_id``, its rows copied, the old one dropped, the new one
    renamed (foreign keys are not enforced while migrating), then its indexes."""
    def time(name: str, nullable: bool = False) -> sa.Column:
        return sa.Column(name, t.time, nullable=nullable)

    new = {
        "walking_sessions": [
            sa.Column("id", sa.Integer(), nullable=False),
            sa.Column("patient_id", sa.Integer(), nullable=False),
            sa.Column("device_id", sa.Text(), nullable=False),
            sa.Column("version_id", sa.Integer(), nullable=True),
            sa.Column("table_version", sa.Integer(), nullable=True),
            sa.Column("table_crc32", t.crc, nullable=True),
            sa.Column("speed_mps", t.float, nullable=False),
            sa.Column("incline_deg", t.float, nullable=False),
            sa.Column("body_mass_kg", t.float, nullable=False),
            sa.Column("status", sa.Text(), nullable=False),
            sa.Column("started_by", sa.Integer(), nullable=False),
            time("started_at"),
            sa.Column("stopped_by", sa.Integer(), nullable=True),
            time("stopped_at", True),
            sa.Column("summary_json", sa.Text(), nullable=True),
            sa.Column("course", sa.Text(), nullable=True),
            t.flag("simulated", nullable=True, column_check=True),
            sa.CheckConstraint("speed_mps > 0 AND speed_mps <= 3"),
            sa.CheckConstraint("incline_deg BETWEEN -20 AND 20"),
            sa.CheckConstraint("body_mass_kg BETWEEN 20 AND 200"),
            sa.CheckConstraint("status IN ('recording', 'stopped')"),
            sa.ForeignKeyConstraint(["patient_id"], ["patients.id"]),
            sa.ForeignKeyConstraint(["device_id"], ["devices.id"]),
            sa.ForeignKeyConstraint(["version_id"], ["versions.id"]),
            sa.ForeignKeyConstraint(["started_by"], ["users.id"]),
            sa.ForeignKeyConstraint(["stopped_by"], ["users.id"]),
            sa.PrimaryKeyConstraint("id"),
        ],
        "pushes": [
            sa.Column("id", sa.Integer(), nullable=False),
            sa.Column("version_id", sa.Integer(), nullable=False),
            sa.Column("device_id", sa.Text(), nullable=False),
            sa.Column("table_version", sa.Integer(), nullable=False),
            sa.Column("crc32", t.crc, nullable=False),
            sa.Column("status", sa.Text(), nullable=False),
            sa.Column("requested_by", sa.Integer(), nullable=False),
            time("requested_at"), time("acknowledged_at", True), time("active_at", True), time("ended_at", True),
            sa.Column("attempts", sa.Integer(), nullable=True),
            sa.Column("elapsed_ms", t.float, nullable=True),
            sa.Column("error", sa.Text(), nullable=True),
            sa.Column("override_reason", sa.Text(), nullable=True),
            sa.Column("sent_back_reason", sa.Text(), nullable=True),
            sa.Column("instance_name", sa.Text(), nullable=True),
            sa.CheckConstraint("table_version BETWEEN 1 AND 65535"),
            sa.CheckConstraint("crc32 BETWEEN 0 AND 4294967295"),
            sa.CheckConstraint("status IN ('sending', 'unconfirmed', 'acknowledged', 'active', 'failed', 'superseded', "
                               "'lost')"),
            sa.ForeignKeyConstraint(["version_id"], ["versions.id"]),
            sa.ForeignKeyConstraint(["device_id"], ["devices.id"]),
            sa.ForeignKeyConstraint(["requested_by"], ["users.id"]),
            sa.PrimaryKeyConstraint("id"),
        ],
        "refinements": [
            sa.Column("id", sa.Integer(), nullable=False),
            sa.Column("version_id", sa.Integer(), nullable=False),
            sa.Column("parent_id", sa.Integer(), nullable=False),
            sa.Column("session_ids_json", sa.Text(), nullable=False),
            sa.Column("evidence_json", sa.Text(), nullable=False),
            sa.Column("created_by", sa.Integer(), nullable=False),
            time("created_at"),
            sa.CheckConstraint("json_valid(session_ids_json)"),
            sa.CheckConstraint("json_valid(evidence_json)"),
            sa.ForeignKeyConstraint(["version_id"], ["versions.id"]),
            sa.ForeignKeyConstraint(["created_by"], ["users.id"]),
            sa.PrimaryKeyConstraint("id"),
            sa.UniqueConstraint("version_id"),
        ],
        "gate_signoffs": [
            sa.Column("id", sa.Integer(), nullable=False),
            sa.Column("version_id", sa.Integer(), nullable=False),
            sa.Column("content_sha256", sa.Text(), nullable=False),
            sa.Column("user_id", sa.Integer(), nullable=False),
            sa.Column("reason", sa.Text(), nullable=False),
            time("signed_at"),
            sa.CheckConstraint("length(content_sha256) = 64"),
            sa.ForeignKeyConstraint(["version_id"], ["versions.id"]),
            sa.ForeignKeyConstraint(["user_id"], ["users.id"]),
            sa.PrimaryKeyConstraint("id"),
            sa.UniqueConstraint("version_id", "user_id"),
        ],
        "withdrawals": [
            sa.Column("id", sa.Integer(), nullable=False),
            sa.Column("version_id", sa.Integer(), nullable=False),
            sa.Column("user_id", sa.Integer(), nullable=False),
            sa.Column("reason", sa.Text(), nullable=False),
            time("withdrawn_at"),
            sa.ForeignKeyConstraint(["version_id"], ["versions.id"]),
            sa.ForeignKeyConstraint(["user_id"], ["users.id"]),
            sa.PrimaryKeyConstraint("id"),
            sa.UniqueConstraint("version_id"),
        ],
    }
    special = {"version_id": moved, "content_sha256": sha, "parent_id": parent}
    for table, columns in new.items():
        op.create_table(f"{table}_0021", *columns)
        names = [c.name for c in columns if isinstance(c, sa.Column)]
        source = ", ".join(special.get(n, n) if n in special else n for n in names)
        op.execute(f"INSERT INTO {table}_0021 ({', '.join(names)}) SELECT {source} FROM {table}")
        op.drop_table(table)
        op.rename_table(f"{table}_0021", table)
    op.create_index("sessions_by_patient", "walking_sessions", ["patient_id", "id"])
    op.create_index("one_recording_session_per_device", "walking_sessions", ["device_id"], unique=True,
                    sqlite_where=sa.text("status = 'recording'"))
    op.create_index("pushes_by_version", "pushes", ["version_id"])
    op.create_index("pushes_by_device", "pushes", ["device_id", "status"])
    op.create_index("one_push_sending_per_device", "pushes", ["device_id"], unique=True,
                    sqlite_where=sa.text("status = 'sending'"))


def _create_version_triggers(pg: bool) -> None:
    for name, event, when, message in VERSION_TRIGGERS:
        table = "legacy_ids" if name.startswith("legacy") else "versions"
        quoted = message.replace("'", "''")
        if pg:        # quasitune_refuse: revision 0012
            condition = f" WHEN ({when})" if when else ""
            op.execute(f"CREATE TRIGGER {name} BEFORE {event} ON {table} FOR EACH ROW{condition} "
                       f"EXECUTE FUNCTION quasitune_refuse('{quoted}')")
        else:
            condition = f" WHEN {when}" if when else ""
            op.execute(f"CREATE TRIGGER {name} BEFORE {event} ON {table}{condition} "
                       f"BEGIN SELECT RAISE(ABORT, '{quoted}'); END")


def downgrade() -> None:
    raise NotImplementedError("QuasiTune's schema only moves forward: restore a backup to go back (the README's "
                              "upgrade note: copy the database file, or pg_dump, before starting this release)")
