"""The gate's two-person override and the take-back: sign off a version's bench findings, withdraw an approved version.

A version the bench did not find clean is approved or pushed only after two prosthetists signed off
(:mod:`backend.services.bench_verdict`). An approved version can be withdrawn: it is never pushed again, and every leg
that runs or holds it is sent back to the last version it ran that was not withdrawn (re-sent, read back by CRC), or
put in safe mode where there is none or it cannot be sent; a leg offline now is put in safe mode when it next reports
(:meth:`backend.devices.DeviceManager.withdrawn`).
"""

from __future__ import annotations

from typing import Literal

from fastapi import APIRouter, Request, status
from sqlalchemy import Connection

from backend.db import write_transaction
from backend.deps import Conn, Prosthetist
from backend.devices import DeviceManager
from backend.errors import ConflictError
from backend.schemas.common import IdPath
from backend.schemas.errors import CONFLICT, FORBIDDEN, NOT_FOUND, UNAUTHORIZED
from backend.schemas.gate import SignoffRequest, SignoffsOut, WithdrawOut, WithdrawRequest
from backend.services import bench_verdict
from backend.services import pushes as push_views
from backend.services.versions import stored_content
from backend.store import pushes as pushes_store
from backend.store import signoffs, versions, withdrawals
from backend.store.users import User
from backend.threads import run_waiting
from device_bridge.as_run import as_run
from device_bridge.host import PushError
from device_bridge.protocol import Command

router = APIRouter(prefix="/api", tags=["gate"], responses=UNAUTHORIZED)
Kind = Literal["proposal", "envelope"]
_RESPONSES = {**FORBIDDEN, **NOT_FOUND, **CONFLICT}


def _sign(kind: Kind, item_id: int, body: SignoffRequest, conn: Connection, user: User) -> dict:
    with write_transaction(conn):
        row = versions.get_row(conn, kind, item_id)
        if row["status"] == "rejected":
            raise ConflictError(f"{kind} {item_id} was rejected; there is nothing to sign off")
        if bench_verdict.verdict(conn, kind, row)["status"] == "clean":
            raise ConflictError(f"{kind} {item_id}'s bench preview is clean: it needs no sign-off to go ahead")
        signed = signoffs.sign(conn, kind, item_id, bench_verdict.content_sha256(row), user, body.reason)
    return {"signoffs": [{k: s[k] for k in ("by", "reason", "at")} for s in signed], "needed": signoffs.NEEDED,
            "complete": len(signed) >= signoffs.NEEDED}


@router.post("/proposals/{proposal_id}/signoffs", response_model=SignoffsOut, status_code=status.HTTP_201_CREATED,
             responses=_RESPONSES)
def sign_off_proposal(proposal_id: IdPath, body: SignoffRequest, conn: Conn, user: Prosthetist) -> dict:
    """Sign off this table's bench findings (prosthetist): it is approved or pushed although its preview is not
    clean only with two sign-offs, from two accounts, each with its own reason, on exactly this content."""
    return _sign("proposal", proposal_id, body, conn, user)


@router.post("/envelopes/{envelope_id}/signoffs", response_model=SignoffsOut, status_code=status.HTTP_201_CREATED,
             responses=_RESPONSES)
def sign_off_envelope(envelope_id: IdPath, body: SignoffRequest, conn: Conn, user: Prosthetist) -> dict:
    """Sign off this envelope's bench findings (prosthetist), as for a table."""
    return _sign("envelope", envelope_id, body, conn, user)


@router.post("/proposals/{proposal_id}/withdraw", response_model=WithdrawOut, responses=_RESPONSES)
async def withdraw_proposal(proposal_id: IdPath, body: WithdrawRequest, request: Request, conn: Conn,
                            user: Prosthetist) -> dict:
    """Withdraw an approved table (prosthetist): never pushed again; a leg running it goes back to the last version
    it ran that was not withdrawn, or to safe mode. The approval itself stays as it was decided."""
    return await run_waiting(_withdraw, "proposal", proposal_id, body, request.app.state.devices, conn, user)


@router.post("/envelopes/{envelope_id}/withdraw", response_model=WithdrawOut, responses=_RESPONSES)
async def withdraw_envelope(envelope_id: IdPath, body: WithdrawRequest, request: Request, conn: Conn,
                            user: Prosthetist) -> dict:
    """Withdraw an approved envelope (prosthetist), as for a table."""
    return await run_waiting(_withdraw, "envelope", envelope_id, body, request.app.state.devices, conn, user)


def _withdraw(kind: Kind, item_id: int, body: WithdrawRequest, devices: DeviceManager, conn: Connection,
              user: User) -> dict:
    with write_transaction(conn):
        row = versions.get_row(conn, kind, item_id)
        done = withdrawals.withdraw(conn, kind, row, user, body.reason)
    devices.withdrawn()
    label = versions.version_label(row["kind"], row["patient_code"], row["version"])
    why = f"{label} was withdrawn by {done['by']} at {done['at']}: {done['reason']}"
    legs = [_send_back(conn, devices, device_id, (kind, item_id), why, user)
            for device_id in devices.ids() if _holds(conn, devices, device_id, (kind, item_id))]
    return {"withdrawal": done, "legs": legs}


def _holds(conn: Connection, devices: DeviceManager, device_id: str, item: pushes_store.Pushed) -> bool:
    """Whether the leg runs the item, or holds it for its next heel strike, as its last status says."""
    dev = devices.get(device_id)
    s = dev.status
    if s is None:
        return False
    for version, crc in ((s.active_version, s.active_crc32), (s.pending_version, None)):
        push = push_views.push_of_version(conn, device_id, version, crc)
        if push is not None and ((push["kind"] == "table" and item == ("proposal", push["proposal_id"]))
                                 or (push["kind"] == "envelope" and item == ("envelope", push["envelope_id"]))):
            return True
    return False


def _send_back(conn: Connection, devices: DeviceManager, device_id: str, withdrawn: pushes_store.Pushed, why: str,
               user: User) -> dict:
    """Send the leg the last version it ran that was not withdrawn; safe mode where there is none or it fails."""
    dev = devices.get(device_id)
    if not devices.online(dev):
        return {"device_id": device_id, "action": "offline", "to_label": None,
                "detail": "the leg is offline: it is put in safe mode when it next reports"}
    back = push_views.last_run_not_withdrawn(conn, device_id, withdrawn)
    if back is not None:
        try:
            sent = _resend(conn, devices, device_id, back, why, user)
            return {"device_id": device_id, "action": "sent_back", "to_label": sent["label"],
                    "detail": f"sent back to {sent['label']} (CRC {sent['crc32']} read back); it runs from the next "
                              "heel strike, as any push"}
        except (PushError, ConflictError) as exc:
            failed = f"sending {back['label']} back failed ({exc}); "
    else:
        failed = "no earlier version that was not withdrawn ran on this leg; "
    devices.command(device_id, Command.ENTER_SAFE_MODE)
    return {"device_id": device_id, "action": "safe_mode", "to_label": None, "detail": failed + "the leg was put in "
            "safe mode"}


def _resend(conn: Connection, devices: DeviceManager, device_id: str, back: dict, why: str, user: User) -> dict:
    """Push ``back`` (a push record of the version to return to) again, recorded with the reason it was sent."""
    item: pushes_store.Pushed = ("proposal", back["proposal_id"]) if back["kind"] == "table" \
        else ("envelope", back["envelope_id"])
    _, content = stored_content(conn, item)
    checked = as_run(content)
    if checked.violations or checked.wire_crc32 is None:
        raise ConflictError(f"{back['label']} no longer passes the safety limits")
    with devices.push_slot(device_id):
        push_id, version = pushes_store.begin_push(conn, item, device_id, checked.wire_crc32, user,
                                                   sent_back_reason=why, instance_name=devices.instance_name)
        devices.push_started(device_id, push_id)
        try:
            result = devices.push(device_id, content, version)
        except BaseException as exc:
            pushes_store.finish_push(conn, push_id, "failed", None, 0.0, str(exc))
            devices.push_finished(device_id, push_id, acknowledged=False)
            raise
        pushes_store.finish_push(conn, push_id, "acknowledged", result.attempts, result.elapsed_ms, None)
        devices.push_finished(device_id, push_id, acknowledged=True)
    return push_views.get_push(conn, push_id)
