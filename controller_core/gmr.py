"""Gaussian mixture model / Gaussian mixture regression.

EM is scikit-learn's ``GaussianMixture`` (full covariances); the regression (conditioning on any subset of
dimensions, with the conditional covariance) is written here. Data are standardised per dimension before
EM and the results mapped back, so the mixture does not depend on units.
"""

from __future__ import annotations

import numpy as np


class GaussianMixtureRegression:
    """GMM over joint data with GMR conditioning.

    Args:
        n_components: mixture components.
        reg_covar: covariance regularisation added by EM (standardised units).
        n_init: EM restarts.
        random_state: seed (fits are deterministic for a given seed).
    """

    def __init__(self, n_components: int = 12, reg_covar: float = 1e-4, n_init: int = 2,
                 random_state: int = 0) -> None:
        self.n_components = n_components
        self.reg_covar = reg_covar
        self.n_init = n_init
        self.random_state = random_state

    def fit(self, Z: np.ndarray) -> GaussianMixtureRegression:
        """Fit the mixture on samples ``Z`` (n, D)."""
        from sklearn.mixture import GaussianMixture  # fitting only: a loaded model conditions without scikit-learn

        Z = np.asarray(Z, dtype=float)
        if Z.ndim != 2 or not np.all(np.isfinite(Z)):
            raise ValueError("GMM data must be a finite (n, D) array")
        self.center_ = Z.mean(axis=0)
        self.scale_ = np.where(Z.std(axis=0) > 0, Z.std(axis=0), 1.0)
        gmm = GaussianMixture(n_components=self.n_components, covariance_type="full",
                              reg_covar=self.reg_covar, n_init=self.n_init,
                              random_state=self.random_state, max_iter=500)
        gmm.fit((Z - self.center_) / self.scale_)
        self.weights_ = gmm.weights_
        self.means_ = gmm.means_ * self.scale_ + self.center_
        self.covariances_ = gmm.covariances_ * np.outer(self.scale_, self.scale_)[None]
        self.converged_ = bool(gmm.converged_)
        self._cache: dict[tuple[int, ...], tuple[np.ndarray, ...]] = {}
        return self

    def _conditioner(self, in_idx: tuple[int, ...]) -> tuple[np.ndarray, ...]:
        """Per-component regression matrices for conditioning on ``in_idx`` (cached)."""
        if in_idx in self._cache:
            return self._cache[in_idx]
        D = self.means_.shape[1]
        out_idx = tuple(i for i in range(D) if i not in in_idx)
        ii, oo = np.ix_(in_idx, in_idx), np.ix_(out_idx, out_idx)
        oi = np.ix_(out_idx, in_idx)
        mu_i = self.means_[:, in_idx]
        mu_o = self.means_[:, out_idx]
        S_ii = self.covariances_[:, ii[0], ii[1]]
        S_oo = self.covariances_[:, oo[0], oo[1]]
        S_oi = self.covariances_[:, oi[0], oi[1]]
        L = np.linalg.cholesky(S_ii)
        Linv = np.linalg.inv(L)                                  # small (|in| x |in|) triangular factors
        gain = np.einsum("koi,kji,kjl->kol", S_oi, Linv, Linv)    # S_oi S_ii^-1
        cond_cov = S_oo - np.einsum("koi,kpi->kop", gain, S_oi)
        log_norm = (np.log(self.weights_) - np.log(np.diagonal(L, axis1=1, axis2=2)).sum(axis=1)
                    - 0.5 * len(in_idx) * np.log(2.0 * np.pi))
        packed = (mu_i, mu_o, Linv, gain, cond_cov, log_norm)
        self._cache[in_idx] = packed
        return packed

    def predict(self, X: np.ndarray, in_idx: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
        """Condition on ``X`` (m, |in_idx|) given at dimensions ``in_idx``.

        Returns:
            mean (m, O) and covariance (m, O, O) of the remaining dimensions, in their order.
        """
        X = np.atleast_2d(np.asarray(X, dtype=float))
        mu_i, mu_o, Linv, gain, cond_cov, log_norm = self._conditioner(tuple(in_idx))
        diff = X[:, None, :] - mu_i[None]                          # (m, K, I)
        w = np.einsum("kij,mkj->mki", Linv, diff)
        logp = log_norm[None] - 0.5 * np.einsum("mki,mki->mk", w, w)
        logp -= logp.max(axis=1, keepdims=True)
        h = np.exp(logp)
        h /= h.sum(axis=1, keepdims=True)                           # responsibilities (m, K)
        means_k = mu_o[None] + np.einsum("koi,mki->mko", gain, diff)   # (m, K, O)
        mean = np.einsum("mk,mko->mo", h, means_k)
        second = np.einsum("mk,kop->mop", h, cond_cov) + np.einsum("mk,mko,mkp->mop", h, means_k, means_k)
        cov = second - np.einsum("mo,mp->mop", mean, mean)
        return mean, cov
