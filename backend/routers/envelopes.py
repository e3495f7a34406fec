"""Envelopes: request one for a patient over speed and incline ranges, read it, approve or reject it once."""

from __future__ import annotations

from typing import Annotated

import numpy as np
from fastapi import APIRouter, Path, Request, Response, status

from backend.clinical_words import violation_words
from backend.deps import Conn, CurrentUser, Model, Prosthetist
from backend.errors import InvalidError
from backend.schemas.common import BeforeVersion, IdPath, PageLimit, page_headers
from backend.schemas.envelopes import (
    EnvelopeDiffOut,
    EnvelopeEditRequest,
    EnvelopeListItem,
    EnvelopeNodeOut,
    EnvelopeOut,
    EnvelopeRequest,
)
from backend.schemas.errors import CONFLICT, FORBIDDEN, NOT_FOUND, UNAUTHORIZED, UNAVAILABLE
from backend.schemas.proposals import DecisionRequest
from backend.services import envelopes, legs
from backend.services.versions import with_state
from backend.store import patients, versions
from backend.task_range import extrapolation_reason
from controller_core.envelope_edit import edit_envelope, hold_to_neighbour_rule
from controller_core.table_edit import EditError
from device_bridge.as_run import as_run

router = APIRouter(prefix="/api", tags=["envelopes"], responses=UNAUTHORIZED)


@router.post("/patients/{patient_id}/envelopes", response_model=EnvelopeOut, status_code=status.HTTP_201_CREATED,
             responses={**FORBIDDEN, **NOT_FOUND, **UNAVAILABLE})
def create_envelope(patient_id: IdPath, body: EnvelopeRequest, request: Request, conn: Conn, user: Prosthetist,
                    model: Model) -> dict:
    """Build the patient's next draft envelope (prosthetist): one table per node of the speed × incline grid, for the
    patient's body mass, each from the model and within the limits, neighbours held to the neighbour rule; with the
    device-side check of every node and both CRCs. Nodes beyond what the model knows (``GET /api/task-range``) are
    refused (422) unless ``extrapolate`` comes with a ``reason``, which is audited and shown with the version."""
    patient = patients.get_patient(conn, patient_id)
    corners = [(s, g) for s in body.speed_range_mps for g in body.incline_range_deg]
    reason = extrapolation_reason(model, corners, body.extrapolate, body.reason)
    leg = legs.patient_leg(patient, request.app.state.bench_leg_file)   # made for the patient's leg
    env = model.propose_envelope(np.linspace(*body.speed_range_mps, body.grid[0]),
                                 np.linspace(*body.incline_range_deg, body.grid[1]), patient["body_mass_kg"],
                                 nominal=(body.nominal_speed_mps, body.nominal_incline_deg),
                                 swing_inertia_ratio=legs.swing_ratio(leg))
    created = envelopes.create_from_model(conn, patient_id, env, user, reason, leg)
    return with_state(conn, "envelope", created)


@router.get("/patients/{patient_id}/envelopes", response_model=list[EnvelopeListItem], responses=NOT_FOUND)
def list_envelopes(patient_id: IdPath, response: Response, conn: Conn, _user: CurrentUser, limit: PageLimit = 50,
                   before_version: BeforeVersion = None) -> list[dict]:
    """One page of the patient's envelope versions, newest first: metadata and axes only (nodes and the live
    device-side check are on ``GET /api/envelopes/{id}``). ``X-Total-Count``: how many in all;
    ``X-Next-Before-Version``: the cursor of the next page."""
    patients.get_patient(conn, patient_id)
    items, total = envelopes.list_envelopes(conn, patient_id, limit, before_version)
    return page_headers(response, items, total, limit)


@router.get("/envelopes/{envelope_id}", response_model=EnvelopeOut, responses=NOT_FOUND)
def get_envelope(envelope_id: IdPath, conn: Conn, _user: CurrentUser) -> dict:
    """An envelope with every node's table, extrapolation flag, feature SDs and guarded values, and its check."""
    return with_state(conn, "envelope", envelopes.get_envelope(conn, envelope_id))


@router.get("/envelopes/{envelope_id}/nodes/{i}/{j}", response_model=EnvelopeNodeOut, responses=NOT_FOUND)
def get_node(envelope_id: IdPath, i: Annotated[int, Path(ge=0, le=14, description="speed index")],
             j: Annotated[int, Path(ge=0, le=14, description="incline index")], conn: Conn, _user: CurrentUser,
             model: Model) -> dict:
    """One node as a proposal is shown: its table as stored in the envelope (held to the neighbour rule, edited as
    approved) with its check, and the model's curves, features and via-points at the node's task."""
    row = versions.get_row(conn, "envelope", envelope_id)
    env = versions.stored_envelope(row)
    view = envelopes.node_view(row, env, i, j)
    return {**view, **model.propose(view["task"]["speed_mps"], view["task"]["incline_deg"], env.mass_kg).model_body()}


@router.post("/envelopes/{envelope_id}/edits", response_model=EnvelopeOut, status_code=status.HTTP_201_CREATED,
             responses={**FORBIDDEN, **NOT_FOUND, **CONFLICT})
def edit(envelope_id: IdPath, body: EnvelopeEditRequest, conn: Conn, user: Prosthetist) -> dict:
    """Derive a new draft with one or more settings changed across the envelope or at one node (prosthetist), e.g.
    knee stance flexion 10 % firmer everywhere. Every node's limits and the neighbour rule are re-checked as the
    device runs them; a refused edit stores nothing. With ``hold_to_neighbour_rule``, values the edit would put more
    than a step from a neighbour are held within it (listed in the changes with ``held_from``) instead."""
    parent = versions.stored_envelope(versions.get_row(conn, "envelope", envelope_id))
    try:
        edited, changes = edit_envelope(parent, [e.model_dump() for e in body.edits])
        if body.hold_to_neighbour_rule:
            edited, changes = hold_to_neighbour_rule(parent, edited, changes)
    except (EditError, ValueError) as exc:
        raise InvalidError(str(exc).splitlines()[0]) from exc
    checked = as_run(edited)
    violations = checked.violations
    if violations:
        neighbours_only = all(v.field.startswith("neighbours[") for v in violations)
        hint = (" Ask again holding those values within a step of their neighbours (“hold within a step”): each "
                "value so held is listed with what the edit gave." if neighbours_only else "")
        raise InvalidError(f"Edit refused, nothing stored: {len(violations)} value(s) outside the safety limits or "
                           "more than a step from a neighbouring task: " + "; ".join(violation_words(v) for v in violations)
                           + "." + hint, violations=[v.model_dump() for v in violations],
                           neighbour_rule_only=neighbours_only)
    created = envelopes.create_edit(conn, envelope_id, checked, changes, body.comment, user)
    return with_state(conn, "envelope", created)


@router.get("/envelopes/{envelope_id}/diff/{other_id}", response_model=EnvelopeDiffOut, responses=NOT_FOUND)
def diff(envelope_id: IdPath, other_id: IdPath, conn: Conn, _user: CurrentUser) -> dict:
    """What changed from ``envelope_id`` to ``other_id``, node by node, with units."""
    return envelopes.diff(conn, envelope_id, other_id)


@router.post("/envelopes/{envelope_id}/approve", response_model=EnvelopeOut,
             responses={**FORBIDDEN, **NOT_FOUND, **CONFLICT})
def approve_envelope(envelope_id: IdPath, body: DecisionRequest, conn: Conn, user: Prosthetist) -> dict:
    """Approve a draft envelope (prosthetist). The stored envelope is re-validated and every node and the neighbour
    rule re-checked as the device will run them; an approved envelope never changes."""
    decided = envelopes.decide(conn, envelope_id, "approved", body.comment, user, body.override_reason)
    return with_state(conn, "envelope", decided)


@router.post("/envelopes/{envelope_id}/reject", response_model=EnvelopeOut,
             responses={**FORBIDDEN, **NOT_FOUND, **CONFLICT})
def reject_envelope(envelope_id: IdPath, body: DecisionRequest, conn: Conn, user: Prosthetist) -> dict:
    """Reject a draft envelope (prosthetist)."""
    return with_state(conn, "envelope", envelopes.decide(conn, envelope_id, "rejected", body.comment, user))
