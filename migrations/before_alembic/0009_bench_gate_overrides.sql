-- Approval and push rest on the bench's verdict for exactly the version's content. Where a prosthetist goes ahead
-- anyway (no preview yet, or a preview with an unsafe figure), the written reason is kept with the decision or the
-- push, decided once like the decision itself.

ALTER TABLE proposals ADD COLUMN decision_override TEXT;
ALTER TABLE envelopes ADD COLUMN decision_override TEXT;
ALTER TABLE pushes ADD COLUMN override_reason TEXT;

CREATE TRIGGER proposals_override_decided_once
BEFORE UPDATE OF decision_override ON proposals
WHEN OLD.status <> 'draft'
BEGIN
    SELECT RAISE(ABORT, 'proposal has already been approved or rejected');
END;

CREATE TRIGGER envelopes_override_decided_once
BEFORE UPDATE OF decision_override ON envelopes
WHEN OLD.status <> 'draft'
BEGIN
    SELECT RAISE(ABORT, 'envelope has already been approved or rejected');
END;

CREATE TRIGGER pushes_override_kept
BEFORE UPDATE OF override_reason ON pushes
BEGIN
    SELECT RAISE(ABORT, 'a push''s override reason is kept as written');
END;
