"""A patient's parameter versions as stored: one table of versions, each an envelope over a speed × incline grid, of
which a fixed-task table is the one-node case; a row written once, read back with who made and decided it, and its
content re-validated against the sha256 it was stored with.

A version's content (its envelope JSON, a table's task and the model's output it came from) is immutable — triggers
refuse any change — and its decision is taken at most once (:func:`backend.store.decisions.record_decision`). What the
clinic calls a version (its ``kind``: "table" for one task, "envelope" for a range) is numbered per patient, each kind
apart (1, 2, …); an edit records its parent. The API names a version by the kind of item it is ("proposal" for a
table, "envelope"), with one id space for both. What a version means to the clinic (its view, its checks, approving
it) is :mod:`backend.services.proposals` and :mod:`backend.services.envelopes`.
"""

from __future__ import annotations

import json
from functools import partial
from typing import Literal

from sqlalchemy import Connection, RowMapping, bindparam, insert, select

from backend.db import utc_now
from backend.errors import ConflictError, MovedError, NotFoundError
from backend.store.decisions import next_version, summary_columns, version_page, version_select
from backend.store.dialect import json_of
from backend.store.patients import lock_patient
from backend.store.tables import legacy_ids, versions
from backend.store.users import User
from controller_core.content import canonical_json, content_sha256
from controller_core.envelope import Envelope, envelope_of_table
from controller_core.table import ParameterTable

Item = Literal["proposal", "envelope"]      # what the API calls a version of one task, and of a range of tasks
KIND_OF: dict[str, str] = {"proposal": "table", "envelope": "envelope"}    # … and what the row calls it
ITEM_OF: dict[str, Item] = {"table": "proposal", "envelope": "envelope"}

_v = versions
_select = partial(version_select, _v)
_BY_ID = _select(_v).where(_v.c.id == bindparam("id"))   # built once (see backend/store/__init__.py)
_INSERT = insert(_v)


def api_ids(kind: str | None, version_id: int | None) -> dict[str, int | None]:
    """A version as the API names it where either kind may be meant (a push, a session, a refinement): a table's
    ``proposal_id`` or an envelope's ``envelope_id``, the other None (both None for no version)."""
    return {"proposal_id": version_id if kind == "table" else None,
            "envelope_id": version_id if kind == "envelope" else None}


def version_label(kind: str, patient_code: str, version: int) -> str:
    """The one name a version has everywhere (its page, the device, the monitor, the report): "P-001 · table v3"."""
    return f"{patient_code} · {kind} v{version}"


def get_row(conn: Connection, item: Item, version_id: int) -> RowMapping:
    """The version ``version_id``, which must be the API's ``item`` (a table for "proposal", a range for "envelope").

    Raises:
        NotFoundError: no such version of that kind.
        MovedError: an envelope's id from before one version (revision 0021), which names no envelope now: the API
            sends the request on to its version id. (Such ids are at most the largest id before the revision, and every
            envelope made since has a larger one, so an old id is never mistaken for a new envelope.)
    """
    row = conn.execute(_BY_ID, {"id": version_id}).mappings().first()
    if item == "envelope" and (row is None or row["kind"] != "envelope"):
        moved = moved_to(conn, item, version_id)
        if moved is not None:
            raise MovedError(f"envelope {version_id} is now version {moved} (one id for tables and envelopes since "
                             "revision 0021)", moved_from=version_id, moved_to=moved)
    if row is None:
        raise NotFoundError(f"{item} {version_id} not found")
    if row["kind"] != KIND_OF[item]:
        raise NotFoundError(f"{item} {version_id} not found: version {version_id} is "
                            f"{'a table' if row['kind'] == 'table' else 'an envelope'} ({ITEM_OF[row['kind']]} "
                            f"{version_id})")
    return row


_KIND = select(_v.c.kind).where(_v.c.id == bindparam("id"))


def kind_of(conn: Connection, version_id: int) -> str:
    """What the clinic calls version ``version_id``: "table" or "envelope" (NotFoundError when there is none)."""
    kind = conn.execute(_KIND, {"id": version_id}).scalar()
    if kind is None:
        raise NotFoundError(f"version {version_id} not found")
    return str(kind)


def stored_envelope(row: RowMapping) -> Envelope:
    """The content, re-validated from storage and checked against its recorded sha256 (a table: the envelope of its
    one node)."""
    what = f"{ITEM_OF[row['kind']]} {row['id']}"
    if content_sha256(row["content_json"]) != row["content_sha256"]:
        raise ConflictError(f"{what}: stored content does not match its sha256; refusing to use it")
    try:
        return Envelope.from_json(json.loads(row["content_json"]))
    except ValueError as exc:
        raise ConflictError(f"{what}: {str(exc).splitlines()[0]}; refusing to use it") from exc


def stored_table(row: RowMapping) -> ParameterTable:
    """A one-task version's table, re-validated and checked against its sha256."""
    envelope = stored_envelope(row)
    if not envelope.single_node:
        raise ConflictError(f"envelope {row['id']} is a range of tasks, not a table")
    return envelope.nodes[0].table


def stored_content(row: RowMapping) -> ParameterTable | Envelope:
    """What a version sends to the leg: a table's table, or the whole envelope."""
    return stored_table(row) if row["kind"] == "table" else stored_envelope(row)


_SUMMARY = {
    "table": _select(*summary_columns(_v), _v.c.kind, _v.c.speed_mps, _v.c.incline_deg, _v.c.body_mass_kg,
                     _v.c.extrapolation, _v.c.extrapolation_reason, _v.c.content_sha256),
    "envelope": _select(*summary_columns(_v), _v.c.kind, _v.c.body_mass_kg, _v.c.n_speeds, _v.c.n_inclines,
                        _v.c.extrapolation, _v.c.extrapolation_reason, _v.c.wire_crc32, _v.c.content_sha256,
                        # the axes read by the database, without loading the nodes
                        json_of(_v.c.content_json)["speeds_mps"].label("speeds_mps"),
                        json_of(_v.c.content_json)["inclines_deg"].label("inclines_deg")),
}


def list_rows(conn: Connection, item: Item, patient_id: int, limit: int = 50,
              before_version: int | None = None) -> tuple[list[RowMapping], int]:
    """One page of a patient's versions of one kind, summary rows newest first (no stored bodies), and how many."""
    kind = KIND_OF[item]
    return version_page(conn, kind, _SUMMARY[kind], patient_id, limit, before_version)


def insert_row(conn: Connection, patient_id: int, parent_id: int | None, content: ParameterTable | Envelope,
               wire_crc32: int | None, safety_ok: bool, comment: str | None, actor: User,
               extrapolation_reason: str | None = None, leg_json: str = "{}", model_json: str | None = None,
               source: str | None = None) -> RowMapping:
    """Insert a draft inside the caller's write transaction: ``content`` as the device will run it (a table is stored
    as the envelope of its one node, with ``model_json``, the model's output it came from), ``wire_crc32`` what the
    device will read back, ``safety_ok`` whether it passed the device-side check, ``extrapolation_reason`` why it was
    requested beyond the tasks the model knows, ``leg_json`` the leg it was made for; numbered after the patient's
    versions of its kind while holding the patient's row. Returns its row as :func:`get_row` reads it."""
    envelope = envelope_of_table(content) if isinstance(content, ParameterTable) else content
    kind = "table" if isinstance(content, ParameterTable) else "envelope"
    body = canonical_json(envelope)
    n_s, n_i = envelope.shape
    lock_patient(conn, patient_id)
    new_id = conn.execute(_INSERT, dict(
        patient_id=patient_id, kind=kind, version=next_version(conn, kind, patient_id), parent_id=parent_id,
        source=source or ("model" if parent_id is None else "edit"), n_speeds=n_s, n_inclines=n_i,
        speed_mps=envelope.nominal_speed_mps, incline_deg=envelope.nominal_incline_deg, body_mass_kg=envelope.mass_kg,
        extrapolation=int(any(n.extrapolation for n in envelope.nodes) or extrapolation_reason is not None),
        extrapolation_reason=extrapolation_reason, safety_ok=int(safety_ok), content_json=body,
        content_sha256=content_sha256(body), wire_crc32=wire_crc32, model_json=model_json, edit_comment=comment,
        created_by=actor.id, created_at=utc_now(), leg_json=leg_json)).inserted_primary_key[0]
    return conn.execute(_BY_ID, {"id": int(new_id)}).mappings().one()


_LEGACY = select(legacy_ids.c.version_id).where(legacy_ids.c.kind == bindparam("kind"),
                                                legacy_ids.c.old_id == bindparam("old_id"))


def moved_to(conn: Connection, item: Item, old_id: int) -> int | None:
    """The version an id from before one version (revision 0021) names now, when it moved (an envelope's), else
    None."""
    found = conn.execute(_LEGACY, {"kind": item, "old_id": old_id}).scalar()
    return None if found is None or found == old_id else int(found)
