"""The content hash storage keys on."""

from __future__ import annotations

import hashlib
import json

import pytest

from controller_core.content import canonical_json, content_sha256


@pytest.fixture
def table(model):
    return model.propose(1.2, 0.0, 75.0).table


def test_the_canonical_text_is_sorted_and_compact_and_its_hash_covers_every_value(table):
    text = canonical_json(table)
    body = json.loads(text)
    assert text == json.dumps(body, sort_keys=True, separators=(",", ":"))
    assert content_sha256(text) == hashlib.sha256(text.encode()).hexdigest()
    changed = table.model_copy(update={"rows": [table.rows[0].model_copy(update={"theta_e_deg": 5.001}),
                                                    *table.rows[1:]]})
    assert content_sha256(canonical_json(changed)) != content_sha256(text)


def test_a_value_json_cannot_carry_is_refused(table):
    broken = table.model_copy(update={"rows": [table.rows[0].model_copy(update={"r2": float("nan")}),
                                                   *table.rows[1:]]})
    with pytest.raises(ValueError):
        canonical_json(broken)
