"""Numerically sound linear least squares for force-state mapping.

Columns are scaled to unit norm before a QR factorisation (the condition number that is
reported is the one of the scaled matrix, which is what limits accuracy), standard errors
come from ``sigma^2 (X^T X)^-1`` with ``sigma^2 = RSS / (n - p)``.

Large records are first reduced to the triangular factor ``R`` of ``[X y]``; stacking the
factors of several records gives the exact pooled least-squares problem at the cost of a
small dense solve (used by the pooled regression across records).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import linalg

__all__ = [
    "LstsqResult",
    "scaled_lstsq",
    "qr_reduce",
    "reduce_blocks",
    "lstsq_from_reduced",
    "pooled_lstsq",
    "PooledSolution",
    "pooled_solve",
]


@dataclass(frozen=True)
class LstsqResult:
    """Coefficients, standard errors, condition number and residual of a linear fit."""

    coefficients: np.ndarray
    stderr: np.ndarray
    covariance: np.ndarray
    condition_number: float
    rss: float
    n_samples: int

    @property
    def dof(self) -> int:
        return max(self.n_samples - len(self.coefficients), 1)

    @property
    def sigma(self) -> float:
        """Residual standard deviation ``sqrt(RSS / (n - p))``."""
        return float(np.sqrt(self.rss / self.dof))


def qr_reduce(X, *ys, chunk=262144) -> np.ndarray:
    """Upper-triangular ``R`` of ``[X y1 y2 ...]`` (square, ``p + len(ys)``), ``M^T M = R^T R``.

    Any residual ``y_j - X theta`` has the norm of ``R[:, y_j] - R[:, :p] theta``.
    """
    X = np.asarray(X, dtype=float)
    M = np.column_stack([X] + [np.asarray(y, float) for y in ys])
    return reduce_blocks(lambda: (M[s : s + chunk] for s in range(0, M.shape[0], chunk)), X.shape[1])


def reduce_blocks(make_blocks, p, gram=None) -> np.ndarray:
    """``R`` of a tall matrix given block by block; ``make_blocks()`` returns a fresh iterator.

    The first ``p`` columns are regressors, the others right-hand sides.  One pass
    accumulates the Gram matrix (or ``gram`` gives it, accumulated by the caller in a pass
    of its own); when its column-scaled regressor block is well conditioned (condition
    number of the matrix below 1e4) ``R`` is its Cholesky factor.  Otherwise a pass runs a
    blockwise Householder QR (a tall-skinny QR), which keeps full accuracy for
    ill-conditioned term sets.
    """
    G = gram
    if G is None:
        for B in make_blocks():
            G = B.T @ B if G is None else G + B.T @ B
    m = G.shape[0]
    scale = np.sqrt(np.diag(G)).copy()
    scale[scale == 0] = 1.0
    Gs = G / np.outer(scale, scale)
    try:
        L = linalg.cholesky(Gs[:p, :p], lower=False, check_finite=False)
        sv = linalg.svdvals(L, check_finite=False)
        ok = sv[-1] > 0 and sv[0] / sv[-1] < 1e4
    except linalg.LinAlgError:
        ok = False
    if ok:
        R = np.zeros((m, m))
        R[:p, :p] = L
        R[:p, p:] = linalg.solve_triangular(L, Gs[:p, p:], trans="T", check_finite=False)
        S = Gs[p:, p:] - R[:p, p:].T @ R[:p, p:]
        # the right-hand sides' residual Gram (positive semi-definite up to rounding)
        w, V = np.linalg.eigh(0.5 * (S + S.T))
        R[p:, p:] = linalg.qr((V * np.sqrt(np.clip(w, 0.0, None))).T, mode="r", check_finite=False)[0]
        return R * scale
    R = None
    for B in make_blocks():
        block = B / scale if R is None else np.vstack([R, B / scale])
        R = linalg.qr(block, mode="r", check_finite=False)[0][:m]
    if R.shape[0] < m:  # fewer rows than columns
        R = np.vstack([R, np.zeros((m - R.shape[0], m))])
    return R * scale


def lstsq_from_reduced(A, b, n_samples, b_noise=None) -> LstsqResult:
    """Solve ``min |A theta - b|`` where ``A, b`` are (stacks of) reduced factors.

    Parameters
    ----------
    A, b : array
        Rows of reduced factors (``R[:, :p]`` and ``R[:, p]`` of :func:`qr_reduce`), possibly
        stacked over records and weighted.
    n_samples : int
        Number of original samples (for the degrees of freedom).
    b_noise : array, optional
        A second right-hand side whose residual ``|A theta - b_noise|`` measures the noise
        for the standard errors.  Force-state mapping fits the harmonic-filtered restoring
        force but takes the noise from the unfiltered one: the filter leaves the noise
        that lies in the regressors' harmonics, which white-noise formulas must see.
    """
    A = np.asarray(A, dtype=float)
    b = np.asarray(b, dtype=float)
    scale = np.sqrt(np.sum(A**2, axis=0))
    scale[scale == 0] = 1.0
    As = A / scale
    Q, R = linalg.qr(As, mode="economic", check_finite=False)
    qtb = Q.T @ b
    p = A.shape[1]
    try:
        z = linalg.solve_triangular(R, qtb, check_finite=False)
        Rinv = linalg.solve_triangular(R, np.eye(p), check_finite=False)
    except linalg.LinAlgError:
        z = np.full(p, np.nan)
        Rinv = np.full((p, p), np.nan)
    sv = linalg.svdvals(R, check_finite=False)
    cond = float(sv[0] / sv[-1]) if sv[-1] > 0 else float("inf")
    if not np.all(np.isfinite(z)):
        rss = float("nan")
    else:
        rss = float(np.sum(((b if b_noise is None else np.asarray(b_noise, float)) - As @ z) ** 2))
    coef = z / scale
    dof = max(n_samples - p, 1)
    cov = (Rinv @ Rinv.T) * (rss / dof) / np.outer(scale, scale)
    se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    return LstsqResult(coef, se, cov, cond, rss, int(n_samples))


def scaled_lstsq(X, y) -> LstsqResult:
    """Least squares of ``X theta = y`` with scaled columns, standard errors and condition number.

    Examples
    --------
    >>> X = np.column_stack([np.arange(5.0), np.ones(5)])
    >>> r = scaled_lstsq(X, 2 * np.arange(5.0) + 1)
    >>> np.round(r.coefficients, 12).tolist()
    [2.0, 1.0]
    """
    X = np.asarray(X, dtype=float)
    R = qr_reduce(X, y)
    return lstsq_from_reduced(R[:, :-1], R[:, -1], X.shape[0])


def pooled_lstsq(reduced, shared, own, rhs, noise=None, weighting="noise"):
    """Pooled least squares over records: shared columns common to all, ``own`` columns per record.

    Parameters
    ----------
    reduced : list of (R, n)
        Each record's reduced factor (:func:`reduce_blocks`) and its number of samples.
    shared, own : sequence of int
        Columns of ``R`` whose coefficients are common to all records / one per record.
    rhs : int
        Column of the right-hand side.
    noise : int, optional
        Column of the right-hand side whose residual measures the noise (see
        :func:`lstsq_from_reduced`); ``rhs`` itself by default.
    weighting : {"noise", "none"}
        ``"noise"`` weights each record by the inverse residual standard deviation of its
        own fit (on all of its columns), so records measured with different noise levels
        count by their information.

    Returns
    -------
    result : LstsqResult
        Coefficients ordered ``shared``, then ``own`` of record 0, record 1, ...
    weights : ndarray
        The weight of each record.
    """
    shared, own = list(shared), list(own)
    ns, no, nr = len(shared), len(own), len(reduced)
    p = ns + no * nr
    noise = rhs if noise is None else noise
    blocks, weights, n_total = [], [], 0
    for r, (R, n) in enumerate(reduced):
        n_total += n
        w = 1.0
        if weighting == "noise":
            single = lstsq_from_reduced(R[:, shared + own], R[:, rhs], n, R[:, noise])
            floor = 1e-13 * float(np.abs(R[:, rhs]).max()) / np.sqrt(n)
            w = 1.0 / max(single.sigma, floor, np.finfo(float).tiny)
        block = np.zeros((R.shape[0], p + 2))
        block[:, :ns] = R[:, shared]
        block[:, ns + r * no : ns + (r + 1) * no] = R[:, own]
        block[:, p] = R[:, rhs]
        block[:, p + 1] = R[:, noise]
        blocks.append(w * block)
        weights.append(w)
    B = np.vstack(blocks)
    return lstsq_from_reduced(B[:, :p], B[:, p], n_total, B[:, p + 1]), np.array(weights)


@dataclass(frozen=True)
class PooledSolution:
    """Pooled least squares with per-record columns eliminated record by record.

    Each record's own coefficients are ``own[r] = a_r - K[r] @ shared``; the shared
    coefficients solve the Schur-complement problem (normal matrix ``schur``).  Nothing of
    size ``n_records^2`` is ever formed.

    Attributes
    ----------
    shared : array ``(ns,)``
    own : array ``(n_records, no)``
    K : array ``(n_records, no, ns)``
        ``M_oo^-1 M_os`` of each record (unweighted Gram blocks).
    own_gram_inv : array ``(n_records, no, no)``
        ``M_oo^-1`` of each record.
    schur : array ``(ns, ns)``
        ``sum_r w_r^2 (M_ss - M_so M_oo^-1 M_os)``.
    weights : array ``(n_records,)``
    condition_number : float
        Of the column-scaled Schur-complement problem (the shared coefficients).
    n_samples : int
    """

    shared: np.ndarray
    own: np.ndarray
    K: np.ndarray
    own_gram_inv: np.ndarray
    schur: np.ndarray
    weights: np.ndarray
    condition_number: float
    n_samples: int


def pooled_solve(reduced, shared, own, rhs, weights) -> PooledSolution:
    """Pooled least squares over records with block-wise elimination of the per-record columns.

    Parameters
    ----------
    reduced : list of (R, n)
        Each record's reduced factor (:func:`reduce_blocks`) and number of samples.
    shared, own : sequence of int
        Columns of ``R`` common to all records / one coefficient per record.
    rhs : int
        Column of the right-hand side.
    weights : array
        Weight of each record (its rows are multiplied by it).

    Notes
    -----
    For each record an orthogonal transformation (QR of its own columns) splits its rows
    into the part that determines its own coefficients and the part orthogonal to them;
    the latter, stacked over the records, is the shared problem, solved by
    :func:`lstsq_from_reduced`.  Memory grows linearly with the number of records.
    """
    shared, own = list(shared), list(own)
    ns, no, nr = len(shared), len(own), len(reduced)
    weights = np.asarray(weights, float)
    rows, tops, Ks, Minv, n_total = [], [], np.zeros((nr, no, ns)), np.zeros((nr, no, no)), 0
    for r, (R, n) in enumerate(reduced):
        n_total += n
        Sy = R[:, shared + [rhs]]
        if no:
            O = R[:, own]
            scale = np.sqrt(np.sum(O**2, axis=0))
            scale[scale == 0] = 1.0
            Qo, Ro = linalg.qr(O / scale, mode="full", check_finite=False)
            T = Qo.T @ Sy
            Ro = Ro[:no] * scale  # upper triangular, O = Qo[:, :no] Ro
            Roi = linalg.solve_triangular(Ro, np.eye(no), check_finite=False)
            Ks[r] = Roi @ T[:no, :ns]
            tops.append(Roi @ T[:no, ns])
            Minv[r] = Roi @ Roi.T
            rows.append(weights[r] * T[no:])
        else:
            tops.append(np.zeros(0))
            rows.append(weights[r] * Sy)
    if ns:
        Bs = np.vstack(rows)
        res = lstsq_from_reduced(Bs[:, :ns], Bs[:, ns], n_total)
        theta_s, cond = res.coefficients, res.condition_number
        schur = Bs[:, :ns].T @ Bs[:, :ns]
    else:
        theta_s, cond, schur = np.zeros(0), 1.0, np.zeros((0, 0))
    own_coef = np.array([a - Ks[r] @ theta_s for r, a in enumerate(tops)]).reshape(nr, no)
    return PooledSolution(theta_s, own_coef, Ks, Minv, schur, weights, float(cond), int(n_total))
