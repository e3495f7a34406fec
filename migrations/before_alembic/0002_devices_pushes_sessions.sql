-- Devices, table pushes and walking sessions (the device-bridge issue).
-- A push records one attempt to put an approved proposal's table on a device, and its fate:
--   sending -> acknowledged (the device read back the exact CRC-32) -> active (its status reports that CRC running)
--   sending -> failed (no acknowledgement; the device keeps its previous table)
--   active  -> superseded (another table became active on that device)
-- The proposal row itself never changes: "pushed" and "active on device" are read from here.

CREATE TABLE devices (
    id            TEXT PRIMARY KEY CHECK (length(id) BETWEEN 1 AND 64),
    kind          TEXT NOT NULL CHECK (kind IN ('simulated', 'can')),
    interface     TEXT NOT NULL,
    channel       TEXT NOT NULL,
    registered_at TEXT NOT NULL
);

CREATE TABLE pushes (
    id              INTEGER PRIMARY KEY,
    proposal_id     INTEGER NOT NULL REFERENCES proposals (id),
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
    error           TEXT
);
CREATE INDEX pushes_by_proposal ON pushes (proposal_id);
CREATE INDEX pushes_by_device ON pushes (device_id, status);

CREATE TRIGGER pushes_never_deleted
BEFORE DELETE ON pushes
BEGIN
    SELECT RAISE(ABORT, 'pushes are never deleted');
END;

CREATE TABLE walking_sessions (
    id            INTEGER PRIMARY KEY,
    patient_id    INTEGER NOT NULL REFERENCES patients (id),
    device_id     TEXT    NOT NULL REFERENCES devices (id),
    proposal_id   INTEGER REFERENCES proposals (id),
    table_version INTEGER,
    table_crc32   INTEGER,
    speed_mps     REAL    NOT NULL CHECK (speed_mps > 0 AND speed_mps <= 3),
    incline_deg   REAL    NOT NULL CHECK (incline_deg BETWEEN -20 AND 20),
    body_mass_kg  REAL    NOT NULL CHECK (body_mass_kg BETWEEN 20 AND 200),
    status        TEXT    NOT NULL CHECK (status IN ('recording', 'stopped')),
    started_by    INTEGER NOT NULL REFERENCES users (id),
    started_at    TEXT    NOT NULL,
    stopped_by    INTEGER REFERENCES users (id),
    stopped_at    TEXT,
    summary_json  TEXT
);
CREATE INDEX sessions_by_patient ON walking_sessions (patient_id, id);
CREATE UNIQUE INDEX one_recording_session_per_device ON walking_sessions (device_id) WHERE status = 'recording';

CREATE TRIGGER sessions_stopped_once
BEFORE UPDATE ON walking_sessions
WHEN OLD.status = 'stopped'
BEGIN
    SELECT RAISE(ABORT, 'a stopped session is final');
END;

-- telemetry samples as the device sent them (SI), one row per sample
CREATE TABLE session_samples (
    session_id           INTEGER NOT NULL REFERENCES walking_sessions (id),
    seq                  INTEGER NOT NULL,
    t_s                  REAL    NOT NULL,
    mode                 INTEGER NOT NULL,
    fsm_state            INTEGER,
    knee_angle_rad       REAL    NOT NULL,
    knee_velocity_rad_s  REAL    NOT NULL,
    knee_torque_Nm       REAL    NOT NULL,
    ankle_angle_rad      REAL    NOT NULL,
    ankle_velocity_rad_s REAL    NOT NULL,
    ankle_torque_Nm      REAL    NOT NULL,
    load_N               REAL    NOT NULL,
    ankle_moment_Nm      REAL    NOT NULL,
    PRIMARY KEY (session_id, seq)
) WITHOUT ROWID;

CREATE TRIGGER session_samples_append_only
BEFORE UPDATE ON session_samples
BEGIN
    SELECT RAISE(ABORT, 'recorded samples never change');
END;
