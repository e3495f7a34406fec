-- Safety and trust (issue 20). A device is assigned to the patient wearing it: pushes and walking sessions must
-- be for that patient, and the assignment is changed deliberately (audited). The table version sent on the
-- wire is the device's own 16-bit counter (1..65535, then 1 again), no longer a database id: ids grow for ever.
-- A push that the device acknowledged but never ran can be superseded too (see backend/store/pushes.py).

ALTER TABLE devices ADD COLUMN patient_id INTEGER REFERENCES patients (id);
ALTER TABLE devices ADD COLUMN assigned_by INTEGER REFERENCES users (id);
ALTER TABLE devices ADD COLUMN assigned_at TEXT;
ALTER TABLE devices ADD COLUMN last_wire_version INTEGER NOT NULL DEFAULT 0
    CHECK (last_wire_version BETWEEN 0 AND 65535);

-- the counter starts where the old scheme (the proposal id) left off, so a device's running table keeps meaning
UPDATE devices SET last_wire_version = coalesce(
    (SELECT max(table_version) FROM pushes WHERE pushes.device_id = devices.id), 0);
