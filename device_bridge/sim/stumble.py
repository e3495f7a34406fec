"""A stumble on the bench (issue 53): an obstacle that catches the toe in mid-swing, or a low platform on which the
foot lands early on a bent knee, and how many strides the leg needs to walk cleanly again.

The walk is first walked without the obstacle (the bench is deterministic): the obstacle is then placed where that walk
put the toe in mid-swing (bench phase 0.8, a 5 cm long block reaching 1.5 cm into the toe's path) or the heel at its
landing (a 40 cm platform, 4 cm high, beginning 15 cm before the heel's landing point) of the first stride after
``after_s``, and the walk is walked again on that floor.

**The person reacts to a trip** (:attr:`device_bridge.sim.person.Person.recovery_steps`): once their hip has dropped
:attr:`~device_bridge.sim.person.Person.recovery_step_sink_m` below its path with the other foot in the air, that
foot comes down at once (the sound leg's recovery step of the lowering strategy); the walk lists each such step. The
steady-walk bench and the gate keep a person who never steps to save themselves, so a hip that sinks there is a fall.

A stride (heel strike to heel strike) is **clean** when it has no fall, no toe catch, no recovery step, the machine
entered stance flexion within :data:`CLEAN_STANCE_ENTRY_MS` of the foot's contact, and the loaded knee stayed below
the larger of :data:`CLEAN_LOADED_KNEE_DEG` (the bench gate's bound) and the same walk's without the obstacle plus
:data:`CLEAN_LOADED_KNEE_MARGIN_DEG` (a downhill knee that always yields to 40° is back when it yields as before);
the leg **recovered** after ``strides_to_recover`` strides when every stride from there to the end of the walk is
clean, and there are at least :data:`RECOVERED_STRIDES` of them.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from controller_core.fsm import GaitState
from controller_core.units import G_MPS2
from controller_core.walking_reference import WalkingReference
from device_bridge.sim.leg_model import LegGeometry
from device_bridge.sim.person import Person
from device_bridge.sim.simulate import (
    StepController,
    WalkLog,
    contact_strikes,
    fall_events,
    fall_mask,
    run_walk,
    toe_catch_mask,
)

KINDS = ("toe_catch", "early_landing")
TOE_CATCH_PHASE = 0.8            # where in the bench's swing the block stands (phase)
TOE_BLOCK_LENGTH_M = 0.05
TOE_BLOCK_REACH_M = 0.015        # how far into the toe's path the block reaches (m)
PLATFORM_LENGTH_M = 0.40
PLATFORM_HEIGHT_M = 0.04
PLATFORM_LEAD_M = 0.15           # the platform begins this far before where the heel would have landed
EDGE_M = 0.005                   # the obstacle's edges rise over this run (a near-vertical face)
CLEAN_STANCE_ENTRY_MS = 50.0
CLEAN_LOADED_KNEE_DEG = 40.0
CLEAN_LOADED_KNEE_MARGIN_DEG = 2.0
RECOVERED_STRIDES = 3            # clean strides the walk must end with for the leg to count as recovered


@dataclass(frozen=True)
class FloorWithObstacle:
    """The tilted plane with one block on it: from ``start_m`` (horizontal position, m) for ``length_m``,
    ``height_m`` above the plane; ``polyline()`` is the floor profile the plant builds its floor from. ``met_s``: when
    the walk without it reached it (s)."""

    incline_deg: float
    start_m: float
    length_m: float
    height_m: float
    end_m: float = 80.0
    met_s: float = 0.0

    def polyline(self) -> tuple[tuple[float, float], ...]:
        slope = math.tan(math.radians(self.incline_deg))
        a, b, h = self.start_m, self.start_m + self.length_m, self.height_m
        xs = [(-5.0, 0.0), (a, 0.0), (a + EDGE_M, h), (b - EDGE_M, h), (b, 0.0), (self.end_m, 0.0)]
        return tuple((x, x * slope + dz) for x, dz in xs)


def _foot_paths(controller: StepController, reference: WalkingReference, mass_kg: float, seconds: float,
                geometry: LegGeometry | None, floor: FloorWithObstacle | None
                ) -> tuple[WalkLog, np.ndarray, np.ndarray]:
    """Walk from standing and record the toe's and the heel's contact-sphere centres (x, z per tick, m)."""
    toe, heel = [], []

    def record(leg) -> None:
        toe.append(leg.data.geom_xpos[leg.model.geom("toe").id][[0, 2]].copy())
        heel.append(leg.data.geom_xpos[leg.model.geom("heel").id][[0, 2]].copy())

    log = run_walk(controller, reference, mass_kg, seconds, geometry, frame_callback=record, frame_every=1,
                   terrain=floor, person=Person(mass_kg, recovery_steps=True))
    return log, np.array(toe), np.array(heel)


def place_obstacle(kind: str, log: WalkLog, toe: np.ndarray, heel: np.ndarray, incline_deg: float, after_s: float,
                   geometry: LegGeometry) -> FloorWithObstacle:
    """The obstacle of ``kind`` for the first stride after ``after_s`` of ``log`` (module docstring).

    Raises:
        ValueError: an unknown kind, or no such stride in the walk.
    """
    c = log.channels
    t, phase = c["time_s"], c["bench_phase"]
    slope = math.tan(math.radians(incline_deg))
    if kind == "toe_catch":
        at = np.flatnonzero((t[1:] >= after_s) & (phase[:-1] < TOE_CATCH_PHASE) & (phase[1:] >= TOE_CATCH_PHASE))
        if not at.size:
            raise ValueError(f"no mid-swing after {after_s:g} s to put the block in")
        x, z = toe[at[0] + 1]
        clearance = z - x * slope - geometry.contact_radius_m
        return FloorWithObstacle(incline_deg, float(x) - TOE_BLOCK_LENGTH_M / 2, TOE_BLOCK_LENGTH_M,
                                 float(max(clearance, 0.0) + TOE_BLOCK_REACH_M), met_s=float(t[at[0] + 1]))
    if kind == "early_landing":
        strikes = contact_strikes(log)
        strikes = strikes[t[strikes] >= after_s]
        if not strikes.size:
            raise ValueError(f"no heel strike after {after_s:g} s to put the platform under")
        x = float(heel[strikes[0]][0])
        return FloorWithObstacle(incline_deg, x - PLATFORM_LEAD_M, PLATFORM_LENGTH_M, PLATFORM_HEIGHT_M,
                                 met_s=float(t[strikes[0]]))
    raise ValueError(f"kind must be one of {', '.join(KINDS)}, got {kind!r}")


def loaded_knee_max_deg(log: WalkLog) -> float:
    """The knee's largest flexion while the leg carries more than half the body weight over the whole walk (deg)."""
    c = log.channels
    loaded = c["load_N"] > 0.5 * log.mass_kg * G_MPS2
    return float(np.degrees(c["knee_angle_rad"][loaded].max())) if loaded.any() else 0.0


def clean_strides(log: WalkLog, toe_off_phase: float, loaded_knee_bound_deg: float = CLEAN_LOADED_KNEE_DEG
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Heel strikes (tick indices) and, per stride between them, whether it was clean (module docstring), the loaded
    knee held to ``loaded_knee_bound_deg``."""
    c, dt = log.channels, log.timestep_s
    weight = log.mass_kg * G_MPS2
    strikes = contact_strikes(log)
    toe_catch = toe_catch_mask(c, toe_off_phase, weight)
    fallen = fall_mask(c, weight)
    loaded_bent = (c["load_N"] > 0.5 * weight) & (c["knee_angle_rad"] > math.radians(loaded_knee_bound_deg))
    stance = c["state"].astype(int) == int(GaitState.STANCE_FLEXION)
    stepped = np.zeros(c["time_s"].shape[0], dtype=bool)
    steps = np.searchsorted(c["time_s"], log.extras.get("recovery_step_times_s", []))
    stepped[np.minimum(steps, stepped.shape[0] - 1)] = True
    lead, late = round(0.1 / dt), round(CLEAN_STANCE_ENTRY_MS / 1000.0 / dt)
    clean = []
    for a, b in itertools.pairwise(strikes):
        entered = stance[max(a - lead, 0): a + late + 1].any()
        clean.append(bool(entered and not (toe_catch[a:b].any() or fallen[a:b].any() or loaded_bent[a:b].any()
                                           or stepped[a:b].any())))
    return strikes, np.array(clean, dtype=bool)


def run_stumble(make: Callable[[], StepController], reference: WalkingReference, mass_kg: float, kind: str,
                after_s: float = 6.0, seconds: float = 14.0, geometry: LegGeometry | None = None) -> dict[str, object]:
    """Walk ``reference``'s task from standing with a fresh controller from ``make``, put the obstacle of ``kind``
    in the stride after ``after_s``, walk it again, and say how the leg came through: ``falls`` and their events,
    ``strides_to_recover`` (strides from the disturbed one until every stride to the end is clean; None if it never
    is), whether the obstacle was touched at all (``disturbed``), and the obstacle."""
    if kind not in KINDS:
        raise ValueError(f"kind must be one of {', '.join(KINDS)}, got {kind!r}")
    geometry = geometry or LegGeometry()
    log, toe, heel = _foot_paths(make(), reference, mass_kg, seconds, geometry, None)
    floor = place_obstacle(kind, log, toe, heel, reference.incline_deg, after_s, geometry)
    log2, toe2, heel2 = _foot_paths(make(), reference, mass_kg, seconds, geometry, floor)
    knee_bound = max(CLEAN_LOADED_KNEE_DEG, loaded_knee_max_deg(log) + CLEAN_LOADED_KNEE_MARGIN_DEG)
    strikes, clean = clean_strides(log2, reference.toe_off_phase, knee_bound)
    t = log2.channels["time_s"]
    # the stride the obstacle is met in (a caught toe's contact, or the early landing, begins one)
    first = max(int(np.searchsorted(t[strikes], floor.met_s + 0.05)) - 1, 0)
    dirty = np.flatnonzero(~clean[first:])
    recover = int(dirty[-1]) + 1 if dirty.size else 0
    if clean[first:].size - recover < RECOVERED_STRIDES:
        recover = None                          # not enough clean strides at the end to call it recovered
    slope, r = math.tan(math.radians(reference.incline_deg)), geometry.contact_radius_m
    touched = any(bool(np.any((p[:, 0] >= floor.start_m - r) & (p[:, 0] <= floor.start_m + floor.length_m + r)
                              & (p[:, 1] - p[:, 0] * slope <= floor.height_m + r + 1e-3))) for p in (toe2, heel2))
    weight = mass_kg * G_MPS2
    events = fall_events(log2.channels, weight, round(0.2 / log2.timestep_s))
    return {"kind": kind, "speed_mps": reference.speed_mps, "incline_deg": reference.incline_deg,
            "leg": geometry.name, "obstacle": {"start_m": round(floor.start_m, 3), "length_m": floor.length_m,
                                               "height_m": round(floor.height_m, 4),
                                               "met_s": round(floor.met_s, 3)},
            "loaded_knee_bound_deg": round(knee_bound, 1),
            "disturbed": touched, "falls": len(events), "fall_events": events,
            "recovery_steps": log2.extras["recovery_step_times_s"],
            "strides_after": int(clean.size - first), "strides_to_recover": recover,
            "clean": [bool(v) for v in clean[first:]]}
