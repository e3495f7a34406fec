-- Simulated previews of proposals (the dashboard issue): the proposal's table and the FSMIC benchmark walked on
-- the MuJoCo bench at the proposal's task. A proposal never changes, so its preview is computed once and kept;
-- table_sha256 records which table was simulated (a mismatch with the proposal is refused when read).

CREATE TABLE proposal_previews (
    proposal_id   INTEGER PRIMARY KEY REFERENCES proposals (id),
    table_sha256  TEXT    NOT NULL CHECK (length(table_sha256) = 64),
    seconds       REAL    NOT NULL CHECK (seconds > 0),
    created_at    TEXT    NOT NULL,
    result_json   TEXT    NOT NULL CHECK (json_valid(result_json))
);
