"""Pushing an approved proposal's table to a device, and the record of every push."""

from __future__ import annotations

import time

from fastapi import APIRouter, Request, status

from backend.deps import Conn, CurrentUser, Prosthetist
from backend.devices import DeviceManager
from backend.errors import ConflictError, DeviceError, InvalidError
from backend.schemas.common import IdPath
from backend.schemas.errors import CONFLICT, DEVICE_FAILED, FORBIDDEN, NOT_FOUND, UNAUTHORIZED
from backend.schemas.pushes import PushOut, PushRequest
from backend.store import proposals
from backend.store import pushes as store
from device_bridge.host import PushError
from device_bridge.protocol import ProtocolError, WireTable, check_as_run

router = APIRouter(prefix="/api/proposals", tags=["pushes"], responses=UNAUTHORIZED)


@router.post("/{proposal_id}/push", response_model=PushOut, status_code=status.HTTP_201_CREATED,
             responses={**FORBIDDEN, **NOT_FOUND, **CONFLICT, **DEVICE_FAILED})
def push(proposal_id: IdPath, body: PushRequest, request: Request, conn: Conn, user: Prosthetist) -> dict:
    """Send an approved proposal's table to a device (prosthetist) and wait for the device to read back its exact
    CRC-32. The push is recorded first; it is ``acknowledged`` when the CRC comes back, and ``active`` (the
    proposal "active on device") when the device's status reports that table running — at the next heel strike.
    The table version on the device is the proposal id. A failed push leaves the device on its previous table."""
    devices: DeviceManager = request.app.state.devices
    row = proposals.get_row(conn, proposal_id)
    if row["status"] != "approved":
        raise ConflictError(f"proposal {proposal_id} is {row['status']}; only approved proposals can be pushed")
    device = devices.get(body.device_id)
    table = proposals.stored_table(row)
    violations = check_as_run(table)
    if violations:
        raise ConflictError(f"proposal {proposal_id} fails the safety limits; not pushed: "
                            + "; ".join(v.message for v in violations), violations=[v.model_dump() for v in violations])
    if proposal_id > 0xFFFF:
        raise ConflictError(f"proposal id {proposal_id} exceeds the 16-bit table version of the device protocol")
    try:
        crc = WireTable.from_table(table).crc32()
    except ProtocolError as exc:
        raise InvalidError(f"the table cannot be sent: {exc}") from exc
    if not devices.online(device):
        raise ConflictError(f"device {body.device_id} is offline (no status in the last second); nothing was sent")
    push_id = store.begin_push(conn, proposal_id, body.device_id, proposal_id, crc, user)
    t0 = time.monotonic()
    try:
        result = devices.push(body.device_id, table, proposal_id)
    except (PushError, ConflictError) as exc:
        store.finish_push(conn, push_id, False, None, (time.monotonic() - t0) * 1e3, str(exc))
        raise DeviceError(f"push {push_id} failed: {exc}", push=store.get_push(conn, push_id)) from exc
    store.finish_push(conn, push_id, True, result.attempts, result.elapsed_ms, None)
    return store.get_push(conn, push_id)


@router.get("/{proposal_id}/pushes", response_model=list[PushOut], responses=NOT_FOUND)
def list_pushes(proposal_id: IdPath, conn: Conn, _user: CurrentUser) -> list[dict]:
    """Every push of this proposal, newest first."""
    proposals.get_row(conn, proposal_id)
    return store.pushes_of_proposal(conn, proposal_id)
