"""Devices in storage: registered once, assigned to a patient, a wire version that wraps."""

from __future__ import annotations

import pytest

from backend.errors import NotFoundError
from backend.store import devices
from tests.helpers.sql import sql


def test_registration_keeps_the_first_and_assignment_is_audited(conn, prosthetist, patient):
    devices.register_device(conn, "leg", "simulated", "virtual", "a")
    devices.register_device(conn, "leg", "can", "socketcan", "can0")
    assert sql(conn, "SELECT kind FROM devices WHERE id = 'leg'").scalar() == "simulated"
    assert devices.assignment(conn, "leg") is None
    devices.assign(conn, "leg", patient["id"], prosthetist)
    a = devices.assignment(conn, "leg")
    assert (a["patient_id"], a["patient_code"], a["body_mass_kg"], a["assigned_by"]) == (patient["id"], "P-1", 80.0, "pat")
    devices.assign(conn, "leg", None, prosthetist)
    assert devices.assignment(conn, "leg") is None
    with pytest.raises(NotFoundError, match="not registered"):
        devices.assign(conn, "other", patient["id"], prosthetist)
    with pytest.raises(NotFoundError, match="patient 999"):
        devices.assign(conn, "leg", 999, prosthetist)


def test_the_wire_version_counts_to_65535_and_wraps_to_1(conn):
    devices.register_device(conn, "leg", "simulated", "virtual", "a")
    assert [devices.next_wire_version(conn, "leg") for _ in range(2)] == [1, 2]
    sql(conn, "UPDATE devices SET last_wire_version = 65535 WHERE id = 'leg'")
    assert devices.next_wire_version(conn, "leg") == 1
