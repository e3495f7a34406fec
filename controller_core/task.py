"""A walking task (speed, incline) and the patient's body mass: the ranges QuasiTune accepts, checked in one place."""

from __future__ import annotations

import math

SPEED_RANGE_MPS = (0.1, 3.0)       # slower than 0.1 m/s is standing, not a walking task
INCLINE_LIMIT_DEG = 20.0
MASS_RANGE_KG = (20.0, 200.0)


class InvalidTaskError(ValueError):
    """A requested task or patient value is out of range or not a number."""


def validate_task(speed_mps: float, incline_deg: float, mass_kg: float) -> None:
    """Refuse NaN and out-of-range requests with a one-line reason."""
    for name, v in (("speed_mps", speed_mps), ("incline_deg", incline_deg), ("mass_kg", mass_kg)):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise InvalidTaskError(f"{name} must be a finite number, got {v!r}")
    if not SPEED_RANGE_MPS[0] <= speed_mps <= SPEED_RANGE_MPS[1]:
        raise InvalidTaskError(f"speed_mps = {speed_mps:g} m/s is outside [{SPEED_RANGE_MPS[0]:g}, "
                               f"{SPEED_RANGE_MPS[1]:g}] m/s")
    if abs(incline_deg) > INCLINE_LIMIT_DEG:
        raise InvalidTaskError(f"incline_deg = {incline_deg:g} deg is outside [-20, 20] deg")
    if not MASS_RANGE_KG[0] <= mass_kg <= MASS_RANGE_KG[1]:
        raise InvalidTaskError(f"mass_kg = {mass_kg:g} kg is outside [20, 200] kg")
