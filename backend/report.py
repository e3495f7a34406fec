"""The printable session report as a PDF (matplotlib's PDF backend): task, the table that ran, strides, cadence,
stride-averaged joint trajectories against the reference (labelled with what it is: measured level walking, the
measured ramp trend, or the model's prediction), and the errors — the same numbers as the dashboard's report page,
from the stored summary."""

from __future__ import annotations

import io
import textwrap
from datetime import datetime
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from matplotlib.figure import Figure

from controller_core.gait_metrics import GAIT_CHANNELS, rmse_key

_LABELS = {"knee_angle_deg": "knee angle (deg, flexion +)", "ankle_angle_deg": "ankle angle (deg, dorsiflexion +)",
           "knee_moment_Nm_per_kg": "knee moment (N·m/kg, flexor +)",
           "ankle_moment_Nm_per_kg": "ankle moment (N·m/kg, dorsiflexor +)"}
REFERENCE_KIND = {
    "measured": "measured able-bodied level walking",
    "measured_ramp_trend": "measured level walking + one participant's measured ramp change, scaled to the incline",
    "model_prediction": "the model's own prediction (no curves were measured this steep), not data",
}
REFERENCE_LEGEND = {"measured": "measured reference", "measured_ramp_trend": "measured ramp trend",
                    "model_prediction": "model prediction (not data)"}


_UNITS = {"knee_angle_deg": "deg", "ankle_angle_deg": "deg", "knee_moment_Nm_per_kg": "N·m/kg",
          "ankle_moment_Nm_per_kg": "N·m/kg"}


def _fmt(value: object, unit: str = "", digits: int = 2) -> str:
    if value is None:
        return "— (fewer than two scored strides)"
    if isinstance(value, float):
        return f"{value:.{digits}f} {unit}".strip()
    return f"{value} {unit}".strip()


def local_time(iso: str | None) -> str:
    """A stored UTC timestamp in the server's local time zone, as a clinic reads it (``2026-11-23 14:05 CET``)."""
    if not iso:
        return "—"
    return datetime.fromisoformat(iso.replace("Z", "+00:00")).astimezone().strftime("%Y-%m-%d %H:%M %Z")


def headline_words(head: dict | None) -> str:
    """The headline errors in words: each stride against its own task, or too few strides to judge."""
    if not head:
        return "—"
    n = head["strides_scored"]
    if not head["enough_strides"]:
        return f"too few strides to judge ({n} scored; at least {head['min_strides']} needed)"
    on_table, unknown = head.get("strides_on_table", n), head.get("strides_without_task", 0)
    why = "" if on_table == n else (f"; of the {on_table} strides on the table {on_table - n} are not scored"
                                   + (f", {unknown} without a task estimate" if unknown else ""))
    return (f"knee {head['knee_angle_rmse_deg']:.1f} deg, ankle {head['ankle_angle_rmse_deg']:.1f} deg (RMSE of each "
            f"of {n} strides against the reference at {head['against']}, averaged{why})")


def report_facts(session: dict, patient: dict) -> list[tuple[str, str]]:
    """The report's first block, (label, words) pairs: task, what ran (and any override), when, how much."""
    s = session["summary"] or {}
    modes = s.get("mode_s") or {}
    # the angles' one error is the headline (each stride at its own task); the mean stride adds the moments only
    rmse = " · ".join(f"{_LABELS[c].split(' (')[0]} {_fmt(s.get(rmse_key(c)), _UNITS[c], 3)}"
                      for c in GAIT_CHANNELS if _UNITS[c] != "deg")
    return [
        *([("SIMULATED", "walked by the simulated patient on the simulated leg (the bench), not by a person")]
          if session.get("simulated") else []),
        ("Patient", f"{patient['code_name']} · {patient['body_mass_kg']:.1f} kg · {patient['side']} side"),
        ("Task", f"{session['task_words']} · device {session['device_id']}"),
        ("Envelope that ran" if session.get("envelope_id") is not None else "Table that ran",
         f"{session['table_label'] or 'none from this server'} (CRC-32 {session['table_crc32'] or '—'}, "
         f"device version {session['table_version'] or '—'})"),
        *([("Bench override", f"approved without a clean bench preview: “{session['approval_override']}”")]
          if session.get("approval_override") else []),
        *([("Extrapolated", f"requested beyond what the model knows: “{session['extrapolation_reason']}”")]
          if session.get("extrapolation_reason") else []),
        *_adaptive_facts(s.get("adaptive")),
        ("Recorded", f"{local_time(session['started_at'])} to {local_time(session['stopped_at'])} "
                     f"by {session['started_by']}"),
        ("Samples", f"{s.get('samples', 0)} over {_fmt(s.get('duration_s'), 's', 1)}; "
                    f"{s.get('missing_samples', '—')} missing"),
        *([("Walking / standing", f"{s['walking_s']:.1f} s walking (the strides), {s['standing_s']:.1f} s standing "
                                  "or paused")] if s.get("walking_s") is not None else []),
        ("Leg off its table", "never" if not s.get("off_table_s") else
         f"{s['off_table_s']:.1f} s (safe mode {modes.get('safe', 0):.1f} s, no table {modes.get('no_table', 0):.1f} s): "
         f"{s.get('strides_off_table', 0)} strides left out of the errors"),
        ("Strides, table / all", f"{s.get('strides_scored', s.get('strides', 0))} on the table of {s.get('strides', 0)} · "
                                 f"cadence on the table {_fmt(s.get('cadence_steps_per_min'), 'steps/min', 1)}"),
        ("Stride time", f"{_fmt(s.get('stride_time_s'), 's', 3)} "
                        f"(reference {_fmt(s.get('reference_stride_time_s'), 's', 3)})"),
        ("Angle error per stride", headline_words(s.get("headline"))),
        *([] if session.get("course") else [("Moments, mean stride", f"{rmse} (RMSE against the reference)")]),
        ("Reference", f"{REFERENCE_KIND.get(s.get('reference_kind'), 'reference')}"
                      + (" [EXTRAPOLATION]" if s.get("reference_extrapolation") else "")),
    ]


def _adaptive_facts(a: dict | None) -> list[tuple[str, str]]:
    """Where in its envelope the leg walked, in a line (the second page draws it). Its per-stride angle error is the
    headline's ("Angle error per stride"), said once on the page."""
    if not a:
        return []
    cells = sorted(((a["time_s"][i][j], a["strides"][i][j], v, g) for i, v in enumerate(a["speeds_mps"])
                    for j, g in enumerate(a["inclines_deg"]) if a["time_s"][i][j] > 0), reverse=True)
    where = "; ".join(f"{v:.2f} m/s {g:+.0f}°: {t:.0f} s, {n} strides" for t, n, v, g in cells[:4]) or "no estimate"
    modes = ", ".join(f"{k} {v:.0f} s" for k, v in (a.get("adaptive_mode_s") or {}).items())
    return [("Where in the envelope", f"{where} (the leg's own estimate; not yet estimated {a['unestimated_s']:.0f} s, "
                                      f"beyond its edge {a['outside_s']:.0f} s) · rows: {modes}")]


def _pyplot():
    """matplotlib's pyplot on its file-only backend, imported when a report is first drawn (a server that never prints
    one starts without it)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def session_report_pdf(session: dict, patient: dict) -> bytes:
    """One A4 page for a stopped session (``session`` as ``GET /api/sessions/{id}`` returns it): facts as label and
    value, then the four joint trajectories; with an envelope, a second page with time, strides and errors per region
    of the envelope. Times in the server's local zone, every number with its unit."""
    figs = [report_figure(session, patient)]
    adaptive = (session["summary"] or {}).get("adaptive")
    if adaptive:
        figs.append(envelope_figure(session, adaptive))
    from matplotlib.backends.backend_pdf import PdfPages

    plt = _pyplot()
    buf = io.BytesIO()
    with PdfPages(buf, metadata={"Title": f"QuasiTune session {session['id']}", "Creator": "QuasiTune"}) as pdf:
        for fig in figs:
            pdf.savefig(fig)
            plt.close(fig)
    return buf.getvalue()


def envelope_figure(session: dict, a: dict) -> Figure:
    """Time per region of the envelope (the leg's own estimate of its task) and per-stride errors by region."""
    fig = _pyplot().figure(figsize=(8.27, 11.69))
    fig.text(0.06, 0.955, f"Session {session['id']} · where in {session['table_label']} the patient walked",
             fontsize=13, weight="bold")
    speeds, inclines = a["speeds_mps"], a["inclines_deg"]
    grids = [("time per region (s) · strides", a["time_s"], lambda i, j: f"{a['time_s'][i][j]:.0f} s\n{a['strides'][i][j]}"),
             ("knee angle RMSE per stride (deg), at each stride's estimated task",
              a["errors_by_region"]["knee_angle_per_stride_rmse_deg"], None),
             ("ankle angle RMSE per stride (deg), at each stride's estimated task",
              a["errors_by_region"]["ankle_angle_per_stride_rmse_deg"], None)]
    for k, (title, grid, text) in enumerate(grids):
        ax = fig.add_axes((0.12, 0.70 - k * 0.30, 0.76, 0.22))
        values = [[float("nan") if grid[i][j] is None else grid[i][j] for i in range(len(speeds))]
                  for j in range(len(inclines))]
        image = ax.imshow(values, origin="lower", cmap="Blues", aspect="auto")
        for j in range(len(inclines)):
            for i in range(len(speeds)):
                v = grid[i][j]
                label = text(i, j) if text else ("—" if v is None else f"{v:.1f}")
                dark = v is not None and image.norm(v) > 0.6          # white on the darker cells
                ax.text(i, j, label, ha="center", va="center", fontsize=7, color="white" if dark else "black")
        ax.set_xticks(range(len(speeds)), [f"{v:.2f}" for v in speeds], fontsize=7)
        ax.set_yticks(range(len(inclines)), [f"{g:+.0f}" for g in inclines], fontsize=7)
        ax.set_xlabel("speed (m/s)", fontsize=8)
        ax.set_ylabel("incline (deg)", fontsize=8)
        ax.set_title(title, fontsize=9)
    fig.text(0.06, 0.03, "A region: the tasks nearer to its node than to any other. Errors: "
             + a.get("errors_reference", "") + ".", fontsize=6.5, color="0.4")
    return fig


def report_figure(session: dict, patient: dict) -> Figure:
    """The report page as a matplotlib figure (A4 portrait)."""
    s = session["summary"] or {}
    fig = _pyplot().figure(figsize=(8.27, 11.69))
    simulated = " · SIMULATED WALK" if session.get("simulated") else ""
    fig.text(0.06, 0.955, f"QuasiTune session report · session {session['id']}{simulated}", fontsize=15, weight="bold",
             color="#b3261e" if simulated else "black")
    y = 0.925
    for label, value in report_facts(session, patient):
        warn = (label == "Leg off its table" and value != "never") or label in ("Bench override", "Extrapolated",
                                                                                   "SIMULATED")
        fig.text(0.06, y, label, fontsize=8, color="0.35")
        for k, line in enumerate(textwrap.wrap(value, 88) or [""]):
            fig.text(0.27, y - k * 0.014, line, fontsize=8, color="#b3261e" if warn else "black",
                     weight="bold" if warn else "normal")
            last = y - k * 0.014
        y = last - 0.019
    phase = [100 * p for p in s.get("phase_grid", [])]
    top = y - 0.05
    height = (top - 0.06 - 0.07) / 2
    for i, ch in enumerate(GAIT_CHANNELS):
        ax = fig.add_axes((0.09 + (i % 2) * 0.47, top - height - (i // 2) * (height + 0.07), 0.38, height))
        # a course's strides are at several tasks: their mean is drawn alone, never against one task's reference
        ref = None if session.get("course") else (s.get("reference_curves") or {}).get(ch)
        mean = (s.get("mean_curves") or {}).get(ch)
        if ref:
            ax.plot(phase, ref, color="k", lw=2, label=REFERENCE_LEGEND.get(s.get("reference_kind"), "reference"))
        if mean:
            ax.plot(phase, mean, color="tab:blue", lw=1.5, label="measured (mean of the strides across the course's "
                    "tasks)" if session.get("course") else "measured (mean of scored strides)")
        else:
            ax.text(0.5, 0.5, "no scored stride", ha="center", transform=ax.transAxes)
        ax.set_xlabel("gait cycle (%)", fontsize=8)
        ax.set_ylabel(_LABELS[ch], fontsize=8)
        # angles: their error is the headline's, given once above; a course's strides are at several tasks, so no
        # single reference's RMSE is printed over them
        name = _LABELS[ch].split(" (")[0]
        title = name if _UNITS[ch] == "deg" or session.get("course") else \
            f"{name}: RMSE of the mean stride {_fmt(s.get(rmse_key(ch)), _UNITS[ch], 3)}"
        ax.set_title(textwrap.fill(title, 48), fontsize=9)     # two lines, not over the next chart, when it is long
        ax.tick_params(labelsize=7)
        ax.legend(fontsize=6, loc="best")
    fig.text(0.06, 0.02, f"Generated {datetime.now().astimezone().strftime('%Y-%m-%d %H:%M %Z')} · strides between heel "
             "strikes (load above 10 % of body weight), averaged on the gait-cycle grid", fontsize=6.5, color="0.4")
    return fig
