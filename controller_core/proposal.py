"""A proposal: predicted features and curves with their uncertainty, the fitted table, and provenance.

Inside, everything is SI. :meth:`Proposal.to_dict` gives the JSON people and scripts read: angles in
degrees and moments in N·m/kg, each with the unit in its field name.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from controller_core.features import FeatureSpec
from controller_core.kmp import ViaPoint
from controller_core.quasi_stiffness import SubphaseFit
from controller_core.table import LimitViolation, ParameterTable, display_rows

FEATURE_UNITS = {"angle": "deg", "moment": "N·m/kg", "timing": "fraction of gait cycle"}


@dataclass(frozen=True)
class FeaturePrediction:
    """GPR prediction of one feature (SI: value rad, N·m/kg or phase; phase in [0, 1])."""

    spec: FeatureSpec
    phase: float
    phase_std: float
    value: float
    std: float
    extrapolation: bool

    def display_value(self) -> tuple[float, float, str]:
        """(value, std, unit) in clinician units."""
        unit = FEATURE_UNITS[self.spec.quantity]
        if self.spec.quantity == "angle":
            return math.degrees(self.value), math.degrees(self.std), unit
        return self.value, self.std, unit


@dataclass
class Proposal:
    """Everything the model proposes for one task and patient."""

    speed_mps: float
    incline_deg: float
    mass_kg: float
    model_version: str
    data_sha256: str
    extrapolation: bool
    features: list[FeaturePrediction]
    phase: np.ndarray
    means: dict[str, np.ndarray]
    stds: dict[str, np.ndarray]
    boundaries: tuple[float, float, float]
    fits: dict[str, list[SubphaseFit]]
    table: ParameterTable
    violations: list[LimitViolation]
    vias: dict[str, list[ViaPoint]] = field(default_factory=dict)

    def via_points_dict(self) -> list[dict[str, float | str]]:
        """The KMP via-points (from the GPR features) in display units: (angle deg, moment N·m/kg) at a phase."""
        return [{"joint": joint, "phase": round(float(v.phase), 4),
                 "angle_deg": round(math.degrees(float(v.mean[0])), 4),
                 "moment_Nm_per_kg": round(float(v.mean[1]), 5)}
                for joint, vias in self.vias.items() for v in vias]

    def curves_dict(self) -> dict[str, list[float]]:
        """Curves in display units on the 101-point phase grid."""
        out: dict[str, list[float]] = {"phase": np.round(self.phase, 4).tolist()}
        for joint in ("knee", "ankle"):
            a, a_sd = self.means[f"{joint}_angle"], self.stds[f"{joint}_angle"]
            m, m_sd = self.means[f"{joint}_moment"], self.stds[f"{joint}_moment"]
            out[f"{joint}_angle_deg"] = np.round(np.degrees(a), 4).tolist()
            out[f"{joint}_angle_deg_std"] = np.round(np.degrees(a_sd), 4).tolist()
            out[f"{joint}_moment_Nm_per_kg"] = np.round(m, 5).tolist()
            out[f"{joint}_moment_Nm_per_kg_std"] = np.round(m_sd, 5).tolist()
        return out

    def to_dict(self) -> dict:
        """JSON-ready dictionary (see the CLI's ``predict --format json``)."""
        body = self.model_body()
        return {
            "task": {"speed_mps": self.speed_mps, "incline_deg": self.incline_deg, "mass_kg": self.mass_kg},
            "model": body["model"],
            "extrapolation": self.extrapolation,
            "features": body["features"],
            "subphase_boundaries_phase": body["subphase_boundaries_phase"],
            "curves": body["curves"],
            "via_points": body["via_points"],
            "table": display_rows(self.table),
            "thresholds": self.table.thresholds.model_dump(),
            "safety": {"ok": not self.violations, "violations": [v.model_dump() for v in self.violations]},
        }

    def model_body(self) -> dict:
        """What the model predicted, in display units: model, features, sub-phase boundaries, curves and
        via-points (:meth:`to_dict` without the task, table and safety check, which are stored apart)."""
        feats = []
        for f in self.features:
            value, std, unit = f.display_value()
            feats.append({
                "joint": f.spec.joint, "quantity": f.spec.quantity, "name": f.spec.name,
                "label": f.spec.label, "phase": round(f.phase, 4), "phase_std": round(f.phase_std, 4),
                "value": round(value, 4), "std": round(std, 4), "unit": unit,
                "extrapolation": f.extrapolation,
            })
        return {
            "model": {"version": self.model_version, "data_sha256": self.data_sha256},
            "features": feats,
            "subphase_boundaries_phase": {
                "stance_flexion_to_stance_extension": round(self.boundaries[0], 4),
                "stance_extension_to_swing_flexion": round(self.boundaries[1], 4),
                "swing_flexion_to_swing_extension": round(self.boundaries[2], 4),
            },
            "curves": self.curves_dict(),
            "via_points": self.via_points_dict(),
        }
