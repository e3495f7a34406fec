"""Proposal versions for the clinic: the view the page and the API give (table, curves, the live limit check), and the
rules around storing one: checked as the device will run it when created or edited, re-checked and gated on the
bench's verdict when approved (:mod:`backend.services.decisions`). Storage is :mod:`backend.store.versions` (a table
is stored as the envelope of its one node, with the model's output it came from).
"""

from __future__ import annotations

import json
from collections.abc import Callable

import numpy as np
from pydantic_core import to_json
from sqlalchemy import Connection, RowMapping

from backend.db import write_transaction
from backend.services import legs
from backend.services.decisions import decide_once, version_meta
from backend.store import audit
from backend.store.users import User
from backend.store.versions import get_row, insert_row, list_rows, stored_table, version_label
from controller_core.proposal import Proposal
from controller_core.table import STUMBLE_THRESHOLDS, LimitViolation, ParameterTable, SafetyLimits, display_rows
from controller_core.table_rules import SWING_SCALED
from device_bridge.as_run import AsRun, as_run
from device_bridge.sim.leg_file import LegFile

LIMITS = SafetyLimits().model_dump()
# display units of the table's values, for diffs
ROW_UNITS = {"k_Nm_per_rad": "N·m/rad", "theta_e_deg": "deg", "b_Nm_s_per_rad": "N·m·s/rad"}
THRESHOLD_UNITS = {"sf_to_se_ankle_moment_Nm": "N·m", "se_to_wf_load_N": "N", "wf_to_we_knee_angle_deg": "deg",
                   "we_to_sf_load_N": "N", "min_state_time_s": "s", "max_state_time_s": "s",
                   "sf_to_se_knee_extension_deg_per_s": "deg/s", **STUMBLE_THRESHOLDS}


def _assemble(meta: dict, table: ParameterTable, body: dict, full: bool,
              violations: list[LimitViolation] | None = None) -> dict:
    """The API view of a proposal from its metadata, its (validated) table and its stored model body
    (``violations``: the table's limit check when the caller has just made it)."""
    violations = as_run(table).violations if violations is None else violations
    out = {
        **meta,
        "model": body["model"],
        "table": display_rows(table),
        "thresholds": table.thresholds.model_dump(),
        "table_sha256": meta["table_sha256"],
        "safety": {"ok": not violations, "violations": [v.model_dump() for v in violations]},
        "swing_inertia": swing_inertia(table),
    }
    if full:
        out |= {"features": body["features"], "subphase_boundaries_phase": body["subphase_boundaries_phase"],
                "curves": body["curves"], "via_points": body.get("via_points", []), "limits": LIMITS}
    return out


def swing_inertia(table: ParameterTable) -> dict[str, object]:
    """The leg a table's swing rows were proposed for (its provenance) and the rows scaled for it, as the API gives
    it."""
    knee, ankle = table.provenance.swing_inertia_ratio
    return {"knee_ratio": round(knee, 4), "ankle_ratio": round(ankle, 4),
            "scaled_rows": [f"{joint}.{subphase}" for joint, subphases in SWING_SCALED.items() for subphase in subphases]}


def _meta(row: RowMapping) -> dict:
    return {**version_meta(row), "table_label": version_label("table", row["patient_code"], row["version"]),
            "task": {"speed_mps": row["speed_mps"], "incline_deg": row["incline_deg"],
                     "body_mass_kg": row["body_mass_kg"]},
            "table_sha256": row["content_sha256"], "content_sha256": row["content_sha256"]}


def _public(row: RowMapping, full: bool) -> dict:
    return _assemble(_meta(row), stored_table(row), json.loads(row["model_json"]), full)


def get_proposal(conn: Connection, proposal_id: int, full: bool = True) -> dict:
    return _public(get_row(conn, "proposal", proposal_id), full)


def list_proposals(conn: Connection, patient_id: int, limit: int = 50,
                   before_version: int | None = None) -> tuple[list[dict], int]:
    """One page of summaries, newest version first (metadata only: the table, curves and the live limit check are
    the full version's, on its own endpoint), and how many versions the patient has in all."""
    rows, total = list_rows(conn, "proposal", patient_id, limit, before_version)
    return [{**_meta(r), "safety_ok": bool(r["safety_ok"])} for r in rows], total


def _refuse_non_finite(proposal: Proposal) -> None:
    """The fast encoder would write NaN into the JSON; a model that produced one has a bug, never stored."""
    arrays = [*proposal.means.values(), *proposal.stds.values(),
              np.array([[f.value, f.std, f.phase, f.phase_std] for f in proposal.features])]
    if not all(np.isfinite(a).all() for a in arrays):
        raise RuntimeError("the model produced a non-finite curve or feature; nothing stored")


def insert_from_model(conn: Connection, patient_id: int, proposal: Proposal, actor: User,
                      extrapolation_reason: str | None = None, leg: LegFile | None = None) -> dict:
    """Store a freshly computed proposal as the patient's next draft version, inside the caller's write
    transaction; returns its API view. ``extrapolation_reason``: the prosthetist's reason for a task beyond the
    tasks the model knows (audited, shown with the version); ``leg``: the leg it was made for (None: the nominal
    one)."""
    body = proposal.model_body()
    _refuse_non_finite(proposal)
    model_json = to_json(body).decode()   # pydantic-core's encoder: far faster than json.dumps on 808 floats
    task = {"speed_mps": proposal.speed_mps, "incline_deg": proposal.incline_deg, "body_mass_kg": proposal.mass_kg}
    checked = as_run(proposal.table)   # stored, shown and checked as the device will run it
    table, violations = checked.item, checked.violations
    meta = _meta(insert_row(conn, patient_id, None, table, checked.wire_crc32, not violations, None, actor,
                            extrapolation_reason, legs.leg_json(leg or LegFile()), model_json=model_json))
    audit.record(conn, actor.id, actor.username, "proposal.create", "proposal", meta["id"],
                 after={"patient_id": patient_id, "version": meta["version"], "task": task, "leg": meta["leg"]["words"],
                        "table_sha256": meta["table_sha256"], "safety_ok": not violations,
                        "extrapolation": meta["extrapolation"], "extrapolation_reason": extrapolation_reason})
    return _assemble(meta, table, body, full=True, violations=violations)


def create_from_model(conn: Connection, patient_id: int, proposal: Proposal, actor: User,
                      extrapolation_reason: str | None = None, leg: LegFile | None = None) -> dict:
    """:func:`insert_from_model` in a write transaction of its own."""
    with write_transaction(conn):
        return insert_from_model(conn, patient_id, proposal, actor, extrapolation_reason, leg)


def create_edit(conn: Connection, parent_id: int, checked: AsRun[ParameterTable], changes: list[dict],
                comment: str, actor: User, action: str = "proposal.edit",
                also: Callable[[Connection, dict], dict] | None = None) -> dict:
    """Store an edited table as a new draft derived from ``parent_id``, as the device runs it: ``checked`` is the
    caller's :func:`~device_bridge.as_run.as_run` of the edit (its check made once, by the caller that refuses).
    ``action``: what the audit calls it (a refinement is ``proposal.refine``); ``also``: run in the same transaction
    with the new version's metadata (e.g. store the refinement's evidence), its result added to the audit entry."""
    table, violations = checked.item, checked.violations
    with write_transaction(conn):
        parent = get_row(conn, "proposal", parent_id)
        meta = _meta(insert_row(conn, parent["patient_id"], parent_id, table, checked.wire_crc32, not violations,
                                comment, actor, parent["extrapolation_reason"], parent["leg_json"],
                                model_json=parent["model_json"]))
        out = _assemble(meta, table, json.loads(parent["model_json"]), full=True, violations=violations)
        pid = meta["id"]
        extra = also(conn, meta) if also is not None else {}
        audit.record(conn, actor.id, actor.username, action, "proposal", pid,
                     before={"proposal_id": parent_id, "version": parent["version"],
                             "table_sha256": parent["content_sha256"],
                             **{c["field"]: c["before"] for c in changes}},
                     after={"version": out["version"], "table_sha256": out["table_sha256"], "comment": comment,
                            **{c["field"]: c["after"] for c in changes}, **extra})
    return out


def decide(conn: Connection, proposal_id: int, status: str, comment: str, actor: User,
           override_reason: str | None = None) -> dict:
    """Approve or reject a draft once. Approval re-validates the stored table and re-checks every limit."""
    with write_transaction(conn):
        row = get_row(conn, "proposal", proposal_id)
        decide_once(conn, "proposal", row, status, comment, actor, lambda: as_run(stored_table(row)).violations,
                    "the safety limits", {"table_sha256": row["content_sha256"]}, override_reason)
        return get_proposal(conn, proposal_id)


def diff(conn: Connection, a_id: int, b_id: int) -> dict:
    """Field-by-field differences from proposal ``a_id`` to ``b_id`` (task, table cells, thresholds)."""
    a, b = get_row(conn, "proposal", a_id), get_row(conn, "proposal", b_id)
    ta, tb = stored_table(a), stored_table(b)
    changes: list[dict] = []

    def add(field: str, before: object, after: object, unit: str | None) -> None:
        if before != after:
            changes.append({"field": field, "before": before, "after": after, "unit": unit})

    add("task.speed_mps", a["speed_mps"], b["speed_mps"], "m/s")
    add("task.incline_deg", a["incline_deg"], b["incline_deg"], "deg")
    add("task.body_mass_kg", a["body_mass_kg"], b["body_mass_kg"], "kg")
    for ra in ta.rows:
        rb = tb.row(ra.joint, ra.subphase)
        for name in (*ROW_UNITS, "fit_method"):
            add(f"{ra.joint}.{ra.subphase}.{name}", getattr(ra, name), getattr(rb, name), ROW_UNITS.get(name))
    for name, unit in THRESHOLD_UNITS.items():
        add(f"thresholds.{name}", getattr(ta.thresholds, name), getattr(tb.thresholds, name), unit)
    return {"from_id": a_id, "to_id": b_id, "from_version": a["version"], "to_version": b["version"],
            "same_patient": a["patient_id"] == b["patient_id"], "changes": changes}
