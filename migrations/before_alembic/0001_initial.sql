-- QuasiTune initial schema: users and their bearer tokens, patients, immutable proposal versions,
-- and the append-only audit log. Times are UTC ISO-8601 text; token expiry is Unix seconds.
-- Immutability and append-only rules are enforced here by triggers, not only by the application.

CREATE TABLE users (
    id            INTEGER PRIMARY KEY,
    username      TEXT    NOT NULL UNIQUE COLLATE NOCASE CHECK (length(username) BETWEEN 1 AND 64),
    role          TEXT    NOT NULL CHECK (role IN ('prosthetist', 'viewer', 'admin')),
    password_hash TEXT    NOT NULL,
    created_at    TEXT    NOT NULL,
    disabled      INTEGER NOT NULL DEFAULT 0 CHECK (disabled IN (0, 1))
);

CREATE TABLE tokens (
    token_sha256    TEXT    PRIMARY KEY,
    user_id         INTEGER NOT NULL REFERENCES users (id),
    issued_at       TEXT    NOT NULL,
    expires_at_unix REAL    NOT NULL
);
CREATE INDEX tokens_by_expiry ON tokens (expires_at_unix);

CREATE TABLE patients (
    id           INTEGER PRIMARY KEY,
    code_name    TEXT    NOT NULL UNIQUE CHECK (length(code_name) BETWEEN 1 AND 64),
    body_mass_kg REAL    NOT NULL CHECK (body_mass_kg BETWEEN 20 AND 200),
    height_m     REAL    CHECK (height_m IS NULL OR height_m BETWEEN 0.5 AND 2.5),
    side         TEXT    NOT NULL CHECK (side IN ('left', 'right')),
    k_level      INTEGER CHECK (k_level IS NULL OR k_level BETWEEN 0 AND 4),
    notes        TEXT    NOT NULL DEFAULT '' CHECK (length(notes) <= 4000),
    created_by   INTEGER NOT NULL REFERENCES users (id),
    created_at   TEXT    NOT NULL,
    updated_at   TEXT    NOT NULL
);

-- One row per proposal version. Content columns never change; status moves draft -> approved|rejected once.
CREATE TABLE proposals (
    id               INTEGER PRIMARY KEY,
    patient_id       INTEGER NOT NULL REFERENCES patients (id),
    version          INTEGER NOT NULL CHECK (version >= 1),
    parent_id        INTEGER REFERENCES proposals (id),
    source           TEXT    NOT NULL CHECK (source IN ('model', 'edit')),
    speed_mps        REAL    NOT NULL CHECK (speed_mps > 0 AND speed_mps <= 3),
    incline_deg      REAL    NOT NULL CHECK (incline_deg BETWEEN -20 AND 20),
    body_mass_kg     REAL    NOT NULL CHECK (body_mass_kg BETWEEN 20 AND 200),
    extrapolation    INTEGER NOT NULL CHECK (extrapolation IN (0, 1)),
    safety_ok        INTEGER NOT NULL CHECK (safety_ok IN (0, 1)),
    model_json       TEXT    NOT NULL,   -- features, curves, boundaries, model provenance (display units)
    table_json       TEXT    NOT NULL,   -- controller_core ParameterTable, validated JSON
    table_sha256     TEXT    NOT NULL,
    edit_comment     TEXT,
    created_by       INTEGER NOT NULL REFERENCES users (id),
    created_at       TEXT    NOT NULL,
    status           TEXT    NOT NULL DEFAULT 'draft' CHECK (status IN ('draft', 'approved', 'rejected')),
    decided_by       INTEGER REFERENCES users (id),
    decided_at       TEXT,
    decision_comment TEXT,
    UNIQUE (patient_id, version)
);
CREATE INDEX proposals_by_patient ON proposals (patient_id, version);

CREATE TRIGGER proposals_content_immutable
BEFORE UPDATE OF patient_id, version, parent_id, source, speed_mps, incline_deg, body_mass_kg, extrapolation,
                 safety_ok, model_json, table_json, table_sha256, edit_comment, created_by, created_at
ON proposals
BEGIN
    SELECT RAISE(ABORT, 'proposal content is immutable; derive a new version instead');
END;

CREATE TRIGGER proposals_decided_once
BEFORE UPDATE OF status, decided_by, decided_at, decision_comment ON proposals
WHEN OLD.status <> 'draft'
BEGIN
    SELECT RAISE(ABORT, 'proposal has already been approved or rejected');
END;

CREATE TRIGGER proposals_never_deleted
BEFORE DELETE ON proposals
BEGIN
    SELECT RAISE(ABORT, 'proposals are never deleted');
END;

CREATE TABLE audit_log (
    id          INTEGER PRIMARY KEY,
    at          TEXT    NOT NULL,
    actor_id    INTEGER REFERENCES users (id),
    actor_name  TEXT    NOT NULL,
    action      TEXT    NOT NULL,
    entity      TEXT    NOT NULL,
    entity_id   INTEGER,
    before_json TEXT,
    after_json  TEXT
);
CREATE INDEX audit_by_entity ON audit_log (entity, entity_id);

CREATE TRIGGER audit_no_update
BEFORE UPDATE ON audit_log
BEGIN
    SELECT RAISE(ABORT, 'the audit log is append-only');
END;

CREATE TRIGGER audit_no_delete
BEFORE DELETE ON audit_log
BEGIN
    SELECT RAISE(ABORT, 'the audit log is append-only');
END;
