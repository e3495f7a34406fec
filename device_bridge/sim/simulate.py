"""Walk a controller on the simulated bench and score it against the able-bodied reference.

:func:`run_walk` runs the 1 kHz loop (bench targets → physics step → sensors → controller → torques) and
logs every tick; :func:`score_walk` turns the log into the metrics ``quasitune simulate`` prints:

* strides: complete strides between heel strikes (foot contact rising above 2 % body weight after at least
  150 ms without contact) after the settling time;
* RMSE of the stride-averaged knee and ankle angle (deg) and joint torque / body mass (N·m/kg) against the
  reference at the task, on the 101-point phase grid, each with a 95 % interval (``*_rmse_ci95_*``: the strides
  resampled with replacement, :func:`controller_core.gait_metrics.bootstrap_rmse`) that says how much the number
  depends on which strides were walked; it says nothing about the bench's own assumptions; and the mean of the
  strides' own RMSEs (``*_per_stride_rmse_*``), which errors that differ from stride to stride cannot cancel;
* the prosthesis carrying the body (:mod:`device_bridge.sim.person`): ``hip_sink_max_mm``, the largest drop of the
  hip below its path while the prosthesis is in its reference stance; ``support_deficit_max_bw``, the largest
  vertical force (mean over 50 ms, body weights) the person added beyond their other leg's reference share — their
  compensation for what the prosthesis did not carry; ``stance_knee_flexion_peak_deg``, the knee's largest flexion
  from heel strike to mid-stance (30 % of the stride on), the mean over strides, with the largest stride's
  (``_max_deg``) and the reference's at the task;
* ``falls``: episodes a person could not recover from: the hip more than :data:`FALL_SINK_M` below its path (about a
  sixth of the leg's length: the other leg cannot catch that in a step), or the knee beyond :data:`FALL_KNEE_DEG`
  while the leg carries more than half the body weight (a knee buckling under the body);
* ``fall_events``: each fall's time, the leg's state, the bench's phase, the knee and the load then, and why it counts;
* ``toe_catches``: episodes of foot contact in mid-swing (bench phase between toe-off + 8 % and 92 %), the
  stumbles a person would feel;
* how late the machine noticed each heel strike: ``heel_strike_to_stance_ms_median`` and ``_max`` run from
  the foot's contact to the state machine's entry into stance flexion (negative: it entered up to 100 ms
  before contact, e.g. by the time guard), ``heel_strikes_without_stance`` counts strides on which it did not
  enter stance at all, and ``loaded_swing_ms_per_stride`` is the time per stride the leg spent on a swing row
  (swing flexion or extension) while the load cell read more than half the body weight — a loaded leg on the
  weak swing impedance, which is a safety question, not a score — and ``loaded_swing_ms_max_stride`` the longest
  such time in any one stride of the walk;
* time in each state, guard-forced transitions, torque saturation, real-time factor (simulated seconds per
  wall-clock second of the loop);
"""

from __future__ import annotations

import itertools
import math
import time
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from controller_core.fsm import GaitState, SensorSample, TorqueCommand
from controller_core.gait_metrics import (
    channel_strides,
    episodes,
    gait_channels,
    heel_strikes,
    reference_curves,
    rising_edges,
    state_entry_delays,
    strided_errors,
)
from controller_core.units import G_MPS2
from controller_core.walking_reference import WalkingReference
from device_bridge.sim import progress
from device_bridge.sim.bench_trajectory import (
    BenchTrajectory,
    plan_bench_trajectory,
    plan_standing_start,
    plan_walk_and_stop,
    standing_pose_rad,
)
from device_bridge.sim.leg_model import LegGeometry
from device_bridge.sim.person import Person
from device_bridge.sim.plant import FloorProfile, SimulatedLeg

STANCE_ENTRY_LEAD_S = 0.1  # an entry into stance up to this long before the foot touches counts for that strike
FALL_SINK_M = 0.15         # the hip this far below its path: a fall
FALL_KNEE_DEG = 60.0       # the knee beyond this while carrying more than half the body weight: a fall
SUPPORT_WINDOW_S = 0.05    # the person's compensation is read as its mean over this window
LOADING_WINDOW = 0.3       # stance knee flexion is looked for from heel strike to this fraction of the stride on

LOG_CHANNELS = ("time_s", "bench_phase", "state", "knee_angle_rad", "knee_velocity_rad_s", "ankle_angle_rad",
                "ankle_velocity_rad_s", "knee_torque_Nm", "ankle_torque_Nm", "load_N", "ankle_moment_Nm",
                "contact_N", "hip_height_error_m", "support_N", "bench_stance")


@dataclass
class WalkLog:
    """Per-tick record of a simulated walk (SI; see :data:`LOG_CHANNELS`)."""

    channels: dict[str, np.ndarray]
    timestep_s: float
    mass_kg: float
    wall_time_s: float
    saturated_ticks: int
    guard_transitions: int
    transitions: int
    extras: dict[str, object] = field(default_factory=dict)

    def to_frame(self):  # pandas is a dependency of the package; imported lazily to keep the loop module light
        """The log as a pandas DataFrame with unit-suffixed columns (angles in deg for people)."""
        import pandas as pd

        c = self.channels
        return pd.DataFrame({
            "time_s": c["time_s"], "bench_phase": c["bench_phase"],
            "state": [GaitState(int(v)).subphase for v in c["state"]],
            "knee_angle_deg": np.degrees(c["knee_angle_rad"]), "knee_velocity_deg_s": np.degrees(c["knee_velocity_rad_s"]),
            "ankle_angle_deg": np.degrees(c["ankle_angle_rad"]),
            "ankle_velocity_deg_s": np.degrees(c["ankle_velocity_rad_s"]),
            "knee_torque_Nm": c["knee_torque_Nm"], "ankle_torque_Nm": c["ankle_torque_Nm"],
            "load_N": c["load_N"], "ankle_moment_Nm": c["ankle_moment_Nm"], "contact_N": c["contact_N"],
            "hip_height_error_m": c["hip_height_error_m"], "support_N": c["support_N"],
            "bench_stance": c["bench_stance"].astype(bool),
        })


class StepController(Protocol):
    """What the bench walks: a state machine, or the adaptive controller that wraps one."""

    transitions_: int
    guard_transitions_: int

    def reset(self) -> None: ...
    def step(self, x: SensorSample) -> TorqueCommand: ...


def run_walk(controller: StepController, reference: WalkingReference, mass_kg: float, seconds: float,
             geometry: LegGeometry | None = None, frame_callback=None, frame_every: int = 0,
             person: Person | None = None, start: str = "standing", stop_s: float | None = None,
             terrain: FloorProfile | None = None) -> WalkLog:
    """Walk ``controller`` on the bench for ``seconds`` at the reference's task.

    Args:
        controller: a fresh (or reset) state machine; it starts in swing extension, the bench in late swing.
        reference: the task's able-bodied pattern (drives the socket and loads the leg).
        mass_kg: patient body mass (kg): the bench's load.
        seconds: simulated time (s).
        geometry: bench and prosthesis geometry.
        frame_callback: called with the plant every ``frame_every`` ticks (rendering), if given.
        person: the person around the prosthesis (default :class:`Person` of ``mass_kg`` as stated there); bench
            studies give another to see what the person's stated strengths hide.
        start: ``"swing"``: in late swing at belt speed (the bench's first start); ``"standing"``: a second of
            quiet standing, then gait initiation into the task
            (:func:`~device_bridge.sim.bench_trajectory.plan_standing_start`).
        stop_s: from standing, stop at the first heel strike after this time and stand to the end
            (:func:`~device_bridge.sim.bench_trajectory.plan_walk_and_stop`).
        terrain: a floor profile instead of the task's plane, one that keeps the task's slope where the feet go
            (an obstacle on it: :mod:`device_bridge.sim.stumble`).
    """
    if not (math.isfinite(seconds) and 0.0 < seconds <= 600.0):
        raise ValueError(f"seconds must be in (0, 600], got {seconds!r}")
    if person is not None and person.mass_kg != mass_kg:
        raise ValueError(f"the person's mass ({person.mass_kg:g} kg) is not the walk's ({mass_kg:g} kg)")
    if start not in ("swing", "standing"):
        raise ValueError(f"start must be 'swing' or 'standing', got {start!r}")
    leg = SimulatedLeg(geometry, reference.incline_deg, terrain=terrain, person=person or Person(mass_kg))
    if stop_s is not None and start != "standing":
        raise ValueError("a walk that stops starts from standing")
    if stop_s is not None:
        traj = plan_walk_and_stop(reference, leg.geometry, mass_kg, seconds, stop_s, leg.timestep_s)
        _, knee0, ankle0 = standing_pose_rad(reference.incline_deg)
    elif start == "standing":
        traj = plan_standing_start(reference, leg.geometry, mass_kg, seconds, leg.timestep_s)
        _, knee0, ankle0 = standing_pose_rad(reference.incline_deg)
    else:
        traj = plan_bench_trajectory(reference, leg.geometry, mass_kg, seconds, leg.timestep_s)
        s0 = traj.phase[0]
        knee0 = float(np.interp(s0, reference.phase, reference.knee_angle_rad))
        ankle0 = float(np.interp(s0, reference.phase, reference.ankle_angle_rad))
    alpha = math.radians(reference.incline_deg)
    n = traj.time_s.shape[0]
    log = walk_loop(controller, leg, traj, (knee0, ankle0), (np.full(n, -math.sin(alpha)), np.full(n, math.cos(alpha))),
                    mass_kg, frame_callback, frame_every, standing=start == "standing")
    return log


def walk_loop(controller: StepController, leg: SimulatedLeg, traj: BenchTrajectory, start_angles_rad: tuple[float, float],
              normals: tuple[np.ndarray, np.ndarray], mass_kg: float, frame_callback=None, frame_every: int = 0,
              standing: bool = False) -> WalkLog:
    """The 1 kHz loop: bench targets → physics → sensors → controller → torques, logged every tick.

    ``normals`` (x, z per tick) is the floor's normal under the socket: the socket's error along it is the
    ``hip_height_error_m`` (actual − path, m: negative when the hip has sunk) the sink and the falls read.
    ``standing``: the person stands on the leg as the run begins (the controller is told so: ``stand()``).
    """
    x: SensorSample = leg.reset(traj, *start_angles_rad)
    controller.reset()
    if hasattr(controller, "use_drive_friction"):     # the leg's firmware knows its drive (controller_core.fsm)
        controller.use_drive_friction(leg.geometry.ankle_friction_Nm)
    if hasattr(controller, "use_forefoot"):           # and its foot (an early landing on the toe)
        controller.use_forefoot(leg.geometry.toe_forward_m)
    if standing and hasattr(controller, "stand"):     # the person stands on the leg as the walk begins
        controller.stand()
    n = traj.time_s.shape[0]
    log = {name: np.empty(n) for name in LOG_CHANNELS}
    log["bench_phase"][:] = traj.phase
    t_col, st_col = log["time_s"], log["state"]
    kq, kv, aq, av = log["knee_angle_rad"], log["knee_velocity_rad_s"], log["ankle_angle_rad"], log["ankle_velocity_rad_s"]
    kt, at, ld, am = log["knee_torque_Nm"], log["ankle_torque_Nm"], log["load_N"], log["ankle_moment_Nm"]
    cn, he, sp = log["contact_N"], log["hip_height_error_m"], log["support_N"]
    log["bench_stance"][:] = traj.stance
    tx, tz = traj.x_m, traj.z_m
    nx, nz = normals
    saturated = 0
    report_every = max(round(1.0 / leg.timestep_s), 1)       # once per simulated second: a caller's progress, cancel
    t0 = time.perf_counter()
    for i in range(n):
        if i and i % report_every == 0:
            progress.walked(report_every * leg.timestep_s)
        cmd = controller.step(x)
        t_col[i], st_col[i] = x.time_s, cmd.state
        kq[i], kv[i], aq[i], av[i] = x.knee_angle_rad, x.knee_velocity_rad_s, x.ankle_angle_rad, x.ankle_velocity_rad_s
        ld[i], am[i] = x.load_N, x.ankle_moment_Nm
        kt[i], at[i] = cmd.knee_torque_Nm, cmd.ankle_torque_Nm
        cn[i] = leg.foot_contact_force() if leg.data.ncon else 0.0
        hx, hz = leg.hip_position_m()
        he[i] = nx[i] * (hx - tx[i]) + nz[i] * (hz - tz[i])
        sp[i] = leg.support_N
        saturated += cmd.saturated
        if frame_callback is not None and frame_every and i % frame_every == 0:
            frame_callback(leg)
        x = leg.step(cmd.knee_torque_Nm, cmd.ankle_torque_Nm)
    wall = time.perf_counter() - t0
    return WalkLog(channels=log, timestep_s=leg.timestep_s, mass_kg=mass_kg, wall_time_s=wall,
                   saturated_ticks=saturated, guard_transitions=controller.guard_transitions_,
                   transitions=controller.transitions_,
                   extras={"stride_time_s": traj.stride_time_s,
                           "recovery_step_times_s": list(leg.recovery_step_times_s)})


def stance_entry_metrics(states: np.ndarray, load_N: np.ndarray, strikes: np.ndarray, weight_N: float,
                  dt: float) -> dict[str, object]:
    """How late the machine noticed each heel strike (see the module docstring): None without a whole stride."""
    keys = ("heel_strike_to_stance_ms_median", "heel_strike_to_stance_ms_max", "heel_strikes_without_stance",
            "loaded_swing_ms_per_stride", "loaded_swing_ms_max_stride")
    if strikes.shape[0] < 2:
        return dict.fromkeys(keys)
    delays_ms = 1000.0 * dt * state_entry_delays(states, int(GaitState.STANCE_FLEXION), strikes[:-1],
                                                 round(STANCE_ENTRY_LEAD_S / dt))
    found = delays_ms[np.isfinite(delays_ms)]
    swing = np.isin(states, (int(GaitState.SWING_FLEXION), int(GaitState.SWING_EXTENSION)))
    loaded_swing = swing & (load_N > 0.5 * weight_N)
    per_stride = np.array([np.count_nonzero(loaded_swing[a:b]) for a, b in itertools.pairwise(strikes)])
    return dict(zip(keys, (
        float(np.median(found)) if found.size else None,
        float(np.max(found)) if found.size else None,
        int(delays_ms.shape[0] - found.shape[0]),
        1000.0 * dt * float(per_stride.sum()) / per_stride.shape[0],
        1000.0 * dt * float(per_stride.max()),
    ), strict=True))


def contact_strikes(log: WalkLog) -> np.ndarray:
    """Tick indices of the walk's heel strikes: the foot's contact rising above 2 % body weight after at least 150 ms
    without contact (module docstring)."""
    weight = log.mass_kg * G_MPS2
    return heel_strikes(log.channels["contact_N"], 0.02 * weight, round(0.15 / log.timestep_s))


def toe_catch_mask(c: dict[str, np.ndarray], toe_off_phase: np.ndarray | float, weight_N: float) -> np.ndarray:
    """Ticks of foot contact in mid-swing of the bench's pattern (phase between toe-off + 8 % and 92 %): a stumble."""
    phase = c["bench_phase"]
    return (phase > toe_off_phase + 0.08) & (phase < 0.92) & (c["contact_N"] > 0.02 * weight_N)


def fall_mask(c: dict[str, np.ndarray], weight_N: float) -> np.ndarray:
    """Ticks a person could not recover from (module docstring: the hip sunk past FALL_SINK_M, or a knee beyond
    FALL_KNEE_DEG under more than half the body weight)."""
    sank = c["hip_height_error_m"] < -FALL_SINK_M
    buckled = (c["knee_angle_rad"] >= math.radians(FALL_KNEE_DEG)) & (c["load_N"] > 0.5 * weight_N)
    return sank | buckled


def fall_events(c: dict[str, np.ndarray], weight_N: float, min_gap_samples: int) -> list[dict[str, object]]:
    """Where and how each fall began (the episodes of :func:`fall_mask`, closer than ``min_gap_samples`` counting as
    one: ``falls`` is how many): its time (s), the leg's state, the bench's phase, the knee angle (deg) and the load
    (body weights) then, and why it counts (the hip sank, or the knee buckled under load)."""
    mask = fall_mask(c, weight_N)
    starts = [int(i) for i in rising_edges(mask.astype(float), 0.5, min_gap_samples)]
    if mask.shape[0] and mask[0]:
        starts.insert(0, 0)
    out = []
    for i in starts:
        sank = bool(c["hip_height_error_m"][i] < -FALL_SINK_M)
        out.append({"time_s": round(float(c["time_s"][i]), 3), "state": GaitState(int(c["state"][i])).subphase,
                    "bench_phase": round(float(c["bench_phase"][i]), 3),
                    "knee_angle_deg": round(float(np.degrees(c["knee_angle_rad"][i])), 1),
                    "load_bw": round(float(c["load_N"][i] / weight_N), 2),
                    "why": "the hip sank" if sank else "the knee buckled under load"})
    return out


def windowed_support_N(support_N: np.ndarray, dt: float) -> np.ndarray:
    """The person's compensation per tick as it is read: its mean over SUPPORT_WINDOW_S around each tick (N)."""
    width = max(round(SUPPORT_WINDOW_S / dt), 1)
    return np.convolve(support_N, np.ones(width) / width, mode="same")


def carrying_figures(c: dict[str, np.ndarray], strikes: np.ndarray, dt: float, weight_N: float,
                     settle_s: float) -> dict[str, float | None]:
    """How well the prosthesis carried the body after ``settle_s`` (module docstring): sink (mm), the person's
    compensation (body weights) and the stance knee flexion (deg; None without a whole stride)."""
    after = c["time_s"] >= settle_s
    stance = after & c["bench_stance"].astype(bool)
    sink = float(max(0.0, -np.min(c["hip_height_error_m"][stance]))) if stance.any() else 0.0
    support = windowed_support_N(c["support_N"], dt)[after]
    peaks = []
    for a, b in itertools.pairwise(strikes):
        peaks.append(math.degrees(float(np.max(c["knee_angle_rad"][a:a + max(round(LOADING_WINDOW * (b - a)), 1)]))))
    return {"hip_sink_max_mm": 1000.0 * sink,
            "support_deficit_max_bw": float(max(0.0, support.max())) / weight_N if support.size else 0.0,
            "stance_knee_flexion_peak_deg": float(np.mean(peaks)) if peaks else None,
            "stance_knee_flexion_peak_max_deg": float(np.max(peaks)) if peaks else None}


def reference_stance_knee_peak_deg(reference: WalkingReference) -> float:
    """The reference knee's largest flexion from heel strike to LOADING_WINDOW of the stride (deg)."""
    early = reference.phase <= LOADING_WINDOW
    return math.degrees(float(np.max(reference.knee_angle_rad[early])))


@dataclass(frozen=True)
class WalkScore:
    """Metrics of one walk (see the module docstring); ``to_dict`` gives the JSON of ``quasitune simulate``."""

    summary: dict[str, object]
    mean_curves: dict[str, np.ndarray]       # stride-averaged measured curves (deg, N·m/kg) on PHASE_GRID
    reference_curves: dict[str, np.ndarray]  # the reference on PHASE_GRID in the same units
    stride_curves: dict[str, np.ndarray] = field(default_factory=dict)  # (strides, PHASE_GRID) per channel

    def to_dict(self) -> dict[str, object]:
        return dict(self.summary)


def score_walk(log: WalkLog, reference: WalkingReference, settle_s: float = 2.0) -> WalkScore:
    """Turn a walk log into metrics against ``reference`` (strides starting before ``settle_s`` are skipped)."""
    c, dt, mass = log.channels, log.timestep_s, log.mass_kg
    weight = mass * G_MPS2
    strikes = contact_strikes(log)
    strikes = strikes[c["time_s"][strikes] >= settle_s] if strikes.size else strikes
    per_channel = gait_channels(c["knee_angle_rad"], c["ankle_angle_rad"], c["knee_torque_Nm"], c["ankle_torque_Nm"],
                                mass)
    ref_curves = reference_curves(reference)
    n_strides = max(int(strikes.shape[0]) - 1, 0)
    strided = channel_strides(per_channel, strikes)
    # fixed seed: the same walk always reports the same intervals
    means, errors = strided_errors(strided, list(per_channel), ref_curves, rng=np.random.default_rng(0),
                                   per_stride=True)
    stride_times = np.diff(c["time_s"][strikes]) if n_strides else np.array([])
    toe_catch = toe_catch_mask(c, reference.toe_off_phase, weight)
    gap = round(0.2 / dt)
    states = c["state"].astype(int)
    time_in_state = {GaitState(k).subphase: float(np.count_nonzero(states == k) * dt) for k in range(4)}
    stance_entry = stance_entry_metrics(states, c["load_N"], strikes, weight, dt)
    seconds = float(c["time_s"].shape[0] * dt)
    falls = fall_events(c, weight, gap)
    summary: dict[str, object] = {
        "speed_mps": reference.speed_mps, "incline_deg": reference.incline_deg, "mass_kg": mass,
        "seconds": seconds,
        "strides": n_strides,
        "falls": len(falls),
        "fall_events": falls,
        "toe_catches": episodes(toe_catch, gap),
        **errors,
        "stride_time_s": float(np.mean(stride_times)) if stride_times.size else None,
        "reference_stride_time_s": reference.stride_time_s,
        "cadence_steps_per_min": float(120.0 / np.mean(stride_times)) if stride_times.size else None,
        "time_in_state_s": time_in_state,
        **stance_entry,
        "transitions": log.transitions,
        "guard_transitions": log.guard_transitions,
        "torque_saturation_fraction": log.saturated_ticks / max(c["time_s"].shape[0], 1),
        **carrying_figures(c, strikes, dt, weight, settle_s),
        "reference_stance_knee_flexion_peak_deg": reference_stance_knee_peak_deg(reference),
        "real_time_factor": seconds / log.wall_time_s if log.wall_time_s > 0 else None,
        "reference_source": reference.source,
        "reference_kind": reference.kind,
        "reference_extrapolation": reference.extrapolation,
        "settle_s": settle_s,
    }
    return WalkScore(summary=summary, mean_curves=means, reference_curves=ref_curves, stride_curves=strided)
