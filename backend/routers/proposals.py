"""Proposals: request a draft for a task, read, edit into a new version, diff, approve or reject."""

from __future__ import annotations

from fastapi import APIRouter, Request, Response, status
from pydantic import ValidationError

from backend.deps import Conn, CurrentUser, Model, Prosthetist
from backend.errors import InvalidError
from backend.schemas.common import BeforeVersion, IdPath, PageLimit, page_headers
from backend.schemas.errors import CONFLICT, FORBIDDEN, NOT_FOUND, UNAUTHORIZED, UNAVAILABLE
from backend.schemas.proposals import (
    DecisionRequest,
    DiffOut,
    EditRequest,
    ProposalListItem,
    ProposalOut,
    ProposalRequest,
)
from backend.services import legs, proposals
from backend.services.versions import with_state
from backend.store import patients, versions
from backend.task_range import extrapolation_reason
from controller_core.table_edit import EditError, edit_table
from device_bridge.as_run import as_run

router = APIRouter(prefix="/api", tags=["proposals"], responses=UNAUTHORIZED)


@router.post("/patients/{patient_id}/proposals", response_model=ProposalOut, status_code=status.HTTP_201_CREATED,
             responses={**FORBIDDEN, **NOT_FOUND, **UNAVAILABLE})
async def create_proposal(patient_id: IdPath, body: ProposalRequest, request: Request, conn: Conn, user: Prosthetist,
                          model: Model) -> dict:
    """Predict features, curves and the parameter table for a task and this patient's body mass, and store it
    as the patient's next draft version (prosthetist). Its safety check and extrapolation flag are included. A task
    beyond what the model knows (``GET /api/task-range``) is refused (422) unless ``extrapolate`` comes with a
    ``reason``, which is audited and shown with the version."""
    # On the event loop: about a millisecond of NumPy, which in a worker thread only contends with the loop for
    # the GIL; the write is one short transaction.
    patient = patients.get_patient(conn, patient_id)
    reason = extrapolation_reason(model, [(body.speed_mps, body.incline_deg)], body.extrapolate, body.reason)
    leg = legs.patient_leg(patient, request.app.state.bench_leg_file)   # made for the patient's leg
    proposal = model.propose(speed_mps=body.speed_mps, incline_deg=body.incline_deg, mass_kg=patient["body_mass_kg"],
                             swing_inertia_ratio=legs.swing_ratio(leg))
    created = proposals.create_from_model(conn, patient_id, proposal, user, reason, leg)
    return with_state(conn, "proposal", created)


@router.get("/patients/{patient_id}/proposals", response_model=list[ProposalListItem], responses=NOT_FOUND)
def list_proposals(patient_id: IdPath, response: Response, conn: Conn, _user: CurrentUser, limit: PageLimit = 50,
                   before_version: BeforeVersion = None) -> list[dict]:
    """One page of the patient's proposal versions, newest first: metadata only (the table, curves and live check
    are on ``GET /api/proposals/{id}``). ``X-Total-Count``: how many in all; ``X-Next-Before-Version``: the
    cursor of the next page."""
    patients.get_patient(conn, patient_id)
    items, total = proposals.list_proposals(conn, patient_id, limit, before_version)
    return page_headers(response, items, total, limit)


@router.get("/proposals/{proposal_id}", response_model=ProposalOut, responses=NOT_FOUND)
def get_proposal(proposal_id: IdPath, conn: Conn, _user: CurrentUser) -> dict:
    """A proposal with its curves, features, table and safety check, and its deployment state."""
    return with_state(conn, "proposal", proposals.get_proposal(conn, proposal_id))


@router.post("/proposals/{proposal_id}/edits", response_model=ProposalOut, status_code=status.HTTP_201_CREATED,
             responses={**FORBIDDEN, **NOT_FOUND, **CONFLICT})
def edit_proposal(proposal_id: IdPath, body: EditRequest, conn: Conn, user: Prosthetist) -> dict:
    """Derive a new draft version with edited table cells (prosthetist). The edited table is re-checked against
    every safety limit and refused (nothing stored) if any value is outside."""
    parent = versions.get_row(conn, "proposal", proposal_id)
    try:
        table, changes = edit_table(versions.stored_table(parent),
                                    [r.model_dump(exclude_none=True) for r in body.rows],
                                    body.thresholds.model_dump(exclude_none=True) if body.thresholds else None)
    except (EditError, ValidationError) as exc:
        raise InvalidError(str(exc).splitlines()[0]) from exc
    checked = as_run(table)
    violations = checked.violations
    if violations:
        raise InvalidError("edit refused, nothing stored: " + "; ".join(v.message for v in violations),
                           violations=[v.model_dump() for v in violations])
    created = proposals.create_edit(conn, proposal_id, checked, changes, body.comment, user)
    return with_state(conn, "proposal", created)


@router.get("/proposals/{proposal_id}/diff/{other_id}", response_model=DiffOut, responses=NOT_FOUND)
def diff_proposals(proposal_id: IdPath, other_id: IdPath, conn: Conn, _user: CurrentUser) -> dict:
    """What changed from ``proposal_id`` to ``other_id``: task, table cells and thresholds, with units."""
    return proposals.diff(conn, proposal_id, other_id)


@router.post("/proposals/{proposal_id}/approve", response_model=ProposalOut,
             responses={**FORBIDDEN, **NOT_FOUND, **CONFLICT})
def approve(proposal_id: IdPath, body: DecisionRequest, conn: Conn, user: Prosthetist) -> dict:
    """Approve a draft (prosthetist). The stored table is re-validated and every limit re-checked first;
    an approved proposal never changes."""
    decided = proposals.decide(conn, proposal_id, "approved", body.comment, user, body.override_reason)
    return with_state(conn, "proposal", decided)


@router.post("/proposals/{proposal_id}/reject", response_model=ProposalOut,
             responses={**FORBIDDEN, **NOT_FOUND, **CONFLICT})
def reject(proposal_id: IdPath, body: DecisionRequest, conn: Conn, user: Prosthetist) -> dict:
    """Reject a draft (prosthetist)."""
    return with_state(conn, "proposal", proposals.decide(conn, proposal_id, "rejected", body.comment, user))
