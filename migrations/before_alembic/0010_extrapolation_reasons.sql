-- A version requested beyond the tasks the model knows (its data's range plus the stated margin,
-- controller_core/known_range.py) carries the prosthetist's written reason for extrapolating, set when the version
-- is created (an edit inherits its parent's) and never changed.

ALTER TABLE proposals ADD COLUMN extrapolation_reason TEXT;
ALTER TABLE envelopes ADD COLUMN extrapolation_reason TEXT;

CREATE TRIGGER proposals_extrapolation_reason_kept
BEFORE UPDATE OF extrapolation_reason ON proposals
BEGIN
    SELECT RAISE(ABORT, 'a version''s extrapolation reason is kept as written');
END;

CREATE TRIGGER envelopes_extrapolation_reason_kept
BEFORE UPDATE OF extrapolation_reason ON envelopes
BEGIN
    SELECT RAISE(ABORT, 'a version''s extrapolation reason is kept as written');
END;
