"""A leg's swing inertia about the knee and the ankle, and its ratio to the reference leg's: what the table rules scale
the swing rows by (:func:`controller_core.table_rules.swing_scale`).

The inertia about a joint is the joint's diagonal entry of the MuJoCo model's mass matrix with the knee straight and
the ankle neutral: everything distal to the joint about its axis (shank, ankle unit, foot about the knee; the foot
about the ankle) plus the actuator's reflected inertia (``*_armature_kg_m2``). It is the leg's own: the person and
their mass do not enter it. The reference is :class:`~device_bridge.sim.leg_model.LegGeometry`'s default leg, the one
the swing rows' per-kg settings were tuned on.
"""

from __future__ import annotations

from functools import lru_cache

import mujoco
import numpy as np

from device_bridge.sim.leg_model import LegGeometry
from device_bridge.sim.plant import SimulatedLeg


@lru_cache(maxsize=64)
def swing_inertia_kg_m2(geometry: LegGeometry) -> tuple[float, float]:
    """(knee, ankle) swing inertia of ``geometry``'s leg (kg·m²), as the module docstring says."""
    leg = SimulatedLeg(geometry)
    m, d = leg.model, leg.data
    mujoco.mj_forward(m, d)                     # qpos all zero: knee straight, ankle neutral
    mass_matrix = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, mass_matrix)
    knee, ankle = (int(m.joint(name).dofadr[0]) for name in ("knee", "ankle"))
    return float(mass_matrix[knee, knee]), float(mass_matrix[ankle, ankle])


def swing_inertia_ratio(geometry: LegGeometry | None) -> tuple[float, float]:
    """(knee, ankle) swing inertia of ``geometry``'s leg over the reference leg's (1, 1 for the reference leg or
    None)."""
    if geometry is None:
        return 1.0, 1.0
    (knee, ankle), (knee0, ankle0) = swing_inertia_kg_m2(geometry), swing_inertia_kg_m2(LegGeometry())
    return knee / knee0, ankle / ankle0
