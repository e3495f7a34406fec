"""The measured able-bodied walking conditions the model was trained on."""

from __future__ import annotations

import math
from typing import Annotated

from fastapi import APIRouter, Query

from backend.deps import CurrentUser, Model
from backend.schemas.errors import UNAUTHORIZED
from backend.schemas.reference import ReferenceOut, TaskRangeOut
from backend.schemas.versions import MAX_NODES
from controller_core.known_range import known_range
from controller_core.model import QuasiStiffnessModel
from controller_core.reference import CITATIONS
from controller_core.task import INCLINE_LIMIT_DEG, MASS_RANGE_KG, SPEED_RANGE_MPS
from controller_core.walking_reference import sloped_walking_reference

router = APIRouter(prefix="/api", tags=["reference"], responses=UNAUTHORIZED)


def _deg(values) -> list[float]:
    return [round(math.degrees(float(v)), 3) for v in values]


def _plain(values) -> list[float]:
    return [round(float(v), 4) for v in values]


def _task(value: float | None) -> float | None:
    return None if value is None or not math.isfinite(value) else round(float(value), 4)


REFERENCE_LABELS = {
    "measured": "measured able-bodied level walking",
    "measured_ramp_trend": "measured level walking + one participant's measured ramp change, scaled to this incline",
}


def _at_task(speed_mps: float, incline_deg: float) -> dict | None:
    ref = sloped_walking_reference(speed_mps, incline_deg)
    if ref is None:
        return None
    cited = ["bovi2011"] + (["vielemeyer2025"] if ref.kind == "measured_ramp_trend" else [])
    return {"kind": ref.kind, "label": REFERENCE_LABELS[ref.kind], "source": ref.source,
            "citations": [CITATIONS[c] for c in cited], "speed_mps": speed_mps, "incline_deg": incline_deg,
            "phase": _plain(ref.phase), "knee_angle_deg": _deg(ref.knee_angle_rad),
            "knee_moment_Nm_per_kg": _plain(ref.knee_moment_Nm_per_kg), "ankle_angle_deg": _deg(ref.ankle_angle_rad),
            "ankle_moment_Nm_per_kg": _plain(ref.ankle_moment_Nm_per_kg)}


def _ramp_conditions(model: QuasiStiffnessModel) -> list[dict]:
    """The conditions of the ramp curves the model learned the slope's change from (none for a model fitted without
    them): the model's own record, not a file read again."""
    ramps = model.ramps_.records if model.ramps_ is not None else []
    return [{"name": rec.name, "dataset": rec.dataset, "citation": CITATIONS.get("vielemeyer2025", rec.dataset),
             "speed_mps": round(float(rec.task["speed_mps"]), 3), "incline_deg": float(rec.task["incline_deg"]),
             "strides": rec.n} for rec in ramps]


@router.get("/reference", response_model=ReferenceOut)
def get_reference(_user: CurrentUser, model: Model,
                  speed_mps: Annotated[float | None, Query(ge=SPEED_RANGE_MPS[0], le=SPEED_RANGE_MPS[1])] = None,
                  incline_deg: Annotated[float, Query(ge=-INCLINE_LIMIT_DEG, le=INCLINE_LIMIT_DEG)] = 0.0) -> dict:
    """The measured able-bodied walking conditions the model was trained on, with their citations: the grey
    curves a proposal is drawn over (angles in deg, moments in N·m/kg, internal, flexor/dorsiflexor +). With
    ``speed_mps`` (and ``incline_deg``): also the reference at that task and what it really is (``at_task``)."""
    conditions = []
    for rec in model.reference_.records:
        conditions.append({
            "name": rec.name, "dataset": rec.dataset, "citation": CITATIONS.get(rec.dataset, rec.dataset),
            "speed_mps": _task(rec.task.get("speed_mps")), "incline_deg": _task(rec.task.get("incline_deg")),
            "subjects_or_strides": rec.n if rec.n >= 0 else None, "phase": _plain(rec.phase),
            "knee_angle_deg": _deg(rec.mean["knee_angle"]), "knee_moment_Nm_per_kg": _plain(rec.mean["knee_moment"]),
            "ankle_angle_deg": _deg(rec.mean["ankle_angle"]),
            "ankle_moment_Nm_per_kg": _plain(rec.mean["ankle_moment"])})
    return {"model_version": model.model_version, "data_sha256": model.data_sha256_, "conditions": conditions,
            "ramp_conditions": _ramp_conditions(model),
            "at_task": None if speed_mps is None else _at_task(speed_mps, incline_deg)}


@router.get("/task-range", response_model=TaskRangeOut)
def get_task_range(_user: CurrentUser, model: Model) -> dict:
    """The limits of any request (speed, incline, body mass, envelope grid) and the tasks the model knows: its data's
    range plus the stated margin, beyond which a proposal or envelope needs ``extrapolate`` and a ``reason``. The
    forms take their bounds from here."""
    return {"speed_mps": list(SPEED_RANGE_MPS), "incline_deg": [-INCLINE_LIMIT_DEG, INCLINE_LIMIT_DEG],
            "body_mass_kg": list(MASS_RANGE_KG), "envelope_nodes_per_axis": [2, 15], "envelope_max_nodes": MAX_NODES,
            "known": known_range(model).to_json()}
