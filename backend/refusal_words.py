"""Refusals in clinical words: a request's validation errors as sentences a prosthetist reads ("body mass must be at
least 20 kg"), not pydantic's ("Input should be greater than or equal to 20"). The 422's ``detail`` carries the
sentences; its ``errors`` keep each field's code and error type for scripts."""

from __future__ import annotations

import itertools
import re
from typing import Any

# unit suffixes of the API's field names (SI or the JSON's degrees), as said after a number
UNITS = (("_Nm_s_per_rad", "N·m·s/rad"), ("_Nm_per_rad", "N·m/rad"), ("_Nm_per_deg", "N·m/deg"),
         ("_deg_per_s", "deg/s"), ("_mps", "m/s"), ("_deg", "°"), ("_kg", "kg"), ("_m", "m"), ("_Nm", "N·m"),
         ("_N", "N"), ("_s", "s"), ("_pct", "%"))
# names whose plain reading would mislead (the rest: the code without its unit, underscores as spaces)
NAMES = {"k_Nm_per_rad": "stiffness k", "theta_e_deg": "equilibrium angle θe", "b_Nm_s_per_rad": "damping b",
         "override_reason": "sign-off reason", "comment": "reason", "k_level": "K-level", "new_password":
         "new password", "speed_range_mps": "speed range", "incline_range_deg": "incline range",
         "nominal_speed_mps": "nominal speed", "nominal_incline_deg": "nominal incline"}


def field_name(loc: tuple) -> tuple[str, str]:
    """The field's words and its unit ("" if none) from a validation error's location."""
    parts = [p for p in loc if p not in ("body", "query", "path", "header", "form")]
    names = [p for p in parts if isinstance(p, str)]
    if not names:
        return "the request", ""
    code = names[-1]
    unit = next((u for suffix, u in UNITS if code.endswith(suffix)), "")
    words = NAMES.get(code) or re.sub(r"_+", " ", next((code[: -len(s)] for s, _ in UNITS if code.endswith(s)), code))
    where = [f"{_item(p, code)} {i + 1}" for p, i in itertools.pairwise(parts)
             if isinstance(p, str) and isinstance(i, int)]
    return (f"{words} ({', '.join(where)})" if where else words), unit


def _item(list_name: str, code: str) -> str:
    """What one element of a list is called: "row" of "rows", "value" of the field itself."""
    return "value" if list_name == code else list_name[:-1] if list_name.endswith("s") else list_name


def _number(v: Any, unit: str) -> str:
    text = f"{v:g}" if isinstance(v, float) else str(v)
    return f"{text}°" if unit == "°" else f"{text} {unit}".strip()


def sentence(error: dict) -> str:
    """One validation error (pydantic's dict) as a sentence."""
    name, unit = field_name(tuple(error.get("loc", ())))
    kind, ctx, msg = error.get("type", ""), error.get("ctx") or {}, str(error.get("msg", "invalid"))
    bound = {"greater_than_equal": ("at least", "ge"), "less_than_equal": ("at most", "le"),
             "greater_than": ("more than", "gt"), "less_than": ("less than", "lt")}
    if kind in bound:
        words, key = bound[kind]
        return f"{name} must be {words} {_number(ctx.get(key), unit)}"
    if kind == "missing":
        return f"{name} is required"
    if kind == "finite_number":
        return f"{name} must be a finite number (not NaN or infinity)"
    if kind in ("float_parsing", "float_type", "int_parsing", "int_type", "int_from_float"):
        return f"{name} must be a {'whole ' if kind.startswith('int') else ''}number"
    if kind in ("string_too_short", "too_short"):
        n = ctx.get("min_length")
        if n == 1:
            return f"{name} must not be empty"
        return f"{name} must have at least {n} {'characters' if kind.startswith('string') else 'values'}"
    if kind in ("string_too_long", "too_long"):
        n = ctx.get("max_length")
        return f"{name} must have at most {n} {'characters' if kind.startswith('string') else 'values'}"
    if kind in ("literal_error", "enum"):
        return f"{name} must be {ctx.get('expected', 'one of the allowed values')}"
    if kind == "extra_forbidden":
        return f"{name} is not part of this request"
    if kind == "json_invalid":
        return "the request body is not valid JSON"
    if kind == "value_error":
        return re.sub(r"^Value error, ", "", msg)
    return f"{name}: {msg[0].lower() + msg[1:] if msg else 'invalid'}"
