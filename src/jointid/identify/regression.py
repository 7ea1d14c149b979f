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

__all__ = ["LstsqResult", "scaled_lstsq", "qr_reduce", "lstsq_from_reduced"]


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


def qr_reduce(X, y, chunk=262144) -> np.ndarray:
    """Upper-triangular ``R`` (``p+1`` square) of ``[X y]`` such that ``[X y]^T [X y] = R^T R``.

    Long matrices are reduced chunk by chunk (a tall-skinny QR), so memory stays bounded.
    """
    X = np.asarray(X, dtype=float)
    y = np.asarray(y, dtype=float)
    n, p = X.shape
    R = None
    for start in range(0, n, chunk):
        block = np.column_stack([X[start : start + chunk], y[start : start + chunk]])
        if R is not None:
            block = np.vstack([R, block])
        R = linalg.qr(block, mode="r", check_finite=False)[0][: p + 1]
    if R.shape[0] < p + 1:  # fewer rows than columns
        R = np.vstack([R, np.zeros((p + 1 - R.shape[0], p + 1))])
    return R


def lstsq_from_reduced(R_aug, n_samples) -> LstsqResult:
    """Solve the least-squares problem whose augmented factor is ``R_aug = [R_X | r_y]``.

    ``R_aug`` may be any stack of rows (several records' factors, weighted) with the
    right-hand side in the last column.
    """
    R_aug = np.asarray(R_aug, dtype=float)
    A = R_aug[:, :-1]
    b = R_aug[:, -1]
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
    rss = float(np.sum((b - As @ z) ** 2)) if np.all(np.isfinite(z)) else float("nan")
    coef = z / scale
    dof = max(n_samples - p, 1)
    cov_s = (Rinv @ Rinv.T) * (rss / dof)
    cov = cov_s / np.outer(scale, scale)
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
    return lstsq_from_reduced(qr_reduce(X, y), X.shape[0])
