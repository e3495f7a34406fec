"""Refinements from walking: a refined draft of an approved envelope or table from the patient's sessions on it."""

from __future__ import annotations

from fastapi import APIRouter, status

from backend import refinement
from backend.deps import Conn, CurrentUser, Model, Prosthetist
from backend.errors import InvalidError
from backend.refinement import refine_envelope_version, refine_proposal_version
from backend.schemas.common import IdPath
from backend.schemas.errors import CONFLICT, FORBIDDEN, NOT_FOUND, TOO_MANY, UNAUTHORIZED, UNAVAILABLE
from backend.schemas.refinements import RefinementOut, RefinementRequest
from backend.store import versions
from backend.threads import run_bench

router = APIRouter(prefix="/api", tags=["refinements"], responses=UNAUTHORIZED)
_REFUSALS = {**FORBIDDEN, **NOT_FOUND, **CONFLICT, **UNAVAILABLE, **TOO_MANY}


def _ids(body: RefinementRequest) -> list[int]:
    try:
        return body.ids()
    except ValueError as e:
        raise InvalidError(str(e)) from e


@router.post("/envelopes/{envelope_id}/refinements", response_model=RefinementOut,
             status_code=status.HTTP_201_CREATED, responses=_REFUSALS)
async def refine_envelope(envelope_id: IdPath, body: RefinementRequest, conn: Conn, user: Prosthetist,
                          model: Model) -> dict:
    """Refine an approved envelope from the patient's stopped sessions on it (prosthetist): each stride's features
    against the model's targets at the leg's own estimate of its task, gathered per node by the leg's blend weights,
    a damped step of the rows where the strides agree. The result is a new draft (diff, edit, preview, approve or
    reject, push as any), stored with its evidence and audited. Refused with why, storing nothing: sessions of another
    patient or version, still recording, in safe mode all along, no strides, nothing to change. The bench walks the
    leg the envelope was made for (the patient's, ``backend/services/legs.py``), and the refinement says which."""
    # it walks the bench: on the bench's queue, never in the request threads a command to a leg needs
    job = ("refinement", f"envelope {envelope_id}", f"/api/envelopes/{envelope_id}")
    return await run_bench(user.username, job, refine_envelope_version, conn, envelope_id, _ids(body), body.comment, user,
                           model)


@router.post("/proposals/{proposal_id}/refinements", response_model=RefinementOut,
             status_code=status.HTTP_201_CREATED, responses=_REFUSALS)
async def refine_proposal(proposal_id: IdPath, body: RefinementRequest, conn: Conn, user: Prosthetist,
                          model: Model) -> dict:
    """Refine an approved table from the patient's stopped sessions on it (prosthetist), as an envelope's node at the
    table's task; the same rules and refusals."""
    job = ("refinement", f"table {proposal_id}", f"/api/proposals/{proposal_id}")
    return await run_bench(user.username, job, refine_proposal_version, conn, proposal_id, _ids(body), body.comment, user,
                           model)


@router.get("/refinements/{refinement_id}", response_model=RefinementOut, responses=NOT_FOUND)
def get_refinement(refinement_id: IdPath, conn: Conn, _user: CurrentUser) -> dict:
    """A refinement: its evidence per node, its changes and where it came from."""
    return refinement.get_refinement(conn, refinement_id)


@router.get("/envelopes/{envelope_id}/refinement", response_model=RefinementOut | None, responses=NOT_FOUND)
def refinement_of_envelope(envelope_id: IdPath, conn: Conn, _user: CurrentUser) -> dict | None:
    """The refinement that made this envelope, or null when it was not made by one (404: no such envelope)."""
    versions.get_row(conn, "envelope", envelope_id)
    return refinement.of_version(conn, envelope_id)


@router.get("/proposals/{proposal_id}/refinement", response_model=RefinementOut | None, responses=NOT_FOUND)
def refinement_of_proposal(proposal_id: IdPath, conn: Conn, _user: CurrentUser) -> dict | None:
    """The refinement that made this table, or null when it was not made by one (404: no such table)."""
    versions.get_row(conn, "proposal", proposal_id)
    return refinement.of_version(conn, proposal_id)
