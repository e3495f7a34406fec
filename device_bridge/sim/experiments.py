"""Experiments on the simulated bench: one walk (``quasitune simulate``) and the controller comparison
(``quasitune compare``).

Both controllers are the same four-state machine (:class:`controller_core.fsm.StateMachineController`); they
differ only in their table: the learned quasi-stiffness table proposed for the task, or the fixed FSMIC
literature table (:mod:`controller_core.fsmic`) tuned once at the nominal task.

Reference at a task: at level walking, the shipped able-bodied curves interpolated in speed
(:func:`controller_core.walking_reference.level_walking_reference`). The shipped data hold no measured curves
on an incline, so there the knee and ankle reference is the model's own prediction (KMP mean) with the level
hip trajectory and load at that speed; ``reference_source`` says so in every result.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np

from controller_core.fsm import ImpedanceSchedule, StateMachineController
from controller_core.fsmic import fsmic_table
from controller_core.gait_metrics import GAIT_CHANNELS, difference_keys, rmse_difference
from controller_core.model import QuasiStiffnessModel, validate_task
from controller_core.table import ImpedanceTable
from controller_core.walking_reference import WalkingReference, level_walking_reference
from device_bridge.sim.simulate import WalkScore, run_walk, score_walk

CONTROLLERS: tuple[str, ...] = ("quasi-stiffness", "fsmic")
COMPARE_SPEEDS_MPS: tuple[float, ...] = (0.84, 1.2, 1.49, 1.95)


def task_reference(speed_mps: float, incline_deg: float, model: QuasiStiffnessModel | None = None,
                   mass_kg: float = 75.0) -> WalkingReference:
    """The reference at a task (see the module docstring); ``model`` is needed only off level ground."""
    validate_task(speed_mps, incline_deg, mass_kg)
    ref = level_walking_reference(speed_mps)
    if incline_deg == 0.0:
        return ref
    if model is None:
        raise ValueError("an inclined task needs the model: the shipped data have no curves on an incline")
    prop = model.propose(speed_mps, incline_deg, mass_kg)
    s = prop.phase
    return dataclasses.replace(
        ref, incline_deg=float(incline_deg),
        knee_angle_rad=np.interp(ref.phase, s, prop.means["knee_angle"]),
        ankle_angle_rad=np.interp(ref.phase, s, prop.means["ankle_angle"]),
        knee_moment_Nm_per_kg=np.interp(ref.phase, s, prop.means["knee_moment"]),
        ankle_moment_Nm_per_kg=np.interp(ref.phase, s, prop.means["ankle_moment"]),
        toe_off_phase=float(next(f.value for f in prop.features if f.spec.name == "toe_off")),
        source=f"KMP prediction at {incline_deg:+g} deg (no measured curves on an incline); hip and load: "
               + ref.source,
        extrapolation=prop.extrapolation or ref.extrapolation)


def make_controller(name: str, speed_mps: float, incline_deg: float, mass_kg: float,
                    model: QuasiStiffnessModel | None = None) -> StateMachineController:
    """A fresh state machine with the table of controller ``name`` for the task.

    Raises:
        ValueError: an unknown controller name (or a quasi-stiffness request without a model).
        SafetyLimitError: the table fails the safety limits (checked again here, as the device does).
    """
    if name == "fsmic":
        table = fsmic_table(mass_kg)
    elif name == "quasi-stiffness":
        if model is None:
            raise ValueError("the quasi-stiffness controller needs a trained model")
        table = model.propose(speed_mps, incline_deg, mass_kg).table
    else:
        raise ValueError(f"unknown controller {name!r}; choose one of {', '.join(CONTROLLERS)}")
    return StateMachineController(ImpedanceSchedule.from_table(table))


def simulate(controller: str, speed_mps: float, incline_deg: float = 0.0, seconds: float = 20.0,
             mass_kg: float = 75.0, model: QuasiStiffnessModel | None = None, record: Path | None = None,
             video: Path | None = None) -> WalkScore:
    """Walk one controller at one task; optionally save the trajectories and a video."""
    validate_task(speed_mps, incline_deg, mass_kg)
    ref = task_reference(speed_mps, incline_deg, model, mass_kg)
    ctrl = make_controller(controller, speed_mps, incline_deg, mass_kg, model)
    recorder = _VideoRecorder(video) if video is not None else None
    log = run_walk(ctrl, ref, mass_kg, seconds, frame_callback=recorder, frame_every=recorder.every if recorder else 0)
    if recorder is not None:
        recorder.close()
    score = score_walk(log, ref)
    score.summary["controller"] = controller
    if record is not None:
        frame = log.to_frame()
        if record.suffix == ".parquet":
            frame.to_parquet(record, index=False)
        else:
            frame.to_csv(record, index=False, float_format="%.6g")
        score.summary["record"] = str(record)
    if video is not None:
        score.summary["video"] = str(video)
    return score


class _VideoRecorder:
    """Render the bench headless (``MUJOCO_GL=egl``) at 30 frames/s into an MP4 or a folder of PNGs."""

    fps = 30

    def __init__(self, path: Path, width: int = 640, height: int = 480) -> None:
        self.path = path
        self.width, self.height = width, height
        self.every = round(1000 / self.fps)
        self._renderer = None
        self._writer = None
        self._count = 0
        if path.suffix.lower() not in (".mp4", ".png", ""):
            raise ValueError(f"--video takes FILE.mp4 or a folder for PNG frames, got {path}")

    def __call__(self, leg) -> None:
        import mujoco

        if self._renderer is None:
            self._renderer = mujoco.Renderer(leg.model, self.height, self.width)
            self._camera = mujoco.MjvCamera()
            self._camera.distance, self._camera.elevation, self._camera.azimuth = 2.4, -8.0, 90.0
        self._camera.lookat[:] = (leg.data.qpos[0], 0.0, 0.55 + leg.data.qpos[0] * math.tan(math.radians(leg.incline_deg)))
        self._renderer.update_scene(leg.data, self._camera)
        frame = self._renderer.render()
        import imageio.v2 as imageio

        if self.path.suffix.lower() == ".mp4":
            if self._writer is None:
                self._writer = imageio.get_writer(self.path, fps=self.fps, macro_block_size=1)
            self._writer.append_data(frame)
        else:
            folder = self.path.with_suffix("") if self.path.suffix else self.path
            folder.mkdir(parents=True, exist_ok=True)
            imageio.imwrite(folder / f"frame_{self._count:05d}.png", frame)
        self._count += 1

    def close(self) -> None:
        if self._writer is not None:
            self._writer.close()
        if self._renderer is not None:
            self._renderer.close()


def compare(model: QuasiStiffnessModel, speeds_mps: tuple[float, ...] = COMPARE_SPEEDS_MPS,
            inclines_deg: tuple[float, ...] = (0.0,), seconds: float = 20.0, mass_kg: float = 75.0
            ) -> list[tuple[WalkScore, str]]:
    """Both controllers over the task grid; returns (score, controller) pairs in grid order.

    Each learned walk's summary also carries ``vs_fsmic`` (:func:`against_fsmic`): how its RMSEs differ from
    the FSMIC's at the same task, and whether the strides walked resolve the difference.
    """
    out = []
    for incline in inclines_deg:
        for speed in speeds_mps:
            pair = {name: simulate(name, speed, incline, seconds, mass_kg, model) for name in CONTROLLERS}
            pair["quasi-stiffness"].summary["vs_fsmic"] = against_fsmic(pair["quasi-stiffness"], pair["fsmic"])
            out.extend((pair[name], name) for name in CONTROLLERS)
    return out


def against_fsmic(learned: WalkScore, fsmic: WalkScore, level: float = 0.95) -> dict[str, object]:
    """Learned minus FSMIC stride-averaged RMSE per channel, with a bootstrap interval over strides.

    Keys per channel (units in the names): ``knee_angle_rmse_difference_deg``,
    ``knee_angle_rmse_difference_ci95_deg`` (lo, hi) and ``knee_angle_verdict``: ``"learned lower"`` or
    ``"FSMIC lower"`` when the interval excludes zero, ``"not resolved"`` when the two walks' stride-to-stride
    variation allows either (:func:`controller_core.gait_metrics.rmse_difference`). A channel either walk could
    not score (fewer than two strides) is None.
    """
    words = {"A lower": "learned lower", "B lower": "FSMIC lower", "not resolved": "not resolved"}
    out: dict[str, object] = {}
    for name in GAIT_CHANNELS:
        key, ci_key, verdict_key = difference_keys(name)
        a, b = learned.stride_curves.get(name), fsmic.stride_curves.get(name)
        if a is None or b is None or a.shape[0] < 2 or b.shape[0] < 2:
            out[key] = out[ci_key] = out[verdict_key] = None
            continue
        d = rmse_difference(a, b, learned.reference_curves[name], level)
        out[key], out[ci_key], out[verdict_key] = d["difference"], list(d["interval"]), words[str(d["verdict"])]
    return out


def plot_compare(results: list[tuple[WalkScore, str]], path: Path) -> None:
    """Mean stride trajectories per controller against the reference, one column per task (PNG/SVG/PDF)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from controller_core.gait_metrics import PHASE_GRID

    tasks = []
    for score, _ in results:
        key = (score.summary["speed_mps"], score.summary["incline_deg"])
        if key not in tasks:
            tasks.append(key)
    channels = [("knee_angle_deg", "knee angle (deg)"), ("ankle_angle_deg", "ankle angle (deg)"),
                ("knee_moment_Nm_per_kg", "knee moment (N·m/kg)"), ("ankle_moment_Nm_per_kg", "ankle moment (N·m/kg)")]
    fig, axes = plt.subplots(len(channels), len(tasks), figsize=(3.2 * len(tasks), 9), squeeze=False, sharex=True)
    colours = {"quasi-stiffness": "tab:blue", "fsmic": "tab:orange"}
    pct = PHASE_GRID * 100
    for j, task in enumerate(tasks):
        for score, name in results:
            if (score.summary["speed_mps"], score.summary["incline_deg"]) != task:
                continue
            for i, (ch, label) in enumerate(channels):
                ax = axes[i][j]
                if name == "fsmic":
                    ax.plot(pct, score.reference_curves[ch], color="k", lw=2, label="able-bodied reference")
                if ch in score.mean_curves:
                    ax.plot(pct, score.mean_curves[ch], color=colours[name], lw=1.5, label=name)
                if j == 0:
                    ax.set_ylabel(label)
        axes[0][j].set_title(f"{task[0]:.2f} m/s, {task[1]:+g}°")
        axes[-1][j].set_xlabel("gait cycle (%)")
    handles: dict[str, object] = {}
    for ax in axes.ravel():
        for h, lab in zip(*ax.get_legend_handles_labels(), strict=True):
            handles.setdefault(lab, h)
    fig.legend(list(handles.values()), list(handles.keys()), loc="upper right", fontsize=8)
    fig.suptitle("Simulated bench: stride-averaged joint trajectories (mean over strides after 2 s)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def preview_table(table: ImpedanceTable, speed_mps: float, incline_deg: float, mass_kg: float,
                  model: QuasiStiffnessModel | None = None, seconds: float = 10.0) -> dict[str, object]:
    """Walk a given (e.g. proposed or edited) table and the FSMIC benchmark on the bench at a task.

    The dashboard's "simulated preview": same plant, same reference, same metrics as ``quasitune simulate``.
    Returns JSON-ready data: ``phase_grid`` (101 points), ``reference_curves`` and, per controller
    (``table``, ``fsmic``), its summary and stride-averaged ``mean_curves`` (deg, N·m/kg); the table's entry
    also carries ``vs_fsmic`` (:func:`against_fsmic`: its RMSEs minus the FSMIC's, with 95 % intervals).

    Raises:
        SafetyLimitError: a table fails the safety limits (checked again, as the device does).
    """
    from controller_core.gait_metrics import PHASE_GRID, reference_curves

    def rounded(curves: dict[str, np.ndarray]) -> dict[str, list[float]]:
        return {k: [round(float(v), 3) for v in c] for k, c in curves.items()}

    validate_task(speed_mps, incline_deg, mass_kg)
    ref = task_reference(speed_mps, incline_deg, model, mass_kg)
    scores = {name: score_walk(run_walk(StateMachineController(ImpedanceSchedule.from_table(tab)), ref, mass_kg,
                                        seconds), ref)
              for name, tab in (("table", table), ("fsmic", fsmic_table(mass_kg)))}
    controllers: dict[str, object] = {name: {**score.summary, "mean_curves": rounded(score.mean_curves)}
                                      for name, score in scores.items()}
    controllers["table"]["vs_fsmic"] = against_fsmic(scores["table"], scores["fsmic"])
    return {"seconds": seconds, "phase_grid": [round(float(s), 3) for s in PHASE_GRID],
            "reference_curves": rounded(reference_curves(ref)), "controllers": controllers}
