"""A stopped session's strides as the leg recorded them: heel strikes, each stride's task, and its measured features.

One way through for the session report and for refinement: the same heel strikes (load above 10 % of body weight after
150 ms below it, on the device's own clock), the same per-stride task (on a bench course the course's task, the truth;
with an envelope the leg's own estimate; otherwise the session's task) and the same rule for strides the leg did not
run its table for the whole of (safe mode, no table): counted, never scored or learnt from.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from sqlalchemy import Connection

from backend.store import sessions as store
from controller_core.gait_metrics import channel_strides, gait_channels
from controller_core.session_summary import device_times, session_strikes
from controller_core.stride_features import MeasuredStride, measure_strides, toe_off_phases
from controller_core.units import G_MPS2
from device_bridge.protocol import TELEMETRY_PERIOD_S, Mode
from device_bridge.sim.course import COURSES


def stride_tasks(session: dict, summary: dict, times: np.ndarray, strikes: np.ndarray
                 ) -> tuple[list[tuple[float, float] | None], str]:
    """Each stride's own task and where it comes from: on a bench course, the course's task at the stride (the truth);
    with an envelope, the leg's own estimate; otherwise the session's task."""
    if session["course"] in COURSES and times.size:
        mid = np.array([0.5 * (times[a] + times[b]) for a, b in itertools.pairwise(strikes)]) - times[0]
        speed, incline = COURSES[session["course"]].task_at(mid)
        return ([(float(v), float(g)) for v, g in zip(speed, incline, strict=True)],
                f"each stride's own task on the '{session['course']}' course")
    adaptive = summary.get("adaptive")
    if adaptive:
        return ([None if x is None else (x[0], x[1]) for x in adaptive["stride_tasks"]],
                "each stride's task as the leg estimated it")
    t = session["task"]
    return [(t["speed_mps"], t["incline_deg"])] * max(int(strikes.size) - 1, 0), "the session's task"


@dataclass(frozen=True)
class SessionStrides:
    """A stopped session's strides: those measured (on its table, with a task), per feature the strides without it,
    how many strides in all and how many the leg ran its table for, and where the tasks come from."""

    strides: list[MeasuredStride]
    not_found: dict[str, int]
    total: int
    on_table: int
    tasks_from: str


def session_strides(conn: Connection, session: dict) -> SessionStrides:
    """Read a stopped session's samples and measure its strides (module docstring)."""
    cols = store.samples(conn, session["id"])
    mass = session["task"]["body_mass_kg"]
    if len(cols["seq"]) < 2:
        return SessionStrides([], {}, 0, 0, "no samples")
    times = device_times(np.asarray(cols["seq"]), np.asarray(cols["t_s"]), TELEMETRY_PERIOD_S)
    running = np.asarray(cols["mode"], dtype=int) == Mode.ACTIVE
    load = np.asarray(cols["load_N"], dtype=float)
    strikes = session_strikes(times, load, mass)
    if strikes.size < 2:
        return SessionStrides([], {}, 0, 0, "no strides")
    measured = gait_channels(np.asarray(cols["knee_angle_rad"]), np.asarray(cols["ankle_angle_rad"]),
                             np.asarray(cols["knee_torque_Nm"]), np.asarray(cols["ankle_torque_Nm"]), mass)
    tasks, tasks_from = stride_tasks(session, session["summary"] or {}, times, strikes)
    use = [bool(running[a:b + 1].all()) for a, b in itertools.pairwise(strikes)]
    toe = toe_off_phases(load, strikes, 0.1 * mass * G_MPS2)
    strides, not_found = measure_strides(channel_strides(measured, strikes), tasks, toe, use)
    return SessionStrides(strides, not_found, len(use), sum(use), tasks_from)
