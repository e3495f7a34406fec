-- Refinements from walking (issue 35): a version derived from an approved one by the leg's own strides. The derived
-- version is an ordinary draft in envelopes or proposals (source 'edit': derived from a parent, decided like any);
-- this table says it came from a refinement, from which sessions, and keeps the evidence per node and the changes,
-- as computed once. Exactly one of envelope_id and proposal_id is set; a refinement never changes and is never deleted.
CREATE TABLE refinements (
    id               INTEGER PRIMARY KEY,
    envelope_id      INTEGER UNIQUE REFERENCES envelopes (id),
    proposal_id      INTEGER UNIQUE REFERENCES proposals (id),
    parent_id        INTEGER NOT NULL,
    session_ids_json TEXT    NOT NULL CHECK (json_valid(session_ids_json)),
    evidence_json    TEXT    NOT NULL CHECK (json_valid(evidence_json)),
    created_by       INTEGER NOT NULL REFERENCES users (id),
    created_at       TEXT    NOT NULL,
    CHECK ((envelope_id IS NULL) <> (proposal_id IS NULL))
);

CREATE TRIGGER refinements_never_change
BEFORE UPDATE ON refinements
BEGIN
    SELECT RAISE(ABORT, 'a refinement never changes');
END;

CREATE TRIGGER refinements_never_deleted
BEFORE DELETE ON refinements
BEGIN
    SELECT RAISE(ABORT, 'refinements are never deleted');
END;
