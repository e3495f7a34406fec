"""The bench's verdict on a version: its stored preview's safety flags, for exactly its content.

Approval and push rest on it: a version whose preview has not been walked, or whose preview flags a figure as
``bad`` (a fall, a toe catch, a stride that never reached stance, a loaded swing past its bound), is approved or
pushed only with a written ``override_reason`` (:data:`MIN_OVERRIDE_CHARS` characters at least), which is audited
and shown wherever the version is shown. Warnings are shown, and do not stop a decision.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Literal

from sqlalchemy import Connection

from backend.bench.safety_figures import safety_figures, safety_flags
from backend.errors import ConflictError
from backend.store import previews

MIN_OVERRIDE_CHARS = 20
Kind = Literal["proposal", "envelope"]
_WORDS = {"clean": "bench preview clean", "warnings": "bench preview with warnings",
          "unsafe": "bench preview UNSAFE", "not_walked": "bench preview not walked yet"}


def verdict(conn: Connection, kind: Kind, row: Mapping) -> dict:
    """``status`` clean / warnings / unsafe / not_walked, the ``flags`` (bad first), every safety ``figure`` beside the
    FSMIC's, and ``words`` for the chip."""
    if kind == "proposal":
        stored, own = previews.get_preview(conn, row["id"], row["table_sha256"]), "table"
    else:
        stored, own = previews.get_envelope_preview(conn, row["id"], row["envelope_sha256"]), "envelope"
    if stored is None:
        return {"status": "not_walked", "flags": [], "figures": [], "words": _WORDS["not_walked"]}
    mine, fsmic = stored["controllers"][own], stored["controllers"]["fsmic"]
    flags = safety_flags(mine, fsmic)
    status = "unsafe" if any(f["severity"] == "bad" for f in flags) else "warnings" if flags else "clean"
    return {"status": status, "flags": flags, "figures": safety_figures(mine, fsmic), "words": _WORDS[status]}


def require_bench(conn: Connection, kind: Kind, row: Mapping, override_reason: str | None,
                  action: str) -> tuple[dict, str | None]:
    """(the verdict, the override reason to keep: None where the bench allows ``action`` by itself), when the
    verdict allows ``action`` ("approved", "pushed") or an override reason is given; else 409 with the reason in a
    prosthetist's words."""
    v = verdict(conn, kind, row)
    if v["status"] in ("clean", "warnings"):
        return v, None
    if override_reason:
        return v, override_reason
    path = f"/api/{kind}s/{row['id']}/preview"
    if v["status"] == "not_walked":
        why = f"its bench preview has not been walked yet (open its preview, GET {path}, and look at it first)"
    else:
        why = "its bench preview shows: " + "; ".join(str(f["message"]) for f in v["flags"]
                                                       if f["severity"] == "bad")
    raise ConflictError(f"{kind} {row['id']} is not {action}: {why}. To go ahead anyway, give override_reason "
                        f"(at least {MIN_OVERRIDE_CHARS} characters): it is audited and shown wherever this version "
                        "is shown", bench=v)
