"""The leg a patient wears and a version was made for: its description, its key, and what the pages call it.

A patient's record may carry a description of their leg (a leg file's fields, ``device_bridge/sim/leg_file.py``:
height, segment and unit masses, drive friction, reflected inertia). A version is made for the patient's leg as it
is described when the version is made, or for the server's bench leg where none is (the nominal leg unless the
server was started with ``--leg``): its swing rows are proposed for that leg's inertia and its bench preview and
refinements walk it, so the bench's verdict that approval and push rest on is the one on that leg. The version keeps
the description it was made for (``leg_json``); an edit or a refinement keeps its parent's.
"""

from __future__ import annotations

import functools
import json
from collections.abc import Mapping

from controller_core.content import canonical_text
from device_bridge.sim.leg_file import NOMINAL_LEG_SHA256, LegFile, parse_leg_file
from device_bridge.sim.swing_inertia import swing_inertia_ratio


def leg_of(text: str | None) -> LegFile:
    """A stored description (None or ``'{}'``: the nominal leg)."""
    return LegFile() if text is None else parse_leg_file(json.loads(text), "stored leg")


def leg_json(leg: LegFile) -> str:
    """The description as stored: the fields it gives, canonical JSON."""
    return canonical_text(leg.description())


def words(leg: LegFile) -> str:
    """Which leg, in words, for a page and a report."""
    if leg.sha256() == NOMINAL_LEG_SHA256:
        return "the nominal bench leg"
    return f"the leg described as '{leg.name}'" if leg.name else "a leg described without a name"


def view(leg: LegFile) -> dict[str, object]:
    """The leg as the API shows it with a version: its description, its key and its name in words."""
    key = leg.sha256()
    return {"description": leg.description(), "leg_sha256": key, "words": words(leg), "nominal": key == NOMINAL_LEG_SHA256}


def patient_leg(patient: Mapping, server_leg: LegFile) -> LegFile:
    """The leg a new version of this patient (their view, :func:`backend.store.patients.get_patient`) is made for:
    theirs as described, or ``server_leg`` where none is."""
    return server_leg if patient["leg"] is None else LegFile.model_validate(patient["leg"])


@functools.lru_cache(maxsize=64)
def _ratio(description: str) -> tuple[float, float]:
    return swing_inertia_ratio(leg_of(description).geometry())


def swing_ratio(leg: LegFile) -> tuple[float, float]:
    """(knee, ankle) swing inertia of the leg over the reference leg's: the swing rows are proposed for it."""
    return _ratio(leg_json(leg))


def version_leg(row: Mapping) -> LegFile:
    """The leg a stored version was made for (its previews and refinements walk it)."""
    return leg_of(row["leg_json"])
