"""Hand edits of an envelope: one setting changed across every node, or at one node, by an offset or a percentage.

"Knee stance flexion 10 % firmer everywhere" is ``{"field": "knee.stance_flexion.k_Nm_per_rad", "percent": 10}``:
a percentage scales the value (k < 0 is restoring, so +10 % is 10 % more restoring); an offset adds to it, in the
field's unit; ``set_to`` sets it, in the field's unit. Each node's table is edited with
:func:`controller_core.table_edit.edit_table` (rows whose k or θe
change become ``manual``), so the same rules hold. The neighbour guard is not re-applied on its own: an edit that
breaks the neighbour rule or a limit is refused by the caller's check
(:func:`device_bridge.envelope_wire.check_envelope_as_run` in the backend), never quietly corrected. A percentage
scales the differences between neighbours too, so "10 % firmer everywhere" breaks the rule wherever two neighbours
were already near a step apart; asked to,
:func:`hold_to_neighbour_rule` then holds those values within a step (the guard the envelope was built with), and
every held value is reported with what the edit gave.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

from controller_core.envelope import (
    THRESHOLD_VALUES,
    VALUE_FIELDS,
    Envelope,
    EnvelopeNode,
    nearest_node,
    neighbour_guard,
    table_values,
    table_with_values,
)
from controller_core.table_edit import ROW_FIELDS, EditError, edit_table


def _target(field: str) -> tuple[str, str | None, str | None]:
    """(kind, joint.subphase or None, value name) of ``joint.subphase.value`` or ``thresholds.name``."""
    parts = field.split(".")
    if len(parts) == 2 and parts[0] == "thresholds" and parts[1] in THRESHOLD_VALUES:
        return "threshold", None, parts[1]
    if len(parts) == 3 and parts[0] in ("knee", "ankle") and parts[2] in ROW_FIELDS and parts[1] in (
            "stance_flexion", "stance_extension", "swing_flexion", "swing_extension"):
        return "row", f"{parts[0]}.{parts[1]}", parts[2]
    raise EditError(f"unknown field {field!r}: use joint.subphase.({', '.join(ROW_FIELDS)}) or "
                    f"thresholds.({', '.join(THRESHOLD_VALUES)})")


def _new_value(old: float, edit: Mapping[str, object]) -> float:
    offset, percent, set_to = edit.get("offset"), edit.get("percent"), edit.get("set_to")
    if sum(v is not None for v in (offset, percent, set_to)) != 1:
        raise EditError(f"{edit.get('field')}: give exactly one of offset, percent or set_to")
    amount = float(next(v for v in (offset, percent, set_to) if v is not None))   # type: ignore[arg-type]
    if not math.isfinite(amount):
        raise EditError(f"{edit.get('field')}: the change must be a finite number")
    if percent is not None and not -100.0 < amount <= 1000.0:
        raise EditError(f"{edit.get('field')}: percent must be within (-100, 1000], got {amount:g}")
    if set_to is not None:
        return amount
    return old + amount if offset is not None else old * (1.0 + amount / 100.0)


def edit_envelope(envelope: Envelope, edits: Sequence[Mapping[str, object]]) -> tuple[Envelope, list[dict]]:
    """Apply edits to every node, or to the node an edit names (``node``: [speed index, incline index]).

    Returns:
        (new envelope, changes), each change ``{"node": [i, j], "speed_mps", "incline_deg", "field", "before",
        "after"}``.

    Raises:
        EditError: unknown field or node, both or neither of offset and percent, a non-finite change, a field edited
            twice at a node, or an edit that changes nothing.
    """
    if not edits:
        raise EditError("no edits given")
    n_s, n_i = envelope.shape
    per_node: dict[int, dict[str, dict]] = {}
    for edit in edits:
        field = str(edit.get("field"))
        kind, key, name = _target(field)
        node = edit.get("node")
        if node is None:
            targets = range(len(envelope.nodes))
        else:
            if not (isinstance(node, Sequence) and len(node) == 2 and all(isinstance(v, int) for v in node)
                    and 0 <= node[0] < n_s and 0 <= node[1] < n_i):
                raise EditError(f"{field}: node must be [speed index, incline index] within {n_s} × {n_i}, got {node!r}")
            targets = [node[0] * n_i + node[1]]
        for idx in targets:
            cells = per_node.setdefault(idx, {})
            if field in cells:
                raise EditError(f"{field} is edited twice at node {divmod(idx, n_i)}")
            table = envelope.nodes[idx].table
            old = getattr(table.thresholds, name) if kind == "threshold" else getattr(
                table.row(*key.split(".")), name)   # type: ignore[union-attr]
            cells[field] = {"kind": kind, "key": key, "name": name, "value": _new_value(float(old), edit)}
    nodes = list(envelope.nodes)
    changes: list[dict] = []
    for idx, cells in sorted(per_node.items()):
        node = nodes[idx]
        rows: dict[str, dict] = {}
        thresholds: dict[str, float] = {}
        for cell in cells.values():
            if cell["kind"] == "threshold":
                thresholds[cell["name"]] = cell["value"]
            else:
                joint, sub = cell["key"].split(".")
                rows.setdefault(cell["key"], {"joint": joint, "subphase": sub})[cell["name"]] = cell["value"]
        try:
            table, node_changes = edit_table(node.table, list(rows.values()), thresholds)
        except EditError:
            continue   # nothing changed at this node (e.g. +0 %)
        i, j = divmod(idx, n_i)
        nodes[idx] = EnvelopeNode(speed_mps=node.speed_mps, incline_deg=node.incline_deg, table=table,
                                  extrapolation=node.extrapolation, feature_std=node.feature_std,
                                  neighbour_guarded=node.neighbour_guarded)
        changes += [{"node": [i, j], "speed_mps": node.speed_mps, "incline_deg": node.incline_deg, **c}
                    for c in node_changes]
    if not changes:
        raise EditError("the edit changes nothing")
    return envelope.model_copy(update={"nodes": nodes}), changes


def hold_to_neighbour_rule(parent: Envelope, edited: Envelope, changes: list[dict]) -> tuple[Envelope, list[dict]]:
    """``edited`` with the neighbour guard applied again, sweeping out from the nominal node: a value more than a step
    from an already swept neighbour is moved the least back within it. Held values are recorded in their node's
    ``neighbour_guarded`` (with the value the edit gave) and their rows become ``neighbour_guard``; the changes
    against ``parent`` say, per held value, ``held_from`` (the edit's value). Raises EditError if holding leaves
    nothing changed."""
    values = [table_values(n.table) for n in edited.nodes]
    start = nearest_node(edited.speeds_mps, edited.inclines_deg, edited.nominal_speed_mps, edited.nominal_incline_deg)
    held = neighbour_guard(edited.shape, values, start, edited.neighbour_steps)
    nodes, moved_at = [], {}
    for idx, (node, wanted, kept) in enumerate(zip(edited.nodes, values, held, strict=True)):
        table, moved = table_with_values(node.table, kept, wanted)
        if moved:
            moved_at[idx] = moved
            node = node.model_copy(update={"table": table, "neighbour_guarded": {**node.neighbour_guarded, **moved}})
        nodes.append(node)
    result = edited.model_copy(update={"nodes": nodes})
    n_i = len(edited.inclines_deg)
    out = [c for c in changes if c["field"] not in VALUE_FIELDS]      # fit-method changes stay as the edit made them
    for idx, (before_node, after_node) in enumerate(zip(parent.nodes, result.nodes, strict=True)):
        for field, before, after in zip(VALUE_FIELDS, table_values(before_node.table), table_values(after_node.table),
                                        strict=True):
            if before != after:
                change = {"node": list(divmod(idx, n_i)), "speed_mps": after_node.speed_mps,
                          "incline_deg": after_node.incline_deg, "field": field, "before": before, "after": after}
                if field in moved_at.get(idx, {}):
                    change["held_from"] = moved_at[idx][field]
                out.append(change)
    if not any(c["field"] in VALUE_FIELDS for c in out):
        raise EditError("held to the neighbour rule, the edit changes nothing")
    return result, out
