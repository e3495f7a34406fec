"""Quasi-stiffness fit per gait sub-phase: least squares τ = kθ + c, θe = −c/k, with R².

Units: θ in rad, τ in N·m (already multiplied by the patient's mass), k in N·m/rad, θe in rad.

Sign convention: QuasiTune moments are internal and positive in the direction of the positive angle, so a
spring-like (restoring) phase has **k < 0**; the controller applies τ = k(θ − θe) − bθ̇ with the same
signs, which makes a negative k restoring and a positive k energy-injecting.

Guard: when |k| is near zero, −c/k is far away and meaningless. If the fitted θe falls outside the joint's
range (which includes the |k| → 0 case), θe is clamped to the range and k is re-fitted with θe fixed
(k = Σ(θ−θe)τ / Σ(θ−θe)²); the row is marked ``guarded``.

Passivity: a least-squares slope can come out energy-injecting (k > 0), typically in swing, where the
moments are small and the joint is carried by the thigh's motion. That is harmless while θe lies beyond the
angles the joint sweeps in the sub-phase (the line then only brakes, as the knee's extensor moment does in
early swing), but with θe inside that span τ = k(θ − θe) pushes the joint away from θe on both sides, into
an end stop. In stance any k > 0 is refused, wherever θe lies: the patient's weight is on the joint (the table's
safety check refuses it too); such a stance line is first re-fitted through an end of the joint range, where a
push-off is a restoring spring that still carries the load. When a ceiling ``max_k_Nm_per_rad`` (< 0) is given, such
a sub-phase is re-fitted with k fixed
at the ceiling and θe = mean(θ − τ/k) (the least-squares θe for that k), clamped to the range; the row is
marked ``guarded`` (``passivity_guard``) and its R² says how much of the moment the constrained line still
explains.

Fit windows: a line can be fitted over part of its sub-phase. The knee's stance-extension sub-phase
(stance-flexion peak to toe-off) holds two movements: the loaded knee extending to its late-stance minimum,
a clean spring (R² 0.8–0.99 over the speed grid), and the pre-swing flexion towards toe-off, where the moment
is small and no line fits; over both, the least-squares line had R² 0.06 at 1.2 m/s and θe below the joint
range (clamped to 0°, pulling the knee into its end stop). With ``fit_windows`` the caller gives, per joint
and sub-phase, the phase window to fit over; the row is marked ``extension_window`` and reports the window
as its phase span and R² over it.

Swing targets: in swing the foot is off the ground and the able-bodied knee and ankle moments are inertial
and braking (the hamstrings slowing the swinging shank), which a line in θ does not capture; on the simulated
bench the least-squares swing lines do not carry a prosthetic shank through swing (``quasitune simulate``
with ``TableRules(swing_rule="least_squares")``). A caller
can therefore give, per swing sub-phase, a fixed restoring k and a target θe (the model takes θe from its
predicted swing features); :func:`fit_quasi_stiffness_joints` then uses that line, marks it ``swing_target``
and reports its R² against the predicted moment, so the table still says how little of the able-bodied
swing moment the line explains.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

SUBPHASES: tuple[str, ...] = ("stance_flexion", "stance_extension", "swing_flexion", "swing_extension")
SUBPHASE_CODES: dict[str, str] = {"stance_flexion": "SF", "stance_extension": "SE",
                                  "swing_flexion": "WF", "swing_extension": "WE"}


@dataclass(frozen=True)
class SubphaseFit:
    """Result of one sub-phase regression (SI units)."""

    subphase: str
    k_Nm_per_rad: float
    theta_e_rad: float
    r2: float
    guarded: bool
    phase_start: float
    phase_end: float
    n_points: int
    method: str = "least_squares"   # least_squares | extension_window | range_guard | passivity_guard | swing_target
    #                                 | support_floor (set by the model, controller_core.model)


def subphase_masks(phase: np.ndarray, boundaries: tuple[float, float, float]) -> np.ndarray:
    """Boolean masks (4, P) of the four sub-phases for boundaries (SF→SE, SE→WF, WF→WE) in phase units.

    SF: [0, b1], SE: [b1, b2], WF: [b2, b3], WE: [b3, 1]; boundary samples belong to both neighbours.
    """
    b1, b2, b3 = boundaries
    if not 0.0 < b1 < b2 < b3 < 1.0:
        raise ValueError(f"sub-phase boundaries must satisfy 0 < b1 < b2 < b3 < 1, got {boundaries}")
    edges = np.array([0.0, b1, b2, b3, 1.0])
    return (phase[None] >= edges[:-1, None] - 1e-12) & (phase[None] <= edges[1:, None] + 1e-12)


def fit_line(theta: np.ndarray, tau: np.ndarray, theta_range: tuple[float, float]) -> tuple[float, float, float, bool]:
    """Fit τ = k(θ − θe) by least squares; returns (k, θe, R², guarded)."""
    theta = np.asarray(theta, dtype=float)
    tau = np.asarray(tau, dtype=float)
    if theta.size < 3:
        raise ValueError("a sub-phase needs at least 3 samples for a line fit")
    tm, ym = theta.mean(), tau.mean()
    dt, dy = theta - tm, tau - ym
    sxx, syy = float(dt @ dt), float(dy @ dy)
    k = float(dt @ dy) / sxx if sxx > 0 else 0.0
    c = ym - k * tm
    lo, hi = theta_range
    guarded = False
    theta_e = -c / k if abs(k) > 1e-12 else np.inf
    if not lo <= theta_e <= hi:
        guarded = True
        if np.isfinite(theta_e):
            theta_e = float(np.clip(theta_e, lo, hi))
        else:  # k ≈ 0: the farthest bound needs the smallest |k| to carry the mean moment
            theta_e = lo if abs(tm - lo) > abs(tm - hi) else hi
        d = theta - theta_e
        k = float(d @ tau) / float(d @ d) if float(d @ d) > 0 else 0.0
    resid = tau - k * (theta - theta_e)
    r2 = 1.0 - float(resid @ resid) / syy if syy > 0 else 0.0
    return k, float(theta_e), r2, guarded


def _range_guard(n: float, tm: float, ym: float, sxx: float, sxy: float, syy: float, theta_e: float,
                 lo: float, hi: float) -> tuple[float, float, float]:
    """:func:`fit_line`'s guard from a sub-phase's centred sums (count, means, Sθθ, Sθτ, Sττ): θe clamped to
    [lo, hi] (the farther bound when k ≈ 0), k re-fitted through it; returns (k, θe, R²)."""
    if math.isfinite(theta_e):
        te = min(max(theta_e, lo), hi)
    else:
        te = lo if abs(tm - lo) > abs(tm - hi) else hi
    dm = tm - te                                    # Σ(θ−θe)² = Sθθ + n·dm², Σ(θ−θe)τ = Sθτ + n·dm·ym
    dd, dt = sxx + n * dm * dm, sxy + n * dm * ym
    k = dt / dd if dd > 0 else 0.0
    # Σ(τ − k(θ−θe))² around τ's mean: Sττ − 2k·Sθτ + k²·Sθθ + n·(ym − k·dm)²
    ss_res = syy - 2.0 * k * sxy + k * k * sxx + n * (ym - k * dm) ** 2
    return k, te, (1.0 - ss_res / syy if syy > 0 else 0.0)


def _restoring_line_through_range_end(theta: np.ndarray, tau: np.ndarray, lo: float, hi: float,
                                      max_k: float) -> tuple[float, float, float] | None:
    """The best line τ = k(θ − θe) with θe at an end of the joint range and k at or below the restoring floor
    ``max_k``: (k, θe, R²), or None when neither end gives one. A stance line that came out energy-injecting is
    replaced by this before the floor itself: a push-off that the least-squares line puts about the far end of
    the range is, about the near end, a restoring spring that still carries the load."""
    best = None
    for end in (lo, hi):
        d = theta - end
        dd = float(d @ d)
        k = float(d @ tau) / dd if dd > 0 else 0.0
        if k <= max_k:
            r2 = _r2(theta, tau, k, end)
            if best is None or r2 > best[2]:
                best = (k, float(end), r2)
    return best


def _r2(theta: np.ndarray, tau: np.ndarray, k: float, theta_e: float) -> float:
    resid = tau - k * (theta - theta_e)
    dy = tau - tau.mean()
    syy = float(dy @ dy)
    return 1.0 - float(resid @ resid) / syy if syy > 0 else 0.0


def fit_fixed_k(theta: np.ndarray, tau: np.ndarray, k: float, theta_range: tuple[float, float]) -> tuple[float, float]:
    """θe minimising Σ(τ − k(θ − θe))² for a fixed k (clamped to the range), and the R² of that line."""
    theta = np.asarray(theta, dtype=float)
    tau = np.asarray(tau, dtype=float)
    theta_e = float(np.clip(np.mean(theta - tau / k), *theta_range))
    return theta_e, _r2(theta, tau, k, theta_e)


def fit_quasi_stiffness(phase: np.ndarray, theta_rad: np.ndarray, tau_Nm: np.ndarray,
                        boundaries: tuple[float, float, float],
                        theta_range_rad: tuple[float, float],
                        max_k_Nm_per_rad: float | None = None) -> list[SubphaseFit]:
    """Per-sub-phase quasi-stiffness of one joint.

    The four least-squares lines are computed together from masked sums; a sub-phase whose θe falls outside
    the joint range goes through :func:`fit_line`'s guard.

    Args:
        phase: (P,) phase grid in [0, 1].
        theta_rad: (P,) joint angle (rad).
        tau_Nm: (P,) joint moment (N·m, internal, + in the direction of + angle).
        boundaries: SF→SE, SE→WF (toe-off), WF→WE phases.
        theta_range_rad: joint range used by the guard.
        max_k_Nm_per_rad: passivity ceiling (< 0, N·m/rad); None leaves the slopes unconstrained.
    """
    return fit_quasi_stiffness_joints(phase, np.atleast_2d(theta_rad), np.atleast_2d(tau_Nm), boundaries,
                                      [theta_range_rad], max_k_Nm_per_rad)[0]


def fit_quasi_stiffness_joints(phase: np.ndarray, theta_rad: np.ndarray, tau_Nm: np.ndarray,
                               boundaries: tuple[float, float, float],
                               theta_ranges_rad: list[tuple[float, float]],
                               max_k_Nm_per_rad: float | None = None,
                               fixed_lines: list[dict[str, tuple[float, float]]] | None = None,
                               fit_windows: list[dict[str, tuple[float, float]]] | None = None,
                               ) -> list[list[SubphaseFit]]:
    """:func:`fit_quasi_stiffness` for several joints sharing one phase grid and one set of boundaries.

    Args:
        theta_rad, tau_Nm: (J, P) angle (rad) and moment (N·m) of J joints.
        theta_ranges_rad: J joint ranges (rad).
        fixed_lines: per joint, sub-phase name → (k N·m/rad, θe rad) to use instead of a fit (the swing
            targets; see the module docstring); k must be restoring (< 0) and θe within the joint range.
        fit_windows: per joint, sub-phase name → (start, end) phase window to fit that sub-phase's line over
            instead of its whole span (see the module docstring); at least 3 samples.
    """
    if max_k_Nm_per_rad is not None and not max_k_Nm_per_rad < 0:
        raise ValueError(f"max_k_Nm_per_rad must be negative (restoring), got {max_k_Nm_per_rad!r}")
    masks = subphase_masks(phase, boundaries)
    M = masks.astype(float)                                  # (4, P)
    theta = np.asarray(theta_rad, dtype=float).T             # (P, J)
    tau = np.asarray(tau_Nm, dtype=float).T
    n = M.sum(axis=1)
    if n.min() < 3:
        raise ValueError("a sub-phase needs at least 3 samples for a line fit")
    n = n[:, None]                                           # (4, 1) against (4, J) sums
    tm, ym = (M @ theta) / n, (M @ tau) / n
    sxx = M @ (theta * theta) - n * tm * tm
    sxy = M @ (theta * tau) - n * tm * ym
    syy = M @ (tau * tau) - n * ym * ym
    with np.errstate(divide="ignore", invalid="ignore"):
        k = np.where(sxx > 0, sxy / sxx, 0.0)
        theta_e = np.where(np.abs(k) > 1e-12, tm - ym / k, np.inf)      # θe = −c/k with c = ym − k·tm
        r2 = np.where(syy > 0, 1.0 - (syy - k * sxy) / syy, 0.0)
    first = masks.argmax(axis=1)
    last = phase.size - 1 - masks[:, ::-1].argmax(axis=1)
    out = []
    for j, (lo, hi) in enumerate(theta_ranges_rad):
        fits = []
        fixed = fixed_lines[j] if fixed_lines is not None else {}
        for i, name in enumerate(SUBPHASES):
            if name in fixed:
                kf, tef = fixed[name]
                if not (kf < 0 and lo <= tef <= hi):
                    raise ValueError(f"the fixed {name} line needs k < 0 and θe within the joint range, "
                                     f"got k = {kf!r} N·m/rad, θe = {tef!r} rad")
                # residual τ − k(θ − θe) = (τ − ȳ) − k(θ − θ̄) + (ȳ − k(θ̄ − θe)), from the masked sums
                offset = ym[i, j] - kf * (tm[i, j] - tef)
                ss_res = syy[i, j] - 2.0 * kf * sxy[i, j] + kf * kf * sxx[i, j] + n[i, 0] * offset * offset
                r2f = 1.0 - ss_res / syy[i, j] if syy[i, j] > 0 else 0.0
                fits.append(SubphaseFit(name, float(kf), float(tef), float(r2f), True,
                                        float(phase[first[i]]), float(phase[last[i]]), int(n[i, 0]), "swing_target"))
                continue
            window = (fit_windows[j] if fit_windows is not None else {}).get(name)
            if window is not None:
                inside = (phase >= window[0] - 1e-12) & (phase <= window[1] + 1e-12)
                th, ta = theta[inside, j], tau[inside, j]
                ki, tei, r2i, guarded = fit_line(th, ta, (lo, hi))
                span = (float(phase[inside][0]), float(phase[inside][-1]), int(inside.sum()))
                method = "range_guard" if guarded else "extension_window"
            else:
                th = ta = None                                   # gathered only if the passivity guard needs them
                if lo <= theta_e[i, j] <= hi:
                    ki, tei, r2i, guarded = float(k[i, j]), float(theta_e[i, j]), float(r2[i, j]), False
                else:    # fit_line's range guard, from the masked sums
                    ki, tei, r2i = _range_guard(float(n[i, 0]), float(tm[i, j]), float(ym[i, j]), float(sxx[i, j]),
                                                float(sxy[i, j]), float(syy[i, j]), float(theta_e[i, j]), lo, hi)
                    guarded = True
                span = (float(phase[first[i]]), float(phase[last[i]]), int(n[i, 0]))
                method = "range_guard" if guarded else "least_squares"
            # an energy-injecting line whose θe lies inside the angles the joint sweeps in this sub-phase
            # would push the joint away from θe in both directions: the unstable case the ceiling removes;
            # in stance the patient's weight is on the joint, so any energy-injecting line is replaced
            stance = name.startswith("stance")
            if max_k_Nm_per_rad is not None and ki > max_k_Nm_per_rad:
                if th is None:
                    th, ta = theta[masks[i], j], tau[masks[i], j]
                if th.min() <= tei <= th.max() or (stance and ki > 0.0):      # unstable
                    end = _restoring_line_through_range_end(th, ta, lo, hi, max_k_Nm_per_rad) if stance else None
                    if end is not None:     # in stance: the joint still carries the load, about an end of its range
                        ki, tei, r2i = end
                    else:
                        ki = float(max_k_Nm_per_rad)
                        tei, r2i = fit_fixed_k(th, ta, ki, (lo, hi))
                    method = "passivity_guard"
            fits.append(SubphaseFit(name, ki, tei, r2i, method not in ("least_squares", "extension_window"),
                                    *span, method))
        out.append(fits)
    return out
