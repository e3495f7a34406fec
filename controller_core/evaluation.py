"""Leave-one-condition-out evaluation of the model against simple baselines.

For each labelled reference condition (a record with a speed in m/s), the model is re-trained on the
others (same recipe as the default model, published incline features included) and asked to propose the
held-out task. Compared:

* **proposal**: GPR features → KMP through the registered reference (the product);
* **reference**: the same registered reference (GMR mean + task trend, re-timed) through KMP without
  via-points;
* **gmr**: the pooled GMR mean (one reference for every task, as in Ma et al.) through KMP without
  via-points, from a model trained with ``reference_mode="pooled"``;
* **linear**: linear interpolation between the neighbouring conditions' curves, per phase point
  (the nearest condition outside the training range);
* **nearest**: the training condition with the closest speed.

Feature RMSE is over the held-out conditions (GPR vs linear/nearest of the feature values); curve RMSE is
over all phase points of all held-out conditions, per channel, next to the published between-subject SD
(RMS over phase and conditions) for scale.
"""

from __future__ import annotations

import math

import numpy as np

from controller_core.features import FEATURES, FeatureSpec, record_features
from controller_core.model_io import train
from controller_core.proposal import FEATURE_UNITS
from controller_core.reference import CHANNELS, ReferenceSet, load_shipped_reference

DISPLAY = {"knee_angle": ("knee_angle_deg", math.degrees(1.0)), "ankle_angle": ("ankle_angle_deg", math.degrees(1.0)),
           "knee_moment": ("knee_moment_Nm_per_kg", 1.0), "ankle_moment": ("ankle_moment_Nm_per_kg", 1.0)}
METHODS = ("proposal", "reference", "gmr", "linear", "nearest")


def _interp_curves(speeds: np.ndarray, curves: np.ndarray, speed: float) -> np.ndarray:
    order = np.argsort(speeds)
    s, c = speeds[order], curves[order]
    return np.array([np.interp(speed, s, c[:, j]) for j in range(c.shape[1])])


def _feature_display(spec: FeatureSpec, value: float) -> float:
    return math.degrees(value) if spec.quantity == "angle" else value


def evaluate(reference: ReferenceSet | None = None, **params) -> dict:
    """Run the leave-one-condition-out evaluation; returns a JSON-ready report.

    Args:
        params: model hyperparameters (:class:`QuasiStiffnessModel`), defaults when omitted.
    """
    ref = reference or load_shipped_reference()
    speeds = np.array([r.task["speed_mps"] for r in ref.records])
    truth_feats = [record_features(r) for r in ref.records]
    sq: dict[str, dict[str, list[float]]] = {m: {c: [] for c in CHANNELS} for m in METHODS}
    feat_err: dict[str, dict[str, list[float]]] = {m: {f.name: [] for f in FEATURES}
                                                   for m in ("gpr", "linear", "nearest")}
    phase_err: dict[str, list[float]] = {f.name: [] for f in FEATURES}
    sd_sq: dict[str, list[float]] = {c: [] for c in CHANNELS}
    folds = []
    for i, held in enumerate(ref.records):
        keep = [j for j in range(len(ref.records)) if j != i]
        train_ref = ref.subset(keep)
        model = train(train_ref, use_published=True, **params)
        pooled = train(train_ref, use_published=True, **(params | {"reference_mode": "pooled"}))
        task, incline = held.task["speed_mps"], held.task.get("incline_deg", 0.0)
        prop = model.propose(task, incline, 75.0)
        base = model.propose(task, incline, 75.0, with_vias=False)
        gmr = pooled.propose(task, incline, 75.0, with_vias=False)
        near = keep[int(np.argmin(np.abs(speeds[keep] - task)))]
        fold = {"held_out": held.name, "speed_mps": task, "curve_rmse": {}}
        for c in CHANNELS:
            truth = np.interp(prop.phase, held.phase, held.mean[c])
            preds = {
                "proposal": prop.means[c], "reference": base.means[c], "gmr": gmr.means[c],
                "linear": np.interp(prop.phase, held.phase,
                                    _interp_curves(speeds[keep], np.vstack([ref.records[j].mean[c] for j in keep]),
                                                   task)),
                "nearest": np.interp(prop.phase, held.phase, ref.records[near].mean[c]),
            }
            name, scale = DISPLAY[c]
            fold["curve_rmse"][name] = {}
            for m, p in preds.items():
                e = (p - truth) * scale
                sq[m][c].extend((e * e).tolist())
                fold["curve_rmse"][name][m] = float(np.sqrt(np.mean(e * e)))
            sd_sq[c].extend(((held.sd[c] * scale) ** 2).tolist())
        folds.append(fold)
        fmap = {f.spec.name: f for f in prop.features}
        train_feats = [truth_feats[j] for j in keep]
        for spec in FEATURES:
            true_phase, true_val = truth_feats[i][spec.name]
            tv = _feature_display(spec, true_val)
            feat_err["gpr"][spec.name].append(_feature_display(spec, fmap[spec.name].value) - tv)
            lin = _interp_curves(speeds[keep], np.array([[f[spec.name][1]] for f in train_feats]), task)[0]
            feat_err["linear"][spec.name].append(_feature_display(spec, lin) - tv)
            feat_err["nearest"][spec.name].append(_feature_display(spec, truth_feats[near][spec.name][1]) - tv)
            phase_err[spec.name].append(fmap[spec.name].phase - true_phase)

    def rms(v: list[float]) -> float:
        return float(np.sqrt(np.mean(np.square(v))))

    def root_mean(squares: list[float]) -> float:
        return float(np.sqrt(np.mean(squares)))

    curve = {DISPLAY[c][0]: {m: root_mean(sq[m][c]) for m in METHODS}
             | {"between_subject_sd": root_mean(sd_sq[c])} for c in CHANNELS}
    features = {}
    for spec in FEATURES:
        features[spec.name] = {"unit": FEATURE_UNITS[spec.quantity], "gpr": rms(feat_err["gpr"][spec.name]),
                               "linear": rms(feat_err["linear"][spec.name]),
                               "nearest": rms(feat_err["nearest"][spec.name]),
                               "gpr_phase": rms(phase_err[spec.name])}
    return {"conditions": [r.name for r in ref.records], "curve_rmse": curve, "feature_rmse": features,
            "folds": folds}


def format_report(report: dict) -> str:
    """Markdown tables of an :func:`evaluate` report."""
    lines = ["Leave-one-condition-out curve RMSE (lower is better)", "",
             "| channel | proposal (GPR+KMP) | registered reference, no via-points | pooled GMR, no via-points "
             "| linear interp. | nearest | between-subject SD |",
             "|---|---|---|---|---|---|---|"]
    for ch, r in report["curve_rmse"].items():
        lines.append(f"| {ch} | {r['proposal']:.3f} | {r['reference']:.3f} | {r['gmr']:.3f} | {r['linear']:.3f} "
                     f"| {r['nearest']:.3f} "
                     f"| {r['between_subject_sd']:.3f} |")
    lines += ["", "Leave-one-condition-out feature RMSE", "",
              "| feature | unit | GPR | linear interp. | nearest | GPR phase (fraction of cycle) |",
              "|---|---|---|---|---|---|"]
    for name, r in report["feature_rmse"].items():
        lines.append(f"| {name} | {r['unit']} | {r['gpr']:.4f} | {r['linear']:.4f} | {r['nearest']:.4f} "
                     f"| {r['gpr_phase']:.4f} |")
    return "\n".join(lines)
