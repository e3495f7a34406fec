"""Kernelized movement primitives (Huang, Rozo, Silvério, Caldwell, IJRR 2019), written from the equations.

Reference database: phases s_n with means μ_n (O,) and covariances Σ_n (O, O) from GMR.
With K the kernel matrix (k ⊗ I_O) and Σ the block-diagonal of the Σ_n:

* mean        ξ(s*) = k* (K + λ Σ)⁻¹ μ
* covariance  Σ(s*) = c · (k(s*, s*) I − k* (K + λc Σ)⁻¹ k*ᵀ)

Huang et al. use c = N/λc; we default to a calibrated c chosen so the unmodulated KMP reproduces the
reference covariance on average (``cov_scale="calibrated"``), which keeps the std in physical units.

Via-points (phase, mean, covariance) are added to the database; a reference point closer than
``via_tolerance`` in phase is replaced (removed) by the via-point.

Speed: the Cholesky factors of (K + λΣ) and (K + λcΣ) over the reference, their explicit inverses and
their products with the default query grid are computed once in ``fit``. A set of via-points changes the
database by a few points, so a new prediction needs only products with those cached matrices, gathers of
their columns and one small bordered system: the via-points added and the replaced reference points removed
(a removed point is a border column that pins its coefficient to zero), whose Schur complement is factorised
by two small Cholesky factors (:class:`_Modified`). ``predict_std`` forms only the per-output variances.
``predict_uncached`` builds and factorises the full system: the tests' oracle, and the fallback when an update's
small system is too ill-conditioned to trust (nearly coincident, very confident via-points at a small λ;
``fallbacks_`` counts them).

Phases are in [0, 1); the kernel is periodic (heel strike at 0 and at 1 coincide), written so that
``length_scale`` is the equivalent squared-exponential length in phase units.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import cho_factor, cho_solve
from scipy.linalg.lapack import dpotrf, dpotrs, dtrtrs


@dataclass(frozen=True)
class ViaPoint:
    """A desired point of the trajectory: phase in [0, 1), mean (O,), covariance (O, O)."""

    phase: float
    mean: np.ndarray
    cov: np.ndarray


def periodic_kernel(a: np.ndarray, b: np.ndarray, length_scale: float) -> np.ndarray:
    """k(a_i, b_j) = exp(−sin²(π(a−b)) / (2 π² ℓ²)); ≈ squared-exponential with length ℓ for small gaps.
    Leading dimensions of ``a`` and ``b`` broadcast (a batch of phase sets)."""
    d = np.sin(np.pi * (np.asarray(a)[..., :, None] - np.asarray(b)[..., None, :]))
    return np.exp(-(d * d) / (2.0 * (np.pi * length_scale) ** 2))


def _kron_eye(k: np.ndarray, o: int) -> np.ndarray:
    """k ⊗ I_o without the generality (and cost) of ``np.kron`` (of each matrix, over leading dimensions)."""
    out = np.zeros((*k.shape[:-2], k.shape[-2] * o, k.shape[-1] * o))
    for i in range(o):
        out[..., i::o, i::o] = k
    return out


def _kron_eye_times(k: np.ndarray, M: np.ndarray, o: int) -> np.ndarray:
    """(k ⊗ I_o) @ M from k alone: a quarter of the memory traffic of the dense product (for o = 2)."""
    return (k @ M.reshape(k.shape[1], -1)).reshape(k.shape[0] * o, -1)


def _chol(A: np.ndarray) -> np.ndarray:
    """Lower Cholesky factor via LAPACK (raises when A is not positive definite)."""
    L, info = dpotrf(A, lower=1, clean=1)
    if info != 0:
        raise np.linalg.LinAlgError(f"matrix not positive definite (LAPACK dpotrf info={info})")
    return L


class _IllConditioned(np.linalg.LinAlgError):
    """A via-point update whose small system is too ill-conditioned for the cached solve to be trusted."""


# Largest error amplification at which the cached update is trusted: its small system is built from the cached
# inverse A⁻¹, so its error grows with cond(A) × cond(small system), both estimated from Cholesky diagonals.
# Measured against the plain solve: below 1e6 the two agree to about 1e-6 rad and N·m/kg; at 7e9 they differed
# by 1.8e-3 rad, and past that the update's Cholesky fails outright (two nearly coincident, very confident
# via-points at a small λ). The model's own updates stay near 1e4.
MAX_UPDATE_AMPLIFICATION = 1e6


def _condition(L: np.ndarray) -> float:
    """Condition estimate of L Lᵀ from a Cholesky factor's diagonal (a lower bound of the true one)."""
    d = [abs(x) for x in L.diagonal().tolist()]     # a dozen values: plain floats beat array reductions
    lo = min(d)
    return (max(d) / lo) ** 2 if lo > 0.0 else float("inf")


def _update_chol(A: np.ndarray, cond_ref: float) -> np.ndarray:
    """Cholesky factor of a via-point update's small system; :class:`_IllConditioned` when it is not positive
    definite or the update's error amplification passes :data:`MAX_UPDATE_AMPLIFICATION`."""
    L, info = dpotrf(A, lower=1, clean=1)
    if info != 0 or _condition(L) * cond_ref > MAX_UPDATE_AMPLIFICATION:
        raise _IllConditioned("ill-conditioned via-point update")
    return L


def _solve(L: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Solve (L Lᵀ) X = B with a lower Cholesky factor (LAPACK dpotrs, no input checks)."""
    X, info = dpotrs(L, B, lower=1)
    if info != 0:  # pragma: no cover - only on malformed input
        raise np.linalg.LinAlgError(f"LAPACK dpotrs info={info}")
    return X


def _tri(L: np.ndarray, B: np.ndarray, trans: int = 0) -> np.ndarray:
    """L⁻¹ B (``trans=1``: L⁻ᵀ B) for a lower-triangular L (LAPACK dtrtrs, no input checks)."""
    X, info = dtrtrs(L, B, lower=1, trans=trans)
    if info != 0:  # pragma: no cover - only on malformed input
        raise np.linalg.LinAlgError(f"LAPACK dtrtrs info={info}")
    return X


@dataclass(frozen=True)
class _Modified:
    """The reference database with via-points added and reference ``rows`` removed, relative to the cached A⁻¹.

    As one bordered system [[A, U], [Uᵀ, D']] with U = [C, E_R] (E_R: unit columns at the removed rows, which pins
    their coefficients to zero) and D' = [[K_vv + λΣ_v, 0], [0, 0]], its Schur complement is
    S = [[S_v, −W_Rᵀ], [−W_R, −A⁻¹_RR]] with W = A⁻¹C and S_v = K_vv + λΣ_v − CᵀW. S is factorised blockwise:
    S_v = Ls Lsᵀ, Y = Ls⁻¹W_Rᵀ, M = A⁻¹_RR + YᵀY = Lm Lmᵀ, so that xᵀS⁻¹y = aₓᵀa_y − cₓᵀc_y with
    a = Ls⁻¹x₁ and c = Lm⁻¹(x₂ + Yᵀa) (:meth:`half`). ``Y`` and ``Lm`` are None when no row is removed.
    """

    W: np.ndarray
    Ls: np.ndarray
    rows: np.ndarray
    Y: np.ndarray | None
    Lm: np.ndarray | None

    def half(self, top: np.ndarray, bottom: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """(a, c) of right-hand sides with via parts ``top`` (mO, k) and removed-row parts ``bottom`` (R, k)."""
        a = _tri(self.Ls, top)
        if self.Lm is None:
            return a, None
        return a, _tri(self.Lm, bottom + self.Y.T @ a)

    def solve(self, top: np.ndarray, bottom: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """S⁻¹ [top; bottom] as (via part z₁, removed-row part z₂; None when no row is removed)."""
        a, c = self.half(top, bottom)
        if c is None:
            return _tri(self.Ls, a, trans=1), None
        e = _tri(self.Lm, c, trans=1)                       # M⁻¹(x₂ + W_R S_v⁻¹ x₁)
        return _tri(self.Ls, a - self.Y @ e, trans=1), -e


def _blocks(G: np.ndarray, X: np.ndarray) -> np.ndarray:
    """Per-query O×O blocks of G X for G (Q, O, c) and X (c, Q, O)."""
    return np.einsum("qac,cqb->qab", G, X)


def _blockdiag(blocks: np.ndarray) -> np.ndarray:
    """Block-diagonal (n·o, n·o) matrix of n blocks (n, o, o), in one scatter (of each set, over leading
    dimensions)."""
    n, o, _ = blocks.shape[-3:]
    lead = blocks.shape[:-3]
    out = np.zeros((*lead, n, o, n, o))
    idx = np.arange(n)
    out[..., idx, :, idx, :] = np.moveaxis(blocks, -3, 0)     # the paired indices come first in the result
    return out.reshape((*lead, n * o, n * o))


class KMP:
    """Kernelized movement primitive over a phase-indexed reference.

    Args:
        length_scale: kernel length in phase units.
        lam: λ of the mean.
        lam_c: λc of the covariance.
        via_tolerance: a reference point closer than this (phase units) to a via-point is replaced.
        cov_scale: ``"calibrated"`` (default) or ``"huang"`` (c = N/λc).
        via_mean_scale: factor on the via-point covariances in the *mean* system only. Below 1 the mean
            is pulled harder through the via-points (dense, strongly correlated reference points otherwise
            out-vote a single via-point); the covariance system keeps the via-points' own covariance,
            so the reported uncertainty is not shrunk by this choice.
    """

    def __init__(self, length_scale: float = 0.05, lam: float = 1.0, lam_c: float = 1.0,
                 via_tolerance: float = 0.006, cov_scale: str = "calibrated",
                 via_mean_scale: float = 1.0) -> None:
        self.length_scale = length_scale
        self.lam = lam
        self.lam_c = lam_c
        self.via_tolerance = via_tolerance
        self.cov_scale = cov_scale
        self.via_mean_scale = via_mean_scale

    # ------------------------------------------------------------------ fit
    def fit(self, s_ref: np.ndarray, mu_ref: np.ndarray, sigma_ref: np.ndarray,
            s_query: np.ndarray | None = None) -> KMP:
        """Cache factorisations for a reference (N,), (N, O), (N, O, O) and a default query grid."""
        s_ref = np.mod(np.asarray(s_ref, dtype=float), 1.0)
        N, O = mu_ref.shape
        if sigma_ref.shape != (N, O, O):
            raise ValueError("sigma_ref must be (N, O, O)")
        if self.cov_scale not in ("calibrated", "huang"):
            raise ValueError("cov_scale must be 'calibrated' or 'huang'")
        self.s_ref_, self.mu_ref_, self.sigma_ref_ = s_ref, np.asarray(mu_ref, float), sigma_ref
        self.n_outputs_ = O
        self._uniform = bool(np.allclose(s_ref, np.arange(N) / N, atol=1e-12, rtol=0.0))
        self.s_query_ = np.linspace(0.0, 1.0, 101) if s_query is None else np.asarray(s_query, float)
        K = _kron_eye(periodic_kernel(s_ref, s_ref, self.length_scale), O)
        S = _blockdiag(sigma_ref)
        self._chol = _chol(K + self.lam * S)
        self._chol_c = _chol(K + self.lam_c * S)
        self._cond_A = max(_condition(self._chol), _condition(self._chol_c))
        # explicit inverses: a via-point update then needs products and gathers instead of triangular solves
        eye = np.eye(N * O)
        self._Ainv = _solve(self._chol, eye)
        self._Ainv_c = self._Ainv if self.lam_c == self.lam else _solve(self._chol_c, eye)
        self._mu_flat = self.mu_ref_.reshape(-1)
        self._alpha = _solve(self._chol, self._mu_flat[:, None])
        self._kq = periodic_kernel(self.s_query_, s_ref, self.length_scale)               # (Q, N); Kq = kq ⊗ I
        Kq = _kron_eye(self._kq, O)                                                       # (QO, NO)
        self._Zc = _solve(self._chol_c, Kq.T.copy())                                      # (NO, QO)
        Q = self.s_query_.size
        self._mean_base = (Kq @ self._alpha).reshape(Q, O)
        self._quad_base = np.einsum("gqa,gqb->qab", Kq.T.reshape(-1, Q, O), self._Zc.reshape(-1, Q, O))
        self._quad_base_diag = np.diagonal(self._quad_base, axis1=1, axis2=2).copy()
        self.fallbacks_ = 0
        self.cov_scale_ = 1.0
        if self.cov_scale == "huang":
            self.cov_scale_ = N / self.lam_c
        else:
            _, raw = self.predict()
            ref_at_q = self._ref_cov_at(self.s_query_)
            self.cov_scale_ = float(np.trace(ref_at_q, axis1=1, axis2=2).mean()
                                    / np.trace(raw, axis1=1, axis2=2).mean())
        return self

    def __setstate__(self, state: dict) -> None:
        """Unpickle, completing what older saves lack (the dense Kq = kq ⊗ I instead of kq; the condition) and
        dropping what they carry that nothing reads now (Kq A⁻¹ and Kq A_c⁻¹)."""
        self.__dict__.update(state)
        for unused in ("_G", "_G_c"):
            self.__dict__.pop(unused, None)
        if "_cond_A" not in state:       # saved before the ill-conditioning fallback
            self._cond_A = max(_condition(self._chol), _condition(self._chol_c))
            self.fallbacks_ = 0
        if "_Kq" in state:
            del self.__dict__["_Kq"]
            self._kq = periodic_kernel(self.s_query_, self.s_ref_, self.length_scale)

    def _ref_cov_at(self, s: np.ndarray) -> np.ndarray:
        idx = np.argmin(np.abs(np.angle(np.exp(2j * np.pi * (s[:, None] - self.s_ref_[None])))), axis=1)
        return self.sigma_ref_[idx]

    # --------------------------------------------------------------- helpers
    def _replaced(self, sv: np.ndarray) -> np.ndarray:
        """Indices (sorted) of reference points replaced by via-points at phases ``sv`` (within tolerance)."""
        if not sv.size:
            return np.zeros(0, dtype=int)
        n = self.s_ref_.size
        if self._uniform and self.via_tolerance < 1.0 / n:    # only the two neighbouring grid points can be hit
            tol = self.via_tolerance                          # a handful of vias: plain floats beat array calls
            hit = {int(c) % n for p in sv.tolist() for c in (math.floor(p * n), math.floor(p * n) + 1.0)
                   if abs(p - c / n) <= tol}
            return np.array(sorted(hit), dtype=int)
        gap = np.abs(sv[:, None] - self.s_ref_[None])
        gap = np.minimum(gap, 1.0 - gap)
        return np.flatnonzero((gap <= self.via_tolerance).any(axis=0))

    def _via_kernels(self, sv: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """k(·, vias) ⊗ I for the query grid (QO, mO), the reference grid C (NO, mO) and the vias themselves
        (mO, mO), from one kernel evaluation."""
        O = self.n_outputs_
        split = (self.s_query_.size * O, (self.s_query_.size + self.s_ref_.size) * O)
        K = _kron_eye(periodic_kernel(np.concatenate([self.s_query_, self.s_ref_, sv]), sv, self.length_scale), O)
        return K[:split[0]], K[split[0]:split[1]], K[split[1]:]

    def _modified(self, Ainv: np.ndarray, C: np.ndarray, Kvv: np.ndarray, lam: float, cov_v: np.ndarray,
                  rows: np.ndarray) -> _Modified:
        """Factorise the database modified by via-points (kernels ``C`` to the reference, ``Kvv`` among themselves,
        covariances ``cov_v``) and the removal of reference ``rows``, from the cached inverse ``Ainv``.

        Raises:
            _IllConditioned: either small factor is not positive definite or its error amplification passes
                :data:`MAX_UPDATE_AMPLIFICATION`.
        """
        W = Ainv @ C
        Ls = _update_chol(Kvv + lam * _blockdiag(cov_v) - C.T @ W, self._cond_A)
        if not rows.size:
            return _Modified(W, Ls, rows, None, None)
        Y = _tri(Ls, W[rows].T)
        return _Modified(W, Ls, rows, Y, _update_chol(Ainv[rows[:, None], rows] + Y.T @ Y, self._cond_A))

    def _mean_through(self, f: _Modified, Ainv: np.ndarray, C: np.ndarray, Kqv: np.ndarray, alpha: np.ndarray,
                      mu_v: np.ndarray) -> np.ndarray:
        """Mean (Q, O) of a modified database: coefficients x = α − A⁻¹U z on the reference, z₁ on the vias."""
        z1, z2 = f.solve(mu_v - C.T @ alpha, -alpha[f.rows])
        x = alpha - f.W @ z1
        if z2 is not None:
            x = x - Ainv[:, f.rows] @ z2
        return (_kron_eye_times(self._kq, x, self.n_outputs_) + Kqv @ z1).reshape(self.s_query_.size, self.n_outputs_)

    # --------------------------------------------------------------- predict
    def _alpha_for(self, mu: np.ndarray | None) -> np.ndarray:
        """A⁻¹μ for the fitted reference means, or for new means on the same grid (covariance unchanged)."""
        if mu is None:
            return self._alpha
        mu = np.asarray(mu, dtype=float)
        if mu.shape != self.mu_ref_.shape:
            raise ValueError(f"mu must have shape {self.mu_ref_.shape}")
        return self._Ainv @ mu.reshape(-1, 1)

    def predict(self, vias: list[ViaPoint] | None = None,
                mu: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Mean (Q, O) and covariance (Q, O, O) on the default query grid, through ``vias``.

        Args:
            vias: via-points to pass through.
            mu: optional new reference means (N, O) on the fitted grid (e.g. a task-dependent reference);
                the covariances Σ, hence the cached factorisations, stay those given to ``fit``.
        """
        try:
            mean, quad = self._predict(vias, mu, True)
        except _IllConditioned:
            self.fallbacks_ = getattr(self, "fallbacks_", 0) + 1
            return self.predict_uncached(vias, mu)
        return mean, self.cov_scale_ * (np.eye(self.n_outputs_)[None] - quad)

    def predict_std(self, vias: list[ViaPoint] | None = None,
                    mu: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Mean (Q, O) and standard deviation (Q, O) per output: :meth:`predict` without the off-diagonal
        covariance terms, which a per-channel display does not need."""
        try:
            mean, quad = self._predict(vias, mu, False)
        except _IllConditioned:
            self.fallbacks_ = getattr(self, "fallbacks_", 0) + 1
            mean, cov = self.predict_uncached(vias, mu)
            return mean, np.sqrt(np.clip(np.diagonal(cov, axis1=1, axis2=2), 0.0, None))
        return mean, np.sqrt(np.clip(self.cov_scale_ * (1.0 - quad), 0.0, None))

    def predict_mean(self, vias: list[ViaPoint] | None = None, mu: np.ndarray | None = None) -> np.ndarray:
        """Mean (Q, O) only: what a parameter table needs (an envelope builds 25 of them), without the
        covariance's right-hand sides. The same mean as :meth:`predict`."""
        vias = list(vias or [])
        O = self.n_outputs_
        Q = self.s_query_.size
        alpha = self._alpha_for(mu)
        if not vias:
            return self._mean_base.copy() if mu is None else _kron_eye_times(self._kq, alpha, O).reshape(Q, O)
        sv = np.mod(np.array([p.phase for p in vias], dtype=float), 1.0)
        J = self._replaced(sv)
        rows = (J[:, None] * O + np.arange(O)[None]).reshape(-1)
        cov_v = np.array([p.cov for p in vias], dtype=float)
        mu_v = np.concatenate([np.asarray(p.mean, float) for p in vias])[:, None]
        Kqv, C, Kvv = self._via_kernels(sv)
        try:
            f = self._modified(self._Ainv, C, Kvv, self.lam, cov_v * self.via_mean_scale, rows)
        except _IllConditioned:
            self.fallbacks_ = getattr(self, "fallbacks_", 0) + 1
            return self.predict_uncached(vias, mu)[0]
        return self._mean_through(f, self._Ainv, C, Kqv, alpha, mu_v)

    def predict_mean_many(self, vias: list[list[ViaPoint]], mus: list[np.ndarray | None]) -> list[np.ndarray]:
        """:meth:`predict_mean` for many (via-points, reference means) at once, the same means (to rounding).

        An envelope asks for 25 means that differ only in their via-points' values and phases: tasks with as many
        via-points and replaced reference points share one stacked solve (numpy's batched Cholesky and LU) instead
        of 25 rounds of small calls. The conditioning rule is the single solve's: a group with an update past
        :data:`MAX_UPDATE_AMPLIFICATION`, or not positive definite, is solved one by one (with its fallback).
        """
        if len(vias) != len(mus):
            raise ValueError("vias and mus must have the same length")
        out: list[np.ndarray | None] = [None] * len(vias)
        groups: dict[tuple[int, int], list[int]] = {}
        replaced: dict[int, np.ndarray] = {}
        for b, v in enumerate(vias):
            v = list(v or [])
            if not v:
                out[b] = self.predict_mean(v, mus[b])
                continue
            replaced[b] = self._replaced(np.mod(np.array([p.phase for p in v], dtype=float), 1.0))
            groups.setdefault((len(v), replaced[b].size), []).append(b)
        for members in groups.values():
            try:
                means = self._mean_group([list(vias[b]) for b in members], [mus[b] for b in members],
                                         np.array([replaced[b] for b in members], dtype=int))
            except _IllConditioned:
                means = [self.predict_mean(vias[b], mus[b]) for b in members]
            for b, mean in zip(members, means, strict=True):
                out[b] = mean
        return out   # type: ignore[return-value]

    def _mean_group(self, vias: list[list[ViaPoint]], mus: list[np.ndarray | None],
                    replaced: np.ndarray) -> list[np.ndarray]:
        """The stacked form of :meth:`predict_mean` for tasks with as many via-points and replaced reference
        points (``replaced``: (B, R) grid indices, as :meth:`_replaced` gives them)."""
        O, Q, N = self.n_outputs_, self.s_query_.size, self.s_ref_.size
        B = len(vias)
        alpha = np.stack([self._alpha_for(mu) for mu in mus])                                  # (B, NO, 1)
        sv = np.mod(np.array([[p.phase for p in v] for v in vias], dtype=float), 1.0)          # (B, m)
        rows = (replaced[:, :, None] * O + np.arange(O)[None, None]).reshape(B, -1)             # (B, R·O)
        cov_v = np.array([[p.cov for p in v] for v in vias], dtype=float) * self.via_mean_scale  # (B, m, O, O)
        mu_v = np.array([np.concatenate([np.asarray(p.mean, float) for p in v]) for v in vias])[:, :, None]
        pts = np.concatenate([np.broadcast_to(self.s_query_, (B, Q)), np.broadcast_to(self.s_ref_, (B, N)), sv], axis=1)
        K = _kron_eye(periodic_kernel(pts, sv, self.length_scale), O)                          # (B, (Q+N+m)O, mO)
        Kqv, C, Kvv = K[:, :Q * O], K[:, Q * O:(Q + N) * O], K[:, (Q + N) * O:]
        W = self._Ainv @ C                                                                     # (B, NO, mO)
        Ct = C.transpose(0, 2, 1)
        S = Kvv + self.lam * _blockdiag(cov_v) - Ct @ W
        self._check_batch(S)
        rhs = mu_v - Ct @ alpha
        bidx = np.arange(B)[:, None]
        if rows.shape[1] == 0:
            T = np.linalg.solve(S, rhs)
            xr, xv = alpha - W @ T, T
        else:
            W_rows = W[bidx, rows]                                                             # (B, R, mO)
            TT = np.linalg.solve(S, np.concatenate([rhs, -W_rows.transpose(0, 2, 1)], axis=2))
            T, T_e = TT[:, :, :1], TT[:, :, 1:]
            P_r = self._Ainv[:, rows].transpose(1, 0, 2) - W @ T_e                             # (B, NO, R)
            M = P_r[bidx, rows]                                                                # (B, R, R)
            self._check_batch(M)
            corr = np.linalg.solve(M, alpha[bidx, rows] - W_rows @ T)
            xr = alpha - W @ T - P_r @ corr
            xv = T - T_e @ corr
        means = (self._kq @ xr.reshape(B, N, O)) + (Kqv @ xv).reshape(B, Q, O)
        return list(means)

    def _check_batch(self, A: np.ndarray) -> None:
        """The single solve's rule on stacked small systems: positive definite, amplification within bounds."""
        try:
            L = np.linalg.cholesky(A)
        except np.linalg.LinAlgError as exc:
            raise _IllConditioned("ill-conditioned via-point update") from exc
        if max(_condition(factor) for factor in L) * self._cond_A > MAX_UPDATE_AMPLIFICATION:
            raise _IllConditioned("ill-conditioned via-point update")

    def _predict(self, vias: list[ViaPoint] | None, mu: np.ndarray | None,
                 full: bool) -> tuple[np.ndarray, np.ndarray]:
        """Mean (Q, O) and the quadratic form k*ᵀ P k*: its (Q, O, O) blocks when ``full``, else their diagonals."""
        vias = list(vias or [])
        O = self.n_outputs_
        Q = self.s_query_.size
        alpha = self._alpha_for(mu)
        if not vias:
            mean = self._mean_base.copy() if mu is None else _kron_eye_times(self._kq, alpha, O).reshape(Q, O)
            return mean, self._quad_base.copy() if full else self._quad_base_diag.copy()
        sv = np.mod(np.array([p.phase for p in vias], dtype=float), 1.0)
        J = self._replaced(sv)
        rows = (J[:, None] * O + np.arange(O)[None]).reshape(-1)
        cov_v = np.array([p.cov for p in vias], dtype=float)
        mu_v = np.concatenate([np.asarray(p.mean, float) for p in vias])[:, None]
        Kqv, C, Kvv = self._via_kernels(sv)                                              # Kqv (QO, mO)
        shared = self.lam == self.lam_c and self.via_mean_scale == 1.0
        f = self._modified(self._Ainv, C, Kvv, self.lam, cov_v * self.via_mean_scale, rows)
        f_c = f if shared else self._modified(self._Ainv_c, C, Kvv, self.lam_c, cov_v, rows)
        # k*ᵀ P k* = base + hᵀS⁻¹h per query column, h = [(Kqv − Kq A_c⁻¹C)ᵀ; −(A_c⁻¹Kqᵀ)_R]
        h_v = (Kqv - _kron_eye_times(self._kq, f_c.W, O)).T
        h_r = -self._Zc[rows]
        if shared:   # one factorisation: the mean's right-hand side r rides along as column 0 (ξ = Kqα + hᵀS⁻¹r)
            a, c = f.half(np.hstack([mu_v - C.T @ alpha, h_v]), np.hstack([-alpha[rows], h_r]))
            shift = a[:, 1:].T @ a[:, :1] if c is None else a[:, 1:].T @ a[:, :1] - c[:, 1:].T @ c[:, :1]
            base_mean = self._mean_base if mu is None else _kron_eye_times(self._kq, alpha, O).reshape(Q, O)
            mean = base_mean + shift.reshape(Q, O)
            a, c = a[:, 1:], (None if c is None else c[:, 1:])
        else:
            mean = self._mean_through(f, self._Ainv, C, Kqv, alpha, mu_v)
            a, c = f_c.half(h_v, h_r)
        if not full:
            gain = np.einsum("ij,ij->j", a, a)
            if c is not None:
                gain -= np.einsum("ij,ij->j", c, c)
            return mean, self._quad_base_diag + gain.reshape(Q, O)
        left, right = (a, a) if c is None else (np.vstack([a, c]), np.vstack([a, -c]))
        n = left.shape[0]
        return mean, self._quad_base + _blocks(left.T.reshape(Q, O, n), right.reshape(n, Q, O))

    def predict_uncached(self, vias: list[ViaPoint] | None = None,
                         mu: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Same result as :meth:`predict`, building and factorising the whole system from scratch."""
        vias = list(vias or [])
        O = self.n_outputs_
        mu_ref = self.mu_ref_ if mu is None else np.asarray(mu, dtype=float)
        keep = np.setdiff1d(np.arange(self.s_ref_.size),
                            self._replaced(np.mod(np.array([p.phase for p in vias], dtype=float), 1.0)))
        s = np.concatenate([self.s_ref_[keep], np.mod([p.phase for p in vias], 1.0)])
        mu = np.concatenate([mu_ref[keep].reshape(-1)] + [np.asarray(p.mean, float) for p in vias])
        sig = np.concatenate([self.sigma_ref_[keep]] + ([np.array([p.cov for p in vias])] if vias else []))
        K = _kron_eye(periodic_kernel(s, s, self.length_scale), O)
        S = _blockdiag(sig)
        Kq = _kron_eye(periodic_kernel(self.s_query_, s, self.length_scale), O)
        Q = self.s_query_.size
        n_v = len(vias)
        S_mean = S.copy()
        if n_v:
            S_mean[-n_v * O:, -n_v * O:] *= self.via_mean_scale
        mean = (Kq @ cho_solve(cho_factor(K + self.lam * S_mean, lower=True), mu)).reshape(Q, O)
        Z = cho_solve(cho_factor(K + self.lam_c * S, lower=True), Kq.T)
        quad = np.einsum("gqa,gqb->qab", Kq.T.reshape(-1, Q, O), Z.reshape(-1, Q, O))
        return mean, self.cov_scale_ * (np.eye(O)[None] - quad)
