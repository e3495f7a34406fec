"""The database's tables, defined once (SQLAlchemy Core metadata): columns, keys, checks and indexes.

This is the schema the shipped migrations build, column for column (``tests/backend/store/test_tables.py`` compares it
with a database they made, through Alembic's own comparison and the reflected checks). What metadata cannot say lives
with the migrations: the triggers that keep versions, decisions, pushes, sessions and the audit log immutable.

Checks that need SQLite's JSON functions apply on SQLite only (``ddl_if``); the user-name collation is SQLite's
``NOCASE``. Times are timestamps and flags booleans (``backend.store.column_types``: on SQLite, which has neither,
ISO-8601 text and checked 0/1 integers), angles and speeds SI floats.
"""

from __future__ import annotations

from sqlalchemy import (
    BigInteger,
    CheckConstraint,
    Column,
    Double,
    ForeignKey,
    Index,
    Integer,
    LargeBinary,
    MetaData,
    PrimaryKeyConstraint,
    Table,
    Text,
    UniqueConstraint,
    false,
    text,
)
from sqlalchemy.dialects.sqlite import REAL

from backend.store.column_types import Flag, Timestamp

metadata = MetaData()

_Float = Double().with_variant(REAL(), "sqlite")            # SI floats, 8 bytes on every database (SQLite's REAL)
_Crc32 = Integer().with_variant(BigInteger(), "postgresql")  # 0 … 2³²−1 does not fit a signed 32-bit integer
_FALSE = false()            # a flag's default: false on PostgreSQL, 0 on SQLite


def _json_check(column: str) -> CheckConstraint:
    """The column holds valid JSON (SQLite's ``json_valid``; on a server database the application writes it)."""
    return CheckConstraint(f"json_valid({column})").ddl_if(dialect="sqlite")


def _flag(name: str) -> CheckConstraint:
    """A flag is 0 or 1 (SQLite; PostgreSQL's boolean is nothing else)."""
    return CheckConstraint(f"{name} IN (0, 1)").ddl_if(dialect="sqlite")


users = Table(
    "users", metadata,
    Column("id", Integer, primary_key=True),
    Column("username", Text().with_variant(Text(collation="NOCASE"), "sqlite"), nullable=False, unique=True),
    Column("role", Text, nullable=False),
    Column("password_hash", Text, nullable=False),
    Column("created_at", Timestamp, nullable=False),
    Column("disabled", Flag, nullable=False, server_default=_FALSE),
    Column("must_change_password", Flag, nullable=False, server_default=_FALSE),
    Column("password_changed_at", Timestamp),
    CheckConstraint("length(username) BETWEEN 1 AND 64"),
    CheckConstraint("role IN ('prosthetist', 'viewer', 'admin')"),
    _flag("disabled"), _flag("must_change_password"),
)

tokens = Table(
    "tokens", metadata,
    Column("token_sha256", Text, primary_key=True),
    Column("user_id", Integer, ForeignKey("users.id"), nullable=False),
    Column("issued_at", Timestamp, nullable=False),
    Column("expires_at_unix", _Float, nullable=False),
    Index("tokens_by_expiry", "expires_at_unix"),
)

patients = Table(
    "patients", metadata,
    Column("id", Integer, primary_key=True),
    Column("code_name", Text, nullable=False, unique=True),
    Column("body_mass_kg", _Float, nullable=False),
    Column("height_m", _Float),
    Column("side", Text, nullable=False),
    Column("k_level", Integer),
    Column("notes", Text, nullable=False, server_default=text("''")),
    Column("leg_json", Text),        # the patient's leg (a leg file's description; NULL: none given), revision 0019
    Column("created_by", Integer, ForeignKey("users.id"), nullable=False),
    Column("created_at", Timestamp, nullable=False),
    Column("updated_at", Timestamp, nullable=False),
    CheckConstraint("length(code_name) BETWEEN 1 AND 64"),
    CheckConstraint("body_mass_kg BETWEEN 20 AND 200"),
    CheckConstraint("height_m IS NULL OR height_m BETWEEN 0.5 AND 2.5"),
    CheckConstraint("side IN ('left', 'right')"),
    CheckConstraint("k_level IS NULL OR k_level BETWEEN 0 AND 4"),
    CheckConstraint("length(notes) <= 4000"),
    CheckConstraint("leg_json IS NULL OR json_valid(leg_json)").ddl_if(dialect="sqlite"),
)


def _decision_columns() -> list:
    return [
        Column("edit_comment", Text),
        Column("created_by", Integer, ForeignKey("users.id"), nullable=False),
        Column("created_at", Timestamp, nullable=False),
        Column("status", Text, nullable=False, server_default="draft"),
        Column("decided_by", Integer, ForeignKey("users.id")),
        Column("decided_at", Timestamp),
        Column("decision_comment", Text),
        Column("decision_override", Text),
        Column("extrapolation_reason", Text),
        # the leg it was made for and its bench walks walk (a leg file's description; '{}': the nominal leg)
        Column("leg_json", Text, nullable=False, server_default="{}"),
    ]


# a patient's parameters, one version each (revision 0021): an envelope over a speed × incline grid, of which a
# fixed-task table is the one-node case (1 × 1); what the clinic calls it ("table" or "envelope") is numbered apart,
# as before (the patient's table v3 and envelope v3 are two versions)
versions = Table(
    "versions", metadata,
    Column("id", Integer, primary_key=True),
    Column("patient_id", Integer, ForeignKey("patients.id"), nullable=False),
    Column("kind", Text, nullable=False),           # 'table': one task (1 × 1); 'envelope': a range of tasks
    Column("version", Integer, nullable=False),
    Column("parent_id", Integer, ForeignKey("versions.id")),
    Column("source", Text, nullable=False),
    Column("n_speeds", Integer, nullable=False),
    Column("n_inclines", Integer, nullable=False),
    Column("speed_mps", _Float, nullable=False),    # its task (a range's nominal task)
    Column("incline_deg", _Float, nullable=False),
    Column("body_mass_kg", _Float, nullable=False),
    Column("extrapolation", Flag, nullable=False),
    Column("safety_ok", Flag, nullable=False),
    Column("content_json", Text, nullable=False),   # the envelope as the device runs it (a table: its one node)
    Column("content_sha256", Text, nullable=False),
    Column("wire_crc32", _Crc32),
    Column("model_json", Text),                     # a table's model output (features, curves); none for a range
    *_decision_columns(),
    CheckConstraint("kind IN ('table', 'envelope')"),
    CheckConstraint("(kind = 'table' AND n_speeds = 1 AND n_inclines = 1) OR (kind = 'envelope' AND n_speeds BETWEEN 2 "
                    "AND 15 AND n_inclines BETWEEN 2 AND 15 AND n_speeds * n_inclines <= 64)"),
    CheckConstraint("speed_mps > 0 AND speed_mps <= 3"),
    CheckConstraint("incline_deg BETWEEN -20 AND 20"),
    CheckConstraint("version >= 1"),
    CheckConstraint("source IN ('model', 'edit')"),
    CheckConstraint("body_mass_kg BETWEEN 20 AND 200"),
    _flag("extrapolation"), _flag("safety_ok"),
    CheckConstraint("status IN ('draft', 'approved', 'rejected')"),
    UniqueConstraint("patient_id", "kind", "version"),
    _json_check("content_json"), _json_check("leg_json"),
)

# the ids versions had before revision 0021 (a table's proposal id, an envelope's envelope id): audit rows written
# before it name them, and an old envelope link is sent on to its version
legacy_ids = Table(
    "legacy_ids", metadata,
    Column("kind", Text, nullable=False),
    Column("old_id", Integer, nullable=False),
    Column("version_id", Integer, ForeignKey("versions.id"), nullable=False, unique=True),
    CheckConstraint("kind IN ('proposal', 'envelope')"),
    PrimaryKeyConstraint("kind", "old_id"),
)

audit_log = Table(
    "audit_log", metadata,
    Column("id", Integer, primary_key=True),
    Column("at", Timestamp, nullable=False),
    Column("actor_id", Integer, ForeignKey("users.id")),
    Column("actor_name", Text, nullable=False),
    Column("action", Text, nullable=False),
    Column("entity", Text, nullable=False),
    Column("entity_id", Integer),
    Column("before_json", Text),
    Column("after_json", Text),
    Index("audit_by_entity", "entity", "entity_id"),
)

devices = Table(
    "devices", metadata,
    Column("id", Text, primary_key=True),
    Column("kind", Text, nullable=False),
    Column("interface", Text, nullable=False),
    Column("channel", Text, nullable=False),
    Column("registered_at", Timestamp, nullable=False),
    Column("patient_id", Integer, ForeignKey("patients.id")),
    Column("assigned_by", Integer, ForeignKey("users.id")),
    Column("assigned_at", Timestamp),
    Column("last_wire_version", Integer, nullable=False, server_default="0"),
    Column("link_mode", Text, CheckConstraint("link_mode IN ('supervised', 'autonomous')"), nullable=False,
           server_default="supervised"),
    CheckConstraint("length(id) BETWEEN 1 AND 64"),
    CheckConstraint("kind IN ('simulated', 'can')"),
    CheckConstraint("last_wire_version BETWEEN 0 AND 65535"),
)

walking_sessions = Table(
    "walking_sessions", metadata,
    Column("id", Integer, primary_key=True),
    Column("patient_id", Integer, ForeignKey("patients.id"), nullable=False),
    Column("device_id", Text, ForeignKey("devices.id"), nullable=False),
    Column("version_id", Integer, ForeignKey("versions.id")),   # what the leg ran, when this server sent it
    Column("table_version", Integer),
    Column("table_crc32", _Crc32),
    Column("speed_mps", _Float, nullable=False),
    Column("incline_deg", _Float, nullable=False),
    Column("body_mass_kg", _Float, nullable=False),
    Column("status", Text, nullable=False),
    Column("started_by", Integer, ForeignKey("users.id"), nullable=False),
    Column("started_at", Timestamp, nullable=False),
    Column("stopped_by", Integer, ForeignKey("users.id")),
    Column("stopped_at", Timestamp),
    Column("summary_json", Text),
    Column("course", Text),
    # revision 0016: walked by the simulated patient on the simulated leg (1), a person on a real leg (0), or not known
    # (sessions recorded before it was kept)
    Column("simulated", Flag, CheckConstraint("simulated IN (0, 1)").ddl_if(dialect="sqlite")),
    CheckConstraint("speed_mps > 0 AND speed_mps <= 3"),
    CheckConstraint("incline_deg BETWEEN -20 AND 20"),
    CheckConstraint("body_mass_kg BETWEEN 20 AND 200"),
    CheckConstraint("status IN ('recording', 'stopped')"),
    Index("sessions_by_patient", "patient_id", "id"),
    # one recording session per device: the recorder's guarantee, held by the database
    Index("one_recording_session_per_device", "device_id", unique=True,
          sqlite_where=Column("status") == "recording", postgresql_where=Column("status") == "recording"),
)

# the session's telemetry, one row per second of walking (revision 0014): that second's samples packed into one value
# (backend.store.sample_pack); merged, never rewritten, as batches arrive (backend.store.sessions.add_samples). A rowid
# table on SQLite: its leaves hold a 2 KB value in place, where a WITHOUT ROWID table's spill past 1 KB into overflow pages
session_sample_seconds = Table(
    "session_sample_seconds", metadata,
    Column("session_id", Integer, ForeignKey("walking_sessions.id"), nullable=False),
    Column("second", Integer, nullable=False),
    Column("n", Integer, nullable=False),
    Column("samples", LargeBinary, nullable=False),
    CheckConstraint("second >= 0"),
    CheckConstraint("n BETWEEN 1 AND 100"),
    PrimaryKeyConstraint("session_id", "second"),
)

# a version's bench preview (computed once: a version never changes): a table's walk at its task, an envelope's course
previews = Table(
    "previews", metadata,
    Column("version_id", Integer, ForeignKey("versions.id"), primary_key=True, autoincrement=False),
    Column("content_sha256", Text, nullable=False),
    Column("seconds", _Float),     # a table's walk (s)
    Column("course", Text),        # an envelope's course
    Column("created_at", Timestamp, nullable=False),
    Column("result_json", Text, nullable=False),
    CheckConstraint("length(content_sha256) = 64"),
    CheckConstraint("seconds IS NULL OR seconds > 0"),
    _json_check("result_json"),
)

pushes = Table(
    "pushes", metadata,
    Column("id", Integer, primary_key=True),
    Column("version_id", Integer, ForeignKey("versions.id"), nullable=False),
    Column("device_id", Text, ForeignKey("devices.id"), nullable=False),
    Column("table_version", Integer, nullable=False),
    Column("crc32", _Crc32, nullable=False),
    Column("status", Text, nullable=False),
    Column("requested_by", Integer, ForeignKey("users.id"), nullable=False),
    Column("requested_at", Timestamp, nullable=False),
    Column("acknowledged_at", Timestamp),
    Column("active_at", Timestamp),
    Column("ended_at", Timestamp),
    Column("attempts", Integer),
    Column("elapsed_ms", _Float),
    Column("error", Text),
    Column("override_reason", Text),
    Column("sent_back_reason", Text),   # revision 0016: sent because the version the leg ran was withdrawn: which, why
    Column("instance_name", Text),      # revision 0017: the instance sending it (NULL: recorded before)
    CheckConstraint("table_version BETWEEN 1 AND 65535"),
    CheckConstraint("crc32 BETWEEN 0 AND 4294967295"),
    CheckConstraint("status IN ('sending', 'unconfirmed', 'acknowledged', 'active', 'failed', 'superseded', 'lost')"),
    Index("pushes_by_version", "version_id"),
    Index("pushes_by_device", "device_id", "status"),
    # one push on its way per device (revision 0013): the guarantee holds across API instances, not only in one process
    Index("one_push_sending_per_device", "device_id", unique=True,
          sqlite_where=Column("status") == "sending", postgresql_where=Column("status") == "sending"),
)

refinements = Table(
    "refinements", metadata,
    Column("id", Integer, primary_key=True),
    Column("version_id", Integer, ForeignKey("versions.id"), nullable=False, unique=True),   # the draft it made
    Column("parent_id", Integer, nullable=False),
    Column("session_ids_json", Text, nullable=False),
    Column("evidence_json", Text, nullable=False),
    Column("created_by", Integer, ForeignKey("users.id"), nullable=False),
    Column("created_at", Timestamp, nullable=False),
    _json_check("session_ids_json"), _json_check("evidence_json"),
)

# each API instance's last heartbeat (revision 0017, backend.instance_beat): one that stopped beating is dead
instance_beats = Table(
    "instance_beats", metadata,
    Column("name", Text, primary_key=True),
    Column("beat_at_unix", _Float, nullable=False),
)

# failed sign-ins in the last minutes (revision 0013): counted by every API instance (backend.throttle)
login_failures = Table(
    "login_failures", metadata,
    Column("id", Integer, primary_key=True),
    Column("at_unix", _Float, nullable=False),
    Column("username_key", Text, nullable=False),   # the name as typed, lower-cased (sign-in ignores case)
    Column("address", Text, nullable=False),
    Index("login_failures_by_user", "username_key", "at_unix"),
    Index("login_failures_by_address", "address", "at_unix"),
    Index("login_failures_by_time", "at_unix"),
)

# a prosthetist's sign-off on a version's bench findings (revision 0016): a version the bench did not find clean is
# approved or pushed only when two prosthetists signed off on exactly its content (backend.store.signoffs)
gate_signoffs = Table(
    "gate_signoffs", metadata,
    Column("id", Integer, primary_key=True),
    Column("version_id", Integer, ForeignKey("versions.id"), nullable=False),
    Column("content_sha256", Text, nullable=False),
    Column("user_id", Integer, ForeignKey("users.id"), nullable=False),
    Column("reason", Text, nullable=False),
    Column("signed_at", Timestamp, nullable=False),
    CheckConstraint("length(content_sha256) = 64"),
    UniqueConstraint("version_id", "user_id"),
)

# an approved version taken back (revision 0016): it is never pushed again, and a leg running it is sent back to the
# last version it ran that was not withdrawn, or to safe mode (backend.store.withdrawals)
withdrawals = Table(
    "withdrawals", metadata,
    Column("id", Integer, primary_key=True),
    Column("version_id", Integer, ForeignKey("versions.id"), nullable=False, unique=True),
    Column("user_id", Integer, ForeignKey("users.id"), nullable=False),
    Column("reason", Text, nullable=False),
    Column("withdrawn_at", Timestamp, nullable=False),
)
