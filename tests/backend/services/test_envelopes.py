"""Envelopes: stored as canonical JSON keyed by its sha256 with the wire CRC the device will read back, shown node by
node, refused at a read where the hash no longer matches."""

from __future__ import annotations

import json

import pytest

from backend.errors import ConflictError, NotFoundError
from backend.services import envelopes
from backend.store import versions
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
    row = versions.get_row(conn, "envelope", out["id"])
    assert row["content_json"] == canonical_json(checked.item)
    assert out["envelope_sha256"] == content_sha256(row["content_json"]) and out["wire_crc32"] == checked.wire_crc32
    assert versions.stored_envelope(row) == checked.item and out["safety"]["ok"]
    assert out["envelope_label"] == versions.version_label("envelope", "P-1", 1)


def test_a_row_from_an_older_release_with_a_json_crc_is_read(conn, stored):
    envelope, out = stored
    legacy = json.dumps({**as_run(envelope).item.to_json(), "crc32": 123}, sort_keys=True)
    drop_trigger(conn, "versions_content_immutable", "versions")
    sql(conn, "UPDATE versions SET content_json = :body, content_sha256 = :sha WHERE id = :id",
        body=legacy, sha=content_sha256(legacy), id=out["id"])
    assert versions.stored_envelope(versions.get_row(conn, "envelope", out["id"])) == as_run(envelope).item


def test_content_changed_in_storage_is_refused(conn, stored):
    _, out = stored
    drop_trigger(conn, "versions_content_immutable", "versions")
    sql(conn, "UPDATE versions SET content_json = content_json || ' ' WHERE id = :id", id=out["id"])
    with pytest.raises(ConflictError, match="does not match its sha256"):
        envelopes.get_envelope(conn, out["id"])


def test_a_node_is_shown_as_stored_and_a_missing_one_is_named(conn, stored):
    _, out = stored
    row = versions.get_row(conn, "envelope", out["id"])
    env = versions.stored_envelope(row)
    view = envelopes.node_view(row, env, 1, 0)
    assert view["task"] == {"speed_mps": 1.4, "incline_deg": -5.0, "body_mass_kg": 80.0} and view["safety"]["ok"]
    with pytest.raises(NotFoundError, match=r"\[0..1\] × \[0..1\]"):
        envelopes.node_view(row, env, 2, 0)
