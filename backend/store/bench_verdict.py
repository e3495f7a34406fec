"""The bench's verdict on a version: its stored preview's safety flags, for exactly its content.

Approval and push rest on it. A version whose preview has not been walked, or shows any figure beyond its bound (a
fall, a toe catch, a stride that never reached stance, a loaded swing, a hip that sank, a late stance: every bound
of :mod:`backend.bench.safety_figures`), is approved or pushed only when two prosthetists signed off on its findings
(:mod:`backend.store.signoffs`: two accounts, each with its written reason, on exactly this content). The approver may
be the second: their ``override_reason`` is then their sign-off, stored with the approval in one transaction. A push
of such a version also needs the pusher's ``override_reason`` (audited with the push).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Literal

from sqlalchemy import Connection

from backend.bench.safety_figures import safety_figures, safety_flags
from backend.errors import ConflictError
from backend.store import previews, signoffs
from backend.store.users import User

MIN_OVERRIDE_CHARS = 20
Kind = Literal["proposal", "envelope"]
_WORDS = {"clean": "bench preview clean", "unsafe": "bench preview UNSAFE",
          "not_walked": "bench preview not walked yet"}


def content_sha256(kind: Kind, row: Mapping) -> str:
    """The SHA-256 of what the version is (its table, or its envelope): what a preview and a sign-off are of."""
    return str(row["table_sha256"] if kind == "proposal" else row["envelope_sha256"])


def verdict(conn: Connection, kind: Kind, row: Mapping) -> dict:
    """``status`` clean / unsafe / not_walked, the ``flags`` (one per figure beyond its bound), every safety ``figure``
    beside the FSMIC's, ``words`` for the chip, and the prosthetists' ``signoffs`` on exactly this content."""
    sha = content_sha256(kind, row)
    signed = [{k: s[k] for k in ("by", "reason", "at")} for s in signoffs.signoffs(conn, kind, row["id"], sha)]
    if kind == "proposal":
        stored, own = previews.get_preview(conn, row["id"], sha), "table"
    else:
        stored, own = previews.get_envelope_preview(conn, row["id"], sha), "envelope"
    if stored is None:
        return {"status": "not_walked", "flags": [], "figures": [], "words": _WORDS["not_walked"],
                "signoffs": signed, "signoffs_needed": signoffs.NEEDED}
    mine, fsmic = stored["controllers"][own], stored["controllers"]["fsmic"]
    flags = safety_flags(mine, fsmic)
    status = "unsafe" if flags else "clean"
    words = _WORDS[status] if not flags else f"{_WORDS[status]}: {len(flags)} figure(s) beyond their bounds"
    return {"status": status, "flags": flags, "figures": safety_figures(mine, fsmic), "words": words,
            "signoffs": signed, "signoffs_needed": signoffs.NEEDED}


def require_bench(conn: Connection, kind: Kind, row: Mapping, override_reason: str | None, action: str,
                  actor: User) -> tuple[dict, str | None]:
    """(the verdict, the override to keep with the decision or push: who signed off and why; None where the bench
    allows ``action`` ("approved", "pushed") by itself). Call inside the write transaction of ``action``: an approver
    who completes the sign-offs has theirs recorded with it. Refused (409, nothing written) otherwise, saying what the
    bench found and who has signed off so far."""
    v = verdict(conn, kind, row)
    if v["status"] == "clean":
        return v, None
    sha = content_sha256(kind, row)
    signed = signoffs.signoffs(conn, kind, row["id"], sha)
    mine = any(s["user_id"] == actor.id for s in signed)
    if action == "approved" and override_reason and not mine and len(signed) + 1 >= signoffs.NEEDED:
        signed = signoffs.sign(conn, kind, row["id"], sha, actor, override_reason)
    if len(signed) >= signoffs.NEEDED and (action == "approved" or override_reason):
        return v, signoffs.summary(signed)
    preview = f"/api/{kind}s/{row['id']}/preview"
    if v["status"] == "not_walked":
        why = f"its bench preview has not been walked yet (open its preview, GET {preview}, and look at it first)"
    else:
        why = "its bench preview shows: " + "; ".join(str(f["message"]) for f in v["flags"])
    so_far = ("nobody has signed off yet" if not signed else
              "signed off so far by " + ", ".join(s["by"] for s in signed))
    if len(signed) >= signoffs.NEEDED:       # a push of an overridden version: the pusher says why too
        need = f"two prosthetists signed off ({so_far[len('signed off so far by '):]}); give override_reason " \
               f"(at least {MIN_OVERRIDE_CHARS} characters, audited with the push) to push it anyway"
    else:
        need = (f"going ahead anyway needs {signoffs.NEEDED} prosthetists' sign-offs, each from their own account "
                f"with their own reason ({so_far}): sign off with POST /api/{kind}s/{row['id']}/signoffs"
                + (", then another prosthetist approves giving their own override_reason" if action == "approved"
                   else ""))
    raise ConflictError(f"{kind} {row['id']} is not {action}: {why}. {need}", bench=v)
