"""The able-bodied walking pattern at a task: what the simulated bench replays and is scored against.

The learning pipeline needs knee and ankle only; the simulated hip-driven bench also needs the hip angle
(to drive the socket), the vertical ground reaction force (to load the leg) and the stride time. This module
interpolates all of them linearly in speed between the shipped Bovi 2011 adult level-walking records
(0.84, 1.19, 1.20, 1.49, 1.95 m/s), point by point on the common phase grid — the "linear interpolation
between conditions" baseline of the evaluation, which is the most literal reading of the data between
its conditions. Outside the covered speeds the nearest record is used and ``extrapolation`` is set.

On a slope (:func:`sloped_walking_reference`), where the shipped ramp curves reach (±10°): the level pattern at the
speed plus the change one person's ramp walking shows (:mod:`controller_core.incline`, hip included), scaled
to the incline. The vertical load and the timing stay those of level walking (the ramp data have no ground
reaction forces). ``kind`` says what a reference is: ``measured`` (level data), ``measured_ramp_trend`` or, built
elsewhere from the model, ``model_prediction``.

Units: phase in [0, 1]; angles in rad (hip and knee flexion +, ankle dorsiflexion +, Bovi ankle aligned to the
anatomical neutral exactly as in :func:`controller_core.reference.load_shipped_reference`); moments in N·m/kg
(internal, + in the + angle direction); vertical GRF in body weights; stride time in s.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cache

import numpy as np

from controller_core.incline import InclineChange
from controller_core.phase_table import load_shipped_ramps
from controller_core.reference import (
    SHIPPED_NPZ,
    bovi_ankle_offset_deg,
    data_dir,
    interp_rows,
    load_npz,
    sha256_of,
)


@dataclass(frozen=True)
class WalkingReference:
    """Mean able-bodied gait cycle for one task.

    Attributes:
        speed_mps: walking speed (m/s).
        incline_deg: incline (deg); the shipped curves are level walking only.
        phase: (P,) gait phase in [0, 1], 0 = heel strike.
        hip_angle_rad, knee_angle_rad, ankle_angle_rad: (P,) joint angles (rad).
        knee_moment_Nm_per_kg, ankle_moment_Nm_per_kg: (P,) internal joint moments (N·m/kg).
        vgrf_bw: (P,) ipsilateral vertical ground reaction force (body weights).
        stride_time_s: duration of one gait cycle (s).
        toe_off_phase: toe-off as a fraction of the cycle.
        source: the records the curves were interpolated from, for provenance.
        extrapolation: the speed lies outside the records' range (nearest record used).
        data_sha256: hash of the data file.
        kind: ``measured``, ``measured_ramp_trend`` or ``model_prediction`` (see the module docstring).
    """

    speed_mps: float
    incline_deg: float
    phase: np.ndarray
    hip_angle_rad: np.ndarray
    knee_angle_rad: np.ndarray
    ankle_angle_rad: np.ndarray
    knee_moment_Nm_per_kg: np.ndarray
    ankle_moment_Nm_per_kg: np.ndarray
    vgrf_bw: np.ndarray
    stride_time_s: float
    toe_off_phase: float
    source: str
    extrapolation: bool
    data_sha256: str
    kind: str = "measured"

    def curve(self, channel: str) -> np.ndarray:
        """A curve by the channel names of :data:`controller_core.reference.CHANNELS` (SI)."""
        return {"knee_angle": self.knee_angle_rad, "ankle_angle": self.ankle_angle_rad,
                "knee_moment": self.knee_moment_Nm_per_kg, "ankle_moment": self.ankle_moment_Nm_per_kg}[channel]


_LEVEL_CURVES: tuple[str, ...] = ("hip_angle_deg", "knee_angle_deg", "ankle_angle_deg", "knee_moment_Nm_per_kg",
                                  "ankle_moment_Nm_per_kg", "vgrf_BW")


@dataclass(frozen=True)
class _LevelRecords:
    """The shipped Bovi 2011 adult level-walking records, sorted by speed (read-only arrays)."""

    speeds_mps: np.ndarray            # (R,)
    phase: np.ndarray                 # (P,) in [0, 1]
    curves: dict[str, np.ndarray]     # name in _LEVEL_CURVES -> (R, P); the ankle already on the anatomical neutral
    stride_time_s: np.ndarray         # (R,)
    toe_off_pct: np.ndarray           # (R,)
    conditions: tuple[str, ...]
    data_sha256: str


@cache
def _level_records() -> _LevelRecords:
    """Read the shipped file once per process: a course walk asks for hundreds of strides' references, and reading
    and hashing the file for each took half of the walk's time."""
    path = data_dir() / SHIPPED_NPZ
    d = load_npz(path)
    keep = np.flatnonzero((d["dataset"] == "bovi2011") & (d["task"] == "level_walking")
                          & (d["population"] == "adult") & np.isfinite(d["speed_mps"]))
    order = keep[np.argsort(d["speed_mps"][keep])]
    offset = bovi_ankle_offset_deg(d)

    def frozen(a: np.ndarray) -> np.ndarray:
        a = np.array(a, dtype=float)
        a.setflags(write=False)
        return a

    curves = {key: frozen(d[key][order].astype(float) + (offset if key == "ankle_angle_deg" else 0.0))
              for key in _LEVEL_CURVES}
    return _LevelRecords(speeds_mps=frozen(d["speed_mps"][order]), phase=frozen(d["phase_pct"] / 100.0),
                         curves=curves, stride_time_s=frozen(d["stride_time_s"][order]),
                         toe_off_pct=frozen(d["toe_off_pct"][order]),
                         conditions=tuple(str(c) for c in d["condition"][order]), data_sha256=sha256_of(path))


def level_walking_reference(speed_mps: float) -> WalkingReference:
    """Interpolate the shipped Bovi 2011 adult level-walking records at ``speed_mps`` (m/s).

    Raises:
        ValueError: a non-finite or non-positive speed.
    """
    if not (np.isfinite(speed_mps) and speed_mps > 0):
        raise ValueError(f"speed_mps must be a positive finite number (m/s), got {speed_mps!r}")
    rec = _level_records()
    speeds = rec.speeds_mps

    def rows(key: str) -> np.ndarray:
        return interp_rows(speed_mps, speeds, rec.curves[key])

    hi = int(np.searchsorted(speeds, speed_mps))
    lo = max(hi - 1, 0)
    hi = min(hi, len(speeds) - 1)
    names = sorted({f"bovi2011/{rec.conditions[lo]}", f"bovi2011/{rec.conditions[hi]}"})
    return WalkingReference(
        speed_mps=float(speed_mps), incline_deg=0.0,
        phase=rec.phase.copy(),
        hip_angle_rad=np.deg2rad(rows("hip_angle_deg")),
        knee_angle_rad=np.deg2rad(rows("knee_angle_deg")),
        ankle_angle_rad=np.deg2rad(rows("ankle_angle_deg")),
        knee_moment_Nm_per_kg=rows("knee_moment_Nm_per_kg"),
        ankle_moment_Nm_per_kg=rows("ankle_moment_Nm_per_kg"),
        vgrf_bw=np.clip(rows("vgrf_BW"), 0.0, None),
        stride_time_s=float(np.interp(speed_mps, speeds, rec.stride_time_s)),
        toe_off_phase=float(np.interp(speed_mps, speeds, rec.toe_off_pct)) / 100.0,
        source=" + ".join(names) + " (linear in speed)",
        extrapolation=bool(speed_mps < speeds[0] or speed_mps > speeds[-1]),
        data_sha256=rec.data_sha256,
    )


RAMP_CHANNELS: tuple[str, ...] = ("hip_angle", "knee_angle", "knee_moment", "ankle_angle", "ankle_moment")


@cache
def shipped_incline_change() -> InclineChange:
    """The change a slope makes, learned from the shipped ramp curves against the Bovi speed curves (hip too)."""
    def population(speed_mps: float) -> dict[str, np.ndarray]:
        ref = level_walking_reference(speed_mps)
        return {"hip_angle": ref.hip_angle_rad, **{c: ref.curve(c) for c in RAMP_CHANNELS[1:]}}

    return InclineChange(channels=RAMP_CHANNELS).fit(load_shipped_ramps(), population)


def sloped_walking_reference(speed_mps: float, incline_deg: float) -> WalkingReference | None:
    """The level pattern at ``speed_mps`` plus the measured ramp trend at ``incline_deg``, or None where the
    shipped ramps do not reach (steeper than the steepest ramp on that side)."""
    change = shipped_incline_change()
    level = level_walking_reference(speed_mps)
    if incline_deg == 0.0:
        return level
    if not change.covers(incline_deg):
        return None
    d = change.predict(incline_deg)
    steepest = change.steepest_deg_["uphill" if incline_deg > 0 else "downhill"]
    return replace(
        level, incline_deg=float(incline_deg), kind="measured_ramp_trend",
        hip_angle_rad=level.hip_angle_rad + d["hip_angle"], knee_angle_rad=level.knee_angle_rad + d["knee_angle"],
        ankle_angle_rad=level.ankle_angle_rad + d["ankle_angle"],
        knee_moment_Nm_per_kg=level.knee_moment_Nm_per_kg + d["knee_moment"],
        ankle_moment_Nm_per_kg=level.ankle_moment_Nm_per_kg + d["ankle_moment"],
        source=f"{level.source} + the change measured on a {steepest:+g}° ramp (Vielemeyer 2025, one participant), "
               f"scaled to {incline_deg:+g}°; load and timing of level walking")
