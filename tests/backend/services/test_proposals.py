"""Proposals: created and edited as the device will run them, stored proved by their hash and refused at a read where
it no longer matches."""

from __future__ import annotations

import pytest

from backend.errors import ConflictError
from backend.services import proposals
from backend.store import versions
from controller_core.content import canonical_json, content_sha256
from controller_core.envelope import envelope_of_table
from device_bridge.as_run import as_run
from tests.helpers.sql import drop_trigger, sql


def test_a_proposal_is_stored_as_the_device_will_run_it(conn, prosthetist, patient, model):
    proposal = model.propose(1.2, 0.0, 80.0)
    out = proposals.create_from_model(conn, patient["id"], proposal, prosthetist)
    row = versions.get_row(conn, "proposal", out["id"])
    stored = versions.stored_table(row)
    assert stored == as_run(proposal.table).item and row["content_json"] == canonical_json(envelope_of_table(stored))
    assert (row["kind"], row["n_speeds"], row["n_inclines"]) == ("table", 1, 1)     # the envelope of one node
    assert row["content_sha256"] == content_sha256(row["content_json"]) == out["table_sha256"]
    assert out["status"] == "draft" and out["version"] == 1 and out["safety"]["ok"]
    assert versions.version_label("table", "P-1", 1) in out["table_label"]


def test_a_table_changed_in_storage_is_refused_at_read(conn, prosthetist, patient, model):
    out = proposals.create_from_model(conn, patient["id"], model.propose(1.2, 0.0, 80.0), prosthetist)
    drop_trigger(conn, "versions_content_immutable", "versions")      # what a tampered database could hold
    sql(conn, "UPDATE versions SET content_json = replace(content_json, '\"theta_e_deg\":', '\"theta_e_deg\": ') "
        "WHERE id = :id", id=out["id"])
    with pytest.raises(ConflictError, match="does not match its sha256"):
        proposals.get_proposal(conn, out["id"])


def test_an_edit_is_a_new_draft_with_its_parent_and_the_diff_names_each_change(conn, prosthetist, patient, model):
    parent = proposals.create_from_model(conn, patient["id"], model.propose(1.2, 0.0, 80.0), prosthetist)
    table = versions.stored_table(versions.get_row(conn, "proposal", parent["id"]))
    first = table.rows[0]
    edited = table.model_copy(update={"rows": [first.model_copy(update={"k_Nm_per_rad": first.k_Nm_per_rad - 20.0}),
                                               *table.rows[1:]]})
    field = f"{first.joint}.{first.subphase}.k_Nm_per_rad"
    changes = [{"field": field, "before": first.k_Nm_per_rad, "after": first.k_Nm_per_rad - 20.0}]
    child = proposals.create_edit(conn, parent["id"], as_run(edited), changes, "firmer landing",
                                  prosthetist)
    assert (child["parent_id"], child["source"], child["version"]) == (parent["id"], "edit", 2)
    d = proposals.diff(conn, parent["id"], child["id"])
    [change] = [c for c in d["changes"] if c["field"] == f"{first.joint}.{first.subphase}.k_Nm_per_rad"]
    assert change["after"] - change["before"] == pytest.approx(-20.0, abs=1e-3)
