"""Harmonic bases of the alternating frequency/time (AFT) method.

A real periodic signal of phase ``tau = omega t`` is written in the coefficient order of
:mod:`jointid.conventions`, ``[a0, a1, b1, ..., aH, bH]``:

    ``q(tau) = a0 + sum_k (a_k cos(k tau) + b_k sin(k tau))``

sampled at ``N`` equispaced phases ``tau_i = 2 pi i / N`` of one period.  With the time
basis ``E`` (rows: samples) the samples are ``E @ x``; the projection ``P`` (the discrete
Fourier coefficients, ``2/N`` for the harmonics and ``1/N`` for the constant) gives them
back, ``P @ (E @ x) = x`` whenever ``N > 2 H``; ``D`` is ``d/dtau`` on coefficient vectors.

Examples
--------
>>> E, D, P = aft_basis(2, 8)
>>> x = np.array([0.5, 1.0, -2.0, 0.25, 3.0])
>>> bool(np.allclose(P @ (E @ x), x))
True
"""

from __future__ import annotations

import functools

import numpy as np

from ..conventions import n_coefficients

__all__ = ["aft_basis", "aft_samples", "basis_at", "resize_harmonics", "to_complex", "to_real"]


def _readonly(a):
    a = np.ascontiguousarray(a)
    a.flags.writeable = False
    return a


@functools.lru_cache(maxsize=64)
def aft_basis(n_harmonics: int, n_time: int, projection_order: str = "C"):
    """Time basis ``E`` (N, n), derivative ``D`` (n, n) and projection ``P`` (n, N).

    ``n = 2 H + 1``.  The arrays are read-only and cached per arguments.  ``E`` and ``D``
    are C-contiguous; ``P`` is C-contiguous (``projection_order="C"``, for ``P @ g``) or
    F-contiguous (``"F"``: ``P.T`` is C-contiguous, for ``g @ P.T``).  The values are the
    same; the memory order decides which BLAS kernel a product uses, and so the last bit
    of its rounding.
    """
    if projection_order not in ("C", "F"):
        raise ValueError(f"projection_order: expected 'C' or 'F', got {projection_order!r}")
    H, N = n_harmonics, n_time
    n = n_coefficients(H)
    tau = 2.0 * np.pi * np.arange(N) / N
    kt = np.outer(tau, np.arange(1, H + 1))
    E = np.empty((N, n))
    E[:, 0] = 1.0
    E[:, 1::2] = np.cos(kt)
    E[:, 2::2] = np.sin(kt)
    D = np.zeros((n, n))
    j = np.arange(1, H + 1)
    D[2 * j - 1, 2 * j] = j  # d/dtau (b sin) -> b k cos
    D[2 * j, 2 * j - 1] = -j  # d/dtau (a cos) -> -a k sin
    P = E.T * (2.0 / N)
    P[0] *= 0.5
    if projection_order == "F":
        P = np.asfortranarray(P)
        P.flags.writeable = False
        return _readonly(E), _readonly(D), P
    return _readonly(E), _readonly(D), _readonly(P)


def basis_at(tau, n_harmonics):
    """Rows of the time basis at phases ``tau`` (array) -> (len(tau), n)."""
    tau = np.atleast_1d(np.asarray(tau, float))
    kt = np.multiply.outer(tau, np.arange(1, n_harmonics + 1))
    out = np.empty(tau.shape + (n_coefficients(n_harmonics),))
    out[..., 0] = 1.0
    out[..., 1::2] = np.cos(kt)
    out[..., 2::2] = np.sin(kt)
    return out


def aft_samples(n_harmonics: int, per_harmonic: int, minimum: int = 1) -> int:
    """Time samples per period of an AFT: the power of two at or above
    ``max(per_harmonic (H + 1), minimum)`` (a power of two suits the FFT).

    Each harmonic-balance solver states its own oversampling (see its ``default_n_time``).

    >>> aft_samples(9, 8), aft_samples(9, 4)
    (128, 64)
    """
    m = max(int(per_harmonic) * (int(n_harmonics) + 1), int(minimum), 1)
    return 1 << (m - 1).bit_length()


def resize_harmonics(c, n_harmonics: int) -> np.ndarray:
    """Coefficient vectors ``(..., m)`` cut or padded with zeros to ``(..., 2H + 1)`` (a new array).

    >>> resize_harmonics([1.0, 2.0, 3.0], 2).tolist(), resize_harmonics([1.0, 2.0, 3.0], 0).tolist()
    ([1.0, 2.0, 3.0, 0.0, 0.0], [1.0])
    """
    c = np.asarray(c, float)
    n = n_coefficients(n_harmonics)
    out = np.zeros(c.shape[:-1] + (n,))
    m = min(n, c.shape[-1])
    out[..., :m] = c[..., :m]
    return out


def to_complex(c):
    """Real coefficient vectors ``(..., 2H+1)`` -> complex amplitudes ``(..., H+1)``, ``X_k = a_k - i b_k``
    (so that ``x(t) = Re sum_k X_k exp(i k omega t)``)."""
    c = np.asarray(c, float)
    out = np.empty(c.shape[:-1] + ((c.shape[-1] + 1) // 2,), complex)
    out[..., 0] = c[..., 0]
    out[..., 1:] = c[..., 1::2] - 1j * c[..., 2::2]
    return out


def to_real(X):
    """Inverse of :func:`to_complex`."""
    X = np.asarray(X)
    out = np.empty(X.shape[:-1] + (2 * X.shape[-1] - 1,))
    out[..., 0] = X[..., 0].real
    out[..., 1::2] = X[..., 1:].real
    out[..., 2::2] = -X[..., 1:].imag
    return out
