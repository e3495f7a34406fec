"""The printable session report as a PDF (matplotlib's PDF backend): task, the table that ran, strides, cadence,
stride-averaged joint trajectories against the reference (labelled with what it is: measured level walking, the
measured ramp trend, or the model's prediction), and the errors — the same numbers as the dashboard's report page,
from the stored summary."""

from __future__ import annotations

import io

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from matplotlib.backends.backend_pdf import PdfPages

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


def _fmt(value: object, unit: str = "", digits: int = 2) -> str:
    if value is None:
        return "— (fewer than two heel strikes)"
    if isinstance(value, float):
        return f"{value:.{digits}f} {unit}".strip()
    return f"{value} {unit}".strip()


def session_report_pdf(session: dict, patient: dict) -> bytes:
    """One A4 page for a stopped session (``session`` as ``GET /api/sessions/{id}`` returns it)."""
    s = session["summary"] or {}
    t = session["task"]
    fig = plt.figure(figsize=(8.27, 11.69))
    fig.text(0.06, 0.965, f"QuasiTune session report — session {session['id']}", fontsize=15, weight="bold")
    crc = session["table_crc32"] or "—"
    version = session["table_version"] if session["table_version"] is not None else "none (no table was active)"
    lines = [
        f"Patient {patient['code_name']} · body mass {patient['body_mass_kg']:.1f} kg · side {patient['side']}",
        f"Task: {t['speed_mps']:.2f} m/s, incline {t['incline_deg']:+.1f}° · device {session['device_id']}",
        f"Active table version {version} (CRC-32 {crc}), proposal {session['proposal_id'] or '—'}",
        f"Recorded {session['started_at']} → {session['stopped_at'] or 'still recording'} "
        f"by {session['started_by']}",
        f"Samples {s.get('samples', 0)} over {_fmt(s.get('duration_s'), 's', 1)}; missing samples "
        f"{s.get('missing_samples', '—')}",
        f"Strides {s.get('strides', 0)} · cadence {_fmt(s.get('cadence_steps_per_min'), 'steps/min', 1)} · "
        f"stride time {_fmt(s.get('stride_time_s'), 's', 3)} (reference {_fmt(s.get('reference_stride_time_s'), 's', 3)})",
        "RMSE against the reference (stride-averaged, on the phase grid): "
        + ", ".join(f"{c.split('_')[0]} {c.split('_')[1]} {_fmt(s.get(rmse_key(c)), '', 3)}" for c in GAIT_CHANNELS),
        f"Reference: {REFERENCE_KIND.get(s.get('reference_kind'), 'reference')} ({s.get('reference_source', '—')})"
        + (" [EXTRAPOLATION]" if s.get("reference_extrapolation") else ""),
    ]
    for i, line in enumerate(lines):
        fig.text(0.06, 0.935 - i * 0.019, line, fontsize=7.5, wrap=True)
    phase = [100 * p for p in s.get("phase_grid", [])]
    for i, ch in enumerate(GAIT_CHANNELS):
        ax = fig.add_axes((0.08 + (i % 2) * 0.47, 0.43 - (i // 2) * 0.36, 0.39, 0.27))
        ref = (s.get("reference_curves") or {}).get(ch)
        mean = (s.get("mean_curves") or {}).get(ch)
        if ref:
            ax.plot(phase, ref, color="k", lw=2, label=REFERENCE_LEGEND.get(s.get("reference_kind"), "reference"))
        if mean:
            ax.plot(phase, mean, color="tab:blue", lw=1.5, label="measured (stride mean)")
        else:
            ax.text(0.5, 0.5, "no complete stride", ha="center", transform=ax.transAxes)
        ax.set_xlabel("gait cycle (%)")
        ax.set_ylabel(_LABELS[ch], fontsize=8)
        ax.set_title(f"RMSE {_fmt(s.get(rmse_key(ch)), '', 3)}", fontsize=8)
        ax.legend(fontsize=6)
    buf = io.BytesIO()
    with PdfPages(buf, metadata={"Title": f"QuasiTune session {session['id']}", "Creator": "QuasiTune"}) as pdf:
        pdf.savefig(fig)
    plt.close(fig)
    return buf.getvalue()
