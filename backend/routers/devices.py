"""Devices: list, status, commands, and the live telemetry WebSocket."""

from __future__ import annotations

import asyncio
import time
from typing import Annotated

from fastapi import APIRouter, Query, Request, WebSocket, WebSocketDisconnect, status

from backend.db import pooled
from backend.deps import Conn, CurrentUser, Prosthetist
from backend.devices import DeviceManager
from backend.devices.calibration_view import calibration_view
from backend.errors import ConflictError, InvalidError
from backend.schemas.devices import (
    AssignmentRequest,
    CalibrationOut,
    CalibrationRequest,
    CommandRequest,
    DeviceIdPath,
    DeviceOut,
    LinkModeRequest,
    ViewerOut,
)
from backend.schemas.errors import CONFLICT, FORBIDDEN, NOT_FOUND, UNAUTHORIZED
from backend.store import devices as devices_store
from backend.store.users import user_for_token
from device_bridge.protocol import CalibrationAction, CalibrationStep, Command

router = APIRouter(prefix="/api/devices", tags=["devices"])

RECHECK_TOKEN_S = 1.0   # an open telemetry stream re-checks its token this often

_COMMANDS = {"enter_safe_mode": Command.ENTER_SAFE_MODE, "leave_safe_mode": Command.LEAVE_SAFE_MODE}


def manager(request: Request) -> DeviceManager:
    return request.app.state.devices


@router.get("", response_model=list[DeviceOut], responses=UNAUTHORIZED)
def list_devices(request: Request, _user: CurrentUser) -> list[dict]:
    """The configured devices with their latest status."""
    m = manager(request)
    return [m.view(d) for d in m.ids()]


@router.get("/{device_id}", response_model=DeviceOut, responses={**UNAUTHORIZED, **NOT_FOUND})
def get_device(device_id: DeviceIdPath, request: Request, _user: CurrentUser) -> dict:
    """State, active table version and CRC read back from the device, last heartbeat."""
    return manager(request).view(device_id)


@router.put("/{device_id}/assignment", response_model=DeviceOut,
            responses={**UNAUTHORIZED, **FORBIDDEN, **NOT_FOUND, **CONFLICT})
def assign(device_id: DeviceIdPath, body: AssignmentRequest, request: Request, conn: Conn, user: Prosthetist) -> dict:
    """Assign the device to the patient who will wear it (prosthetist; audited). Pushes and walking sessions on
    the device are then for this patient only. Refused while a session records. The table on the leg stays: if
    it is another patient's, push this patient's table before a session."""
    m = manager(request)
    m.get(device_id)
    devices_store.assign(conn, device_id, body.patient_id, user)
    m.worn_by(device_id, devices_store.assignment(conn, device_id))   # a simulated patient stands, on their leg
    return m.view(device_id)


@router.delete("/{device_id}/assignment", response_model=DeviceOut,
               responses={**UNAUTHORIZED, **FORBIDDEN, **NOT_FOUND, **CONFLICT})
def unassign(device_id: DeviceIdPath, request: Request, conn: Conn, user: Prosthetist) -> dict:
    """The device is worn by nobody (prosthetist; audited): nothing can be pushed to it or recorded on it."""
    m = manager(request)
    m.get(device_id)
    devices_store.assign(conn, device_id, None, user)
    m.worn_by(device_id, None)
    return m.view(device_id)


@router.get("/{device_id}/viewer", response_model=ViewerOut, responses={**UNAUTHORIZED, **NOT_FOUND, **CONFLICT})
def get_viewer(device_id: DeviceIdPath, request: Request, _user: CurrentUser) -> dict:
    """The live 3D view of the leg (viser), only on a server started with ``--viewer3d`` (else 409): viser has no
    login, so its loopback port would show the live telemetry to anyone on the machine. Started on first request
    on a port the OS assigns, read back here; embed ``url`` in a page served from the same machine. An unknown
    device is a 404."""
    if request.app.state.viewers is None:
        manager(request).get(device_id)
        raise ConflictError("the 3D view is off on this server: viser has no login, so its port would show the "
                            "live telemetry to anyone on this machine; the leg view on the monitor comes through "
                            "your signed-in stream (an engineer on a single-user bench: quasitune serve --viewer3d)")
    viewer = request.app.state.viewers.get(device_id)
    return {"device_id": device_id, "host": viewer.host, "port": viewer.port,
            "url": f"http://{viewer.host}:{viewer.port}/", "frames_drawn": viewer.frames_drawn}


@router.post("/{device_id}/commands", response_model=DeviceOut, status_code=status.HTTP_202_ACCEPTED,
             responses={**UNAUTHORIZED, **FORBIDDEN, **NOT_FOUND, **CONFLICT})
def command(device_id: DeviceIdPath, body: CommandRequest, request: Request, conn: Conn, user: Prosthetist) -> dict:
    """Put the device into its passive safe mode, or let it leave safe mode (it does so only with a table and a
    live host; never onto a withdrawn version). The device's status reports the outcome."""
    m = manager(request)
    if body.command == "leave_safe_mode":
        notice = m.view(device_id)["withdrawal_notice"]
        if notice is not None and notice["state"] == "runs_withdrawn":
            raise ConflictError(f"the leg holds {notice['label']}, which was withdrawn by {notice['by']} "
                                f"({notice['reason']}): it stays in safe mode; push a version that was not withdrawn")
    m.command(device_id, _COMMANDS[body.command])
    devices_store.record_command(conn, device_id, body.command, user)
    return m.view(device_id)


@router.post("/{device_id}/calibration", response_model=CalibrationOut,
             responses={**UNAUTHORIZED, **FORBIDDEN, **NOT_FOUND, **CONFLICT})
def calibrate(device_id: DeviceIdPath, body: CalibrationRequest, request: Request, conn: Conn,
              user: Prosthetist) -> dict:
    """Guided calibration of a real leg, step by step (prosthetist; each command audited with the leg's answer).

    ``start`` (only while the leg runs no table: put it in safe mode, in its stand; it then gives no torque at all),
    then ``measure`` each step after doing what its prompt asks: ``joint_zero``, ``direction``, ``loadcell_zero``,
    ``loadcell_sign`` (read against the assigned patient's body mass). The leg answers what it measured, or why it
    refused (a step can be measured again); ``keep`` writes the result on the leg and uses it, ``cancel`` leaves its
    calibration as it was; either ends in safe mode. The simulated leg has nothing to calibrate (refused
    ``no_sensors``). 409 when the leg is offline or does not answer."""
    m = manager(request)
    m.get(device_id)
    if (body.action == "measure") != (body.step is not None):
        raise InvalidError("a step is named with action 'measure', and only then")
    worn = devices_store.assignment(conn, device_id)
    mass = None if worn is None else float(worn["body_mass_kg"])
    step = None if body.step is None else CalibrationStep[body.step.upper()]
    answer = m.calibrate(device_id, CalibrationAction[body.action.upper()], step, mass or 0.0)
    out = calibration_view(device_id, answer, step, mass)
    devices_store.record_calibration(conn, device_id, body.action, body.step, out, user)
    return out


@router.put("/{device_id}/link-mode", response_model=DeviceOut,
            responses={**UNAUTHORIZED, **FORBIDDEN, **NOT_FOUND, **CONFLICT})
def set_link_mode(device_id: DeviceIdPath, body: LinkModeRequest, request: Request, conn: Conn,
                  user: Prosthetist) -> dict:
    """Choose what a lost link to the server does to this leg (prosthetist; audited with the reason). *Supervised*
    (tuning in the clinic): the leg goes to its passive safe mode within the heartbeat timeout and back to its table
    once the link returns and the host says so. *Autonomous* (daily life, far from any server): the leg runs on with
    the approved table or envelope it holds, and the lost link changes nothing the patient feels. Stored at once and
    sent to the device now, or when it next reports if it is offline: ``link_mode_on_device`` shows what it does."""
    m = manager(request)
    m.get(device_id)
    devices_store.set_link_mode(conn, device_id, body.link_mode, body.reason, user)
    m.link_mode_chosen(device_id, body.link_mode)
    return m.view(device_id)


@router.websocket("/{device_id}/telemetry")
async def telemetry(websocket: WebSocket, device_id: str,
                    token: Annotated[str | None, Query(description="bearer token (browsers cannot set headers)")] = None
                    ) -> None:
    """Live telemetry: one JSON message per sample (``type: telemetry``, 100 Hz, ``seq`` without gaps) and one per
    device status (``type: status``, 10 Hz). Sign in with ``?token=<bearer token>``."""
    app = websocket.app
    with pooled(app.state.db) as conn:
        user = user_for_token(conn, token) if token else None
    m: DeviceManager = app.state.devices
    if user is None or user.must_change_password or device_id not in m.ids():
        await websocket.close(code=1008, reason="sign in with ?token=" if user is None else "change the one-time "
                              "password first" if user.must_change_password else "unknown device")
        return
    await websocket.accept()
    queue: asyncio.Queue = asyncio.Queue(maxsize=1000)
    fanout = m.get(device_id).fanout
    fanout.subscribe(queue, asyncio.get_running_loop())
    try:
        await websocket.send_json({"type": "status", **m.view(device_id)})
        checked = time.monotonic()
        while True:
            await websocket.send_json(await queue.get())
            if time.monotonic() - checked >= RECHECK_TOKEN_S:   # signed out, expired or disabled: stop streaming
                with pooled(app.state.db) as conn:
                    still = user_for_token(conn, token)
                if still is None:
                    await websocket.close(code=1008, reason="signed out, token expired or account disabled")
                    return
                checked = time.monotonic()
    except (WebSocketDisconnect, RuntimeError):
        pass
    finally:
        fanout.unsubscribe(queue)
