"""Small numerical kernels of the harmonic balance: harmonic bases, the peak of a series,
2x2 and small dense linear algebra, Lagrange extrapolation.

The AFT basis itself is :func:`jointid.numerics.aft.aft_basis` (shared with the rig's
reduced model); here are the pieces only this solver uses: the default number of time
samples, the basis at the Gauss nodes of the Magnus steps, the product-to-sum gather of
``P diag(h) E`` and the machine-precision peak ``max_tau |q(tau)|``.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from scipy.linalg.lapack import dgesv as _dgesv

from ...conventions import harmonic_index, n_coefficients
from ...numerics.aft import aft_basis, aft_samples, basis_at


_TINY = 1e-300

# ----------------------------------------------------------------------------------------
# Harmonic bases (built lazily, cached per (H, N))
# ----------------------------------------------------------------------------------------


def default_n_time(n_harmonics: int) -> int:
    """Default number of time samples per period used by the AFT.

    A power of two (rfft-friendly) of at least ``8 (H + 1)``: exact (alias-free) for
    polynomial restoring forces up to degree 7, small aliasing for non-smooth terms.
    """
    return aft_samples(n_harmonics, 8, minimum=16)


def _readonly(a):
    a = np.ascontiguousarray(a)
    a.flags.writeable = False
    return a


#: Time basis, phase derivative and projection of the AFT (:func:`jointid.numerics.aft.aft_basis`).
_basis = aft_basis

#: Rows of the time basis at given phases (:func:`jointid.numerics.aft.basis_at`).
_basis_at = basis_at

@functools.lru_cache(maxsize=16)
def _gauss_nodes(steps):
    """Phases of the two Gauss points of each of ``steps`` equal steps over one period."""
    h = 2.0 * np.pi / steps
    mid = (np.arange(steps) + 0.5) * h
    off = h / (2.0 * math.sqrt(3.0))
    return _readonly(np.stack([mid - off, mid + off], axis=1).ravel())  # node pairs in time order


@functools.lru_cache(maxsize=32)
def _gauss_basis(n_harmonics, steps):
    """``(E.T, (E D).T)`` of the full basis at the Gauss nodes of ``steps`` steps."""
    Eg = _basis_at(_gauss_nodes(steps), n_harmonics)
    _, D, _ = _basis(n_harmonics, default_n_time(n_harmonics))
    return _readonly(Eg.T), _readonly((Eg @ D).T)


@functools.lru_cache(maxsize=64)
def _product_gather(n_harmonics: int, idx: tuple):
    """Gather indices expressing ``P diag(h) E`` (rows/columns ``idx``) by the spectrum of ``h``.

    With ``A_m = (2/N) sum h cos(m tau)`` and ``B_m = (2/N) sum h sin(m tau)``
    (``m = 0 .. 2H``) stacked as ``S = [A, B]``, the product-to-sum identities give every
    entry as ``w1 S[i1] + w2 S[i2]``; returns ``(i1, w1, i2, w2)`` of shape ``(n, n)``.
    """
    H = n_harmonics
    k_all = harmonic_index(H)
    pos = np.arange(n_coefficients(H))
    kind_all = np.where(pos == 0, 0, np.where(pos % 2 == 1, 1, 2))  # const, cos, sin
    idx = np.asarray(idx)
    k, kind = k_all[idx], kind_all[idx]
    L = 2 * H + 1
    n = idx.size
    i1 = np.zeros((n, n), int)
    i2 = np.zeros((n, n), int)
    w1 = np.zeros((n, n))
    w2 = np.zeros((n, n))
    for r in range(n):
        kr, tr = int(k[r]), int(kind[r])
        half = 0.25 if tr == 0 else 0.5  # constant row projects with 1/N, others 2/N
        for c in range(n):
            kc, tc = int(k[c]), int(kind[c])
            d, s_ = abs(kr - kc), kr + kc
            if tr in (0, 1) and tc in (0, 1):  # cos.cos
                i1[r, c], w1[r, c], i2[r, c], w2[r, c] = d, half, s_, half
            elif tr in (0, 1) and tc == 2:  # cos k . sin l = (sin(l+k) + sin(l-k)) / 2
                i1[r, c], w1[r, c] = L + s_, half
                i2[r, c], w2[r, c] = L + d, half * np.sign(kc - kr)
            elif tr == 2 and tc in (0, 1):  # sin k . cos l = (sin(k+l) + sin(k-l)) / 2
                i1[r, c], w1[r, c] = L + s_, half
                i2[r, c], w2[r, c] = L + d, half * np.sign(kr - kc)
            else:  # sin.sin = (cos(k-l) - cos(k+l)) / 2
                i1[r, c], w1[r, c], i2[r, c], w2[r, c] = d, half, s_, -half
    return i1, w1, i2, w2


#: Newton step on the peak's phase below which the peak search stops: the value carried
#: to the step's end by Taylor to third order is then exact to rounding (see
#: :meth:`_Problem.peak_batch`).
PEAK_STEP = 1e-5


def _peak(x, kh, a_idx, b_idx, const_idx, E_dense):
    """``max_tau |q(tau)|`` of a harmonic series to machine precision.

    ``x`` is the (possibly reduced) coefficient vector, ``kh`` the harmonic numbers of
    its (cosine, sine) pairs, ``a_idx``/``b_idx``/``const_idx`` the positions of the
    cosine, sine and constant entries and ``E_dense`` the time basis on a dense grid.
    The grid maximum is refined by a parabola through its neighbours, then by Newton
    on ``dq/dtau = 0`` until a step is below ``PEAK_STEP``, whose value is carried by
    Taylor as in :meth:`_Problem.peak_batch`.  Returns ``(value, tau, sign)``.
    """
    qd = E_dense @ x
    aq = np.abs(qd)
    i = int(np.argmax(aq))
    M = qd.size
    h = 2.0 * np.pi / M
    y0, y1, y2 = aq[i - 1], aq[i], aq[(i + 1) % M]
    den = y0 - 2.0 * y1 + y2
    tau0 = i * h
    tau = tau0 + (0.5 * h * (y0 - y2) / den if den < 0.0 else 0.0)
    a, b = x[a_idx], x[b_idx]
    ka, kb = kh * a, kh * b
    k2a, k2b = kh * ka, kh * kb
    # one product gives q and its first three derivatives (less the constant) from cos and sin
    Mc = np.array([kb, -k2a, -(kh * k2b), a])
    Ms = np.array([-ka, -k2b, kh * k2a, b])
    step = 0.0
    for _ in range(8):
        ph = tau * kh
        g, d2, d3, q = Mc @ np.cos(ph) + Ms @ np.sin(ph)
        step = g / d2 if d2 != 0.0 else 0.0
        if abs(step) < PEAK_STEP:
            break
        tau -= step
        if abs(tau - tau0) > h:  # left the neighbourhood of the grid maximum
            tau, step = tau0, None
            break
    if step is not None:
        q_tau = float(q - step * (g - step * (0.5 * d2 - step * d3 / 6.0))) + float(np.sum(x[const_idx]))
        tau -= step
    if step is None or abs(q_tau) < y1:  # the grid: left its neighbourhood, or never worse (a stray Newton)
        tau, q_tau = tau0, float(qd[i])
    return abs(q_tau), tau, (1.0 if q_tau >= 0 else -1.0)


# ----------------------------------------------------------------------------------------
# Small dense linear algebra
# ----------------------------------------------------------------------------------------


def _horner(c, x):
    """``sum c[i] x^i`` in the order of :func:`numpy.polynomial.polynomial.polyval`."""
    y = c[-1] + x * 0.0
    for ci in c[-2::-1]:
        y = ci + y * x
    return y


def _solve(A, b):
    """``A x = b`` for a small dense system by LAPACK ``gesv`` (without the per-call
    overhead of :func:`numpy.linalg.solve`); raises :class:`numpy.linalg.LinAlgError`
    when ``A`` is exactly singular."""
    _, _, x, info = _dgesv(A, b)
    if info != 0:
        raise np.linalg.LinAlgError(f"singular matrix (gesv info {info})")
    return x


def hill_companion(K0, C1):
    """Companion matrix ``[[0, I], [-K0, -C1]]`` of Hill's quadratic eigenproblem
    ``(lambda^2 I + lambda C1 + K0) x = 0`` (stacks of matrices too): its eigenvalues are the
    ``lambda`` and its eigenvectors ``[x, lambda x]``.  Both engines' Hill methods solve it."""
    n = K0.shape[-1]
    A = np.zeros(K0.shape[:-2] + (2 * n, 2 * n))
    A[..., :n, n:] = np.eye(n)
    A[..., n:, :n] = -K0
    A[..., n:, n:] = -C1
    return A


def _matmul2(A, B):
    """Products of stacks of 2x2 matrices (written out: ``@`` on 2x2 blocks is slower)."""
    C = np.empty(np.broadcast_shapes(A.shape, B.shape))
    C[..., 0, 0] = A[..., 0, 0] * B[..., 0, 0] + A[..., 0, 1] * B[..., 1, 0]
    C[..., 0, 1] = A[..., 0, 0] * B[..., 0, 1] + A[..., 0, 1] * B[..., 1, 1]
    C[..., 1, 0] = A[..., 1, 0] * B[..., 0, 0] + A[..., 1, 1] * B[..., 1, 0]
    C[..., 1, 1] = A[..., 1, 0] * B[..., 0, 1] + A[..., 1, 1] * B[..., 1, 1]
    return C


def _cos_sin(x, hyp):
    """``(cosh x, sinh x)`` where ``hyp``, ``(cos x, sin x)`` elsewhere (``hyp`` broadcast
    against ``x``); each function is evaluated only where it is kept."""
    C = np.empty(x.shape)
    S = np.empty(x.shape)
    for is_hyp, fc, fs in ((hyp, np.cosh, np.sinh), (~hyp, np.cos, np.sin)):
        if is_hyp.all():
            fc(x, out=C)
            fs(x, out=S)
        elif is_hyp.any():
            fc(x, out=C, where=is_hyp)
            fs(x, out=S, where=is_hyp)
    return C, S


def _expm2(o00, o01, o10, o11):
    """``exp`` of stacks of 2x2 matrices given by their entries (closed form)."""
    half = 0.5 * (o00 + o11)
    p = o00 - half
    delta = p * p + o01 * o10  # (O - half I)^2 = delta I
    r = np.sqrt(np.abs(delta))
    small = r < 1e-4
    rr = np.where(small, 1.0, r)
    C, S = _cos_sin(rr, delta >= 0)
    S /= rr
    if small.any():
        C = np.where(small, 1.0 + 0.5 * delta, C)
        S = np.where(small, 1.0 + delta / 6.0, S)
    e = np.exp(half)
    out = np.empty(o00.shape + (2, 2))
    out[..., 0, 0] = e * (C + S * p)
    out[..., 0, 1] = e * S * o01
    out[..., 1, 0] = e * S * o10
    out[..., 1, 1] = e * (C - S * p)
    return out


# ----------------------------------------------------------------------------------------
# Lagrange extrapolation (the predictors of the sweep and of the continuation)
# ----------------------------------------------------------------------------------------


def _extrapolate(wh, zh, w):
    """Lagrange extrapolation to many frequencies at once: nodes ``wh`` ``(K, n)``, solutions
    ``zh`` ``(K, n, m)`` (or one set broadcast), targets ``w`` ``(K,)``; one node, or repeated
    nodes, give the last solution."""
    n = wh.shape[1]
    eye = np.eye(n, dtype=bool)
    den = wh[:, :, None] - wh[:, None, :]  # (K, i, j): w_i - w_j
    same = np.any((den == 0.0) & ~eye, axis=(1, 2))
    with np.errstate(divide="ignore", invalid="ignore"):
        # weight i: product over j != i of (w - w_j) / (w_i - w_j)
        li = np.where(eye, 1.0, (w[:, None] - wh)[:, None, :] / den).prod(axis=2)
    out = (li[:, None, :] @ zh)[:, 0]
    if same.any():
        out[same] = np.broadcast_to(zh[:, -1], out.shape)[same]
    return out


def _extrapolate_one(wh, zh, w):
    """:func:`_extrapolate` to one target ``w`` from nodes ``wh`` and solutions ``zh``
    (sequences), with the weights in floats (a twentieth of the array calls)."""
    weights = []
    for i, wi in enumerate(wh):
        weight = 1.0
        for j, wj in enumerate(wh):
            if j != i:
                if wi == wj:
                    return np.array(zh[-1], float)
                weight *= (w - wj) / (wi - wj)
        weights.append(weight)
    return np.array(weights) @ np.array(zh)
