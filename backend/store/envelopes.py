"""Envelope versions as stored: a draft's row written once, read back with who made and decided it, and its content
re-validated against the sha256 it was stored with.

Like a proposal, an envelope's content is immutable (triggers refuse any change, the baseline revision), its decision
is taken at most once, and versions are numbered per patient. What is stored is the Envelope JSON with its sha256
(:mod:`controller_core.content`) and the wire CRC-32 the device will read back. What a version means to the clinic
(its view, its checks, approving it) is :mod:`backend.services.envelopes`.
"""

from __future__ import annotations

import json
from functools import partial

from sqlalchemy import Connection, RowMapping, bindparam, insert

from backend.db import utc_now
from backend.errors import ConflictError, NotFoundError
from backend.store.decisions import next_version, summary_columns, version_page, version_select
from backend.store.dialect import json_of
from backend.store.patients import lock_patient
from backend.store.tables import envelopes
from backend.store.users import User
from controller_core.content import canonical_json, content_sha256
from controller_core.envelope import Envelope

_e = envelopes
_select = partial(version_select, _e)


_BY_ID = _select(_e).where(_e.c.id == bindparam("id"))   # built once (see backend/store/__init__.py)
_INSERT = insert(_e)


def envelope_label(patient_code: str, version: int) -> str:
    """The one name an envelope has everywhere (page, device, monitor, report)."""
    return f"{patient_code} · envelope v{version}"


def stored_envelope(row: RowMapping) -> Envelope:
    """The envelope, re-validated from storage and checked against its recorded sha256."""
    if content_sha256(row["envelope_json"]) != row["envelope_sha256"]:
        raise ConflictError(f"envelope {row['id']}: stored content does not match its sha256; refusing to use it")
    try:
        return Envelope.from_json(json.loads(row["envelope_json"]))
    except ValueError as exc:
        raise ConflictError(f"envelope {row['id']}: {str(exc).splitlines()[0]}; refusing to use it") from exc


def get_row(conn: Connection, envelope_id: int) -> RowMapping:
    row = conn.execute(_BY_ID, {"id": envelope_id}).mappings().first()
    if row is None:
        raise NotFoundError(f"envelope {envelope_id} not found")
    return row


_SUMMARY_SELECT = _select(*summary_columns(_e), _e.c.body_mass_kg, _e.c.n_speeds, _e.c.n_inclines, _e.c.extrapolation,
                          _e.c.extrapolation_reason, _e.c.wire_crc32, _e.c.envelope_sha256,
                          # the axes read by the database, without loading the nodes
                          json_of(_e.c.envelope_json)["speeds_mps"].label("speeds_mps"),
                          json_of(_e.c.envelope_json)["inclines_deg"].label("inclines_deg"))


def list_rows(conn: Connection, patient_id: int, limit: int = 50,
              before_version: int | None = None) -> tuple[list[RowMapping], int]:
    """One page of a patient's versions' summary rows with their axes, newest first (no nodes), and how many in all."""
    return version_page(conn, "envelope", _SUMMARY_SELECT, patient_id, limit, before_version)


def insert_row(conn: Connection, patient_id: int, parent_id: int | None, envelope: Envelope, wire_crc32: int | None,
               safety_ok: bool, comment: str | None, actor: User, extrapolation_reason: str | None = None,
               leg_json: str = "{}") -> RowMapping:
    """Insert a draft inside the caller's write transaction: ``envelope`` as the device will run it, ``wire_crc32`` what
    the device will read back, ``safety_ok`` whether it passed the device-side check, ``extrapolation_reason`` why it
    was requested beyond the tasks the model knows, ``leg_json`` the leg it was made for; numbered after the patient's
    versions while holding the patient's row. Returns its row as :func:`get_row` reads it."""
    body = canonical_json(envelope)
    n_s, n_i = envelope.shape
    lock_patient(conn, patient_id)
    new_id = conn.execute(_INSERT, dict(
        patient_id=patient_id, version=next_version(conn, "envelope", patient_id), parent_id=parent_id,
        source="model" if parent_id is None else "edit", body_mass_kg=envelope.mass_kg, n_speeds=n_s, n_inclines=n_i,
        extrapolation=int(any(n.extrapolation for n in envelope.nodes) or extrapolation_reason is not None),
        extrapolation_reason=extrapolation_reason, safety_ok=int(safety_ok), envelope_json=body,
        envelope_sha256=content_sha256(body), wire_crc32=wire_crc32, edit_comment=comment,
        created_by=actor.id, created_at=utc_now(), leg_json=leg_json)).inserted_primary_key[0]
    return get_row(conn, int(new_id))
