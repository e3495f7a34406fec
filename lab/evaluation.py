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

Over incline: one ramp condition held out at a time (:func:`evaluate_incline`), and the model trained on everything
against ten other people's change from level walking (:mod:`lab.um21_envelopes`), data it never saw.
"""

from __future__ import annotations

import copy
import math

import numpy as np

from controller_core.features import FEATURES, FeatureSpec, record_features
from controller_core.joint_reference import JointReference
from controller_core.model_io import train
from controller_core.phase_table import load_shipped_ramps
from controller_core.proposal import FEATURE_UNITS
from controller_core.reference import (
    CHANNEL_DISPLAY,
    CHANNELS,
    ReferenceSet,
    interp_rows,
    level_curves_at,
    load_shipped_reference,
)
from lab.um21_envelopes import um21_change_check

METHODS = ("proposal", "reference", "gmr", "linear", "nearest")


def _interp_curves(speeds: np.ndarray, curves: np.ndarray, speed: float) -> np.ndarray:
    order = np.argsort(speeds)
    return interp_rows(speed, speeds[order], curves[order])


def _feature_display(spec: FeatureSpec, value: float) -> float:
    return math.degrees(value) if spec.quantity == "angle" else value


def evaluate(reference: ReferenceSet | None = None, ramps: ReferenceSet | None = None, **params) -> dict:
    """Run the leave-one-condition-out evaluation over speed and over incline; returns a JSON-ready report.

    Args:
        reference: the level speed conditions (default: the shipped ones).
        ramps: one person's level and ramp walking (default: the shipped ones), trained on as the default model
            is, and held out one sloped condition at a time by :func:`evaluate_incline`.
        params: model hyperparameters (:class:`QuasiStiffnessModel`), defaults when omitted.
    """
    ref = reference or load_shipped_reference()
    ramps = ramps or load_shipped_ramps()
    speeds = np.array([r.task["speed_mps"] for r in ref.records])
    truth_feats = [record_features(r) for r in ref.records]
    sq: dict[str, dict[str, list[float]]] = {m: {c: [] for c in CHANNELS} for m in METHODS}
    feat_err: dict[str, dict[str, list[float]]] = {m: {f.name: [] for f in FEATURES}
                                                   for m in ("gpr", "linear", "nearest")}
    phase_err: dict[str, list[float]] = {f.name: [] for f in FEATURES}
    sd_sq: dict[str, list[float]] = {c: [] for c in CHANNELS}
    folds = []
    pooled_reference = copy.deepcopy(params.get("joint_reference") or JointReference())
    pooled_reference.reference_mode = "pooled"      # the GMR baseline: the same settings, one reference for all tasks
    for i, held in enumerate(ref.records):
        keep = [j for j in range(len(ref.records)) if j != i]
        train_ref = ref.subset(keep)
        model = train(train_ref, use_published=True, ramps=ramps, **params)
        pooled = model.with_joint_reference(pooled_reference)   # the same features, one reference for all tasks
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
            name, scale = CHANNEL_DISPLAY[c]
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

    curve = {CHANNEL_DISPLAY[c][0]: {m: root_mean(sq[m][c]) for m in METHODS}
             | {"between_subject_sd": root_mean(sd_sq[c])} for c in CHANNELS}
    features = {}
    for spec in FEATURES:
        features[spec.name] = {"unit": FEATURE_UNITS[spec.quantity], "gpr": rms(feat_err["gpr"][spec.name]),
                               "linear": rms(feat_err["linear"][spec.name]),
                               "nearest": rms(feat_err["nearest"][spec.name]),
                               "gpr_phase": rms(phase_err[spec.name])}
    full = train(ref, use_published=True, ramps=ramps, **params)
    return {"conditions": [r.name for r in ref.records], "curve_rmse": curve, "feature_rmse": features,
            "folds": folds, "incline": evaluate_incline(ref, ramps, **params),
            "um21_envelopes": um21_change_check(full)}


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


INCLINE_METHODS = ("model", "ignore_incline", "linear")


def _ramp_level(ramps: ReferenceSet) -> tuple[dict[str, np.ndarray], float]:
    level = [r for r in ramps.records if r.task["incline_deg"] == 0.0]
    w = np.array([r.n for r in level], dtype=float) / sum(r.n for r in level)
    return ({c: sum(wi * r.mean[c] for wi, r in zip(w, level, strict=True)) for c in CHANNELS},
            float(sum(wi * r.task["speed_mps"] for wi, r in zip(w, level, strict=True))))


def evaluate_incline(reference: ReferenceSet, ramps: ReferenceSet, **params) -> dict:
    """Leave one ramp condition out: how well the change from level walking at a held-out slope is predicted.

    For each sloped condition of ``ramps`` the model is trained on the reference, the published incline features
    and the other ramp conditions (so the held-out side of level is known from the published features alone),
    and its change from level, ``propose(v_ramp, γ) − propose(v_level, 0)``, is compared with the measured one,
    the person's ramp curves minus their own level curves. Baselines, with the same population speed effect:

    * **ignore_incline**: the model's speed effect only (what a model that ignores incline predicts);
    * **linear**: linear interpolation (here extrapolation: one condition per side) between level and the other
      ramp conditions, per phase point, of their speed-corrected changes.

    RMSE over phase per channel (deg, N·m/kg), and each method's RMSE relative to ignore_incline's.
    """
    level_curves, level_speed = _ramp_level(ramps)
    sloped = [r for r in ramps.records if r.task["incline_deg"] != 0.0]
    out: dict[str, object] = {"conditions": [r.name for r in sloped], "folds": []}
    sq = {m: {c: [] for c in CHANNELS} for m in INCLINE_METHODS}
    for held in sloped:
        keep = [i for i, r in enumerate(ramps.records) if r is not held]
        model = train(reference, use_published=True, ramps=ramps.subset(keep), **params)
        speed, incline = held.task["speed_mps"], held.task["incline_deg"]
        base = model.propose(level_speed, 0.0, 75.0).means
        on_slope = model.propose(speed, incline, 75.0).means
        speed_only = model.propose(speed, 0.0, 75.0).means
        population = {v: level_curves_at(reference, v)[0] for v in (level_speed, speed)}
        others = [r for r in sloped if r is not held]
        fold: dict[str, object] = {"held_out": held.name, "speed_mps": speed, "incline_deg": incline,
                                   "rmse": {}, "ratio_to_ignore_incline": {}}
        for c in CHANNELS:
            truth = held.mean[c] - level_curves[c]
            speed_effect = population[speed][c] - population[level_speed][c]
            corrected = [(r.task["incline_deg"], r.mean[c] - level_curves[c]
                          - (level_curves_at(reference, r.task["speed_mps"])[0][c] - population[level_speed][c]))
                         for r in others]
            slope = sum(g * d for g, d in corrected) / sum(g * g for g, _ in corrected) if corrected else 0.0
            preds = {"model": on_slope[c] - base[c], "ignore_incline": speed_only[c] - base[c],
                     "linear": speed_effect + incline * slope}
            name, scale = CHANNEL_DISPLAY[c]
            fold["rmse"][name] = {}
            for m, pred in preds.items():
                e = (np.interp(held.phase, model.s_query_, pred) - truth) * scale if pred.shape != truth.shape \
                    else (pred - truth) * scale
                sq[m][c].extend((e * e).tolist())
                fold["rmse"][name][m] = float(np.sqrt(np.mean(e * e)))
            fold["ratio_to_ignore_incline"][name] = {
                m: fold["rmse"][name][m] / fold["rmse"][name]["ignore_incline"] for m in INCLINE_METHODS}
        out["folds"].append(fold)
    rmse = {CHANNEL_DISPLAY[c][0]: {m: float(np.sqrt(np.mean(sq[m][c]))) for m in INCLINE_METHODS} for c in CHANNELS}
    out["rmse"] = rmse
    out["ratio_to_ignore_incline"] = {
        m: float(np.mean([rmse[ch][m] / rmse[ch]["ignore_incline"] for ch in rmse])) for m in INCLINE_METHODS}
    return out


def format_incline_report(report: dict) -> str:
    """Markdown table of :func:`evaluate_incline`'s report."""
    lines = ["Leave-one-ramp-condition-out: RMSE of the change from level walking (lower is better)", "",
             "| held out | channel | model | ignore incline | linear interp. |", "|---|---|---|---|---|"]
    for fold in report["folds"]:
        for ch, r in fold["rmse"].items():
            lines.append(f"| {fold['incline_deg']:+g}° | {ch} | {r['model']:.3f} | {r['ignore_incline']:.3f} "
                         f"| {r['linear']:.3f} |")
    ratio = report["ratio_to_ignore_incline"]
    lines += ["", f"Mean over channels of RMSE relative to ignoring incline: model {ratio['model']:.2f}, "
                  f"linear interpolation {ratio['linear']:.2f}"]
    return "\n".join(lines)
