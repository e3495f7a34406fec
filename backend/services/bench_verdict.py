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

from sqlalchemy import Connection, select

from backend.bench.node_previews import envelope_flags, flagged_nodes
from backend.bench.safety_figures import safety_figures, safety_flags
from backend.errors import ConflictError
from backend.store import previews, signoffs
from backend.store.tables import versions
from backend.store.users import User

MIN_OVERRIDE_CHARS = 20
MESSAGES_SAID = 6      # a refusal names this many of the bench's findings, then counts the rest
Kind = Literal["proposal", "envelope"]
_WORDS = {"clean": "bench preview clean", "unsafe": "bench preview UNSAFE",
          "not_walked": "bench preview not walked yet"}


def content_sha256(row: Mapping) -> str:
    """The SHA-256 of what the version is (its stored content): what a preview and a sign-off are of."""
    return str(row["content_sha256"])


# how much larger a safety figure must be than the parent's to count as worse, per unit: any count; otherwise a step
# beyond what one bench stride's timing (5 ms at 200 Hz control ticks, doubled), a millimetre-scale sink or a degree
# tells apart
WORSE_BY = {"falls": 0.0, "catches": 0.0, "strides": 0.0, "nodes": 0.0, "ms": 10.0, "mm": 5.0, "BW": 0.02, "deg": 1.0}


_OWN = {"proposal": "table", "envelope": "envelope"}     # the version's own walk in a stored preview


def _stored(conn: Connection, kind: Kind, version_id: int, sha: str) -> dict | None:
    """The stored preview of exactly this content of a version (None: not walked)."""
    return previews.get_preview(conn, kind, version_id, sha)


def worse_than_parent(conn: Connection, kind: Kind, row: Mapping, figures: list[dict]) -> dict | None:
    """The safety figures in which this version's bench walk is worse than its parent's (an edit's or a refinement's
    starting version) on the same walk: what a draft must say before anything else. None without a parent; ``walked``
    False while the parent's preview has not been walked."""
    parent_id = row.get("parent_id")
    if parent_id is None:
        return None
    parent = conn.execute(select(versions.c.version, versions.c.content_sha256.label("sha"))
                          .where(versions.c.id == parent_id)).mappings().first()
    if parent is None:
        return None
    stored = _stored(conn, kind, parent_id, str(parent["sha"]))
    if stored is None:
        return {"parent_id": parent_id, "parent_version": parent["version"], "walked": False, "figures": []}
    theirs = {f["figure"]: f["value"] for f in _figures(kind, stored)}
    worse = [{"figure": f["figure"], "label": f["label"], "unit": f["unit"], "parent_value": theirs.get(f["figure"]),
              "value": f["value"]} for f in figures
             if f["value"] is not None and theirs.get(f["figure"]) is not None
             and f["value"] - theirs[f["figure"]] > WORSE_BY.get(str(f["unit"]), 0.0)]
    return {"parent_id": parent_id, "parent_version": parent["version"], "walked": True, "figures": worse}


def _figures(kind: Kind, stored: Mapping) -> list[dict]:
    """Every safety figure of a stored preview beside the FSMIC's; an envelope's node walks as one more: how many
    nodes have a figure beyond its bound."""
    figures = safety_figures(stored["controllers"][_OWN[kind]], stored["controllers"]["fsmic"])
    if kind == "envelope":
        n = flagged_nodes(stored)
        figures.append({"figure": "nodes_beyond_bounds", "label": "nodes beyond a bound, each walked alone at its task",
                        "unit": "nodes", "value": n, "fsmic_value": None,
                        "severity": "bad" if n is None or n > 0 else None})
    return figures


def verdict(conn: Connection, kind: Kind, row: Mapping) -> dict:
    """``status`` clean / unsafe / not_walked, the ``flags`` (one per figure beyond its bound), every safety ``figure``
    beside the FSMIC's, ``words`` for the chip, and the prosthetists' ``signoffs`` on exactly this content."""
    sha = content_sha256(row)
    signed = [{k: s[k] for k in ("by", "reason", "at")} for s in signoffs.signoffs(conn, kind, row["id"], sha)]
    stored, own = _stored(conn, kind, row["id"], sha), _OWN[kind]
    if stored is None:
        return {"status": "not_walked", "flags": [], "figures": [], "words": _WORDS["not_walked"],
                "signoffs": signed, "signoffs_needed": signoffs.NEEDED, "worse_than_parent": None}
    mine, fsmic = stored["controllers"][own], stored["controllers"]["fsmic"]
    flags = envelope_flags(stored) if kind == "envelope" else safety_flags(mine, fsmic)
    status = "unsafe" if flags else "clean"
    words = _WORDS[status] if not flags else f"{_WORDS[status]}: {len(flags)} figure(s) beyond their bounds"
    figures = _figures(kind, stored)
    return {"status": status, "flags": flags, "figures": figures, "words": words,
            "signoffs": signed, "signoffs_needed": signoffs.NEEDED,
            "worse_than_parent": worse_than_parent(conn, kind, row, figures)}


def require_bench(conn: Connection, kind: Kind, row: Mapping, override_reason: str | None, action: str,
                  actor: User) -> tuple[dict, str | None]:
    """(the verdict, the override to keep with the decision or push: who signed off and why; None where the bench
    allows ``action`` ("approved", "pushed") by itself). Call inside the write transaction of ``action``: an approver
    who completes the sign-offs has theirs recorded with it. Refused (409, nothing written) otherwise, saying what the
    bench found and who has signed off so far."""
    v = verdict(conn, kind, row)
    if v["status"] == "clean":
        return v, None
    sha = content_sha256(row)
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
        shown = [str(f["message"]) for f in v["flags"][:MESSAGES_SAID]]
        more = len(v["flags"]) - len(shown)
        why = "its bench preview shows: " + "; ".join(shown) + (f"; and {more} more (see its preview)" if more else "")
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
