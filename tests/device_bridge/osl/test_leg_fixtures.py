"""The learned table and envelope that the leg's environment walks (tests/leg/data) are what the model proposes now."""

from __future__ import annotations

import json

import pytest

from tests.leg.fixtures import ENVELOPE, TABLE, proposed


def _numbers(value: object, path: str = "") -> dict[str, object]:
    """Every leaf of a JSON document by its path."""
    if isinstance(value, dict):
        return {k: v for key, item in value.items() for k, v in _numbers(item, f"{path}.{key}").items()}
    if isinstance(value, list):
        return {k: v for i, item in enumerate(value) for k, v in _numbers(item, f"{path}[{i}]").items()}
    return {path: value}


def test_the_leg_environments_table_and_envelope_are_the_models_own(model):
    """Regenerate with `.venv/bin/python -m tests.leg.fixtures` when the model's proposals change (every number; the
    model's version string, which changes with any edit of its code, is not compared)."""
    table, envelope = proposed()
    for stored, now in ((TABLE.read_text(), table), (ENVELOPE.read_text(), envelope)):
        a, b = _numbers(json.loads(stored)), _numbers(json.loads(now))
        assert a.keys() == b.keys()
        for key in a:
            if key.endswith(".model_version"):     # names the code that fitted it: changes with any edit of the model
                continue
            if isinstance(a[key], float):
                assert a[key] == pytest.approx(b[key], rel=1e-6, abs=1e-9), key
            else:
                assert a[key] == b[key], key
