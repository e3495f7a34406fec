"""Pushing an approved proposal's table to a device, and the record of every push."""

from __future__ import annotations

import sqlite3
import time

from fastapi import APIRouter, Request, status

from backend.deps import Conn, CurrentUser, Prosthetist
from backend.devices import DeviceManager
from backend.errors import ConflictError, DeviceError, InvalidError
from backend.schemas.common import IdPath
from backend.schemas.errors import CONFLICT, DEVICE_FAILED, FORBIDDEN, NOT_FOUND, UNAUTHORIZED
from backend.schemas.pushes import PushOut, PushRequest
from backend.store import devices as devices_store
from backend.store import patients, proposals
from backend.store import pushes as store
from device_bridge.host import PushError
from device_bridge.protocol import ProtocolError, WireTable, check_as_run

router = APIRouter(prefix="/api/proposals", tags=["pushes"], responses=UNAUTHORIZED)

MASS_TOLERANCE = 0.02   # a table proposed for a body mass more than 2 % off the patient's current one is refused


@router.post("/{proposal_id}/push", response_model=PushOut, status_code=status.HTTP_201_CREATED,
             responses={**FORBIDDEN, **NOT_FOUND, **CONFLICT, **DEVICE_FAILED})
def push(proposal_id: IdPath, body: PushRequest, request: Request, conn: Conn, user: Prosthetist) -> dict:
    """Send an approved proposal's table to a device (prosthetist) and wait for the device to read back its exact
    CRC-32. The device must be assigned to the proposal's patient, whose body mass must still be the one the table
    was proposed for. The caller confirms what it replaces (``replaces_proposal_id``: the table they saw on the
    leg, null for none of ours; refused if the leg runs another now) and that the patient is seated or in the
    parallel bars. The push is recorded first; it is ``acknowledged`` when the CRC comes back, and ``active``
    when the device's status reports that table running — at the next heel strike. The version on the wire is
    the device's own counter. A failed push leaves the device on its previous table."""
    devices: DeviceManager = request.app.state.devices
    row = proposals.get_row(conn, proposal_id)
    if row["status"] != "approved":
        raise ConflictError(f"proposal {proposal_id} is {row['status']}; only approved proposals can be pushed")
    device = devices.get(body.device_id)
    _check_patient(conn, row, body.device_id)
    _check_replaces(conn, body)
    table = proposals.stored_table(row)
    violations = check_as_run(table)
    if violations:
        raise ConflictError(f"proposal {proposal_id} fails the safety limits; not pushed: "
                            + "; ".join(v.message for v in violations), violations=[v.model_dump() for v in violations])
    try:
        crc = WireTable.from_table(table).crc32()
    except ProtocolError as exc:
        raise InvalidError(f"the table cannot be sent: {exc}") from exc
    if not devices.online(device):
        raise ConflictError(f"device {body.device_id} is offline (no status in the last second); nothing was sent")
    push_id, version = store.begin_push(conn, proposal_id, body.device_id, crc, user)
    t0 = time.monotonic()
    try:
        result = devices.push(body.device_id, table, version)
    except (PushError, ConflictError) as exc:
        store.finish_push(conn, push_id, False, None, (time.monotonic() - t0) * 1e3, str(exc))
        raise DeviceError(f"push {push_id} failed: {exc}", push=store.get_push(conn, push_id)) from exc
    store.finish_push(conn, push_id, True, result.attempts, result.elapsed_ms, None)
    return store.get_push(conn, push_id)


def _check_patient(conn: sqlite3.Connection, row: sqlite3.Row, device_id: str) -> None:
    """The device is assigned to the proposal's patient, who still weighs what the table was proposed for."""
    patient = patients.get_patient(conn, row["patient_id"])
    assigned = devices_store.assignment(conn, device_id)
    who = f"{patient['code_name']} ({patient['body_mass_kg']:g} kg)"
    if assigned is None:
        raise ConflictError(f"device {device_id} is not assigned to a patient; assign it to {who} first (live "
                            "monitor, Device) — nothing was sent")
    if assigned["patient_id"] != row["patient_id"]:
        raise ConflictError(f"device {device_id} is assigned to {assigned['patient_code']} "
                            f"({assigned['body_mass_kg']:g} kg), not to {who} whose table this is; nothing was sent")
    if abs(patient["body_mass_kg"] - row["body_mass_kg"]) > MASS_TOLERANCE * row["body_mass_kg"]:
        raise ConflictError(f"this table was proposed for {row['body_mass_kg']:g} kg and {patient['code_name']} now "
                            f"weighs {patient['body_mass_kg']:g} kg: its torques and load thresholds scale with body "
                            "mass; propose again for the new mass. Nothing was sent")


def _check_replaces(conn: sqlite3.Connection, body: PushRequest) -> None:
    """What the caller confirmed replacing is what the leg runs (or is about to run) now."""
    current = store.current_push(conn, body.device_id)
    now_id = None if current is None else current["proposal_id"]
    if now_id != body.replaces_proposal_id:
        now = "no table from this server" if current is None else (
            f"{current['table_label']} ({current['task']['speed_mps']:g} m/s, {current['task']['incline_deg']:g}°)")
        raise ConflictError(f"device {body.device_id} now runs {now}, not what you confirmed replacing; review and "
                            "confirm again. Nothing was sent")


@router.get("/{proposal_id}/pushes", response_model=list[PushOut], responses=NOT_FOUND)
def list_pushes(proposal_id: IdPath, conn: Conn, _user: CurrentUser) -> list[dict]:
    """Every push of this proposal, newest first."""
    proposals.get_row(conn, proposal_id)
    return store.pushes_of_proposal(conn, proposal_id)
