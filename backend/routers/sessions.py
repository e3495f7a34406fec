"""Walking sessions: start and stop recording a device's telemetry for a patient; the summary and the samples."""

from __future__ import annotations

import itertools
import math
from typing import Annotated, Literal

import numpy as np
from fastapi import APIRouter, Query, Request, Response, status
from sqlalchemy import Connection

from backend.deps import Conn, CurrentUser, Model, Prosthetist
from backend.devices import DeviceManager
from backend.errors import ConflictError, InvalidError
from backend.report import session_report_pdf
from backend.schemas.common import IdPath
from backend.schemas.errors import CONFLICT, FORBIDDEN, NOT_FOUND, UNAUTHORIZED
from backend.schemas.sessions import SamplesOut, SessionOut, SessionRequest, TrendDay
from backend.services import sessions as session_views
from backend.session_export import samples_csv, samples_parquet
from backend.session_strides import stride_tasks
from backend.store import devices as devices_store
from backend.store import patients, versions
from backend.store import sessions as store
from controller_core.session_regions import adaptive_summary, own_task_errors
from controller_core.session_summary import device_times, session_strikes, summarize_session
from controller_core.session_trend import session_trend
from device_bridge.bench.task_reference import task_reference
from device_bridge.protocol import TELEMETRY_PERIOD_S, Mode
from device_bridge.sim.course import COURSES

router = APIRouter(prefix="/api", tags=["sessions"], responses=UNAUTHORIZED)


@router.post("/patients/{patient_id}/sessions", response_model=SessionOut, status_code=status.HTTP_201_CREATED,
             responses={**FORBIDDEN, **NOT_FOUND, **CONFLICT})
def start_session(patient_id: IdPath, body: SessionRequest, request: Request, conn: Conn, user: Prosthetist,
                  model: Model) -> dict:
    """Start recording the device's telemetry for this patient (prosthetist: on the simulated leg the patient sets
    off walking, so starting, like stopping, is theirs; a viewer watches): the device must be
    assigned to the patient, and the table or envelope it reports running (if any) be theirs; the session records the
    version and CRC the device reports, never what the records believe. The task defaults to that of the
    table on the device (an envelope's nominal task); the simulated leg starts walking at it, or walks ``course``
    (its first task is then the session's task)."""
    devices: DeviceManager = request.app.state.devices
    patient = patients.get_patient(conn, patient_id)
    devices.get(body.device_id)
    assigned = devices_store.assignment(conn, body.device_id)
    if assigned is None or assigned["patient_id"] != patient_id:
        on = "nobody" if assigned is None else f"{assigned['patient_code']} ({assigned['body_mass_kg']:g} kg)"
        raise ConflictError(f"device {body.device_id} is assigned to {on}, not to {patient['code_name']}: a session "
                            "records the patient wearing the device; change the assignment first")
    leg = devices.on_leg(conn, body.device_id, running_only=True)   # what the device reports, not our records
    active = leg["push"]
    if active is not None and active["patient_id"] != patient_id:
        raise ConflictError(f"the leg runs {active['label']}, another patient's {active['kind']}; push one of "
                            f"{patient['code_name']}'s approved tables or envelopes before recording")
    course = None
    if body.course is not None:
        if devices.get(body.device_id).walker is None:
            raise InvalidError(f"course {body.course!r} is walked by the simulated leg only; device {body.device_id} "
                               "is a real leg: record the session at its task instead")
        course = COURSES[body.course]
        speed, incline = course.segments[0].speed_mps, course.segments[0].incline_deg
    elif body.speed_mps is not None:
        speed, incline = body.speed_mps, body.incline_deg or 0.0
    elif active is not None:
        speed, incline = active["task"]["speed_mps"], active["task"]["incline_deg"]
    else:
        raise InvalidError("give speed_mps (and incline_deg), or push a table to the device first: the session's "
                           "task sets the reference its errors are measured against")
    mass = patient["body_mass_kg"]
    reference = task_reference(speed, incline, model, mass)
    task = {"speed_mps": speed, "incline_deg": incline, "body_mass_kg": mass}
    ran = {"proposal_id": active and active["proposal_id"], "envelope_id": active and active["envelope_id"],
           "table_version": leg["version"], "crc32": leg["crc32"]}
    session_id = store.start_session(conn, patient_id, body.device_id, task, ran, user, body.course,
                                     simulated=devices.get(body.device_id).spec.kind == "simulated")
    devices.start_recording(body.device_id, session_id, reference, mass, course)
    return session_views.get_session(conn, session_id)


@router.post("/sessions/{session_id}/stop", response_model=SessionOut,
             responses={**FORBIDDEN, **NOT_FOUND, **CONFLICT})
def stop_session(session_id: IdPath, request: Request, conn: Conn, user: Prosthetist, model: Model) -> dict:
    """Stop recording and store the summary: strides, cadence, joint RMSE against the reference for the task. The
    prosthetist's (a viewer who watches remotely must not end the prosthetist's recording: 403)."""
    devices: DeviceManager = request.app.state.devices
    session = session_views.get_session(conn, session_id)
    if session["status"] != "recording":
        raise ConflictError(f"session {session_id} was already stopped at {session['stopped_at']}")
    reported: list[dict] = []
    late = 0
    if session["device_id"] in devices.ids():
        reported, late = devices.stop_recording(session["device_id"])
    t = session["task"]
    cols = store.samples(conn, session_id)
    times = device_times(np.asarray(cols["seq"]), np.asarray(cols["t_s"]), TELEMETRY_PERIOD_S)
    modes = np.asarray(cols["mode"], dtype=int)
    running = modes == Mode.ACTIVE
    knee, ankle, load = (np.asarray(cols[c]) for c in ("knee_angle_rad", "ankle_angle_rad", "load_N"))

    def reference_at(speed_mps: float, incline_deg: float):
        return task_reference(speed_mps, incline_deg, model, t["body_mass_kg"])

    summary = summarize_session(times, knee, ankle, np.asarray(cols["knee_torque_Nm"]),
                                np.asarray(cols["ankle_torque_Nm"]), load, t["body_mass_kg"],
                                reference_at(t["speed_mps"], t["incline_deg"]), running_table=running)
    strikes = session_strikes(times, load, t["body_mass_kg"])
    if session["envelope_id"] is not None:
        envelope = versions.stored_envelope(versions.get_row(conn, "envelope", session["envelope_id"]))
        summary["adaptive"] = adaptive_summary(
            times, knee, ankle, strikes, _floats(cols["estimated_speed_mps"]), _floats(cols["estimated_incline_deg"]),
            cols["adaptive_mode"], envelope.speeds_mps, envelope.inclines_deg, reference_at, running_table=running)
    tasks, against = stride_tasks(session, summary, times, strikes)
    summary["headline"] = own_task_errors(
        knee, ankle, strikes, tasks, reference_at, against,
        scored=[bool(running[a:b + 1].all()) for a, b in itertools.pairwise(strikes)])
    period = summary["sample_period_s"] or 0.0
    summary["mode_s"] = {m.name.lower(): round(float(np.count_nonzero(modes == m)) * period, 3) for m in Mode}
    summary["device_reported"] = reported
    seqs = cols["seq"]
    summary["missing_samples"] = int(seqs[-1] - seqs[0] + 1 - len(seqs)) if seqs else 0
    summary["late_samples"] = late   # kept by the leg's bridge while its link was down, delivered after
    store.stop_session(conn, session_id, summary, user)
    return session_views.get_session(conn, session_id)


def _floats(values: list) -> np.ndarray:
    """A stored column with NULLs as NaN."""
    return np.array([np.nan if v is None else v for v in values], dtype=float)


@router.get("/patients/{patient_id}/sessions", response_model=list[SessionOut], responses=NOT_FOUND)
def list_sessions(patient_id: IdPath, conn: Conn, _user: CurrentUser) -> list[dict]:
    patients.get_patient(conn, patient_id)
    return session_views.sessions_of_patient(conn, patient_id)


@router.get("/patients/{patient_id}/trend", response_model=list[TrendDay], responses=NOT_FOUND)
def get_trend(patient_id: IdPath, conn: Conn, _user: CurrentUser) -> list[dict]:
    """The patient's stopped sessions per day (UTC), oldest first: sessions, strides, walking time, stride-weighted
    cadence and joint-angle errors, and time per task class (slow / moderate / fast × downhill / level / uphill: edges
    0.9 and 1.3 m/s, ±4°; an adaptive session by the leg's own estimate, a single-table session at its task)."""
    patients.get_patient(conn, patient_id)
    return session_trend(session_views.sessions_of_patient(conn, patient_id))


@router.get("/sessions/{session_id}/report.pdf", response_class=Response,
            responses={**NOT_FOUND, **CONFLICT, 200: {"content": {"application/pdf": {}},
                                                      "description": "one A4 page; a second with an envelope's regions"}})
def get_report_pdf(session_id: IdPath, conn: Conn, _user: CurrentUser) -> Response:
    """The session report as a PDF: task, the table or envelope that ran with its version and CRC, strides,
    cadence, trajectories against the reference, errors; with an envelope a second page of time, strides and errors
    per region (a stopped session: the summary is made on stop)."""
    session = session_views.get_session(conn, session_id)
    if session["status"] != "stopped":
        raise ConflictError(f"session {session_id} is still recording; stop it first, the report needs its summary")
    pdf = session_report_pdf(session, patients.get_patient(conn, session["patient_id"]))
    return Response(pdf, media_type="application/pdf",
                    headers={"Content-Disposition": f'attachment; filename="quasitune-session-{session_id}.pdf"'})


@router.get("/sessions/{session_id}", response_model=SessionOut, responses=NOT_FOUND)
def get_session(session_id: IdPath, conn: Conn, _user: CurrentUser) -> dict:
    return session_views.get_session(conn, session_id)


_DEG = 180 / math.pi
_DISPLAY = {"knee_angle_rad": ("knee_angle_deg", _DEG), "knee_velocity_rad_s": ("knee_velocity_deg_s", _DEG),
            "ankle_angle_rad": ("ankle_angle_deg", _DEG), "ankle_velocity_rad_s": ("ankle_velocity_deg_s", _DEG)}


def _display_columns(conn: Connection, session_id: int, every: int = 1) -> dict[str, list]:
    """The recorded telemetry in display units, with the unit in each column's name (deg, deg/s, N·m, N, s)."""
    cols = store.samples(conn, session_id)
    out: dict[str, list] = {}
    for name, values in cols.items():
        new, scale = _DISPLAY.get(name, (name, None))
        kept = values[::every]
        if name == "mode":
            out[new] = [Mode(v).name.lower() for v in kept]
        else:
            out[new] = [round(v * scale, 3) for v in kept] if scale else kept
    return out


@router.get("/sessions/{session_id}/samples", response_model=SamplesOut, responses=NOT_FOUND)
def get_samples(session_id: IdPath, conn: Conn, _user: CurrentUser,
                every: Annotated[int, Query(ge=1, le=1000, description="keep every n-th sample")] = 1) -> dict:
    """The recorded telemetry in display units (deg, deg/s, N·m, N), columns of equal length; ``mode`` per sample
    says whether the leg ran its table (``active``), was in ``safe`` mode or had ``no_table``."""
    session_views.get_session(conn, session_id)
    out = _display_columns(conn, session_id, every)
    return {"session_id": session_id, "count": len(out["seq"]), "every": every, "columns": out}


@router.get("/sessions/{session_id}/samples.{fmt}", response_class=Response,
            responses={**NOT_FOUND, 200: {"content": {"text/csv": {}, "application/vnd.apache.parquet": {}},
                                          "description": "every recorded sample, one row each"}})
def export_samples(session_id: IdPath, fmt: Literal["csv", "parquet"], conn: Conn, _user: CurrentUser) -> Response:
    """Every recorded sample of the session as CSV or Parquet (what engineers open in their own tools): the columns
    of ``/samples`` with the unit in each name; the Parquet file also carries the session's facts as metadata
    (patient code, version on the leg with its CRC, whether the walk was simulated)."""
    session = session_views.get_session(conn, session_id)
    facts = {"session_id": str(session_id), "simulated": str(session.get("simulated")),
             "version_on_leg": str(session.get("table_label")), "crc32": str(session.get("table_crc32")),
             "started_at": str(session.get("started_at")), "source": "QuasiTune session recording"}
    columns = _display_columns(conn, session_id)
    name = f"quasitune-session-{session_id}-samples.{fmt}"
    headers = {"Content-Disposition": f'attachment; filename="{name}"'}
    if fmt == "csv":
        return Response(samples_csv(columns), media_type="text/csv; charset=utf-8", headers=headers)
    return Response(samples_parquet(columns, facts), media_type="application/vnd.apache.parquet", headers=headers)
