"""Versions of a patient's parameters: a table for one task (``/api/proposals/…``) or an envelope over a range of tasks
(``/api/envelopes/…``), both rows of one versions table. Request one, read it, derive an edited version, diff two,
approve or reject it once. What is the same for both kinds (read, list, diff, decide) is one handler registered under
each kind's paths; requesting and editing differ (a task or a grid; table cells or settings across nodes)."""

from collections.abc import Callable
from dataclasses import dataclass
from typing import Annotated, Any

import numpy as np
from fastapi import APIRouter, Path, Request, Response, status
from fastapi.responses import RedirectResponse
from pydantic import ValidationError
from sqlalchemy import Connection

from backend.clinical_words import violation_words
from backend.deps import Conn, CurrentUser, Model, Prosthetist
from backend.errors import InvalidError
from backend.schemas.common import MAX_ID, BeforeVersion, IdPath, PageLimit, page_headers
from backend.schemas.errors import CONFLICT, FORBIDDEN, NOT_FOUND, UNAUTHORIZED, UNAVAILABLE
from backend.schemas.versions import (
    DecisionRequest,
    DiffOut,
    EditRequest,
    EnvelopeDiffOut,
    EnvelopeEditRequest,
    EnvelopeListItem,
    EnvelopeNodeOut,
    EnvelopeOut,
    EnvelopeRequest,
    ProposalListItem,
    ProposalOut,
    ProposalRequest,
)
from backend.services import envelopes, legs, proposals
from backend.services.versions import with_state
from backend.store import patients, versions
from backend.store.versions import Item
from backend.task_range import extrapolation_reason
from controller_core.envelope_edit import edit_envelope, hold_to_neighbour_rule
from controller_core.table_edit import EditError, edit_table
from device_bridge.as_run import as_run

router = APIRouter(prefix="/api", responses=UNAUTHORIZED)
_DECIDE = {**FORBIDDEN, **NOT_FOUND, **CONFLICT}


@dataclass(frozen=True)
class _Kind:
    """What differs between a table and an envelope where the handlers are the same."""

    item: Item
    words: str                      # what the clinic calls it
    out: type
    list_item: type
    diff_out: type
    get: Callable[[Connection, int], dict]
    listed: Callable[..., tuple[list[dict], int]]
    diff: Callable[[Connection, int, int], dict]
    decide: Callable[..., dict]
    shows: str                      # what its full view holds
    diff_shows: str


_KINDS = (
    _Kind("proposal", "table", ProposalOut, ProposalListItem, DiffOut, proposals.get_proposal,
          proposals.list_proposals, proposals.diff, proposals.decide,
          "its curves, features, table and safety check", "task, table cells and thresholds"),
    _Kind("envelope", "envelope", EnvelopeOut, EnvelopeListItem, EnvelopeDiffOut, envelopes.get_envelope,
          envelopes.list_envelopes, envelopes.diff, envelopes.decide,
          "every node's table, extrapolation flag, feature SDs and guarded values, and its device-side check",
          "node by node, every value"),
)


def _register(k: _Kind) -> None:
    """Read, list, diff and decide a version of kind ``k``, under its own paths (``/api/proposals/{proposal_id}`` …;
    no deferred annotations in this module: the path parameter's type is made here, per kind)."""
    plural = f"{k.item}s"
    version_path = Annotated[int, Path(alias=f"{k.item}_id", ge=1, le=MAX_ID, description=f"the {k.words}'s id")]

    def list_versions(patient_id: IdPath, response: Response, conn: Conn, _user: CurrentUser, limit: PageLimit = 50,
                      before_version: BeforeVersion = None) -> list[dict]:
        patients.get_patient(conn, patient_id)
        items, total = k.listed(conn, patient_id, limit, before_version)
        return page_headers(response, items, total, limit)

    def get_version(version_id: version_path, conn: Conn, _user: CurrentUser) -> dict:
        return with_state(conn, k.item, k.get(conn, version_id))

    def diff_versions(version_id: version_path, other_id: IdPath, conn: Conn, _user: CurrentUser) -> dict:
        return k.diff(conn, version_id, other_id)

    def approve(version_id: version_path, body: DecisionRequest, conn: Conn, user: Prosthetist) -> dict:
        return with_state(conn, k.item, k.decide(conn, version_id, "approved", body.comment, user,
                                                 body.override_reason))

    def reject(version_id: version_path, body: DecisionRequest, conn: Conn, user: Prosthetist) -> dict:
        return with_state(conn, k.item, k.decide(conn, version_id, "rejected", body.comment, user))

    routes: list[tuple[str, Callable[..., Any], str, Any, dict, str]] = [
        (f"/patients/{{patient_id}}/{plural}", list_versions, "GET", list[k.list_item], NOT_FOUND,
         f"One page of the patient's {k.words} versions, newest first: metadata only (the rest is on "
         f"``GET /api/{plural}/{{id}}``). ``X-Total-Count``: how many in all; ``X-Next-Before-Version``: the cursor "
         "of the next page."),
        (f"/{plural}/{{{k.item}_id}}", get_version, "GET", k.out, NOT_FOUND,
         f"A {k.words} with {k.shows}, its deployment state, the bench's verdict and any withdrawal."),
        (f"/{plural}/{{{k.item}_id}}/diff/{{other_id}}", diff_versions, "GET", k.diff_out, NOT_FOUND,
         f"What changed from this {k.words} to ``other_id``: {k.diff_shows}, with units."),
        (f"/{plural}/{{{k.item}_id}}/approve", approve, "POST", k.out, _DECIDE,
         f"Approve a draft {k.words} (prosthetist), once. The stored content is re-validated and re-checked as the "
         "device will run it, and the approval rests on the bench's verdict on exactly this content "
         "(two prosthetists' sign-offs otherwise); an approved version never changes."),
        (f"/{plural}/{{{k.item}_id}}/reject", reject, "POST", k.out, _DECIDE, f"Reject a draft {k.words} "
         "(prosthetist), once."),
    ]
    for path, endpoint, method, model, responses, description in routes:
        router.add_api_route(path, endpoint, methods=[method], response_model=model, responses=responses,
                             description=description, name=f"{endpoint.__name__}_{k.item}",
                             tags=[plural])


for _k in _KINDS:
    _register(_k)


@router.get("/versions/{version_id}", status_code=status.HTTP_307_TEMPORARY_REDIRECT, responses=NOT_FOUND,
            response_class=RedirectResponse, tags=["versions"])
def find_version(version_id: IdPath, conn: Conn, _user: CurrentUser) -> RedirectResponse:
    """Any version by its id (tables and envelopes share one id space): sent on to its kind's path,
    ``/api/proposals/{id}`` for a table or ``/api/envelopes/{id}`` for an envelope."""
    kind = versions.kind_of(conn, version_id)
    return RedirectResponse(f"/api/{versions.ITEM_OF[kind]}s/{version_id}",
                            status_code=status.HTTP_307_TEMPORARY_REDIRECT)


# ---------------------------------------------------------------------------------------------- a table (one task)

@router.post("/patients/{patient_id}/proposals", response_model=ProposalOut, status_code=status.HTTP_201_CREATED,
             responses={**FORBIDDEN, **NOT_FOUND, **UNAVAILABLE}, tags=["proposals"])
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


@router.post("/proposals/{proposal_id}/edits", response_model=ProposalOut, status_code=status.HTTP_201_CREATED,
             responses={**FORBIDDEN, **NOT_FOUND, **CONFLICT}, tags=["proposals"])
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
    if checked.violations:
        raise InvalidError("edit refused, nothing stored: " + "; ".join(v.message for v in checked.violations),
                           violations=[v.model_dump() for v in checked.violations])
    return with_state(conn, "proposal", proposals.create_edit(conn, proposal_id, checked, changes, body.comment, user))


# ------------------------------------------------------------------------------------ an envelope (a range of tasks)

@router.post("/patients/{patient_id}/envelopes", response_model=EnvelopeOut, status_code=status.HTTP_201_CREATED,
             responses={**FORBIDDEN, **NOT_FOUND, **UNAVAILABLE}, tags=["envelopes"])
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


@router.get("/envelopes/{envelope_id}/nodes/{i}/{j}", response_model=EnvelopeNodeOut, responses=NOT_FOUND,
            tags=["envelopes"])
def get_node(envelope_id: IdPath, i: Annotated[int, Path(ge=0, le=14, description="speed index")],
             j: Annotated[int, Path(ge=0, le=14, description="incline index")], conn: Conn, _user: CurrentUser,
             model: Model) -> dict:
    """One node as a table is shown: its table as stored in the envelope (held to the neighbour rule, edited as
    approved) with its check, and the model's curves, features and via-points at the node's task."""
    row = versions.get_row(conn, "envelope", envelope_id)
    env = versions.stored_envelope(row)
    view = envelopes.node_view(row, env, i, j)
    return {**view, **model.propose(view["task"]["speed_mps"], view["task"]["incline_deg"], env.mass_kg).model_body()}


@router.post("/envelopes/{envelope_id}/edits", response_model=EnvelopeOut, status_code=status.HTTP_201_CREATED,
             responses={**FORBIDDEN, **NOT_FOUND, **CONFLICT}, tags=["envelopes"])
def edit_envelope_version(envelope_id: IdPath, body: EnvelopeEditRequest, conn: Conn, user: Prosthetist) -> dict:
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
    return with_state(conn, "envelope", envelopes.create_edit(conn, envelope_id, checked, changes, body.comment, user))
