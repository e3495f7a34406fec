"""Physical constants and the few unit conversions the project uses (SI inside the code; deg and % BW on screen)."""

from __future__ import annotations

import math

G_MPS2 = 9.81                      # standard gravity (m/s²): body weight = mass × G_MPS2
RAD_PER_DEG = math.pi / 180.0
DEG_PER_RAD = 180.0 / math.pi


def body_weight_N(mass_kg: float) -> float:
    """Body weight (N) of a mass (kg)."""
    return mass_kg * G_MPS2


def require_positive(owner: object, names: tuple[str, ...] | None = None) -> None:
    """Refuse a setting that is not a positive finite number: each of ``names`` (default: every field of ``owner``)
    read from ``owner``, the first bad one named in the ValueError."""
    for name in names if names is not None else tuple(vars(owner)):
        v = getattr(owner, name)
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise ValueError(f"{name} must be a positive finite number, got {v!r}")
