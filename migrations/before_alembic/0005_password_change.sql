-- Accounts a security reviewer expects (issue 20 item 9). A password someone else chose (the one-time password
-- printed at first start, or one an admin typed for a new user) must be changed by its user before anything else
-- works; the time of the last change is kept for the account list.

ALTER TABLE users ADD COLUMN must_change_password INTEGER NOT NULL DEFAULT 0
    CHECK (must_change_password IN (0, 1));
ALTER TABLE users ADD COLUMN password_changed_at TEXT;
