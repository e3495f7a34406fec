"""The picture a prosthetist looks at: torque-angle loops with the KMP ±σ band over the reference curves,
the via-points, and the per-sub-phase regression lines; below, angle and moment over the gait cycle."""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.patches import Ellipse

from controller_core.model import QuasiStiffnessModel
from controller_core.proposal import Proposal
from controller_core.quasi_stiffness import SUBPHASES, subphase_masks

SUBPHASE_COLOURS = dict(zip(SUBPHASES, ("#1b9e77", "#d95f02", "#7570b3", "#e7298a"), strict=True))


def plot_proposal(model: QuasiStiffnessModel, proposal: Proposal, out: str | Path) -> Path:
    """Draw and save the proposal figure; returns the path written."""
    fig, axes = plt.subplots(3, 2, figsize=(12, 13), gridspec_kw={"height_ratios": [2.2, 1, 1]})
    s = proposal.phase
    masks = subphase_masks(s, proposal.boundaries)
    for col, joint in enumerate(("knee", "ankle")):
        ax = axes[0, col]
        ang = np.degrees(proposal.means[f"{joint}_angle"])
        mom = proposal.means[f"{joint}_moment"] * proposal.mass_kg
        for i, rec in enumerate(model.reference_.records):
            ax.plot(np.degrees(rec.mean[f"{joint}_angle"]), rec.mean[f"{joint}_moment"] * proposal.mass_kg,
                    color="0.75", lw=1, label="reference conditions" if i == 0 else None)
        sa, sm = np.degrees(proposal.stds[f"{joint}_angle"]), proposal.stds[f"{joint}_moment"] * proposal.mass_kg
        for k in range(0, s.size, 2):  # ±1σ ellipses along the loop form the band
            ax.add_patch(Ellipse((ang[k], mom[k]), 2 * sa[k], 2 * sm[k], color="tab:blue", alpha=0.12, lw=0))
        ax.plot(ang, mom, color="tab:blue", lw=2, label="KMP proposal (±1σ band)")
        for sub, mask in zip(SUBPHASES, masks, strict=True):
            row = proposal.table.row(joint, sub)
            th = np.linspace(ang[mask].min(), ang[mask].max(), 10)
            ax.plot(th, row.k_Nm_per_rad * np.radians(th - row.theta_e_deg), "--", color=SUBPHASE_COLOURS[sub],
                    lw=2, label=f"{sub}: k={row.k_Nm_per_rad:.0f} N·m/rad, θe={row.theta_e_deg:.1f}°, "
                                f"R²={row.r2:.2f}")
        for v in proposal.vias.get(joint, []):
            ax.plot(math.degrees(v.mean[0]), v.mean[1] * proposal.mass_kg, "k*", ms=11)
        ax.plot([], [], "k*", ms=11, label="via-points (GPR features)")
        ax.set_xlabel(f"{joint} angle (deg, {'flexion' if joint == 'knee' else 'dorsiflexion'} +)")
        ax.set_ylabel(f"{joint} moment (N·m, internal, {'flexor' if joint == 'knee' else 'dorsiflexor'} +)")
        ax.set_title(f"{joint.capitalize()} torque-angle loop")
        ax.legend(fontsize=7, loc="best")
        for r, (q, unit, sc) in enumerate((("angle", "deg", 180 / math.pi), ("moment", "N·m/kg", 1.0)), start=1):
            ax2 = axes[r, col]
            m, sd = proposal.means[f"{joint}_{q}"] * sc, proposal.stds[f"{joint}_{q}"] * sc
            for i, rec in enumerate(model.reference_.records):
                ax2.plot(rec.phase * 100, rec.mean[f"{joint}_{q}"] * sc, color="0.75", lw=1,
                         label="reference" if i == 0 else None)
            ax2.fill_between(s * 100, m - sd, m + sd, color="tab:blue", alpha=0.25, label="±1σ")
            ax2.plot(s * 100, m, color="tab:blue", lw=2, label="proposal")
            for b in proposal.boundaries:
                ax2.axvline(b * 100, color="0.4", ls=":", lw=1)
            ax2.set_xlabel("gait cycle (%)")
            ax2.set_ylabel(f"{joint} {q} ({unit})")
            ax2.legend(fontsize=7)
    title = (f"{proposal.speed_mps:.2f} m/s, {proposal.incline_deg:+.1f}°, {proposal.mass_kg:.0f} kg — "
             f"model {proposal.model_version}")
    if proposal.extrapolation:
        title += "  [EXTRAPOLATION: outside the training data]"
    fig.suptitle(title)
    fig.tight_layout()
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out
