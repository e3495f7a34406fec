"""Proposal versions as stored: a draft's row written once, read back with who made and decided it, and its table
re-validated against the sha256 it was stored with.

A proposal's content (task, curves, features, table) is immutable — triggers refuse any change (the baseline
revision) — and its decision is taken at most once (:func:`backend.store.decisions.record_decision`). Versions are
numbered per patient (1, 2, …); an edit records its parent. What a version means to the clinic (its view, its
checks, approving it) is :mod:`backend.services.proposals`.
"""

from __future__ import annotations

from functools import partial

from sqlalchemy import Connection, RowMapping, bindparam, insert

from backend.db import utc_now
from backend.errors import ConflictError, NotFoundError
from backend.store.decisions import next_version, summary_columns, version_page, version_select
from backend.store.patients import lock_patient
from backend.store.tables import proposals
from backend.store.users import User
from controller_core.content import canonical_json, content_sha256
from controller_core.table import ParameterTable

_p = proposals
_select = partial(version_select, _p)


_BY_ID = _select(_p).where(_p.c.id == bindparam("id"))   # built once (see backend/store/__init__.py)
_INSERT = insert(_p)


def stored_table(row: RowMapping) -> ParameterTable:
    """The proposal's table, re-validated from storage and checked against its recorded sha256."""
    if content_sha256(row["table_json"]) != row["table_sha256"]:
        raise ConflictError(f"proposal {row['id']}: stored table does not match its sha256; refusing to use it")
    return ParameterTable.model_validate_json(row["table_json"])


def table_label(patient_code: str, proposal_version: int) -> str:
    """The one name a table has everywhere: on its page, the device, the monitor and the report."""
    return f"{patient_code} · table v{proposal_version}"


def get_row(conn: Connection, proposal_id: int) -> RowMapping:
    row = conn.execute(_BY_ID, {"id": proposal_id}).mappings().first()
    if row is None:
        raise NotFoundError(f"proposal {proposal_id} not found")
    return row


_SUMMARY_SELECT = _select(*summary_columns(_p), _p.c.speed_mps, _p.c.incline_deg, _p.c.body_mass_kg, _p.c.extrapolation,
                          _p.c.extrapolation_reason, _p.c.table_sha256)


def list_rows(conn: Connection, patient_id: int, limit: int = 50,
              before_version: int | None = None) -> tuple[list[RowMapping], int]:
    """One page of a patient's versions' summary rows, newest first (no stored bodies), and how many in all."""
    return version_page(conn, "proposal", _SUMMARY_SELECT, patient_id, limit, before_version)


def insert_row(conn: Connection, patient_id: int, parent_id: int | None, source: str, task: dict,
               extrapolation: bool, model_json: str, table: ParameterTable, comment: str | None, actor: User,
               safety_ok: bool, extrapolation_reason: str | None = None, leg_json: str = "{}") -> RowMapping:
    """Insert a draft inside the caller's write transaction (``safety_ok``: its table passed the limit check;
    ``extrapolation_reason``: why it was requested beyond the tasks the model knows; ``leg_json``: the leg it was made
    for, :mod:`backend.services.legs`), numbered after the patient's versions while holding the patient's row; returns
    its row as :func:`get_row` reads it."""
    table_json = canonical_json(table)
    lock_patient(conn, patient_id)
    new_id = conn.execute(_INSERT, dict(
        patient_id=patient_id, version=next_version(conn, "proposal", patient_id), parent_id=parent_id, source=source,
        speed_mps=task["speed_mps"], incline_deg=task["incline_deg"], body_mass_kg=task["body_mass_kg"],
        extrapolation=int(extrapolation or extrapolation_reason is not None),
        extrapolation_reason=extrapolation_reason, safety_ok=int(safety_ok), model_json=model_json,
        table_json=table_json, table_sha256=content_sha256(table_json), edit_comment=comment, created_by=actor.id,
        created_at=utc_now(), leg_json=leg_json)).inserted_primary_key[0]
    return get_row(conn, int(new_id))
