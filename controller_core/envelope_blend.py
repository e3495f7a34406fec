"""Bilinear blending of an envelope's schedules at a task: what the adaptive leg runs at each heel strike.

:class:`EnvelopeBlender` is built from the grid axes and one table per node. Building it is the device's own
check: every node passes the safety limits (:meth:`ImpedanceSchedule.from_table`) and every pair of neighbours
the neighbour rule (:func:`controller_core.envelope.neighbour_violations`); anything else raises
:class:`controller_core.table.SafetyLimitError` and nothing is built. :meth:`EnvelopeBlender.at` then blends the
four nodes around a task; a task outside the grid is clamped to its edge and the result says so.

It runs on the leg once per stride, so a blend is one small matrix product with each cell's four corners stacked in
advance, and the schedule is built without the dataclass's per-field frozen checks (``python -m benchmarks
envelope``).
Units: SI schedules (rad, N·m/rad, N·m·s/rad, N, N·m, s); speed m/s, incline deg.
"""

from __future__ import annotations

import bisect
import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, fields

import numpy as np

from controller_core.envelope import DEFAULT_STEPS, NeighbourSteps, neighbour_violations
from controller_core.fsm import ImpedanceSchedule
from controller_core.table import ImpedanceTable, SafetyLimitError, SafetyLimits

_PER_STATE = ("knee_k", "knee_theta_e", "knee_b", "ankle_k", "ankle_theta_e", "ankle_b")
_SCALARS = ("sf_to_se_ankle_moment_Nm", "se_to_wf_load_N", "wf_to_we_knee_angle_rad", "we_to_sf_load_N",
            "min_state_time_s", "max_state_time_s", "sf_to_se_knee_extension_rad_s")


_SCHEDULE_FIELDS = tuple(f.name for f in fields(ImpedanceSchedule))


def _schedule(values: list[float], fixed: tuple[float, ...]) -> ImpedanceSchedule:
    """An ImpedanceSchedule from a blended vector, without the frozen dataclass's 16 checked assignments (7 µs of a
    20 µs budget): the values are blends of schedules that passed every check."""
    v = values
    out = object.__new__(ImpedanceSchedule)
    out.__dict__.update(zip(_SCHEDULE_FIELDS, (
        tuple(v[0:4]), tuple(v[4:8]), tuple(v[8:12]), tuple(v[12:16]), tuple(v[16:20]), tuple(v[20:24]),
        v[24], v[25], v[26], v[27], v[28], v[29], v[30], *fixed), strict=True))
    return out


def schedule_vector(schedule: ImpedanceSchedule) -> tuple[float, ...]:
    """The blended values of a schedule as one flat tuple (24 per-state values, then 7 thresholds)."""
    out: list[float] = []
    for name in _PER_STATE:
        out.extend(getattr(schedule, name))
    return tuple(out) + tuple(float(getattr(schedule, name)) for name in _SCALARS)


@dataclass(frozen=True, slots=True)
class Blend:
    """A blended schedule and where it was taken.

    Attributes:
        schedule: the blended schedule (SI).
        speed_mps, incline_deg: the task it was blended at, after clamping to the grid.
        clamped: the requested task lay outside the grid (clamped to its edge).
        cell: (speed index, incline index) of the cell's lower corner.
        weights: (speed, incline) position inside the cell, each in [0, 1].
    """

    schedule: ImpedanceSchedule
    speed_mps: float
    incline_deg: float
    clamped: bool
    cell: tuple[int, int]
    weights: tuple[float, float]


def _locate(axis: tuple[float, ...], x: float) -> tuple[int, float, float, bool]:
    """(lower index, weight, clamped value, clamped?) of x on an increasing axis."""
    lo, hi = axis[0], axis[-1]
    clamped = x < lo or x > hi
    x = lo if x < lo else hi if x > hi else x
    i = min(max(bisect.bisect_right(axis, x) - 1, 0), len(axis) - 2)
    return i, (x - axis[i]) / (axis[i + 1] - axis[i]), x, clamped


def node_weights(speeds_mps: Sequence[float], inclines_deg: Sequence[float], speed_mps: float, incline_deg: float
                 ) -> list[tuple[int, int, float]]:
    """The bilinear weights of a task on the grid's nodes, as the leg blends them: (speed index, incline index,
    weight) for the up to four nodes around the task (clamped at the grid's edge), weights summing to 1."""
    i, wi, _, _ = _locate(tuple(speeds_mps), speed_mps)
    j, wj, _, _ = _locate(tuple(inclines_deg), incline_deg)
    out = [(i + di, j + dj, (wi if di else 1.0 - wi) * (wj if dj else 1.0 - wj)) for di in (0, 1) for dj in (0, 1)]
    return [(a, b, w) for a, b, w in out if w > 0.0]


class EnvelopeBlender:
    """Blends per-node schedules bilinearly over speed × incline (nodes speed-major).

    Args:
        speeds_mps, inclines_deg: the grid axes, strictly increasing, at least two values each.
        tables: one table per node, ``tables[i * len(inclines_deg) + j]``.
        limits: the safety limits every node must pass.
        steps: the neighbour rule's steps.

    Raises:
        SafetyLimitError: a node violates a limit, or two neighbours break the neighbour rule; nothing is built.
        ValueError: the axes or the number of tables do not make a grid.
    """

    def __init__(self, speeds_mps: Sequence[float], inclines_deg: Sequence[float], tables: Sequence[ImpedanceTable],
                 limits: SafetyLimits | None = None, steps: NeighbourSteps = DEFAULT_STEPS) -> None:
        speeds, inclines = tuple(float(v) for v in speeds_mps), tuple(float(v) for v in inclines_deg)
        for name, axis in (("speeds_mps", speeds), ("inclines_deg", inclines)):
            if len(axis) < 2 or any(not math.isfinite(v) for v in axis) or any(
                    b <= a for a, b in itertools.pairwise(axis)):
                raise ValueError(f"{name} must be at least two finite, strictly increasing values, got {list(axis)}")
        if len(tables) != len(speeds) * len(inclines):
            raise ValueError(f"a {len(speeds)} × {len(inclines)} grid needs {len(speeds) * len(inclines)} tables, "
                             f"got {len(tables)}")
        schedules = [ImpedanceSchedule.from_table(t, limits) for t in tables]   # each node's limits
        broken = neighbour_violations(speeds, inclines, tables, steps)
        if broken:
            raise SafetyLimitError(broken)
        self.speeds_mps, self.inclines_deg = speeds, inclines
        self.schedules = tuple(schedules)
        n_i = len(inclines)
        v = np.array([schedule_vector(s) for s in schedules])
        self._cells = [[np.stack([v[i * n_i + j], v[i * n_i + j + 1], v[(i + 1) * n_i + j], v[(i + 1) * n_i + j + 1]])
                        for j in range(n_i - 1)] for i in range(len(speeds) - 1)]
        first = schedules[0]
        # what every node shares (not blended): the fields after the thresholds, in the schedule's own order
        self._fixed = tuple(getattr(first, name) for name in _SCHEDULE_FIELDS[13:])

    def contains(self, speed_mps: float, incline_deg: float, margin_mps: float = 0.0, margin_deg: float = 0.0) -> bool:
        """The task lies inside the grid (edges included), or within the margins (m/s, deg) beyond its edges."""
        return (self.speeds_mps[0] - margin_mps <= speed_mps <= self.speeds_mps[-1] + margin_mps
                and self.inclines_deg[0] - margin_deg <= incline_deg <= self.inclines_deg[-1] + margin_deg)

    def at(self, speed_mps: float, incline_deg: float) -> Blend:
        """The schedule blended at a task (clamped to the grid's edge outside it).

        Raises:
            ValueError: a non-finite task.
        """
        if not (math.isfinite(speed_mps) and math.isfinite(incline_deg)):
            raise ValueError(f"a task to blend at must be finite, got {speed_mps!r} m/s, {incline_deg!r} deg")
        i, wx, sp, cs = _locate(self.speeds_mps, speed_mps)
        j, wy, inc, ci = _locate(self.inclines_deg, incline_deg)
        weights = np.array(((1.0 - wx) * (1.0 - wy), (1.0 - wx) * wy, wx * (1.0 - wy), wx * wy))
        x = (weights @ self._cells[i][j]).tolist()
        return Blend(_schedule(x, self._fixed), sp, inc, cs or ci, (i, j), (wx, wy))
