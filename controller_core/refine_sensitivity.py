"""How the controlled quantities respond to the refined table values: the sensitivity the refinement steps through.

Measured on the simulated bench, not modelled (``quasitune sensitivity``,
:mod:`device_bridge.bench.sensitivity`): at each node of a task grid, the central difference of each quantity's mean
error for a small change of each refined value, on the nominal leg at 75 kg. Shipped as
``controller_core/data/refine_sensitivity.json`` with its provenance; read here, with no bench needed, so a refinement
costs the same on a laptop, the server or the leg's own tools.

Units: a quantity's unit (deg, % of the gait cycle) per deg of an equilibrium angle, or per unit of ln|value| of a
stiffness or damping (so a 10 % stiffer row changes the quantity by 0.095 × the entry). At a task between nodes the
sensitivity is blended bilinearly, as the leg blends the rows. An entry the bench could not resolve at a node (its
walk fell), or one that lies further than :data:`OUTLIER_MADS` robust deviations from the same entry's median over the
grid (a walk that changed its gait pattern, e.g. into alternating long and short strides, rather than responding
smoothly), is taken from the grid's median of that entry, and is 0 if no node resolved it.

It is the nominal leg's: a patient's leg responds differently (friction, inertia, foot, how they walk). The refinement
is built for that: each round re-measures, the step is damped and limited, and a quantity that does not move as this
sensitivity expects is held (:func:`controller_core.refine.not_responding`).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import cached_property, lru_cache
from pathlib import Path

import numpy as np

from controller_core.envelope_blend import node_weights

SENSITIVITY_VERSION = 1
OUTLIER_MADS = 4.0   # robust deviations (1.4826 × median absolute deviation) beyond which a node's entry is not used
DEFAULT_PATH = Path(__file__).resolve().parent / "data" / "refine_sensitivity.json"


class SensitivityError(ValueError):
    """A sensitivity file that does not fit the code reading it."""


@dataclass(frozen=True)
class BenchSensitivity:
    """The measured sensitivity grid (module docstring).

    Attributes:
        parameters, quantities: the names of the columns and rows (``PARAMETERS`` fields, ``QUANTITIES`` keys).
        speeds_mps, inclines_deg: the grid.
        jacobians: (speeds, inclines, quantities, parameters) as measured, NaN where unresolved.
        provenance: how it was measured.
    """

    parameters: tuple[str, ...]
    quantities: tuple[str, ...]
    speeds_mps: tuple[float, ...]
    inclines_deg: tuple[float, ...]
    jacobians: np.ndarray
    provenance: dict

    @classmethod
    def from_json(cls, body: dict) -> BenchSensitivity:
        """Read the JSON of ``quasitune sensitivity``; SensitivityError naming what does not fit."""
        if body.get("version") != SENSITIVITY_VERSION:
            raise SensitivityError(f"sensitivity version {body.get('version')!r}; this code reads "
                                   f"{SENSITIVITY_VERSION} (re-measure with 'quasitune sensitivity')")
        speeds, inclines = tuple(map(float, body["speeds_mps"])), tuple(map(float, body["inclines_deg"]))
        params, quants = tuple(body["parameters"]), tuple(body["quantities"])
        raw = body["jacobians"]
        if len(raw) != len(speeds) * len(inclines):
            raise SensitivityError(f"{len(raw)} node sensitivities for a {len(speeds)} × {len(inclines)} grid")
        J = np.array([[[np.nan if v is None else float(v) for v in row] for row in node] for node in raw], dtype=float)
        if J.shape[1:] != (len(quants), len(params)):
            raise SensitivityError(f"node sensitivities of shape {J.shape[1:]}; the names say "
                                   f"{(len(quants), len(params))}")
        return cls(params, quants, speeds, inclines, J.reshape(len(speeds), len(inclines), *J.shape[1:]),
                   dict(body.get("provenance", {})))

    def check_names(self, parameters: tuple[str, ...], quantities: tuple[str, ...]) -> None:
        """Refuse a grid measured for other refined values or quantities than the code's."""
        if self.parameters != parameters or self.quantities != quantities:
            raise SensitivityError("the sensitivity was measured for other parameters or quantities than the "
                                   "refinement's: re-measure with 'quasitune sensitivity'")

    def at(self, speed_mps: float, incline_deg: float) -> np.ndarray:
        """(quantities × parameters) at a task: the grid's nodes blended bilinearly (clamped at the edges), each entry
        over the nodes where it is usable (module docstring), else the grid's median of it, else 0."""
        usable, median = self._cleaned
        weights = node_weights(self.speeds_mps, self.inclines_deg, speed_mps, incline_deg)
        stack = np.array([usable[i, j] for i, j, _ in weights])
        w = np.array([w for _, _, w in weights])[:, None, None] * np.isfinite(stack)
        total = w.sum(axis=0)
        blended = np.sum(np.nan_to_num(stack) * w, axis=0) / np.where(total > 0, total, 1.0)
        return np.where(total > 0, blended, median)

    def grid_median(self) -> np.ndarray:
        """Per entry, its median over the nodes that resolved it (0 where none did)."""
        return self._cleaned[1]

    def outliers(self) -> int:
        """How many resolved entries the outlier rule sets aside."""
        usable, _ = self._cleaned
        return int(np.sum(np.isfinite(self.jacobians) & ~np.isfinite(usable)))

    @cached_property
    def _cleaned(self) -> tuple[np.ndarray, np.ndarray]:
        flat = self.jacobians.reshape(-1, *self.jacobians.shape[2:])
        resolved = np.isfinite(flat).any(axis=0)
        median = np.nanmedian(np.where(resolved, flat, 0.0), axis=0)      # an entry no node resolved: 0
        spread = 1.4826 * np.nanmedian(np.where(resolved, np.abs(flat - median), 0.0), axis=0)
        with np.errstate(invalid="ignore"):
            far = np.abs(flat - median) > OUTLIER_MADS * np.maximum(spread, 1e-9)
        usable = np.where(far, np.nan, flat)
        return usable.reshape(self.jacobians.shape), median


@lru_cache(maxsize=4)
def load_sensitivity(path: Path | str = DEFAULT_PATH) -> BenchSensitivity:
    """The shipped (or a given) sensitivity grid, read once per path."""
    try:
        body = json.loads(Path(path).read_text())
    except FileNotFoundError as err:
        raise SensitivityError(f"no sensitivity file at {path}: measure it with 'quasitune sensitivity'") from err
    return BenchSensitivity.from_json(body)
