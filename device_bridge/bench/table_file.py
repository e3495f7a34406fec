"""A table from a file for the bench: the JSON ``quasitune predict --format json`` prints or ``GET /api/proposals/{id}``
returns.

Both carry ``task`` (speed, incline, the patient's mass), ``table`` (one row per joint and sub-phase) and
``thresholds``; display fields beside a row's parameters (``k_Nm_per_deg``, ``weak_fit`` …) are read past. What comes
back is a :class:`controller_core.table.ParameterTable` whose provenance says it came from this file; its limits are
checked where it is walked, as the device checks them.
"""

from __future__ import annotations

import json
from pathlib import Path

from pydantic import ValidationError

from controller_core.table import ParameterRow, ParameterTable, Provenance, Thresholds

_ROW_FIELDS = ("joint", "subphase", "k_Nm_per_rad", "theta_e_deg", "b_Nm_s_per_rad", "r2", "guarded", "fit_method")


def read_table_file(path: Path) -> ParameterTable:
    """The table in ``path`` (see the module docstring).

    Raises:
        ValueError: the file cannot be read, is not JSON, or lacks a whole, valid table (says which part).
    """
    try:
        body = json.loads(Path(path).read_text())
    except OSError as exc:
        raise ValueError(f"table file {path}: {exc.strerror or exc}") from exc
    except json.JSONDecodeError as exc:
        raise ValueError(f"table file {path}: not JSON ({exc.msg}, line {exc.lineno})") from exc
    if not isinstance(body, dict):
        raise ValueError(f"table file {path}: expected a JSON object with task, table and thresholds")
    missing = [k for k in ("task", "table", "thresholds") if k not in body]
    if missing:
        raise ValueError(f"table file {path}: missing {', '.join(missing)} (give the JSON of 'quasitune predict "
                         "--format json' or of GET /api/proposals/{id})")
    task, rows = body["task"], body["table"]
    if not isinstance(task, dict) or not isinstance(rows, list) or not all(isinstance(r, dict) for r in rows):
        raise ValueError(f"table file {path}: task must be an object and table a list of rows")
    model = body.get("model") if isinstance(body.get("model"), dict) else {}
    try:
        return ParameterTable(
            rows=[ParameterRow(**{k: r[k] for k in _ROW_FIELDS if k in r}) for r in rows],
            thresholds=Thresholds(**body["thresholds"]),
            provenance=Provenance(model_version=str(model.get("version", f"file {Path(path).name}")),
                                  data_sha256=str(model.get("data_sha256", "")), speed_mps=float(task["speed_mps"]),
                                  incline_deg=float(task["incline_deg"]), patient_mass_kg=float(task["mass_kg"]),
                                  extrapolation=bool(body.get("extrapolation", False)), source="edit"))
    except (ValidationError, KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"table file {path}: not a valid table: {_short(exc)}") from exc


def _short(exc: Exception) -> str:
    if isinstance(exc, ValidationError):
        e = exc.errors()[0]
        return f"{'.'.join(str(p) for p in e['loc'])}: {e['msg']} ({exc.error_count()} problem(s))"
    if isinstance(exc, KeyError):
        return f"task lacks {exc.args[0]}"
    return str(exc)
