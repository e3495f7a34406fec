"""The simulated preview of a proposal's table against the FSMIC benchmark, and the measured reference data."""

from __future__ import annotations

import math

from fastapi import APIRouter, Request

from backend.deps import Conn, CurrentUser, Model
from backend.schemas.common import IdPath
from backend.schemas.errors import NOT_FOUND, UNAUTHORIZED, UNAVAILABLE
from backend.schemas.previews import PreviewOut, ReferenceOut
from backend.store import previews, proposals
from controller_core.reference import CITATIONS
from device_bridge.sim.experiments import preview_table

router = APIRouter(prefix="/api", tags=["previews"], responses=UNAUTHORIZED)

PREVIEW_SECONDS = 10.0


@router.get("/proposals/{proposal_id}/preview", response_model=PreviewOut, responses={**NOT_FOUND, **UNAVAILABLE})
async def get_preview(proposal_id: IdPath, request: Request, conn: Conn, _user: CurrentUser, model: Model) -> dict:
    """Walk this proposal's table and the FSMIC benchmark for 10 s each on the simulated bench at the proposal's
    task (computed on first request, about a second, then stored: a proposal never changes). Falls, strides and
    joint RMSE against the able-bodied reference, and the stride-averaged trajectories."""
    row = proposals.get_row(conn, proposal_id)
    stored = previews.get_preview(conn, proposal_id, row["table_sha256"])
    if stored is not None:
        return stored
    table = proposals.stored_table(row)

    def work() -> dict:
        result = preview_table(table, row["speed_mps"], row["incline_deg"], row["body_mass_kg"], model,
                               PREVIEW_SECONDS)
        return previews.store_preview(conn, proposal_id, row["table_sha256"], result)

    return await request.app.state.preview_lane.run(work)


def _deg(values) -> list[float]:
    return [round(math.degrees(float(v)), 3) for v in values]


def _plain(values) -> list[float]:
    return [round(float(v), 4) for v in values]


def _task(value: float | None) -> float | None:
    return None if value is None or not math.isfinite(value) else round(float(value), 4)


@router.get("/reference", response_model=ReferenceOut)
def get_reference(_user: CurrentUser, model: Model) -> dict:
    """The measured able-bodied walking conditions the model was trained on, with their citations: the grey
    curves a proposal is drawn over (angles in deg, moments in N·m/kg, internal, flexor/dorsiflexor +)."""
    conditions = []
    for rec in model.reference_.records:
        conditions.append({
            "name": rec.name, "dataset": rec.dataset, "citation": CITATIONS.get(rec.dataset, rec.dataset),
            "speed_mps": _task(rec.task.get("speed_mps")), "incline_deg": _task(rec.task.get("incline_deg")),
            "subjects_or_strides": rec.n if rec.n >= 0 else None, "phase": _plain(rec.phase),
            "knee_angle_deg": _deg(rec.mean["knee_angle"]), "knee_moment_Nm_per_kg": _plain(rec.mean["knee_moment"]),
            "ankle_angle_deg": _deg(rec.mean["ankle_angle"]),
            "ankle_moment_Nm_per_kg": _plain(rec.mean["ankle_moment"])})
    return {"model_version": model.model_version_, "data_sha256": model.data_sha256_, "conditions": conditions}
