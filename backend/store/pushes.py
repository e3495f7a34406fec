"""Pushes: an approved proposal's table or an approved envelope, sent to a device.

A push row is written before anything goes on the bus (status ``sending``) and finished afterwards
(``acknowledged`` with the CRC the device read back, or ``failed`` with the reason); ``active`` is set only when
the device's own status reports that version and CRC running. The version is the device's own counter
(:func:`backend.store.devices.next_wire_version`); a table is named to people as "patient code · table vN",
N being the table's version for that patient (:func:`backend.store.versions.version_label`), an envelope as
"patient code · envelope vN". A push names its version (``version_id``); the API says it as the ``proposal_id`` of a
table or the ``envelope_id`` of an envelope.
"""

from __future__ import annotations

from datetime import UTC, datetime, timedelta
from typing import Literal

from sqlalchemy import Connection, RowMapping, and_, bindparam, case, insert, or_, select, update
from sqlalchemy.exc import IntegrityError

from backend.db import utc_now, utc_text, write_transaction
from backend.errors import ConflictError, NotFoundError
from backend.store import audit, devices
from backend.store.dialect import unique_violation
from backend.store.instance_beats import is_dead
from backend.store.tables import patients, pushes, users, versions, withdrawals
from backend.store.users import User
from backend.store.versions import ITEM_OF, Item

_pu, _v, _wd, _wu = pushes, versions, withdrawals, users.alias("wu")
_PUSH_SELECT = (
    select(_pu, users.c.username.label("requested_by_name"), _v.c.kind, _v.c.version, _v.c.patient_id,
           patients.c.code_name.label("patient_code"), _v.c.speed_mps, _v.c.incline_deg,
           _v.c.body_mass_kg.label("built_for_mass_kg"), _v.c.decision_override.label("approval_override"),
           _v.c.extrapolation_reason, _wd.c.reason.label("withdrawn_reason"), _wd.c.withdrawn_at,
           _wu.c.username.label("withdrawn_by_name"))
    .select_from(_pu.join(users, users.c.id == _pu.c.requested_by).join(_v, _v.c.id == _pu.c.version_id)
                 .join(patients, patients.c.id == _v.c.patient_id)
                 .outerjoin(_wd, _wd.c.version_id == _pu.c.version_id)
                 .outerjoin(_wu, _wu.c.id == _wd.c.user_id)))


def push_row(conn: Connection, push_id: int) -> RowMapping:
    """A push with its version's kind, number, patient and task, who asked and any withdrawal of its version."""
    row = conn.execute(_PUSH_SELECT.where(_pu.c.id == push_id)).mappings().first()
    if row is None:
        raise NotFoundError(f"push {push_id} not found")
    return row


PushedKind = Item
Pushed = tuple[PushedKind, int]      # ("proposal", id): a table; ("envelope", id): the whole envelope


def rows_of(conn: Connection, item: Pushed) -> list[RowMapping]:
    """Every push of this proposal or envelope, newest first (rows as :func:`push_row` reads them)."""
    return list(conn.execute(_PUSH_SELECT.where(_pu.c.version_id == item[1]).order_by(_pu.c.id.desc())).mappings())


def begin_push(conn: Connection, item: Pushed, device_id: str, crc32: int, actor: User,
               override_reason: str | None = None, sent_back_reason: str | None = None,
               instance_name: str | None = None) -> tuple[int, int]:
    """Record a push about to be sent (``sending``) by ``instance_name`` under the device's next table version, and
    audit it (with the prosthetist's reason when it goes ahead without a clean bench preview); returns (push id,
    version)."""
    kind, item_id = item
    with write_transaction(conn):
        _abandoned_to_unconfirmed(conn, device_id)
        version = devices.next_wire_version(conn, device_id)
        try:
            push_id = int(conn.execute(insert(_pu).values(
                {"version_id": item_id, "device_id": device_id, "table_version": version, "crc32": crc32,
                 "status": "sending", "requested_by": actor.id, "requested_at": utc_now(),
                 "instance_name": instance_name,
                 "override_reason": override_reason, "sent_back_reason": sent_back_reason})).inserted_primary_key[0])
        except IntegrityError as exc:   # the database's one push on its way per device, across instances
            if not unique_violation(exc, "one_push_sending_per_device", "pushes.device_id"):
                raise
            raise ConflictError(f"another push to device {device_id} is still in progress; nothing was sent") from None
        audit.record(conn, actor.id, actor.username, f"{kind}.push", kind, item_id,
                     after={"push_id": push_id, "device_id": device_id, "table_version": version,
                            "crc32": f"{crc32:08x}", **({"override_reason": override_reason} if override_reason
                                                        else {}),
                            **({"sent_back_reason": sent_back_reason} if sent_back_reason else {})})
    return push_id, version


# a push ends within seconds (the host gives up after 2-3 s, a broker link's resends included); one recorded before
# pushes named their instance (revision 0017) and still "sending" after this long was left by an instance that died
ABANDONED_AFTER_S = 60.0


def _abandoned_to_unconfirmed(conn: Connection, device_id: str) -> None:
    """A push to ``device_id`` left ``sending`` by an instance that stopped beating (``backend.store.instance_beats``;
    a push recorded without its instance: after :data:`ABANDONED_AFTER_S`) becomes ``unconfirmed``: the device's next
    status decides it (:func:`reconcile`), and it no longer blocks a new push from any instance. The instance that
    left it would do the same at its restart (:func:`interrupted_pushes`)."""
    cutoff = utc_text(datetime.now(UTC) - timedelta(seconds=ABANDONED_AFTER_S))
    left = or_(and_(_pu.c.instance_name.is_not(None), is_dead(_pu.c.instance_name)),
               and_(_pu.c.instance_name.is_(None), _pu.c.requested_at < cutoff))
    conn.execute(update(_pu).where(_pu.c.device_id == device_id, _pu.c.status == "sending", left).values(
        status="unconfirmed", error="left sending by an instance that stopped; the device's next status tells whether "
                                    "it holds it"))


def finish_push(conn: Connection, push_id: int, outcome: Literal["acknowledged", "failed", "unconfirmed"],
                attempts: int | None, elapsed_ms: float, error: str | None) -> None:
    """``acknowledged`` (the device read back the CRC), ``failed`` (it refused) or ``unconfirmed`` (no answer: its
    next status decides, :func:`reconcile`). A push the device's status has already decided keeps that."""
    now = utc_now()
    with write_transaction(conn):
        status = case((_pu.c.status == "sending", outcome), else_=_pu.c.status)
        if outcome == "acknowledged":
            values = {"status": status, "acknowledged_at": now, "attempts": attempts, "elapsed_ms": elapsed_ms}
        else:
            values = {"status": status, "elapsed_ms": elapsed_ms, "error": error,
                      **({"ended_at": now} if outcome == "failed" else {})}
        conn.execute(update(_pu).where(_pu.c.id == push_id).values(values))


def interrupted_pushes(conn: Connection, device_ids: list[str]) -> int:
    """At start-up: pushes to the devices this server serves left ``sending`` by a server that stopped mid-push become
    ``unconfirmed`` (each device's next status decides them); another instance's push on its way to its own device is
    left alone. Returns how many."""
    with write_transaction(conn):
        cur = conn.execute(update(_pu).where(_pu.c.status == "sending", _pu.c.device_id.in_(device_ids)).values(
            status="unconfirmed",
            error="the server stopped during this push; the device's next status tells whether it holds it"))
    return cur.rowcount


def _describe(active: tuple[int, int] | None) -> str:
    return "no table" if active is None else f"version {active[0]}, CRC {active[1]:08x}"


def reconcile(conn: Connection, device_id: str, active: tuple[int, int] | None, pending_version: int | None,
              in_flight: set[int]) -> list[Pushed]:
    """Make the records say what the device reports: ``active`` (version, CRC) running, ``pending_version`` staged.

    * the newest push of exactly the running version and CRC is ``active`` (whatever it was recorded as: a push whose
      acknowledgement was lost, or one from before a restart);
    * an ``active`` push the device no longer runs is ``superseded`` when the device runs one of ours sent later or a
      table this server did not send, and ``lost`` when it reports no table (it restarted, or lost it);
    * an ``acknowledged`` push stays while the device reports it staged; otherwise it is superseded or lost likewise;
    * ``sending`` and ``unconfirmed`` pushes not in flight in this process are ``acknowledged`` when the device
      reports them staged and ``failed`` when it holds neither.

    Pushes in ``in_flight`` (being sent now) are left to their sender, unless the device reports running exactly
    them. Returns what changed."""
    now, changed = utc_now(), []
    reported = _describe(active)
    with write_transaction(conn):
        running_id = None if active is None else conn.execute(
            select(_pu.c.id).where(_pu.c.device_id == device_id, _pu.c.table_version == active[0],
                                   _pu.c.crc32 == active[1]).order_by(_pu.c.id.desc()).limit(1)).scalar()
        rows = conn.execute(
            select(_pu.c.id, _pu.c.version_id, _v.c.kind, _pu.c.status, _pu.c.table_version)
            .join_from(_pu, _v, _v.c.id == _pu.c.version_id).where(_pu.c.device_id == device_id,
                   or_(_pu.c.status.in_(("sending", "unconfirmed", "acknowledged", "active")), _pu.c.id == running_id))
            .order_by(_pu.c.id).with_for_update(of=_pu)).mappings().all()
        for r in rows:
            status, error, at = r["status"], None, {}
            if r["id"] == running_id:   # the device's word on this push is final, in flight or not
                status, at = "active", {"active_at": now}
            elif r["id"] in in_flight:
                continue
            elif r["status"] in ("sending", "unconfirmed"):
                if pending_version == r["table_version"]:
                    status, at = "acknowledged", {"acknowledged_at": now}
                    error = "no acknowledgement arrived; the device's status then reported it staged"
                else:
                    status, at = "failed", {"ended_at": now}
                    error = f"no acknowledgement, and the device then reported {reported}: it did not take this push"
            elif r["status"] == "acknowledged" and pending_version == r["table_version"]:
                continue
            elif r["status"] in ("acknowledged", "active"):
                ours_later = running_id is not None and running_id > r["id"]
                status, at = ("superseded" if ours_later or active is not None else "lost"), {"ended_at": now}
                error = None if ours_later else f"the device reported {reported}: it no longer holds this table"
            if status == r["status"]:
                continue
            conn.execute(update(_pu).where(_pu.c.id == r["id"]).values(
                status=status, **at, **({"error": error} if error else {})))
            changed.append(_item(r))
    return changed


def _item(row: RowMapping) -> Pushed:
    return ITEM_OF[row["kind"]], row["version_id"]


def row_of_version(conn: Connection, device_id: str, version: int | None,
                   crc32: int | None = None) -> RowMapping | None:
    """The newest push of this table version (and CRC, when given) to the device: what its status reports
    running or waiting for heel strike. None for no version, or a table this server never sent."""
    if version is None:
        return None
    query = _PUSH_SELECT.where(_pu.c.device_id == device_id, _pu.c.table_version == version)
    if crc32 is not None:
        query = query.where(_pu.c.crc32 == crc32)
    return conn.execute(query.order_by(_pu.c.id.desc()).limit(1)).mappings().first()


def last_run_not_withdrawn(conn: Connection, device_id: str, besides: Pushed) -> RowMapping | None:
    """The newest push of a version that ran on the device (it reported it active once), was not withdrawn, is not
    ``besides``, and is of the patient the device is assigned to now: where a withdrawal sends the leg back."""
    assigned = devices.assignment(conn, device_id)
    if assigned is None:
        return None
    return conn.execute(_PUSH_SELECT.where(
        _pu.c.device_id == device_id, _pu.c.active_at.is_not(None), _wd.c.id.is_(None),
        _v.c.patient_id == assigned["patient_id"], _pu.c.version_id != besides[1])
        .order_by(_pu.c.id.desc()).limit(1)).mappings().first()


# shown with every version: built once (see backend/store/__init__.py)
_STATUSES = select(_pu.c.status).where(_pu.c.version_id == bindparam("item_id")).order_by(_pu.c.id.desc())


def deployment_state(conn: Connection, item: Pushed) -> str | None:
    """From its pushes, as the device last reported them (:func:`reconcile`): ``active_on_device`` / ``pushed`` (on
    its way: sent or read back, not yet running) / ``unconfirmed`` (no acknowledgement yet; the device's next status
    decides) / ``replaced`` (ran or was sent, then another table took its place) / ``not_on_device`` (the device
    reported it no longer holds it: restarted or lost) / ``push_failed`` / None (never pushed)."""
    newest_first = list(conn.execute(_STATUSES, {"item_id": item[1]}).scalars())
    statuses = set(newest_first)
    if "active" in statuses:
        return "active_on_device"
    if statuses & {"acknowledged", "sending"}:
        return "pushed"
    if "unconfirmed" in statuses:
        return "unconfirmed"
    if newest_first and newest_first[0] == "lost":
        return "not_on_device"
    if statuses & {"superseded", "lost"}:
        return "replaced"
    return "push_failed" if statuses else None
