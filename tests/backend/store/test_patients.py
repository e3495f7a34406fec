"""Patients in storage: unique code names, audited changes."""

from __future__ import annotations

import pytest

from backend.errors import ConflictError, NotFoundError
from backend.store import audit, patients


def test_a_patient_is_stored_audited_and_listed(conn, prosthetist, patient):
    assert patients.get_patient(conn, patient["id"])["body_mass_kg"] == 80.0
    assert [p["code_name"] for p in patients.list_patients(conn)] == ["P-1"]
    assert audit.list_entries(conn, entity="patient")[0]["after"]["code_name"] == "P-1"
    with pytest.raises(NotFoundError):
        patients.get_patient(conn, 999)


def test_code_names_stay_unique_and_changes_are_audited_before_and_after(conn, prosthetist, patient):
    with pytest.raises(ConflictError, match="already used"):
        patients.create_patient(conn, {**{k: patient[k] for k in patients.FIELDS}}, prosthetist)
    changed = patients.update_patient(conn, patient["id"], {"body_mass_kg": 82.5}, prosthetist)
    assert changed["body_mass_kg"] == 82.5
    entry = audit.list_entries(conn, entity="patient", entity_id=patient["id"])[0]
    assert entry["before"]["body_mass_kg"] == 80.0 and entry["after"]["body_mass_kg"] == 82.5
