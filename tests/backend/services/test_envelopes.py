"""Envelopes: stored as canonical JSON keyed by its sha256 with the wire CRC the device will read back, shown node by
node, refused at a read where the hash no longer matches."""

from __future__ import annotations

import json

import pytest

from backend.errors import ConflictError, NotFoundError
from backend.services import envelopes
from backend.store import envelopes as envelope_rows
from controller_core.content import canonical_json, content_sha256
from device_bridge.as_run import as_run
from tests.helpers.sql import drop_trigger, sql


@pytest.fixture
def stored(conn, prosthetist, patient, model):
    envelope = model.propose_envelope([0.8, 1.4], [-5.0, 5.0], 80.0)
    return envelope, envelopes.create_from_model(conn, patient["id"], envelope, prosthetist)


def test_an_envelope_is_stored_rounded_with_its_hash_and_wire_crc(conn, stored):
    envelope, out = stored
    checked = as_run(envelope)
    row = envelope_rows.get_row(conn, out["id"])
    assert row["envelope_json"] == canonical_json(checked.item)
    assert out["envelope_sha256"] == content_sha256(row["envelope_json"]) and out["wire_crc32"] == checked.wire_crc32
    assert envelope_rows.stored_envelope(row) == checked.item and out["safety"]["ok"]
    assert out["envelope_label"] == envelope_rows.envelope_label("P-1", 1)


def test_a_row_from_an_older_release_with_a_json_crc_is_read(conn, stored):
    envelope, out = stored
    legacy = json.dumps({**as_run(envelope).item.to_json(), "crc32": 123}, sort_keys=True)
    drop_trigger(conn, "envelopes_content_immutable", "envelopes")
    sql(conn, "UPDATE envelopes SET envelope_json = :body, envelope_sha256 = :sha WHERE id = :id",
        body=legacy, sha=content_sha256(legacy), id=out["id"])
    assert envelope_rows.stored_envelope(envelope_rows.get_row(conn, out["id"])) == as_run(envelope).item


def test_content_changed_in_storage_is_refused(conn, stored):
    _, out = stored
    drop_trigger(conn, "envelopes_content_immutable", "envelopes")
    sql(conn, "UPDATE envelopes SET envelope_json = envelope_json || ' ' WHERE id = :id", id=out["id"])
    with pytest.raises(ConflictError, match="does not match its sha256"):
        envelopes.get_envelope(conn, out["id"])


def test_a_node_is_shown_as_stored_and_a_missing_one_is_named(conn, stored):
    _, out = stored
    row = envelope_rows.get_row(conn, out["id"])
    env = envelope_rows.stored_envelope(row)
    view = envelopes.node_view(row, env, 1, 0)
    assert view["task"] == {"speed_mps": 1.4, "incline_deg": -5.0, "body_mass_kg": 80.0} and view["safety"]["ok"]
    with pytest.raises(NotFoundError, match=r"\[0..1\] × \[0..1\]"):
        envelopes.node_view(row, env, 2, 0)
