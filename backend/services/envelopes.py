"""Envelope versions for the clinic: the view the page and the API give (every node's table, the device-side check),
one node as a table is shown, the diff in clinical words, and the rules around storing one: checked as the device will
run it when created or edited, re-checked and gated on the bench's verdict when approved
(:mod:`backend.services.decisions`). Every read re-runs the device-side check (every node's limits and the neighbour
rule), so what is shown and approved is what the device would accept. Storage is :mod:`backend.store.versions`.
"""

from __future__ import annotations

from collections.abc import Callable

from sqlalchemy import Connection, RowMapping

from backend.clinical_words import field_words
from backend.db import write_transaction
from backend.errors import NotFoundError
from backend.services import legs
from backend.services.decisions import decide_once, version_meta
from backend.services.proposals import LIMITS, ROW_UNITS, THRESHOLD_UNITS, swing_inertia
from backend.store import audit
from backend.store.users import User
from backend.store.versions import get_row, insert_row, list_rows, stored_envelope, version_label
from controller_core.envelope import VALUE_FIELDS, Envelope, table_values
from controller_core.table import LimitViolation, display_rows
from device_bridge.as_run import AsRun, as_run
from device_bridge.sim.leg_file import LegFile

_UNITS = ROW_UNITS | THRESHOLD_UNITS


def _hex(crc32: int | None) -> str | None:
    """A CRC-32 in the audit log as pushes and the device page show it (eight hex digits)."""
    return None if crc32 is None else f"{crc32:08x}"


def _meta(row: RowMapping) -> dict:
    return {**version_meta(row), "envelope_label": version_label("envelope", row["patient_code"], row["version"]),
            "body_mass_kg": row["body_mass_kg"], "grid": [row["n_speeds"], row["n_inclines"]],
            "wire_crc32": row["wire_crc32"], "envelope_sha256": row["content_sha256"],
            "content_sha256": row["content_sha256"]}


def _public(meta: dict, envelope: Envelope, full: bool, violations: list[LimitViolation] | None = None) -> dict:
    violations = as_run(envelope).violations if violations is None else violations
    out = {**meta, "speeds_mps": envelope.speeds_mps, "inclines_deg": envelope.inclines_deg,
           "nominal": {"speed_mps": envelope.nominal_speed_mps, "incline_deg": envelope.nominal_incline_deg},
           "model": {"version": envelope.model_version, "data_sha256": envelope.data_sha256},
           "neighbour_steps": envelope.neighbour_steps.model_dump(),
           "safety": {"ok": not violations, "violations": [v.model_dump() for v in violations]},
           "swing_inertia": swing_inertia(envelope.nodes[0].table)}       # one leg: every node's is the same
    if full:
        out["nodes"] = [{"speed_mps": n.speed_mps, "incline_deg": n.incline_deg, "extrapolation": n.extrapolation,
                         "feature_std": n.feature_std, "neighbour_guarded": n.neighbour_guarded,
                         "table": display_rows(n.table), "thresholds": n.table.thresholds.model_dump()}
                        for n in envelope.nodes]
    return out


def node_view(row: RowMapping, envelope: Envelope, i: int, j: int) -> dict:
    """One node as the proposal page shows a table: its stored table (guarded and edited as approved) and its check;
    the caller adds the model's curves, features and via-points at its task."""
    n_s, n_i = envelope.shape
    if not (0 <= i < n_s and 0 <= j < n_i):
        raise NotFoundError(f"envelope {row['id']} has nodes [0..{n_s - 1}] × [0..{n_i - 1}], not [{i}, {j}]")
    node = envelope.node(i, j)
    violations = as_run(node.table).violations
    return {"envelope_id": row["id"], "envelope_label": version_label("envelope", row["patient_code"], row["version"]),
            "envelope_status": row["status"], "patient_id": row["patient_id"], "node": [i, j],
            "task": {"speed_mps": node.speed_mps, "incline_deg": node.incline_deg, "body_mass_kg": envelope.mass_kg},
            "extrapolation": node.extrapolation, "feature_std": node.feature_std,
            "neighbour_guarded": node.neighbour_guarded, "envelope_model": {"version": envelope.model_version,
                                                                            "data_sha256": envelope.data_sha256},
            "table": display_rows(node.table), "thresholds": node.table.thresholds.model_dump(), "limits": LIMITS,
            "safety": {"ok": not violations, "violations": [v.model_dump() for v in violations]},
            "swing_inertia": swing_inertia(node.table)}


def get_envelope(conn: Connection, envelope_id: int, full: bool = True) -> dict:
    row = get_row(conn, "envelope", envelope_id)
    return _public(_meta(row), stored_envelope(row), full)


def list_envelopes(conn: Connection, patient_id: int, limit: int = 50,
                   before_version: int | None = None) -> tuple[list[dict], int]:
    """One page of summaries, newest version first (metadata and axes: the nodes and the live device-side check are
    the full version's, on its own endpoint), and how many versions the patient has in all."""
    rows, total = list_rows(conn, "envelope", patient_id, limit, before_version)
    return [{**_meta(r), "speeds_mps": r["speeds_mps"], "inclines_deg": r["inclines_deg"],
             "safety_ok": bool(r["safety_ok"])} for r in rows], total


def create_from_model(conn: Connection, patient_id: int, envelope: Envelope, actor: User,
                      extrapolation_reason: str | None = None, leg: LegFile | None = None) -> dict:
    """Store a freshly built envelope as the patient's next draft version, rounded to the node quanta (what the
    device runs); returns its API view. ``extrapolation_reason``: the prosthetist's reason for nodes beyond the
    tasks the model knows (audited, shown with the version); ``leg``: the leg it was made for (None: the nominal
    one)."""
    checked = as_run(envelope)
    envelope, violations = checked.item, checked.violations
    with write_transaction(conn):
        meta = _meta(insert_row(conn, patient_id, None, envelope, checked.wire_crc32, not violations, None, actor,
                                extrapolation_reason, legs.leg_json(leg or LegFile())))
        audit.record(conn, actor.id, actor.username, "envelope.create", "envelope", meta["id"],
                     after={"patient_id": patient_id, "version": meta["version"], "leg": meta["leg"]["words"],
                            "speeds_mps": envelope.speeds_mps,
                            "inclines_deg": envelope.inclines_deg, "wire_crc32": _hex(meta["wire_crc32"]),
                            "safety_ok": not violations,
                            "extrapolation": meta["extrapolation"], "extrapolation_reason": extrapolation_reason})
    return _public(meta, envelope, full=True, violations=violations)


def create_edit(conn: Connection, parent_id: int, checked: AsRun[Envelope], changes: list[dict], comment: str,
                actor: User, action: str = "envelope.edit",
                also: Callable[[Connection, dict], dict] | None = None) -> dict:
    """Store an edited envelope as a new draft of the parent's patient, as the device runs it: ``checked`` is the
    caller's :func:`~device_bridge.as_run.as_run` of the edit (checked and found within every limit, once).
    ``action``: what the audit calls it (a refinement is ``envelope.refine``); ``also``: run in the same transaction
    with the new version's metadata (e.g. store the refinement's evidence), its result added to the audit entry."""
    envelope = checked.item
    with write_transaction(conn):
        parent = get_row(conn, "envelope", parent_id)
        meta = _meta(insert_row(conn, parent["patient_id"], parent_id, envelope, checked.wire_crc32,
                                not checked.violations, comment, actor, parent["extrapolation_reason"],
                                parent["leg_json"]))
        extra = also(conn, meta) if also is not None else {}
        audit.record(conn, actor.id, actor.username, action, "envelope", meta["id"],
                     before={"envelope_id": parent_id, "version": parent["version"],
                             "wire_crc32": _hex(parent["wire_crc32"])},
                     after={"version": meta["version"], "wire_crc32": _hex(meta["wire_crc32"]), "comment": comment,
                            "changes": changes, **extra})
    return _public(meta, envelope, full=True, violations=checked.violations)


def diff(conn: Connection, a_id: int, b_id: int) -> dict:
    """What changed from envelope ``a_id`` to ``b_id``: the grid, or node by node every value (with units)."""
    ra, rb = get_row(conn, "envelope", a_id), get_row(conn, "envelope", b_id)
    a, b = stored_envelope(ra), stored_envelope(rb)
    changes: list[dict] = []
    same_grid = (a.speeds_mps, a.inclines_deg) == (b.speeds_mps, b.inclines_deg)
    if same_grid:
        n_i = len(a.inclines_deg)
        for idx, (na, nb) in enumerate(zip(a.nodes, b.nodes, strict=True)):
            for field, x, y in zip(VALUE_FIELDS, table_values(na.table), table_values(nb.table), strict=True):
                if x != y:
                    held = field in nb.neighbour_guarded   # the rule, not the fit or the edit, set this value
                    changes.append({"node": list(divmod(idx, n_i)), "speed_mps": na.speed_mps,
                                    "incline_deg": na.incline_deg, "field": field, "setting": field_words(field),
                                    "before": x, "after": y, "change": y - x,
                                    "percent": None if x == 0 else round(100.0 * (y - x) / x, 2),   # as an edit's percent
                                    "unit": _UNITS[field.rsplit(".", 1)[1]], "held_by_neighbour_rule": held,
                                    "wanted": nb.neighbour_guarded[field] if held else None})
    return {"from_id": a_id, "to_id": b_id, "from_version": ra["version"], "to_version": rb["version"],
            "same_patient": ra["patient_id"] == rb["patient_id"], "same_grid": same_grid, "changes": changes}



def decide(conn: Connection, envelope_id: int, status: str, comment: str, actor: User,
           override_reason: str | None = None) -> dict:
    """Approve or reject a draft once. Approval re-validates the stored envelope and re-runs the device-side check."""
    with write_transaction(conn):
        row = get_row(conn, "envelope", envelope_id)
        decide_once(conn, "envelope", row, status, comment, actor, lambda: as_run(stored_envelope(row)).violations,
                    "the safety limits or the neighbour rule", {"wire_crc32": _hex(row["wire_crc32"])}, override_reason)
        return get_envelope(conn, envelope_id)
