-- Envelopes on the leg (issue 24). A push now carries either an approved proposal's table or an approved envelope:
-- exactly one of proposal_id and envelope_id is set. SQLite cannot relax a NOT NULL column in place, so the pushes
-- table is rebuilt with every row kept (nothing references pushes; its indexes and trigger are recreated).
-- A walking session records the envelope on the leg and the course the simulated leg walked, and each sample the
-- leg's task telemetry: its estimate (NULL before one), where its rows are blended, and the adaptive mode. The
-- preview of an envelope on the bench course is kept like a proposal's.

CREATE TABLE pushes_rebuilt (
    id              INTEGER PRIMARY KEY,
    proposal_id     INTEGER REFERENCES proposals (id),
    envelope_id     INTEGER REFERENCES envelopes (id),
    device_id       TEXT    NOT NULL REFERENCES devices (id),
    table_version   INTEGER NOT NULL CHECK (table_version BETWEEN 1 AND 65535),
    crc32           INTEGER NOT NULL CHECK (crc32 BETWEEN 0 AND 4294967295),
    status          TEXT    NOT NULL CHECK (status IN ('sending', 'acknowledged', 'active', 'failed', 'superseded')),
    requested_by    INTEGER NOT NULL REFERENCES users (id),
    requested_at    TEXT    NOT NULL,
    acknowledged_at TEXT,
    active_at       TEXT,
    ended_at        TEXT,
    attempts        INTEGER,
    elapsed_ms      REAL,
    error           TEXT,
    CHECK ((proposal_id IS NULL) <> (envelope_id IS NULL))
);
INSERT INTO pushes_rebuilt (id, proposal_id, device_id, table_version, crc32, status, requested_by, requested_at,
                            acknowledged_at, active_at, ended_at, attempts, elapsed_ms, error)
    SELECT id, proposal_id, device_id, table_version, crc32, status, requested_by, requested_at, acknowledged_at,
           active_at, ended_at, attempts, elapsed_ms, error FROM pushes;
DROP TABLE pushes;
ALTER TABLE pushes_rebuilt RENAME TO pushes;
CREATE INDEX pushes_by_proposal ON pushes (proposal_id);
CREATE INDEX pushes_by_envelope ON pushes (envelope_id);
CREATE INDEX pushes_by_device ON pushes (device_id, status);

CREATE TRIGGER pushes_never_deleted
BEFORE DELETE ON pushes
BEGIN
    SELECT RAISE(ABORT, 'pushes are never deleted');
END;

ALTER TABLE walking_sessions ADD COLUMN envelope_id INTEGER REFERENCES envelopes (id);
ALTER TABLE walking_sessions ADD COLUMN course TEXT;

ALTER TABLE session_samples ADD COLUMN estimated_speed_mps REAL;
ALTER TABLE session_samples ADD COLUMN estimated_incline_deg REAL;
ALTER TABLE session_samples ADD COLUMN running_speed_mps REAL;
ALTER TABLE session_samples ADD COLUMN running_incline_deg REAL;
ALTER TABLE session_samples ADD COLUMN adaptive_mode TEXT
    CHECK (adaptive_mode IS NULL OR adaptive_mode IN ('nominal', 'partial', 'adaptive', 'clamped', 'unknown'));

-- The simulated preview of an envelope: the bench's varying-task course walked with the envelope (the leg adapting)
-- and with the FSMIC, computed once (an envelope never changes); envelope_sha256 records which envelope was walked.
CREATE TABLE envelope_previews (
    envelope_id     INTEGER PRIMARY KEY REFERENCES envelopes (id),
    envelope_sha256 TEXT    NOT NULL CHECK (length(envelope_sha256) = 64),
    course          TEXT    NOT NULL,
    created_at      TEXT    NOT NULL,
    result_json     TEXT    NOT NULL CHECK (json_valid(result_json))
);
