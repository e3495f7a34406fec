"""Gaussian-process regression from a walking task to one feature value (or phase).

Hyperparameters are fitted by maximising the marginal likelihood with scikit-learn's
``GaussianProcessRegressor``; the fitted estimator keeps what predicting needs as arrays (the kernel's hyperparameters,
the Cholesky factor ``L_`` and ``alpha_``), so a model loaded from disk predicts without importing scikit-learn (a
server or a CLI command starts without it; it is imported when something is fitted). A proposal needs every feature's
GPR at one task: :class:`FeatureGPRBank` evaluates them together from those factors (mean k*ᵀα and variance
k** − ‖L⁻¹k*‖², batched); :meth:`FeatureGPR.predict` is the bank of one.

Kernel (on inputs divided by ``input_scale``):
``C_rbf · RBF(ℓ) + C_lin · (σ0² + x·x') + white``, or with ``additive=True`` one RBF term per task dimension,
``Σ_j C_j · RBF_j(ℓ_j) + C_lin · (σ0² + x·x') + white``, so that the target is a sum of one function per dimension
(a level value over speed plus a change over incline: a slope's effect does not change with speed, and data on a
slope do not pass for level data at a nearby speed, as they do under the product kernel when ℓ_incline is long).
The RBF length scales are bounded in physical units
(default speed 0.3–3 m/s, incline 3–30°); the linear part lets a trend (e.g. knee flexion rising with
speed) extrapolate with growing uncertainty instead of reverting to the mean; the white term absorbs
differences between labs. ``C_lin`` is a fixed, broad prior variance of the trend (``linear_prior_var``,
in units of the target's variance per scaled input²) rather than a fitted one: with four or five
training tasks the marginal likelihood tends to shrink it to nearly zero and explain the trend as noise,
and the prediction then reverts to the mean one step outside the data (the fixed prior is the one the
leave-one-condition-out evaluation chose, ``quasitune evaluate``).
A broad prior is the Gaussian-process form of an explicit linear mean with a vague prior on its
coefficients (Rasmussen & Williams 2006, §2.7): the trend is set by the data, and its uncertainty widens
the std away from the data. A task dimension that is constant in the training data (e.g. incline for
features seen only on level ground) cannot be learned, so its length scale is pinned at its lower bound:
uncertainty then grows as fast as the bounds allow away from the data, which is the honest choice.
Published per-point standard errors enter as fixed noise (``alpha``).
"""

from __future__ import annotations

import math
import warnings

import numpy as np
from scipy.linalg import solve_triangular

from controller_core.hull import TaskHull
from controller_core.training_data import training_arrays

_IGNORED = 1e6   # RBF length (scaled input units) of a dimension an additive term does not use


def _terms(kernel) -> list:
    """The summands of a fitted sum kernel, flattened."""
    from sklearn.gaussian_process.kernels import Sum

    if isinstance(kernel, Sum):
        return _terms(kernel.k1) + _terms(kernel.k2)
    return [kernel]


class FeatureGPR:
    """GPR for one scalar target over task variables (scikit-learn-style estimator).

    Args:
        length_scale_bounds: per task dimension (low, high) in physical units.
        input_scale: per task dimension, physical unit of one scaled input (e.g. 1 m/s, 10°).
        noise_bounds: bounds of the white-noise variance in units of the target's variance.
        hull_tolerance: per-dimension tolerance of the extrapolation test (physical units).
        linear_prior_var: fixed prior variance C_lin of the linear trend (see the module docstring).
        n_restarts: optimizer restarts for the marginal likelihood.
        random_state: seed for the restarts.
        y_scale: the target's unit of normalisation (default: its SD over the training points, or 1).
        center: subtract the targets' mean first; a model of *changes* keeps 0 as its prior mean instead.
        additive: one RBF term per task dimension instead of one over all of them (see the module docstring).
    """

    def __init__(
        self,
        length_scale_bounds: tuple[tuple[float, float], ...] = ((0.3, 3.0), (3.0, 30.0)),
        input_scale: tuple[float, ...] = (1.0, 10.0),
        noise_bounds: tuple[float, float] = (1e-4, 1.0),
        hull_tolerance: tuple[float, ...] = (0.05, 0.5),
        linear_prior_var: float = 10.0,
        n_restarts: int = 2,
        random_state: int = 0,
        y_scale: float | None = None,
        center: bool = True,
        additive: bool = False,
    ) -> None:
        self.length_scale_bounds = length_scale_bounds
        self.input_scale = input_scale
        self.noise_bounds = noise_bounds
        self.hull_tolerance = hull_tolerance
        self.linear_prior_var = linear_prior_var
        self.n_restarts = n_restarts
        self.random_state = random_state
        self.y_scale = y_scale
        self.center = center
        self.additive = additive

    def fit(self, X: np.ndarray, y: np.ndarray, y_se: np.ndarray | None = None) -> FeatureGPR:
        """Fit on tasks ``X`` (n, d) in physical units and targets ``y`` (n,).

        Args:
            y_se: optional (n,) standard error of each target (same unit as ``y``); NaN = unknown.
        """
        from sklearn.exceptions import ConvergenceWarning
        from sklearn.gaussian_process import GaussianProcessRegressor
        from sklearn.gaussian_process.kernels import RBF, ConstantKernel, DotProduct, WhiteKernel

        X, y = training_arrays(X, y, "FeatureGPR", "training points with one target each")
        d = X.shape[1]
        if len(self.length_scale_bounds) != d or len(self.input_scale) != d:
            raise ValueError(f"bounds/scales given for {len(self.input_scale)} task dims, data have {d}")
        scale = np.asarray(self.input_scale, dtype=float)
        Xs = X / scale
        self.y_mean_ = float(y.mean()) if self.center else 0.0
        if self.y_scale is not None and not (math.isfinite(self.y_scale) and self.y_scale > 0):
            raise ValueError(f"y_scale must be a positive finite number, got {self.y_scale!r}")
        self.y_std_ = self.y_scale or (float(y.std()) if y.std() > 0 else 1.0)
        yn = (y - self.y_mean_) / self.y_std_
        se = np.zeros_like(y) if y_se is None else np.nan_to_num(np.asarray(y_se, float), nan=0.0)
        alpha = (se / self.y_std_) ** 2 + 1e-8
        bounds = []
        init = []
        for j, (lo, hi) in enumerate(self.length_scale_bounds):
            lo_s, hi_s = lo / scale[j], hi / scale[j]
            if np.ptp(X[:, j]) == 0.0:  # unidentifiable: pin at the lower bound (see module docstring)
                bounds.append((lo_s, lo_s * (1.0 + 1e-9)))
                init.append(lo_s)
            else:
                bounds.append((lo_s, hi_s))
                init.append(float(np.sqrt(lo_s * hi_s)))
        if self.additive:        # one RBF per dimension: the others get a fixed, effectively infinite length
            rbf = None
            for j in range(d):
                ls = [_IGNORED] * d
                ls[j] = init[j]
                lb = [(_IGNORED, _IGNORED * (1.0 + 1e-9))] * d
                lb[j] = bounds[j]
                term = ConstantKernel(1.0, (1e-2, 1e2)) * RBF(length_scale=ls, length_scale_bounds=lb)
                rbf = term if rbf is None else rbf + term
        else:
            rbf = ConstantKernel(1.0, (1e-2, 1e2)) * RBF(length_scale=init, length_scale_bounds=bounds)
        kernel = (rbf + ConstantKernel(self.linear_prior_var, "fixed") * DotProduct(sigma_0=1.0, sigma_0_bounds="fixed")
                  + WhiteKernel(1e-2, self.noise_bounds))
        gpr = GaussianProcessRegressor(kernel=kernel, alpha=alpha, normalize_y=False,
                                       n_restarts_optimizer=self.n_restarts, random_state=self.random_state)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)
            gpr.fit(Xs, yn)
        self.alpha_ = gpr.alpha_                                  # (n,) K⁻¹y, scaled targets
        self.L_ = gpr.L_                                          # (n, n) lower Cholesky factor of K + noise
        self.input_scale_ = scale
        amps, inverse = [], []
        for term in _terms(gpr.kernel_):
            if isinstance(term, WhiteKernel):
                self.noise_ = float(term.noise_level)
            elif isinstance(term.k2, RBF):
                ls = np.broadcast_to(np.asarray(term.k2.length_scale, dtype=float), (d,))
                amps.append(float(term.k1.constant_value))
                inverse.append(np.where(ls >= _IGNORED, 0.0, 1.0 / ls))
            else:
                self.amp_lin_ = float(term.k1.constant_value)
                self.sigma0_ = float(term.k2.sigma_0)
        self.rbf_amplitudes_ = np.array(amps)                     # per RBF term
        self.rbf_inverse_lengths_ = np.array(inverse)              # (terms, d), scaled units; 0: ignored
        with np.errstate(divide="ignore"):
            # physical length per dimension (the term that uses it)
            self.length_scale_ = scale / self.rbf_inverse_lengths_.max(axis=0)
        self.log_marginal_likelihood_ = float(gpr.log_marginal_likelihood_value_)
        self.X_train_ = X
        self.hull_ = TaskHull(self.hull_tolerance).fit(X)
        return self

    def __setstate__(self, state: dict) -> None:
        """Unpickle; a model saved when the fitted scikit-learn estimator was kept (``gpr_``) gives its factors."""
        fitted = state.pop("gpr_", None)
        if fitted is not None:
            state.setdefault("alpha_", fitted.alpha_)
            state.setdefault("L_", fitted.L_)
        self.__dict__.update(state)

    def predict(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Means and stds (target unit) at tasks ``X`` (m, d) in physical units.

        The std includes the fitted white-noise term: it is the uncertainty of a new group mean, not only of the
        latent function.
        """
        mean, std, _ = FeatureGPRBank([self]).predict_many(X)
        return mean[:, 0], std[:, 0]

    def extrapolates(self, x: np.ndarray) -> bool:
        """True when ``x`` lies outside the convex hull of this target's training tasks."""
        return not self.hull_.contains(x)


class FeatureGPRBank:
    """Many fitted :class:`FeatureGPR` evaluated together at one task (same algebra, batched).

    Training sets are zero-padded to a common length (padded kernel entries are zero and the padded
    triangular factor is the identity, which leaves means and variances unchanged). Identical training
    inputs share one hull test.
    """

    def __init__(self, gprs: list[FeatureGPR]) -> None:
        if not gprs:
            raise ValueError("a bank needs at least one fitted GPR")
        scaled = [g.X_train_ / g.input_scale_ for g in gprs]
        n = max(x.shape[0] for x in scaled)
        d = scaled[0].shape[1]
        m = len(gprs)
        self.Xs = np.zeros((m, n, d))
        self.alpha = np.zeros((m, n))
        self.Linv = np.tile(np.eye(n), (m, 1, 1))
        self.mask = np.zeros((m, n))
        for i, (g, x) in enumerate(zip(gprs, scaled, strict=True)):
            k = x.shape[0]
            self.Xs[i, :k] = x
            self.alpha[i, :k] = g.alpha_
            self.Linv[i, :k, :k] = solve_triangular(g.L_, np.eye(k), lower=True)
            self.mask[i, :k] = 1.0
        terms = max(g.rbf_amplitudes_.size for g in gprs)
        self.amp_rbf = np.zeros((m, terms))                 # padded terms have zero amplitude
        self.inv_ls = np.zeros((m, terms, d))
        for i, g in enumerate(gprs):
            self.amp_rbf[i, :g.rbf_amplitudes_.size] = g.rbf_amplitudes_
            self.inv_ls[i, :g.rbf_amplitudes_.size] = g.rbf_inverse_lengths_
        self.scale = gprs[0].input_scale_
        self.amp_lin = np.array([g.amp_lin_ for g in gprs])
        self.sigma0_sq = np.array([g.sigma0_**2 for g in gprs])
        self.noise = np.array([g.noise_ for g in gprs])
        self.y_mean = np.array([g.y_mean_ for g in gprs])
        self.y_std = np.array([g.y_std_ for g in gprs])
        hulls: dict[bytes, int] = {}
        self.hulls: list[TaskHull] = []
        self.hull_of = np.zeros(m, dtype=int)
        for i, g in enumerate(gprs):
            key = g.X_train_.tobytes()
            if key not in hulls:
                hulls[key] = len(self.hulls)
                self.hulls.append(g.hull_)
            self.hull_of[i] = hulls[key]
        # full-rank hulls are tested together: every face of every hull in one product (M x + q), then the
        # largest value per hull; degenerate ones (a line, a point) one by one
        forms = [h.halfspaces() for h in self.hulls]
        self.flat_hulls = [j for j, f in enumerate(forms) if f is None]
        full = [(j, f) for j, f in enumerate(forms) if f is not None]
        self.full_hulls = np.array([j for j, _ in full], dtype=int)
        self.faces_M = np.vstack([f[0] for _, f in full]) if full else np.zeros((0, d))
        self.faces_q = np.concatenate([f[1] for _, f in full]) if full else np.zeros(0)
        self.faces_start = np.cumsum([0] + [f[0].shape[0] for _, f in full[:-1]]).astype(int)

    def predict(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Means (m,), stds (m,) and extrapolation flags (m,) of every GPR at one task ``x`` (d,)."""
        xs = np.asarray(x, dtype=float) / self.scale
        diff = self.Xs - xs                                                  # (m, n, d)
        z = np.einsum("mnd,mtd->mtn", diff * diff, self.inv_ls * self.inv_ls)  # per term: ‖Δ/ℓ‖²
        k = np.einsum("mt,mtn->mn", self.amp_rbf, np.exp(-0.5 * z))
        k += self.amp_lin[:, None] * (self.sigma0_sq[:, None] + self.Xs @ xs)
        k *= self.mask
        mean = np.einsum("mn,mn->m", k, self.alpha) * self.y_std + self.y_mean
        v = np.einsum("mij,mj->mi", self.Linv, k)
        prior = self.amp_rbf.sum(axis=1) + self.amp_lin * (self.sigma0_sq + xs @ xs) + self.noise
        var = np.maximum(prior - np.einsum("mi,mi->m", v, v), 1e-12)
        outside = np.zeros(len(self.hulls), dtype=bool)
        if self.full_hulls.size:
            faces = self.faces_M @ np.asarray(x, dtype=float) + self.faces_q
            outside[self.full_hulls] = np.maximum.reduceat(faces, self.faces_start) > 1.0
        for j in self.flat_hulls:
            outside[j] = not self.hulls[j].contains(x)
        return mean, np.sqrt(var) * self.y_std, outside[self.hull_of]

    def predict_many(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`predict` at T tasks at once (X (T, d)): means, stds and extrapolation flags, each (T, m)."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        xs = X / self.scale                                                  # (T, d)
        diff = self.Xs[None] - xs[:, None, None, :]                          # (T, m, n, d)
        z = np.einsum("tmnd,mkd->tmkn", diff * diff, self.inv_ls * self.inv_ls)
        k = np.einsum("mk,tmkn->tmn", self.amp_rbf, np.exp(-0.5 * z))
        k += self.amp_lin[None, :, None] * (self.sigma0_sq[None, :, None] + np.einsum("mnd,td->tmn", self.Xs, xs))
        k *= self.mask[None]
        mean = np.einsum("tmn,mn->tm", k, self.alpha) * self.y_std + self.y_mean
        v = np.einsum("mij,tmj->tmi", self.Linv, k)
        prior = self.amp_rbf.sum(axis=1)[None] + self.amp_lin[None] * (
            self.sigma0_sq[None] + np.einsum("td,td->t", xs, xs)[:, None]) + self.noise[None]
        var = np.maximum(prior - np.einsum("tmi,tmi->tm", v, v), 1e-12)
        outside = np.zeros((X.shape[0], len(self.hulls)), dtype=bool)
        if self.full_hulls.size:
            faces = X @ self.faces_M.T + self.faces_q                        # (T, faces)
            outside[:, self.full_hulls] = np.maximum.reduceat(faces, self.faces_start, axis=1) > 1.0
        for j in self.flat_hulls:
            outside[:, j] = [not self.hulls[j].contains(x) for x in X]
        return mean, np.sqrt(var) * self.y_std[None], outside[:, self.hull_of]
