-- An envelope keeps one checksum of each kind: wire_crc32, the CRC-32 the device verifies and reads back, and
-- envelope_sha256, the content hash storage keys on and checks at every read. The CRC-32 of the envelope's JSON
-- (crc32) guarded nothing the sha256 does not, so it goes; every other column and row is kept.

DROP TRIGGER envelopes_content_immutable;
ALTER TABLE envelopes DROP COLUMN crc32;

CREATE TRIGGER envelopes_content_immutable
BEFORE UPDATE OF patient_id, version, parent_id, source, body_mass_kg, n_speeds, n_inclines, extrapolation, safety_ok,
                 envelope_json, envelope_sha256, wire_crc32, edit_comment, created_by, created_at
ON envelopes
BEGIN
    SELECT RAISE(ABORT, 'envelope content is immutable; derive a new version instead');
END;
