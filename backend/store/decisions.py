"""The versions table's shared queries: a page of a patient's versions of one kind, the next version number, and the
decision written once (the rule around it, the content's check and the bench, is :mod:`backend.services.decisions`; the
triggers enforce "once" too)."""

from __future__ import annotations

from sqlalchemy import Connection, RowMapping, Select, Table, bindparam, func, select, update

from backend.db import utc_now
from backend.store.tables import patients, users, versions
from backend.store.users import User


def record_decision(conn: Connection, version_id: int, status: str, comment: str, actor: User,
                    override: str | None) -> bool:
    """Write the decision on draft ``version_id`` (inside the caller's write transaction) if it is still a draft;
    whether it was. Taken once even when two servers decide the same version at the same moment: the update changes
    the row only while it is still a draft, and the database lets one such update through at a time (SQLite's write
    lock; on PostgreSQL the row lock the first update holds until its commit, after which the second finds no draft
    and changes nothing)."""
    table = versions
    taken = conn.execute(update(table).where(table.c.id == version_id, table.c.status == "draft").values(
        status=status, decided_by=actor.id, decided_at=utc_now(), decision_comment=comment,
        decision_override=override))
    return taken.rowcount == 1


# what every decided-once version's summary reads, besides its own columns
VERSION_COLUMNS = ("id", "patient_id", "version", "parent_id", "source", "status", "created_at", "edit_comment",
                   "decided_at", "decision_comment", "decision_override", "safety_ok", "leg_json")


def version_select(table: Table, *columns) -> Select:
    """``columns`` of the versions table with who created and who decided each version, its parent's version and its
    patient's code name."""
    cu, du, parent = users.alias("cu"), users.alias("du"), table.alias("parent")
    return (select(*columns, cu.c.username.label("created_by_name"), du.c.username.label("decided_by_name"),
                   parent.c.version.label("parent_version"), patients.c.code_name.label("patient_code"))
            .select_from(table.join(cu, cu.c.id == table.c.created_by).outerjoin(du, du.c.id == table.c.decided_by)
                         .outerjoin(parent, parent.c.id == table.c.parent_id)
                         .join(patients, patients.c.id == table.c.patient_id)))


def summary_columns(table: Table) -> list:
    """The shared version columns of ``table`` (not the stored bodies)."""
    return [table.c[c] for c in VERSION_COLUMNS]


# built once (see backend/store/__init__.py); ``kind``: "table" or "envelope", numbered apart
_v = versions
_COUNT = select(func.count()).select_from(_v).where(_v.c.patient_id == bindparam("patient_id"),
                                                    _v.c.kind == bindparam("kind"))
_NEXT = select(func.coalesce(func.max(_v.c.version), 0) + 1).where(_v.c.patient_id == bindparam("patient_id"),
                                                                   _v.c.kind == bindparam("kind"))
_PAGES: dict[tuple[int, bool], tuple[Select, Select]] = {}   # (id(query), paged back) → (query, its page statement)


def _page_statement(query: Select, before: bool) -> Select:
    """``query`` narrowed to one patient's versions of one kind (older than a bound version when ``before``), newest
    first, a bound number of them; built once per summary query (the queries are module constants)."""
    key = (id(query), before)
    if key not in _PAGES:
        table = versions
        page = query.where(table.c.patient_id == bindparam("patient_id"), table.c.kind == bindparam("kind"))
        if before:
            page = page.where(table.c.version < bindparam("before_version"))
        _PAGES[key] = (query, page.order_by(table.c.version.desc()).limit(bindparam("limit")))
    return _PAGES[key][1]


def version_page(conn: Connection, kind: str, query: Select, patient_id: int, limit: int,
                 before_version: int | None) -> tuple[list[RowMapping], int]:
    """One page of a patient's versions of ``kind``, newest first (older than ``before_version``), and how many."""
    total = conn.execute(_COUNT, {"patient_id": patient_id, "kind": kind}).scalar_one()
    params = {"patient_id": patient_id, "kind": kind, "limit": limit}
    if before_version is not None:
        params["before_version"] = before_version
    rows = conn.execute(_page_statement(query, before_version is not None), params).mappings().all()
    return list(rows), total


def next_version(conn: Connection, kind: str, patient_id: int) -> int:
    """The patient's next version number of ``kind`` (inside a write transaction that holds the patient's row:
    :func:`backend.store.patients.lock_patient`)."""
    return int(conn.execute(_NEXT, {"patient_id": patient_id, "kind": kind}).scalar_one())
