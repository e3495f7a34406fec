-- The device's own status is the truth about what it holds. Two push states join the five:
-- 'unconfirmed': the transfer ended without an acknowledgement (lost, or the server stopped mid-push); the device's
--   next status decides it (active or acknowledged when it reports that version and CRC, failed when it does not);
-- 'lost': the device reported running or holding this table, then reported something else without another push of
--   ours replacing it (it restarted, or lost its table).
-- SQLite cannot change a CHECK constraint in place, so the pushes table is rebuilt with every row kept.

CREATE TABLE pushes_rebuilt (
    id              INTEGER PRIMARY KEY,
    proposal_id     INTEGER REFERENCES proposals (id),
    envelope_id     INTEGER REFERENCES envelopes (id),
    device_id       TEXT    NOT NULL REFERENCES devices (id),
    table_version   INTEGER NOT NULL CHECK (table_version BETWEEN 1 AND 65535),
    crc32           INTEGER NOT NULL CHECK (crc32 BETWEEN 0 AND 4294967295),
    status          TEXT    NOT NULL CHECK (status IN ('sending', 'unconfirmed', 'acknowledged', 'active', 'failed',
                                                       'superseded', 'lost')),
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
INSERT INTO pushes_rebuilt (id, proposal_id, envelope_id, device_id, table_version, crc32, status, requested_by,
                            requested_at, acknowledged_at, active_at, ended_at, attempts, elapsed_ms, error)
    SELECT id, proposal_id, envelope_id, device_id, table_version, crc32, status, requested_by, requested_at,
           acknowledged_at, active_at, ended_at, attempts, elapsed_ms, error FROM pushes;
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
