"""A leg file: the simulated leg and person as JSON, for a bench patient who is not the nominal one.

Every field is optional and defaults to today's bench (:class:`device_bridge.sim.leg_model.LegGeometry`); the names are
the contract (units in the names):

``name``, ``body_height_m``, ``socket_mass_kg``, ``shank_mass_kg``, ``ankle_unit_mass_kg``, ``foot_mass_kg``,
``heel_back_m``, ``contact_radius_m``, ``knee_armature_kg_m2``, ``ankle_armature_kg_m2``, ``knee_friction_Nm`` and
``ankle_friction_Nm`` (Coulomb), ``knee_damping_Nm_s_per_rad`` and ``ankle_damping_Nm_s_per_rad`` (viscous, on top of
the table's b).

An unknown field or a value outside its range is refused with the field and the reason. The ranges are what the bench
can represent as an adult wearing a knee-ankle prosthesis: Winter's proportions hold for adults (1.40–2.10 m); masses
from a light carbon foot to a heavy powered one; armature up to 0.5 kg·m² (a stiff-geared actuator's reflected
inertia); friction up to 15 N·m (a harmonic or ball-screw drive with its seals).
"""

from __future__ import annotations

import json
from pathlib import Path

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from controller_core.content import canonical_text, content_sha256
from controller_core.fsm import MAX_DRIVE_FRICTION_NM
from device_bridge.sim.leg_model import LegGeometry

LEGS_DIR = Path(__file__).resolve().parent / "legs"


class LegFile(BaseModel):
    """The JSON of a leg file (module docstring); ``None`` means the nominal bench's value."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, frozen=True)

    name: str | None = Field(default=None, min_length=1, max_length=60)
    body_height_m: float | None = Field(default=None, ge=1.40, le=2.10)
    socket_mass_kg: float | None = Field(default=None, ge=0.5, le=15.0)
    shank_mass_kg: float | None = Field(default=None, ge=0.5, le=10.0)
    ankle_unit_mass_kg: float | None = Field(default=None, ge=0.1, le=5.0)
    foot_mass_kg: float | None = Field(default=None, ge=0.2, le=4.0)
    heel_back_m: float | None = Field(default=None, gt=0.0, le=0.12)
    contact_radius_m: float | None = Field(default=None, ge=0.005, le=0.05)
    knee_armature_kg_m2: float | None = Field(default=None, gt=0.0, le=0.5)
    ankle_armature_kg_m2: float | None = Field(default=None, gt=0.0, le=0.5)
    knee_friction_Nm: float | None = Field(default=None, ge=0.0, le=MAX_DRIVE_FRICTION_NM)
    ankle_friction_Nm: float | None = Field(default=None, ge=0.0, le=MAX_DRIVE_FRICTION_NM)
    knee_damping_Nm_s_per_rad: float | None = Field(default=None, ge=0.0, le=10.0)
    ankle_damping_Nm_s_per_rad: float | None = Field(default=None, ge=0.0, le=10.0)

    def geometry(self) -> LegGeometry:
        """The bench geometry: the nominal bench with this file's fields over it."""
        return LegGeometry(**self.description())

    def description(self) -> dict[str, object]:
        """The fields this file gives (the rest are the nominal bench's): what a patient's record keeps."""
        return {k: v for k, v in self.model_dump().items() if v is not None}

    def sha256(self) -> str:
        """What the bench walks, as one key: SHA-256 of the given fields but the name (words only), canonical JSON.
        Every file that gives nothing but a name is the nominal leg, :data:`NOMINAL_LEG_SHA256`."""
        physics = {k: v for k, v in self.description().items() if k != "name"}
        return content_sha256(canonical_text(physics))


NOMINAL_LEG_SHA256 = content_sha256(canonical_text({}))   # the nominal bench's key (LegFile.sha256 of no fields)


def _reason(error: ValidationError) -> str:
    parts = []
    for e in error.errors():
        field = ".".join(str(p) for p in e["loc"]) or "(file)"
        reason = "unknown field (see device_bridge/sim/leg_file.py for the names)" if e["type"] == "extra_forbidden" \
            else e["msg"]
        parts.append(f"{field}: {reason}")
    return "; ".join(parts)


def parse_leg_file(body: object, source: str = "leg") -> LegFile:
    """A leg file from its parsed JSON.

    Raises:
        ValueError: not an object, an unknown field, a value out of range (each named with the reason).
    """
    if not isinstance(body, dict):
        raise ValueError(f"{source}: a leg file is a JSON object of fields, got {type(body).__name__}")
    try:
        return LegFile.model_validate(body)
    except ValidationError as e:
        raise ValueError(f"{source}: {_reason(e)}") from None


def parse_leg(body: object, source: str = "leg") -> LegGeometry:
    """A leg from its parsed JSON (:func:`parse_leg_file`'s refusals)."""
    return parse_leg_file(body, source).geometry()


def load_leg(path: Path | str) -> LegGeometry:
    """A leg from a file, or from the repository's legs by name (``stiff_geared`` → ``legs/stiff_geared.json``).

    Raises:
        ValueError: no such file or leg, not JSON, or a field refused (named with the reason).
    """
    return load_leg_file(path).geometry()


def load_leg_file(path: Path | str) -> LegFile:
    """:func:`load_leg`'s file itself (its description and key)."""
    p = Path(path)
    if not p.exists() and p.suffix == "" and (LEGS_DIR / f"{p.name}.json").exists():
        p = LEGS_DIR / f"{p.name}.json"
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as e:
        known = ", ".join(sorted(f.stem for f in LEGS_DIR.glob("*.json")))
        raise ValueError(f"leg file {str(path)!r}: {e.strerror or e}; the repository's legs: {known}") from None
    try:
        body = json.loads(text)
    except json.JSONDecodeError as e:
        raise ValueError(f"leg file {p}: not JSON ({e.msg} at line {e.lineno})") from None
    return parse_leg_file(body, f"leg file {p}")
