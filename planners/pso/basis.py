"""The feed's B-spline basis over normalised time τ ∈ [0, 1]: dense arrays, or sparse ones for a
piece over the size bound (BASIS_MAX_ELEMENTS)."""
from __future__ import annotations

import numpy as np
from scipy import sparse as sp
from scipy.interpolate import BSpline
from scipy.linalg import LinAlgError, solveh_banded

from .tuning import DEGREE


def sparse_basis(knots, p, tau):
    """CSR design matrices at τ of the degree-p B-splines on ``knots`` (M, K), of their first
    and second derivatives, and of the antiderivative (M, K + 1, degree p + 1 on the knots with
    one more at each end), with the weights wₖ = ∫₀¹Bₖ = (t_{k+p+1} − t_k)/(p + 1): the
    antiderivative of Σcₖ Bₖ has the coefficients 0, w₀c₀, w₀c₀ + w₁c₁, …  Each row holds at
    most p + 2 nonzeros, so memory grows with M + K, not M·K as the dense arrays do."""
    K = len(knots) - p - 1

    def diff(t, q, n):
        # (n − 1, n): coefficients of the derivative of a degree-q spline on t (knots t[1:−1])
        h = t[q + 1:n + q] - t[1:n]
        g = np.where(h > 0, q / np.where(h > 0, h, 1.0), 0.0)
        return sp.diags([-g, g], [0, 1], shape=(n - 1, n), format="csr")

    d1 = diff(knots, p, K)
    B = BSpline.design_matrix(tau, knots, p)
    B1 = BSpline.design_matrix(tau, knots[1:-1], p - 1) @ d1
    B2 = BSpline.design_matrix(tau, knots[2:-2], p - 2) @ (diff(knots[1:-1], p - 1, K - 1) @ d1)
    A = BSpline.design_matrix(tau, np.concatenate([knots[:1], knots, knots[-1:]]), p + 1)
    w = (knots[p + 1:] - knots[:K]) / (p + 1)
    return B.tocsr(), B1.tocsr(), B2.tocsr(), A.tocsr(), w


class Shape:
    """B-spline basis over τ ∈ [0, 1] sampled at M points (and its antiderivative)."""

    def __init__(self, K: int, M: int, density=None, degree: int = DEGREE, inner=None,
                 sparse: bool = False):
        """``density``: (τ grid, weights) — knots and samples at its quantiles (uniform if
        None); ``inner``: explicit knots in [0, 1] (then K follows from them); ``sparse``: the
        basis as CSR matrices (see `sparse_basis`), for a piece over BASIS_MAX_ELEMENTS."""
        self.degree = p = degree
        if inner is not None:
            if density is not None and K > 0:      # add K knots at the density's quantiles
                g, wts = density
                cum = np.concatenate([[0.0], np.cumsum(0.5 * (wts[1:] + wts[:-1]) * np.diff(g))])
                inner = np.concatenate([inner, np.interp(np.linspace(0, 1, K + 2)[1:-1], cum / cum[-1], g)])
            inner = np.unique(np.concatenate([[0.0], np.clip(inner, 0, 1), [1.0]]))
            inner = inner[np.concatenate([[True], np.diff(inner) > 1e-9])]
            K = len(inner) + p - 1
            mids = 0.5 * (inner[1:] + inner[:-1])
            self.tau = np.unique(np.concatenate([np.linspace(0, 1, M), inner, mids]))
        self.K, self.M = K, M
        if inner is not None:
            pass
        elif density is None:
            inner, self.tau = np.linspace(0, 1, K - 2), np.linspace(0, 1, M)
        else:
            g, wts = density
            cum = np.concatenate([[0.0], np.cumsum(0.5 * (wts[1:] + wts[:-1]) * np.diff(g))])
            cum /= cum[-1]
            inner = np.interp(np.linspace(0, 1, K - 2), cum, g)
            inner[0], inner[-1] = 0.0, 1.0
            self.tau = np.unique(np.concatenate([np.interp(np.linspace(0, 1, M // 2), cum, g),
                                                 np.linspace(0, 1, M - M // 2)]))
        if len(inner) != K - p + 1:
            inner = np.interp(np.linspace(0, 1, K - p + 1), np.linspace(0, 1, len(inner)), inner)
        self.knots = np.concatenate([[0] * p, inner, [1] * p])
        self.free = np.arange(2, K - 2)
        self.sparse = sparse
        if sparse:
            self.B, self.B1, self.B2, self.A, self.w = sparse_basis(self.knots, p, self.tau)
            return
        eye = np.eye(K)
        basis = [BSpline(self.knots, eye[k], self.degree) for k in range(K)]
        self.B = np.stack([b(self.tau) for b in basis], 1)               # (M, K)
        self.B1 = np.stack([b.derivative(1)(self.tau) for b in basis], 1)
        self.B2 = np.stack([b.derivative(2)(self.tau) for b in basis], 1)
        anti = [b.antiderivative(1) for b in basis]
        self.I = np.stack([a(self.tau) - a(0.0) for a in anti], 1)        # ∫₀^τ Bₖ

    def full(self, X):
        """Control points (P, K) from free coefficients (P, K−4), ends pinned at rest."""
        C = np.zeros((X.shape[0], self.K))
        C[:, self.free] = np.maximum(X, 0.0)
        return C

    def eval(self, C):
        """(∫₀¹ṡ dτ (P,), ∫₀^τ ṡ, ṡ, ṡ′, ṡ″ (P, M) each) of control points C (P, K)."""
        if not self.sparse:
            return C @ self.I[-1], C @ self.I.T, C @ self.B.T, C @ self.B1.T, C @ self.B2.T
        # the antiderivative's coefficients: running sums of wₖcₖ from 0 (see sparse_basis)
        anti = np.concatenate([np.zeros((C.shape[0], 1)), np.cumsum(C * self.w, axis=1)], axis=1)
        return (C @ self.w, (self.A @ anti.T).T, (self.B @ C.T).T, (self.B1 @ C.T).T,
                (self.B2 @ C.T).T)

    def fit(self, tau, v):
        """Least-squares free coefficients of a sampled feed v(τ)."""
        if self.sparse:
            # normal equations of a B-spline basis are banded (half-bandwidth = degree): a
            # banded Cholesky solve, O(samples + K) memory where lstsq needs samples × K
            B = BSpline.design_matrix(tau, self.knots, self.degree).tocsc()[:, self.free]
            N, rhs, p = (B.T @ B).todia(), B.T @ v, self.degree
            ab = np.zeros((p + 1, len(self.free)))
            for d in range(p + 1):
                ab[p - d, d:] = N.diagonal(d)
            try:
                x = solveh_banded(ab, rhs)
            except LinAlgError:
                # a span without samples (seed switch times closer than its sampling) leaves
                # the fit singular there; a tiny ridge picks the small-norm coefficients
                ab[p] += 1e-12 * ab[p].max()
                x = solveh_banded(ab, rhs)
            return np.maximum(x, 1e-6 * max(v.max(), 1e-9))
        eye = np.eye(self.K)
        B = np.stack([BSpline(self.knots, eye[k], self.degree)(tau) for k in range(self.K)], 1)
        x, *_ = np.linalg.lstsq(B[:, self.free], v, rcond=None)
        return np.maximum(x, 1e-6 * max(v.max(), 1e-9))

