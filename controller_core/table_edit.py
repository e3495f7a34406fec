"""Hand edits of a parameter table: a new, fully re-validated table and the list of changed cells.

Rows whose k or θe is edited become ``fit_method="manual"`` with no R² (the line is no longer a fit);
editing only the damping keeps the row's fit. The result carries ``provenance.source = "edit"``. Limits are
not checked here: callers run :func:`controller_core.table.check_table` on the result and refuse it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from controller_core.table import ParameterRow, ParameterTable, Thresholds

ROW_FIELDS = ("k_Nm_per_rad", "theta_e_deg", "b_Nm_s_per_rad")


class EditError(ValueError):
    """An edit names an unknown cell or changes nothing."""


def edit_table(table: ParameterTable, rows: Sequence[Mapping[str, object]] = (),
               thresholds: Mapping[str, float] | None = None, method: str = "manual", source: str = "edit"
               ) -> tuple[ParameterTable, list[dict]]:
    """Apply cell edits (``method``/``source``: what a re-fitted row and the table then say; ``refined``/``refinement``
    for a refinement from walking).

    Args:
        table: the table edited (not modified).
        rows: items ``{"joint", "subphase", <any of ROW_FIELDS>: value}``; one item per row at most.
        thresholds: ``{threshold field: value}``.

    Returns:
        (new table, changes) where each change is ``{"field", "before", "after"}`` (e.g. field
        ``"knee.stance_flexion.k_Nm_per_rad"``); cells set to their current value are not changes.

    Raises:
        EditError: unknown joint/sub-phase or field, a row edited twice, or nothing changed.
        pydantic.ValidationError: a value that is not a finite number.
    """
    by_key = {(r.joint, r.subphase): r for r in table.rows}
    changes: list[dict] = []
    new_rows = dict(by_key)
    for item in rows:
        key = (item.get("joint"), item.get("subphase"))
        if key not in by_key:
            raise EditError(f"no table row for joint {key[0]!r} and sub-phase {key[1]!r}")
        if new_rows[key] is not by_key[key]:
            raise EditError(f"row {key[0]}.{key[1]} is edited twice in one request")
        old = by_key[key]
        unknown = set(item) - {"joint", "subphase", *ROW_FIELDS}
        if unknown:
            raise EditError(f"unknown table fields {sorted(unknown)}; editable: {', '.join(ROW_FIELDS)}")
        values = {f: item[f] for f in ROW_FIELDS if item.get(f) is not None and item[f] != getattr(old, f)}
        if not values:
            continue
        changes += [{"field": f"{key[0]}.{key[1]}.{f}", "before": getattr(old, f), "after": v}
                    for f, v in values.items()]
        refit = "k_Nm_per_rad" in values or "theta_e_deg" in values
        update = old.model_dump() | values
        if refit:
            update |= {"fit_method": method, "r2": None, "guarded": False}
        new_rows[key] = ParameterRow.model_validate(update)
    th = table.thresholds.model_dump()
    for name, value in (thresholds or {}).items():
        if name not in th:
            raise EditError(f"unknown threshold {name!r}; editable: {', '.join(th)}")
        if value is not None and value != th[name]:
            changes.append({"field": f"thresholds.{name}", "before": th[name], "after": value})
            th[name] = value
    if not changes:
        raise EditError("the edit changes nothing: every value given equals the current one")
    new = ParameterTable(rows=[new_rows[(r.joint, r.subphase)] for r in table.rows],
                         thresholds=Thresholds.model_validate(th),
                         provenance=table.provenance.model_copy(update={"source": source}))
    return new, changes
