"""Patients."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, Field, field_validator

from backend.schemas.common import StrictIn, Text, json_integer
from device_bridge.sim.leg_file import LegFile

CODE_NAME_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9 ._-]{0,63}$"

CodeName = Annotated[str, Field(pattern=CODE_NAME_PATTERN,
                                description="pseudonymous code (no real names): letters, digits, space . _ -")]
BodyMass = Annotated[float, Field(ge=20, le=200, description="body mass (kg) including the prosthesis, 20-200")]
Height = Annotated[float, Field(ge=0.5, le=2.5, description="height (m), 0.5-2.5")]
Side = Annotated[Literal["left", "right"], Field(description="amputated side")]
KLevel = Annotated[int, Field(ge=0, le=4, description="Medicare functional level K0-K4")]
Notes = Annotated[Text, Field(max_length=4000, description="free-text clinical notes")]
Leg = Annotated[LegFile, Field(description="the patient's leg as a leg file describes it (device_bridge/sim/leg_file.py: "
                                           "name, body_height_m, segment and unit masses in kg, drive friction in N·m, "
                                           "reflected inertia in kg·m²; a field left out is the nominal bench leg's): "
                                           "new versions are made for it and the bench walks it. null: none given, "
                                           "the server's bench leg stands in")]


def _with_leg(fields: dict, leg: LegFile | None) -> dict:
    """The fields as the store takes them: the leg as the description it gives (the fields it sets)."""
    return {**fields, "leg": None if leg is None else leg.description()} if "leg" in fields else fields


class PatientCreate(StrictIn):
    code_name: CodeName
    body_mass_kg: BodyMass
    height_m: Height | None = None
    side: Side
    k_level: KLevel | None = None
    notes: Notes = ""
    leg: Leg | None = None

    _k_level_integer = field_validator("k_level", mode="before")(json_integer)

    def fields(self) -> dict:
        return _with_leg(self.model_dump(), self.leg)


class PatientPatch(StrictIn):
    """Any subset of the patient's fields. ``null`` clears height and K-level; the other fields cannot be null
    (their ``None`` default only means "not given" and is never validated)."""

    code_name: CodeName = None  # type: ignore[assignment]
    body_mass_kg: BodyMass = None  # type: ignore[assignment]
    height_m: Height | None = None
    side: Side = None  # type: ignore[assignment]
    k_level: KLevel | None = None
    notes: Notes = None  # type: ignore[assignment]
    leg: Leg | None = None

    _k_level_integer = field_validator("k_level", mode="before")(json_integer)

    def changes(self) -> dict:
        """Only the fields the request named (``leg``: null clears it, the server's bench leg then stands in)."""
        return _with_leg({k: getattr(self, k) for k in self.model_fields_set}, self.leg)


class PatientOut(BaseModel):
    id: int
    code_name: str
    body_mass_kg: float = Field(description="kg")
    height_m: float | None = Field(description="m")
    side: Literal["left", "right"]
    k_level: int | None
    notes: str
    leg: dict | None = Field(description="the patient's leg as described (the fields given; the rest are the nominal "
                                         "bench leg's), or null: none given, the server's bench leg stands in")
    created_at: str
    updated_at: str
