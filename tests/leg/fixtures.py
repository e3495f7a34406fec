"""The learned table and envelope the leg's tests walk, as the server proposes them for a 75 kg patient on the reference
leg (the leg's environment has no model: these files carry them over). Written by
``.venv/bin/python -m tests.leg.fixtures`` in the server's environment; ``tests/device_bridge/osl/test_leg_fixtures.py``
fails when the model would propose something else."""

from __future__ import annotations

from pathlib import Path

DATA = Path(__file__).with_name("data")
TABLE = DATA / "table_1.2mps_level_75kg.json"
ENVELOPE = DATA / "envelope_default_75kg.json"


def proposed() -> tuple[str, str]:
    """(table JSON, envelope JSON) as the model proposes them now (the server's environment only)."""
    from controller_core.model_io import load_default_model
    from device_bridge.bench.controllers import default_envelope

    model = load_default_model()
    table = model.propose(1.2, 0.0, 75.0).table
    return table.model_dump_json(indent=1), default_envelope(model, 75.0).model_dump_json(indent=1)


def main() -> None:
    table, envelope = proposed()
    TABLE.write_text(table + "\n")
    ENVELOPE.write_text(envelope + "\n")
    print(f"wrote {TABLE} and {ENVELOPE}")


if __name__ == "__main__":
    main()
