"""Gaussian-process regression from a walking task to one feature value (or phase).

Hyperparameters are fitted by maximising the marginal likelihood with scikit-learn's
``GaussianProcessRegressor``. Prediction uses our own cached arrays instead of ``gpr.predict``: the
proposal calls ~17 of these per task and sklearn's per-call overhead (~60 µs) would dominate the
sub-millisecond budget; the algebra is the same (mean k*ᵀα, variance k** − ‖L⁻¹k*‖²).

Kernel (on inputs divided by ``input_scale``):
``C_rbf · RBF(ℓ) + C_lin · (σ0² + x·x') + white``. The RBF length scales are bounded in physical units
(default speed 0.3–3 m/s, incline 3–30°); the linear part lets a trend (e.g. knee flexion rising with
speed) extrapolate with growing uncertainty instead of reverting to the mean; the white term absorbs
differences between labs. ``C_lin`` is a fixed, broad prior variance of the trend (``linear_prior_var``,
in units of the target's variance per scaled input²) rather than a fitted one: with four or five
training tasks the marginal likelihood tends to shrink it to nearly zero and explain the trend as noise,
and the prediction then reverts to the mean one step outside the data (leave-one-condition-out, the
fitted C_lin gave worse feature errors on 8 of 9 features than the fixed broad prior; docs/results.md).
A broad prior is the Gaussian-process form of an explicit linear mean with a vague prior on its
coefficients (Rasmussen & Williams 2006, §2.7): the trend is set by the data, and its uncertainty widens
the std away from the data. A task dimension that is constant in the training data (e.g. incline for
features seen only on level ground) cannot be learned, so its length scale is pinned at its lower bound:
uncertainty then grows as fast as the bounds allow away from the data, which is the honest choice.
Published per-point standard errors enter as fixed noise (``alpha``).
"""

from __future__ import annotations

import warnings

import numpy as np
from scipy.linalg import solve_triangular
from sklearn.exceptions import ConvergenceWarning
from sklearn.gaussian_process import GaussianProcessRegressor
from sklearn.gaussian_process.kernels import RBF, ConstantKernel, DotProduct, WhiteKernel

from controller_core.hull import TaskHull
from controller_core.training_data import training_arrays


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
    ) -> None:
        self.length_scale_bounds = length_scale_bounds
        self.input_scale = input_scale
        self.noise_bounds = noise_bounds
        self.hull_tolerance = hull_tolerance
        self.linear_prior_var = linear_prior_var
        self.n_restarts = n_restarts
        self.random_state = random_state

    def fit(self, X: np.ndarray, y: np.ndarray, y_se: np.ndarray | None = None) -> FeatureGPR:
        """Fit on tasks ``X`` (n, d) in physical units and targets ``y`` (n,).

        Args:
            y_se: optional (n,) standard error of each target (same unit as ``y``); NaN = unknown.
        """
        X, y = training_arrays(X, y, "FeatureGPR", "training points with one target each")
        d = X.shape[1]
        if len(self.length_scale_bounds) != d or len(self.input_scale) != d:
            raise ValueError(f"bounds/scales given for {len(self.input_scale)} task dims, data have {d}")
        scale = np.asarray(self.input_scale, dtype=float)
        Xs = X / scale
        self.y_mean_ = float(y.mean())
        self.y_std_ = float(y.std()) if y.std() > 0 else 1.0
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
        kernel = (
            ConstantKernel(1.0, (1e-2, 1e2)) * RBF(length_scale=init, length_scale_bounds=bounds)
            + ConstantKernel(self.linear_prior_var, "fixed") * DotProduct(sigma_0=1.0, sigma_0_bounds="fixed")
            + WhiteKernel(1e-2, self.noise_bounds)
        )
        gpr = GaussianProcessRegressor(kernel=kernel, alpha=alpha, normalize_y=False,
                                       n_restarts_optimizer=self.n_restarts, random_state=self.random_state)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)
            gpr.fit(Xs, yn)
        k = gpr.kernel_
        self.amp_rbf_ = float(k.k1.k1.k1.constant_value)
        self.length_scale_ = np.atleast_1d(k.k1.k1.k2.length_scale).astype(float) * scale  # physical
        self.amp_lin_ = float(k.k1.k2.k1.constant_value)
        self.sigma0_ = float(k.k1.k2.k2.sigma_0)
        self.noise_ = float(k.k2.noise_level)
        self.log_marginal_likelihood_ = float(gpr.log_marginal_likelihood_value_)
        self.X_train_ = X
        self._Xs = Xs
        self._ls_scaled = self.length_scale_ / scale
        self._scale = scale
        self.L_ = gpr.L_
        self.alpha_ = gpr.alpha_
        self.hull_ = TaskHull(self.hull_tolerance).fit(X)
        return self

    def predict_one(self, x: np.ndarray) -> tuple[float, float]:
        """Mean and std (target unit) at one task ``x`` (d,) in physical units.

        The std includes the fitted white-noise term, i.e. it is the uncertainty of a new group mean,
        not only of the latent function.
        """
        xs = np.asarray(x, dtype=float) / self._scale
        diff = (self._Xs - xs) / self._ls_scaled
        k = self.amp_rbf_ * np.exp(-0.5 * np.einsum("ij,ij->i", diff, diff))
        k += self.amp_lin_ * (self.sigma0_**2 + self._Xs @ xs)
        mean = float(k @ self.alpha_) * self.y_std_ + self.y_mean_
        v = solve_triangular(self.L_, k, lower=True, check_finite=False)
        prior = self.amp_rbf_ + self.amp_lin_ * (self.sigma0_**2 + xs @ xs) + self.noise_
        var = max(prior - float(v @ v), 1e-12)
        return mean, float(np.sqrt(var)) * self.y_std_

    def predict(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Means and stds at tasks ``X`` (m, d)."""
        out = np.array([self.predict_one(x) for x in np.atleast_2d(X)])
        return out[:, 0], out[:, 1]

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
        n = max(g._Xs.shape[0] for g in gprs)
        d = gprs[0]._Xs.shape[1]
        m = len(gprs)
        self.Xs = np.zeros((m, n, d))
        self.alpha = np.zeros((m, n))
        self.Linv = np.tile(np.eye(n), (m, 1, 1))
        self.mask = np.zeros((m, n))
        for i, g in enumerate(gprs):
            k = g._Xs.shape[0]
            self.Xs[i, :k] = g._Xs
            self.alpha[i, :k] = g.alpha_
            self.Linv[i, :k, :k] = solve_triangular(g.L_, np.eye(k), lower=True)
            self.mask[i, :k] = 1.0
        self.ls = np.array([g._ls_scaled for g in gprs])
        self.scale = gprs[0]._scale
        self.amp_rbf = np.array([g.amp_rbf_ for g in gprs])
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

    def predict_one(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Means (m,), stds (m,) and extrapolation flags (m,) of every GPR at task ``x``."""
        xs = np.asarray(x, dtype=float) / self.scale
        diff = (self.Xs - xs) / self.ls[:, None, :]
        k = self.amp_rbf[:, None] * np.exp(-0.5 * np.einsum("mnd,mnd->mn", diff, diff))
        k += self.amp_lin[:, None] * (self.sigma0_sq[:, None] + self.Xs @ xs)
        k *= self.mask
        mean = np.einsum("mn,mn->m", k, self.alpha) * self.y_std + self.y_mean
        v = np.einsum("mij,mj->mi", self.Linv, k)
        prior = self.amp_rbf + self.amp_lin * (self.sigma0_sq + xs @ xs) + self.noise
        var = np.maximum(prior - np.einsum("mi,mi->m", v, v), 1e-12)
        outside = np.array([not h.contains(x) for h in self.hulls])
        return mean, np.sqrt(var) * self.y_std, outside[self.hull_of]
