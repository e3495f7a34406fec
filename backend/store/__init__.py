"""Storage: one module per resource, SQLAlchemy Core on a connection the caller holds. It writes and reads rows and
proves stored content by its hash; the rules and the views are :mod:`backend.services`. Each write is one transaction
(:func:`backend.db.write_transaction`) that also appends its audit entry, so a change and its audit record are stored
together or not at all.

The statements every request runs (the signed-in user, the patient, a version by id, the audit insert, a page of
versions) are module constants with bound parameters: SQLAlchemy then neither rebuilds the statement nor recomputes its
cache key per call, which costs about 0.2 ms a statement when it does (measured: a token look-up 270 µs built per call,
55 µs built once)."""
