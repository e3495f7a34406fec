"""Storage: one module per resource. Each write is one ``BEGIN IMMEDIATE`` transaction that also appends
its audit entry, so a change and its audit record are stored together or not at all."""
