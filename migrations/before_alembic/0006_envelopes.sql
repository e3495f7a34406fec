-- Envelopes (issue 24): one table per node of a speed × incline grid, approved once for a patient instead of one
-- table per task. Like proposals: immutable content, versions per patient, an edit records its parent, decided once,
-- never deleted. envelope_json is controller_core's Envelope JSON with its CRC-32; wire_crc32 is the CRC the device
-- will report for it (the values as the device runs them).

CREATE TABLE envelopes (
    id               INTEGER PRIMARY KEY,
    patient_id       INTEGER NOT NULL REFERENCES patients (id),
    version          INTEGER NOT NULL CHECK (version >= 1),
    parent_id        INTEGER REFERENCES envelopes (id),
    source           TEXT    NOT NULL CHECK (source IN ('model', 'edit')),
    body_mass_kg     REAL    NOT NULL CHECK (body_mass_kg BETWEEN 20 AND 200),
    n_speeds         INTEGER NOT NULL CHECK (n_speeds BETWEEN 2 AND 15),
    n_inclines       INTEGER NOT NULL CHECK (n_inclines BETWEEN 2 AND 15),
    extrapolation    INTEGER NOT NULL CHECK (extrapolation IN (0, 1)),
    safety_ok        INTEGER NOT NULL CHECK (safety_ok IN (0, 1)),
    envelope_json    TEXT    NOT NULL,
    envelope_sha256  TEXT    NOT NULL,
    crc32            INTEGER NOT NULL,
    wire_crc32       INTEGER,
    edit_comment     TEXT,
    created_by       INTEGER NOT NULL REFERENCES users (id),
    created_at       TEXT    NOT NULL,
    status           TEXT    NOT NULL DEFAULT 'draft' CHECK (status IN ('draft', 'approved', 'rejected')),
    decided_by       INTEGER REFERENCES users (id),
    decided_at       TEXT,
    decision_comment TEXT,
    UNIQUE (patient_id, version)
);
CREATE INDEX envelopes_by_patient ON envelopes (patient_id, version);

CREATE TRIGGER envelopes_content_immutable
BEFORE UPDATE OF patient_id, version, parent_id, source, body_mass_kg, n_speeds, n_inclines, extrapolation, safety_ok,
                 envelope_json, envelope_sha256, crc32, wire_crc32, edit_comment, created_by, created_at
ON envelopes
BEGIN
    SELECT RAISE(ABORT, 'envelope content is immutable; derive a new version instead');
END;

CREATE TRIGGER envelopes_decided_once
BEFORE UPDATE OF status, decided_by, decided_at, decision_comment ON envelopes
WHEN OLD.status <> 'draft'
BEGIN
    SELECT RAISE(ABORT, 'envelope has already been approved or rejected');
END;

CREATE TRIGGER envelopes_never_deleted
BEFORE DELETE ON envelopes
BEGIN
    SELECT RAISE(ABORT, 'envelopes are never deleted');
END;
