"""The simulated preview of a proposal's table against the FSMIC benchmark."""

from __future__ import annotations

from fastapi import APIRouter

from backend.deps import Conn, CurrentUser, Model
from backend.experiments.preview import preview_table
from backend.experiments.safety_figures import safety_flags
from backend.schemas.common import IdPath
from backend.schemas.errors import NOT_FOUND, UNAUTHORIZED, UNAVAILABLE
from backend.schemas.previews import PreviewOut
from backend.store import previews, proposals

router = APIRouter(prefix="/api", tags=["previews"], responses=UNAUTHORIZED)

PREVIEW_SECONDS = 10.0


@router.get("/proposals/{proposal_id}/preview", response_model=PreviewOut, responses={**NOT_FOUND, **UNAVAILABLE})
def get_preview(proposal_id: IdPath, conn: Conn, _user: CurrentUser, model: Model) -> dict:
    """Walk this proposal's table and the FSMIC benchmark for 10 s each on the simulated bench at the proposal's
    task (computed on first request, about a second, then stored: a proposal never changes). Falls, strides and
    joint RMSE against the able-bodied reference, and the stride-averaged trajectories; ``safety`` flags the
    table's safety figures (falls, toe catches, time on swing settings under load) on their own bounds."""
    row = proposals.get_row(conn, proposal_id)
    stored = previews.get_preview(conn, proposal_id, row["table_sha256"])
    if stored is None:
        table = proposals.stored_table(row)
        result = preview_table(table, row["speed_mps"], row["incline_deg"], row["body_mass_kg"], model,
                               PREVIEW_SECONDS)
        stored = previews.store_preview(conn, proposal_id, row["table_sha256"], result)
    runs = stored["controllers"]
    return {**stored, "safety": safety_flags(runs["table"], runs["fsmic"])}
