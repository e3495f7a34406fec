"""Refinement from walking, for the API: stopped sessions on an approved version → a refined draft version.

The sessions must be this version's (the leg reported running exactly it) and this patient's, stopped, and have run
the version for at least one whole stride; their strides are read as the session report reads them
(:mod:`backend.session_strides`), judged per node against the model's targets at each stride's task
(:mod:`controller_core.refine_evidence`) and stepped (:mod:`controller_core.refine`). The result is a new draft derived
from the approved version, stored with its evidence in the same transaction, audited as ``envelope.refine`` or
``proposal.refine``, and decided like any version: nothing reaches the leg without approval. A refinement that would
change nothing, or that has nothing to learn from, is refused with why and stores nothing.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass

from sqlalchemy import Connection, RowMapping

from backend.errors import ConflictError, InvalidError
from backend.services import envelopes, legs, proposals
from backend.services import sessions as session_views
from backend.session_strides import session_strides
from backend.store import refinements, versions
from backend.store.users import User
from backend.store.versions import Item, api_ids
from controller_core.model import QuasiStiffnessModel
from controller_core.refine import REACH_FRACTION, RefineRules, change_in_steps, refine_envelope, refine_node
from controller_core.refine_evidence import (
    MIN_CONSISTENT_STRIDES,
    QUANTITIES,
    feature_abs_errors,
    gather_evidence,
    model_targets,
)
from controller_core.stride_features import MeasuredStride
from device_bridge.as_run import as_run
from device_bridge.bench.refine_walks import BenchStepCheck
from device_bridge.sim.leg_file import LegFile

BENCH_SECONDS = 12.0


def _bench_expectation(nodes: list[dict], before: list, after: list, check: BenchStepCheck) -> None:
    """Per changed node, what the bench expects: the node's old and new rows walked at its task (``BENCH_SECONDS``, the
    walks that checked the step, so mostly already made), the controlled quantities' mean errors with the same feature
    definitions; added to each node's summary as ``bench`` (the bench is not the patient: read the change, after −
    before, more than either figure)."""
    for k, n in enumerate(nodes):
        if not (n["changed"] and n["strides"]):
            continue
        old = check.errors(before[k], n["speed_mps"], n["incline_deg"])
        new = check.errors(after[k], n["speed_mps"], n["incline_deg"])
        n["bench"] = {"walked": True, "seconds": BENCH_SECONDS, "before": old["error"], "after": new["error"],
                      "falls_before": old["falls"], "falls_after": new["falls"],
                      "change": {q: None if old["error"][q] is None or new["error"][q] is None
                                 else round(new["error"][q] - old["error"][q], 3) for q in old["error"]}}


SENSITIVITY = ("measured on the simulated bench at the node's task (controller_core/data/refine_sensitivity.json, "
               "'quasitune sensitivity'): how far each controlled feature moved when each refined value was changed a "
               "little, on the nominal leg; each node's step is walked on the bench's leg before it is taken (halved, "
               "then quartered, then left out where the bench does not confirm it); this leg's response is checked "
               "each round and a feature that does not respond is held")


def _sessions(conn: Connection, kind: str, version_id: int, patient_id: int, session_ids: list[int]
              ) -> list[dict]:
    """The sessions, each checked to be this version's and this patient's, stopped (refusals say which and why)."""
    label = {"envelope": "this envelope", "proposal": "this table"}[kind]
    out = []
    for sid in dict.fromkeys(session_ids):
        s = session_views.get_session(conn, sid)   # 404 for an unknown id
        if s["patient_id"] != patient_id:
            raise InvalidError(f"session {sid} records patient {s['patient_code']}, not the patient of {label}: a "
                               "refinement learns from the patient's own strides only")
        ran = s["envelope_id"] if kind == "envelope" else s["proposal_id"]
        if ran != version_id:
            on = s["table_label"] or "no table of ours"
            raise InvalidError(f"session {sid} ran {on}, not {label}: refine the version the strides were walked with")
        if s["status"] != "stopped":
            raise ConflictError(f"session {sid} is still recording: stop it first")
        out.append(s)
    return out


def _strides(conn: Connection, sessions: list[dict]) -> tuple[list[MeasuredStride], dict]:
    """Every session's measured strides, and what was counted along the way (refuses a session that never ran)."""
    strides: list[MeasuredStride] = []
    total = on_table = 0
    not_found: dict[str, int] = {}
    for s in sessions:
        got = session_strides(conn, s)
        if got.total and not got.on_table:
            raise InvalidError(f"session {s['id']} never ran its version for a whole stride (safe mode or no table "
                               "all along): its strides say nothing about the version")
        strides += got.strides
        total += got.total
        on_table += got.on_table
        for k, v in got.not_found.items():
            not_found[k] = not_found.get(k, 0) + v
    if not strides:
        raise InvalidError(f"no strides to learn from in sessions {[s['id'] for s in sessions]}: {total} stride(s) "
                           f"in all, {on_table} on the version, none with a task to compare with")
    return strides, {"strides": total, "strides_on_version": on_table, "strides_used": len(strides),
                     "strides_without_feature": {k: v for k, v in not_found.items() if v}}


def _evidence(counted: dict, strides: list[MeasuredStride], targets, nodes: list[dict], changes: list[dict],
              session_ids: list[int], rules: RefineRules, leg: LegFile) -> dict:
    return {**counted, "session_ids": session_ids, "feature_abs_error": feature_abs_errors(strides, targets),
            "bench_leg": legs.words(leg),
            "quantities": {q.key: {"label": q.label, "tolerance": q.tolerance,
                                   "unit": q.unit} for q in QUANTITIES},
            "nodes": nodes, "changes": changes, "nodes_changed": sorted({tuple(c["node"]) for c in changes}),
            "sensitivity": SENSITIVITY,
            "change_in_steps": change_in_steps(changes, rules),
            "rules": {**{k: getattr(rules, k) for k in ("damping", "theta_step_deg", "k_step_fraction",
                                                         "swing_threshold_fraction")},
                      "reach_fraction": REACH_FRACTION,
                      "min_consistent_strides": MIN_CONSISTENT_STRIDES}}


def _nothing(nodes: list[dict]) -> InvalidError:
    why = sorted({n["left_alone"] for n in nodes if n["strides"] and n.get("left_alone")})
    return InvalidError("nothing to refine, nothing stored: " + ("; ".join(why) if why else "no node was walked"),
                        nodes=nodes)



def view(row: RowMapping) -> dict:
    """A refinement as the API gives it: the version it made (a table's ``proposal_id`` or an envelope's
    ``envelope_id``), its parent, sessions, author and time, and its stored evidence."""
    return {"id": row["id"], **api_ids(row["kind"], row["version_id"]), "parent_id": row["parent_id"],
            "session_ids": json.loads(row["session_ids_json"]),
            "created_by": row["created_by_name"], "created_at": row["created_at"],
            **json.loads(row["evidence_json"])}


def get_refinement(conn: Connection, refinement_id: int) -> dict:
    return view(refinements.refinement_row(conn, refinement_id))


def of_version(conn: Connection, version_id: int) -> dict | None:
    """The refinement that made this version, if one did."""
    row = refinements.row_of_version(conn, version_id)
    return None if row is None else view(row)

@dataclass(frozen=True)
class _Inputs:
    """What either kind of refinement starts from: the approved version's row, the sessions walked on it and their
    strides (and what was counted of them), the model's targets, the last refinement of it, and the leg it was made
    for, which every bench check walks."""

    row: RowMapping
    sessions: list[dict]
    strides: list[MeasuredStride]
    counted: dict
    targets: Callable
    before: dict | None
    leg: LegFile


def _inputs(conn: Connection, kind: Item, version_id: int, session_ids: list[int], model: QuasiStiffnessModel
            ) -> _Inputs:
    row = versions.get_row(conn, kind, version_id)
    if row["status"] != "approved":
        what = "envelope" if kind == "envelope" else "table"
        raise ConflictError(f"{what} {version_id} is {row['status']}: a refinement derives from the approved version "
                            "the leg walked")
    sessions = _sessions(conn, kind, version_id, row["patient_id"], session_ids)
    strides, counted = _strides(conn, sessions)
    return _Inputs(row, sessions, strides, counted, model_targets(model), of_version(conn, version_id),
                   legs.version_leg(row))


def refine_envelope_version(conn: Connection, envelope_id: int, session_ids: list[int], comment: str,
                            actor: User, model: QuasiStiffnessModel) -> dict:
    """A refined draft of an approved envelope from its sessions (module docstring); returns the refinement."""
    x = _inputs(conn, "envelope", envelope_id, session_ids, model)
    parent = versions.stored_envelope(x.row)
    evidence = gather_evidence(x.strides, parent.speeds_mps, parent.inclines_deg, x.targets)
    rules = RefineRules()
    check = BenchStepCheck(model, parent.mass_kg, BENCH_SECONDS, x.leg.geometry())
    result = refine_envelope(parent, evidence, rules, x.before["nodes"] if x.before else None, check)
    if not result.changes:
        raise _nothing(result.nodes)
    checked = as_run(result.envelope)
    if checked.violations:   # not reached by construction; refused rather than stored
        raise InvalidError("the refined envelope breaks a limit, nothing stored: " + "; ".join(
            v.message for v in checked.violations))
    _bench_expectation(result.nodes, parent.tables(), result.envelope.tables(), check)
    body = _evidence(x.counted, x.strides, x.targets, result.nodes, result.changes, [s["id"] for s in x.sessions],
                     rules, x.leg)
    created = envelopes.create_edit(conn, envelope_id, checked, result.changes, comment, actor, "envelope.refine",
                                    refinements.recorder(envelope_id, body["session_ids"], body, actor))
    return {**of_version(conn, created["id"]), "version": created}


def refine_proposal_version(conn: Connection, proposal_id: int, session_ids: list[int], comment: str,
                            actor: User, model: QuasiStiffnessModel) -> dict:
    """A refined draft of an approved table from its sessions: the table is one node at its task, every stride its
    evidence; returns the refinement."""
    x = _inputs(conn, "proposal", proposal_id, session_ids, model)
    row = x.row
    table = versions.stored_table(row)
    [evidence] = gather_evidence(x.strides, [row["speed_mps"]], [row["incline_deg"]], x.targets)
    rules = RefineRules()
    check = BenchStepCheck(model, row["body_mass_kg"], BENCH_SECONDS, x.leg.geometry())
    result = refine_node(table, evidence, rules, previous=x.before["nodes"][0] if x.before else None, check=check)
    node = {**evidence.to_json(), "changed": bool(result.changes), "left_alone": result.left_alone}
    if result.step_refused:
        node["step_scale"], node["step_refused"] = result.step_scale, result.step_refused
    for key, q in node["quantities"].items():
        q["expected_error"] = None if key not in result.expected_error else round(result.expected_error[key], 3)
    if not result.changes:
        raise _nothing([node])
    checked = as_run(result.table)
    if checked.violations:
        raise InvalidError("the refined table breaks a limit, nothing stored: " + "; ".join(
            v.message for v in checked.violations))
    changes = [{"node": [0, 0], "speed_mps": row["speed_mps"], "incline_deg": row["incline_deg"], "walked": True,
                **c} for c in result.changes]
    node["stride_weight"] = evidence.weight
    _bench_expectation([node], [table], [result.table], check)
    body = _evidence(x.counted, x.strides, x.targets, [node], changes, [s["id"] for s in x.sessions], rules, x.leg)
    created = proposals.create_edit(conn, proposal_id, checked, result.changes, comment, actor, "proposal.refine",
                                    refinements.recorder(proposal_id, body["session_ids"], body, actor))
    return {**of_version(conn, created["id"]), "version": created}
