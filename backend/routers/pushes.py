"""Pushing an approved proposal's table, or an approved envelope, to a device; and the record of every push."""

from __future__ import annotations

import time

from fastapi import APIRouter, Request, status
from sqlalchemy import Connection, RowMapping

from backend.deps import Conn, CurrentUser, Prosthetist
from backend.devices import DeviceManager
from backend.devices.manager import mass_differs
from backend.errors import ConflictError, DeviceError, InvalidError
from backend.schemas.common import IdPath
from backend.schemas.errors import CONFLICT, DEVICE_FAILED, FORBIDDEN, NOT_FOUND, UNAUTHORIZED
from backend.schemas.pushes import PushOut, PushRequest
from backend.services import bench_verdict
from backend.services import pushes as push_views
from backend.services.versions import stored_content
from backend.store import devices as devices_store
from backend.store import patients, versions, withdrawals
from backend.store import pushes as store
from backend.store.users import User
from backend.threads import run_waiting
from device_bridge.as_run import as_run
from device_bridge.host import PushError

router = APIRouter(prefix="/api", tags=["pushes"], responses=UNAUTHORIZED)

_PUSH_RESPONSES = {**FORBIDDEN, **NOT_FOUND, **CONFLICT, **DEVICE_FAILED}


@router.post("/proposals/{proposal_id}/push", response_model=PushOut, status_code=status.HTTP_201_CREATED,
             responses=_PUSH_RESPONSES)
async def push(proposal_id: IdPath, body: PushRequest, request: Request, conn: Conn, user: Prosthetist) -> dict:
    """Send an approved proposal's table to a device (prosthetist) and wait for the device to read back its exact
    CRC-32. The device must be assigned to the proposal's patient, whose body mass must still be the one the table
    was proposed for. The caller confirms what it replaces (``replaces_proposal_id`` / ``replaces_envelope_id``:
    what they saw on the leg, both null for none of ours; refused if the leg runs another now) and that the patient
    is seated or in the parallel bars. The push is recorded first; it is ``acknowledged`` when the CRC comes back,
    and ``active`` when the device's status reports that table running — at the next heel strike. The version on
    the wire is the device's own counter. A failed push leaves the device on what it ran before."""
    return await run_waiting(_push, conn, request.app.state.devices, user, body, ("proposal", proposal_id))


@router.post("/envelopes/{envelope_id}/push", response_model=PushOut, status_code=status.HTTP_201_CREATED,
             responses=_PUSH_RESPONSES)
async def push_envelope(envelope_id: IdPath, body: PushRequest, request: Request, conn: Conn,
                        user: Prosthetist) -> dict:
    """Send an approved envelope to a device (prosthetist), all or nothing, and wait for the device to read back its
    exact CRC-32 after re-checking every node and the neighbour rule itself. The same checks and confirmations as a
    table push (device assigned to the envelope's patient, same body mass, what it replaces, patient ready); from
    the next heel strike the leg takes its rows from the envelope at the task it estimates."""
    return await run_waiting(_push, conn, request.app.state.devices, user, body, ("envelope", envelope_id))


def _push(conn: Connection, devices: DeviceManager, user: User, body: PushRequest, item: store.Pushed) -> dict:
    """The checks every push of a version passes, in order, then record → send → finish, one push at a time per device
    (what the leg runs is checked inside that turn, so two pushes confirming the same table cannot both go). Nothing
    is sent when a check fails."""
    kind, item_id = item
    row, content = stored_content(conn, item)
    checked = as_run(content)
    violations, crc = checked.violations, checked.wire_crc32
    if row["status"] != "approved":
        raise ConflictError(f"{kind} {item_id} is {row['status']}; only approved {kind}s can be pushed")
    taken_back = withdrawals.withdrawal(conn, kind, item_id)
    if taken_back is not None:
        raise ConflictError(f"{kind} {item_id} was withdrawn by {taken_back['by']} at {taken_back['at']} "
                            f"(“{taken_back['reason']}”) and is never pushed again; derive a new version instead")
    devices.get(body.device_id)
    mass_overridden = _check_patient(conn, row, body.device_id, "table" if kind == "proposal" else "envelope",
                                     body.override_reason)
    if violations:
        raise ConflictError(f"{kind} {item_id} fails the safety limits; not pushed: "
                            + "; ".join(v.message for v in violations[:5]),
                            violations=[v.model_dump() for v in violations])
    if crc is None:
        raise InvalidError(f"{kind} {item_id} cannot be sent: a value does not fit the link")
    _, signed_off = bench_verdict.require_bench(conn, kind, row, body.override_reason, "pushed", user)
    override = body.override_reason if signed_off or mass_overridden else None
    with devices.push_slot(body.device_id):
        _check_replaces(conn, devices, body)
        if not devices.online(devices.get(body.device_id)):
            raise ConflictError(f"device {body.device_id} is offline (no status in the last second); nothing was sent")
        push_id, version = store.begin_push(conn, item, body.device_id, crc, user, override,
                                             instance_name=devices.instance_name)
        devices.push_started(body.device_id, push_id)
        t0 = time.monotonic()
        try:
            result = devices.push(body.device_id, content, version)
        except (PushError, ConflictError) as exc:
            unconfirmed = isinstance(exc, PushError) and exc.reason in ("timeout", "link_lost")
            store.finish_push(conn, push_id, "unconfirmed" if unconfirmed else "failed", None,
                              (time.monotonic() - t0) * 1e3, str(exc))
            devices.push_finished(body.device_id, push_id, acknowledged=False)
            raise DeviceError(f"push {push_id} {'unconfirmed' if unconfirmed else 'failed'}: {exc}",
                              push=push_views.get_push(conn, push_id)) from exc
        except BaseException:
            store.finish_push(conn, push_id, "unconfirmed", None, (time.monotonic() - t0) * 1e3,
                              "the push was interrupted; the device's next status tells whether it holds it")
            devices.push_finished(body.device_id, push_id, acknowledged=False)
            raise
        store.finish_push(conn, push_id, "acknowledged", result.attempts, result.elapsed_ms, None)
        devices.push_finished(body.device_id, push_id, acknowledged=True)
    return push_views.get_push(conn, push_id)


def _check_patient(conn: Connection, row: RowMapping, device_id: str, what: str,
                   override_reason: str | None) -> bool:
    """The device is assigned to the row's patient, who still weighs (within 5 %) what the table or envelope was
    made for, or the prosthetist wrote why it goes anyway; returns whether that reason was needed."""
    patient = patients.get_patient(conn, row["patient_id"])
    assigned = devices_store.assignment(conn, device_id)
    who = f"{patient['code_name']} ({patient['body_mass_kg']:g} kg)"
    if assigned is None:
        raise ConflictError(f"device {device_id} is not assigned to a patient; assign it to {who} first (live "
                            "monitor, Device) — nothing was sent")
    if assigned["patient_id"] != row["patient_id"]:
        raise ConflictError(f"device {device_id} is assigned to {assigned['patient_code']} "
                            f"({assigned['body_mass_kg']:g} kg), not to {who} whose {what} this is; nothing was sent")
    if not mass_differs(row["body_mass_kg"], patient["body_mass_kg"]):
        return False
    if override_reason:
        return True
    raise ConflictError(f"this {what} was built for {row['body_mass_kg']:g} kg and {patient['code_name']} now "
                        f"weighs {patient['body_mass_kg']:g} kg (more than 5 % apart): its torques and load "
                        "thresholds scale with body mass; propose again for the new mass, or give override_reason "
                        "(at least 20 characters, audited). Nothing was sent")


def _check_replaces(conn: Connection, devices: DeviceManager, body: PushRequest) -> None:
    """What the caller confirmed replacing is what the device reports running (or about to run) now."""
    leg = devices.on_leg(conn, body.device_id)
    current = leg["push"]
    now = (None, None) if current is None else (current["proposal_id"], current["envelope_id"])
    if now != (body.replaces_proposal_id, body.replaces_envelope_id):
        running = leg["words"] if current is None else (
            f"{current['label']} ({current['task']['speed_mps']:g} m/s, {current['task']['incline_deg']:g}°"
            f"{' nominal' if current['kind'] == 'envelope' else ''})")
        raise ConflictError(f"device {body.device_id} now runs {running}, not what you confirmed replacing; review "
                            "and confirm again. Nothing was sent", on_leg={
                                "label": None if current is None else current["label"],
                                "proposal_id": now[0], "envelope_id": now[1], "words": leg["words"]})


@router.get("/proposals/{proposal_id}/pushes", response_model=list[PushOut], responses=NOT_FOUND)
def list_pushes(proposal_id: IdPath, conn: Conn, _user: CurrentUser) -> list[dict]:
    """Every push of this proposal, newest first."""
    versions.get_row(conn, "proposal", proposal_id)
    return push_views.pushes_of(conn, ("proposal", proposal_id))


@router.get("/envelopes/{envelope_id}/pushes", response_model=list[PushOut], responses=NOT_FOUND)
def list_envelope_pushes(envelope_id: IdPath, conn: Conn, _user: CurrentUser) -> list[dict]:
    """Every push of this envelope, newest first."""
    versions.get_row(conn, "envelope", envelope_id)
    return push_views.pushes_of(conn, ("envelope", envelope_id))
