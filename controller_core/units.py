"""Physical constants and the few unit conversions the project uses (SI inside the code; deg and % BW on screen)."""

from __future__ import annotations

import math

G_MPS2 = 9.81                      # standard gravity (m/s²): body weight = mass × G_MPS2
RAD_PER_DEG = math.pi / 180.0
DEG_PER_RAD = 180.0 / math.pi


def body_weight_N(mass_kg: float) -> float:
    """Body weight (N) of a mass (kg)."""
    return mass_kg * G_MPS2
