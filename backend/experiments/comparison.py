"""The controller comparison (``quasitune compare``): the learned table against the FSMIC over a task grid, with
intervals over strides saying whether each difference is resolved, and the trajectory figure."""

from __future__ import annotations

from pathlib import Path

from backend.experiments.walks import CONTROLLERS, simulate
from controller_core.gait_metrics import GAIT_CHANNELS, difference_keys, rmse_difference
from controller_core.model import QuasiStiffnessModel
from device_bridge.sim.simulate import WalkScore

COMPARE_SPEEDS_MPS: tuple[float, ...] = (0.84, 1.2, 1.49, 1.95)


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
                    kind = score.summary.get("reference_kind", "measured")
                    ax.plot(pct, score.reference_curves[ch], color="k", lw=2,
                            label={"measured": "measured reference", "measured_ramp_trend": "measured ramp trend"}.get(
                                kind, "model prediction (not data)"))
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
