"""The fixed-task controller comparison (``quasitune compare``): the learned table against the FSMIC over a task grid, with
intervals over strides saying whether each difference is resolved, and the trajectory figure."""

from __future__ import annotations

from pathlib import Path

from controller_core.gait_metrics import GAIT_CHANNELS, difference_keys
from controller_core.model import QuasiStiffnessModel
from device_bridge.bench.versus import against_fsmic
from device_bridge.bench.walks import simulate
from device_bridge.sim.leg_model import LegGeometry
from device_bridge.sim.simulate import WalkScore

COMPARE_SPEEDS_MPS: tuple[float, ...] = (0.84, 1.2, 1.49, 1.95)
COMPARED: tuple[str, ...] = ("quasi-stiffness", "fsmic")


def compare(model: QuasiStiffnessModel, speeds_mps: tuple[float, ...] = COMPARE_SPEEDS_MPS,
            inclines_deg: tuple[float, ...] = (0.0,), seconds: float = 20.0, mass_kg: float = 75.0,
            geometry: LegGeometry | None = None, start: str = "standing") -> list[tuple[WalkScore, str]]:
    """Both controllers over the task grid on the leg ``geometry`` (default the nominal bench), each walk from
    ``start`` (``swing`` or ``standing``); returns (score, controller) pairs in grid order.

    Each learned walk's summary also carries ``vs_fsmic`` (:func:`device_bridge.bench.versus.against_fsmic`): how its
    RMSEs differ from the FSMIC's at the same task, and whether the strides walked resolve the difference.
    """
    out = []
    for incline in inclines_deg:
        for speed in speeds_mps:
            pair = {name: simulate(name, speed, incline, seconds, mass_kg, model, geometry=geometry, start=start)
                    for name in COMPARED}
            pair["quasi-stiffness"].summary["vs_fsmic"] = against_fsmic(pair["quasi-stiffness"], pair["fsmic"])
            out.extend((pair[name], name) for name in COMPARED)
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


def cell(v: object) -> str:
    """A table cell: — for none, two decimals for a float."""
    return "—" if v is None else f"{v:.2f}" if isinstance(v, float) else str(v)


def format_compare(rows: list[dict]) -> str:
    """Markdown table of a comparison (one row per task and controller)."""
    cols = ["speed_mps", "incline_deg", "controller", "strides", "falls", "toe_catches", "loaded_swing_ms_max_stride",
            "knee_angle_rmse_deg", "ankle_angle_rmse_deg", "knee_moment_rmse_Nm_per_kg", "ankle_moment_rmse_Nm_per_kg",
            "real_time_factor"]
    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    lines += ["| " + " | ".join(cell(r.get(c)) for c in cols) + " |" for r in rows]
    verdicts = [r for r in rows if r.get("vs_fsmic")]
    if verdicts:
        keys = [difference_keys(channel) for channel in GAIT_CHANNELS]
        lines += ["", "learned − FSMIC RMSE, 95 % interval over strides (bootstrap), verdict:", "",
                  "| speed_mps | incline_deg | " + " | ".join(k for k, _, _ in keys) + " |",
                  "|" + "---|" * (2 + len(keys))]
        for r in verdicts:
            v = r["vs_fsmic"]
            cells = []
            for key, ci_key, verdict_key in keys:
                d, ci = v.get(key), v.get(ci_key)
                cells.append("—" if d is None else f"{d:+.2f} [{ci[0]:+.2f}, {ci[1]:+.2f}] {v[verdict_key]}")
            lines.append(f"| {cell(r.get('speed_mps'))} | {cell(r.get('incline_deg'))} | " + " | ".join(cells) + " |")
    return "\n".join(lines)
