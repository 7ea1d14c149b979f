"""Harmonic balance (alternating frequency/time) for the single-mode model.

Solves the periodic steady state of

    ``q'' + h(q, q'; theta) = F sin(omega t)``

where ``h`` is the model's term library and ``theta`` its coefficients (seed paper
Eq 19).  The unknown is the harmonic coefficient vector of ``q`` in the convention of
:mod:`jointid.conventions` (``[a0, a1, b1, ..., aH, bH]``).  The restoring force is
evaluated in time on an equispaced grid of one period and projected back on the
harmonics (AFT); the Jacobian is built analytically from the terms' partial
derivatives (the values of :meth:`jointid.identify.terms.TermLibrary.derivatives`; each
term's ``dq``/``dv`` is called directly to avoid per-call overhead) through the same
transforms.  For odd libraries only odd harmonics are solved for.

Amplitude closure
    When the model has amplitude laws (seed Eq 20) the coefficients of a steady state
    are ``model.coefficients_at(q_max)`` with ``q_max = max_t |q(t)|`` of that same
    steady state.  ``q_max`` is then an extra unknown with the extra equation
    ``q_max - max_t |q(t)| = 0``; the maximum is found to machine precision (dense grid
    then Newton on ``dq/dt = 0``) and, by the envelope theorem, its derivative with
    respect to the coefficients is ``sign(q(t*)) * basis(t*)``.

Public functions
    :func:`steady_state` (one frequency), :func:`frequency_response` (a sequential
    sweep at given frequencies, or pseudo-arclength continuation over a range with fold
    detection), :func:`linear_frf` (the linear part's receptance, for "linear vs
    nonlinear" plots as in the seed's Fig 4).

Examples
--------
>>> from jointid.simulate.model import seed_model
>>> s = steady_state(seed_model(), 169.5, 1.0)
>>> round(s.q_max * 1e3, 4)
6.333
>>> bool(s.stable)
True
"""

from __future__ import annotations

import functools
import math
import warnings
from dataclasses import dataclass

import numpy as np
from scipy import optimize
from scipy.linalg.lapack import dgesv as _dgesv

from .._blas import single_threaded
from ..conventions import harmonic_index, n_coefficients
from ..errors import ConvergenceError, ConvergenceWarning, RecordError
from ..identify.terms import STANDARD_TERMS
from .model import SingleModeModel

__all__ = [
    "SteadyState",
    "FrequencyResponse",
    "steady_state",
    "frequency_response",
    "linear_frf",
    "default_n_time",
]

_TINY = 1e-300


# ----------------------------------------------------------------------------------------
# Harmonic bases (built lazily, cached per (H, N))
# ----------------------------------------------------------------------------------------


def default_n_time(n_harmonics: int) -> int:
    """Default number of time samples per period used by the AFT.

    A power of two (rfft-friendly) of at least ``8 (H + 1)``: exact (alias-free) for
    polynomial restoring forces up to degree 7, small aliasing for non-smooth terms.
    """
    return int(2 ** math.ceil(math.log2(max(8 * (n_harmonics + 1), 16))))


def _readonly(a):
    a = np.ascontiguousarray(a)
    a.flags.writeable = False
    return a


@functools.lru_cache(maxsize=64)
def _basis(n_harmonics: int, n_time: int):
    """Time basis ``E`` (N, n), derivative ``D`` (n, n) and projection ``P`` (n, N)."""
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
    return _readonly(E), _readonly(D), _readonly(P)


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


def _basis_at(tau, n_harmonics):
    """Rows of the time basis at phases ``tau`` (array) -> (len(tau), n)."""
    tau = np.atleast_1d(np.asarray(tau, float))
    kt = np.multiply.outer(tau, np.arange(1, n_harmonics + 1))
    out = np.empty(tau.shape + (n_coefficients(n_harmonics),))
    out[..., 0] = 1.0
    out[..., 1::2] = np.cos(kt)
    out[..., 2::2] = np.sin(kt)
    return out


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
# Problem context: everything that does not change with omega
# ----------------------------------------------------------------------------------------


class _Problem:
    """AFT residual/Jacobian of one model, force level and harmonic truncation.

    The unknown ``z`` is the coefficient vector restricted to the active harmonics
    (odd harmonics only for odd libraries) followed by ``q_max`` when the amplitude
    closure is active.
    """

    def __init__(self, model, force_amplitude, n_harmonics, n_time=None, odd=None):
        if not isinstance(model, SingleModeModel):
            raise TypeError(f"model must be a SingleModeModel, got {type(model).__name__}")
        H = int(n_harmonics)
        if H < 1:
            raise RecordError(f"n_harmonics must be >= 1, got {n_harmonics!r}")
        F = float(force_amplitude)
        if not np.isfinite(F):
            raise RecordError(f"force_amplitude must be finite, got {force_amplitude!r}")
        N = default_n_time(H) if n_time is None else int(n_time)
        if N < 2 * H + 2:
            raise RecordError(f"n_time must be > 2 n_harmonics + 1 = {2 * H + 1}, got {N}")
        self.model = model
        self.lib = model.terms
        self.F = F
        self.H = H
        self.N = N
        self.n = n_coefficients(H)
        self.closure = model.depends_on_amplitude
        self.odd = self.lib.odd if odd is None else bool(odd)
        kfull = harmonic_index(H)
        active = (kfull % 2 == 1) if self.odd else np.ones(self.n, bool)
        self.active = np.flatnonzero(active)
        self.k = kfull[self.active]
        E, D, P = _basis(H, N)
        self.E_full, self.D_full, self.P_full = E, D, P
        self.ED_full = E @ D
        self.E = np.ascontiguousarray(E[:, self.active])
        self.ED = np.ascontiguousarray(self.ED_full[:, self.active])
        self.P = np.ascontiguousarray(P[self.active])
        self.k2 = self.k.astype(float) ** 2
        self.m = self.active.size + (1 if self.closure else 0)
        # positions (in the reduced vector) of cosine / sine entries with k >= 1
        pos = np.arange(self.active.size)
        full_pos = self.active
        self.a_idx = pos[(full_pos % 2 == 1)]
        self.b_idx = pos[(full_pos % 2 == 0) & (full_pos > 0)]
        self.const_idx = pos[full_pos == 0]
        self.kh = self.k[self.a_idx].astype(float)  # harmonic number of each (a, b) pair
        # rows of dq/dtau, d2q/dtau2, d3q/dtau3 and q against c_k e^(i k tau), c_k = a_k - i b_k (peak_batch)
        self.peak_rows = np.array([1j * self.kh, -(self.kh**2), -1j * self.kh**3, np.ones_like(self.kh)])
        M = max(2 * N, 256)
        self.E_dense = np.ascontiguousarray(_basis_at(2 * np.pi * np.arange(M) / M, H)[:, self.active])
        fvec = np.zeros(self.active.size)
        fvec[pos[full_pos == 2]] = F  # b1
        self.f = fvec
        self.theta0 = np.array(model.coefficients, float)
        # derivative polynomials of the amplitude laws (d theta_j / d q_max)
        P_ = np.polynomial.polynomial
        poly_laws = {name: law for name, law in model.amplitude_laws.items() if isinstance(law, tuple)}
        # laws that are no polynomial (the micro-slip power law) are objects with value / derivative
        self.law_objects = tuple(
            (self.lib.index(name), law) for name, law in model.amplitude_laws.items() if name not in poly_laws
        )
        self.law_der = tuple(
            (self.lib.index(name), P_.polyder(np.asarray(poly, float))) for name, poly in poly_laws.items()
        )
        # terms with analytic partial derivatives are called directly (same values as
        # TermLibrary.derivatives, without its per-call broadcasting overhead)
        self.fast_terms = tuple((j, t.func, t.dq, t.dv) for j, t in enumerate(self.lib.terms))
        # odd harmonic symmetry splits Hill's matrix into odd / even harmonic blocks
        kfull_ = harmonic_index(H)
        self.hill_blocks = (
            (np.flatnonzero(kfull_ % 2 == 1), np.flatnonzero(kfull_ % 2 == 0)) if self.odd else (np.arange(self.n),)
        )
        names = self.lib.names
        self.i_q = names.index("q") if "q" in names else None
        self.i_v = names.index("q'") if "q'" in names else None
        # the standard linear terms have constant partial derivatives (1 and 0), and a
        # stiffness term does not depend on the velocity: such parts need no arrays
        q_lin, v_lin = STANDARD_TERMS["q"], STANDARD_TERMS["q'"]
        self.lin_q = tuple(j for j, t in enumerate(self.lib.terms) if t is q_lin)
        self.lin_v = tuple(j for j, t in enumerate(self.lib.terms) if t is v_lin)
        self.nl_terms = tuple(
            (j, t.dq, t.dv, t.kind == "stiffness")
            for j, t in enumerate(self.lib.terms)
            if t is not q_lin and t is not v_lin
        )
        self.PED = self.P @ self.ED
        self.kq = abs(float(self.theta0[self.i_q])) if self.i_q is not None else 0.0
        self.D_active = np.ascontiguousarray(D[np.ix_(self.active, self.active)])
        self.eye = np.eye(self.active.size)
        self.laws = tuple((self.lib.index(name), tuple(float(c) for c in poly)) for name, poly in poly_laws.items())
        self.law_der = tuple((j, tuple(float(c) for c in d)) for j, d in self.law_der)
        self.E_ED = np.vstack([self.E, self.ED])  # P diag(c) ED for a constant c (viscous damping)
        # terms whose coefficient is zero at every amplitude (no law, zero value): skipped
        with_law = {j for j, _ in self.laws} | {j for j, _ in self.law_objects}
        self.zero_terms = frozenset(j for j in range(len(self.lib)) if j not in with_law and self.theta0[j] == 0.0)
        self._last_failure = ""

    # -- small helpers ---------------------------------------------------------------

    def coefficients_at(self, q_max):
        """``model.coefficients_at(q_max)`` (the same Horner sums, without array overhead)."""
        theta = self.theta0.copy()
        for j, poly in self.laws:
            theta[j] = _horner(poly, float(q_max))
        for j, law in self.law_objects:
            theta[j] = law.value(float(q_max))
        return theta

    def full(self, x):
        out = np.zeros(self.n)
        out[self.active] = x
        return out

    def reduce(self, coefficients):
        c = np.asarray(coefficients, float)
        full = np.zeros(self.n)
        m = min(c.size, self.n)
        full[:m] = c[:m]
        return full[self.active]

    def peak(self, x):
        return _peak(x, self.kh, self.a_idx, self.b_idx, self.const_idx, self.E_dense)

    def peak_row(self, tau):
        row = np.zeros(self.active.size)
        row[self.a_idx] = np.cos(self.kh * tau)
        row[self.b_idx] = np.sin(self.kh * tau)
        row[self.const_idx] = 1.0
        return row

    # -- residual and Jacobian -------------------------------------------------------

    def _forces(self, q, v, theta):
        """``h`` at the time samples."""
        h = None
        for j, func, _, _ in self.fast_terms:
            c = theta[j]
            if c != 0.0:
                if h is None:
                    h = c * func(q, v)
                else:
                    h += c * func(q, v)
        return np.zeros_like(q) if h is None else h

    def _derivatives(self, q, v, theta):
        """``(dh/dq, dh/dv)`` at the time samples (as TermLibrary.derivatives).

        ``theta`` is one coefficient vector ``(p,)``, or one per row ``(K, p)`` of states
        ``(K, n)``.  A part that is constant in time (linear terms only) comes back as a
        float, or a column ``(K, 1)`` per row.
        """
        rows = theta.ndim == 2
        if rows:
            def coef(j):
                return theta[:, j : j + 1]
            gq = gv = np.zeros((theta.shape[0], 1))
        else:
            coef = theta.item
            gq = gv = 0.0
        for j in self.lin_q:
            gq = gq + coef(j)
        for j in self.lin_v:
            gv = gv + coef(j)
        for j, dq, dv, stiffness in self.nl_terms:
            if j in self.zero_terms:
                continue
            c = coef(j)
            if not rows and c == 0.0:
                continue
            if dq is not None and (dv is not None or stiffness):
                gq = gq + c * dq(q, v)
                if not stiffness:
                    gv = gv + c * dv(q, v)
            else:
                a, b = self.lib.terms[j].derivatives(q, v)
                gq = gq + c * a
                gv = gv + c * b
        return gq, gv

    def evaluate(self, z, omega, jacobian=True, domega=False):
        """Residual ``R(z)`` and (optionally) ``dR/dz`` and ``dR/domega``.

        Returns a dict with ``R``, ``err`` (scaled residual norm), ``q``, ``v``,
        ``theta``, ``peak`` and, when asked, ``J`` and ``Jw`` (see :meth:`jacobian`).
        """
        nx = self.active.size
        x = z[:nx]
        theta = self.coefficients_at(z[nx]) if self.closure else self.theta0
        qd = self.E_ED @ x
        q, dv = qd[: self.N], qd[self.N :]
        v = omega * dv
        h = self._forces(q, v, theta)
        R = np.empty(self.m)
        R[:nx] = self.P @ h - (omega * omega) * self.k2 * x - self.f
        peak = None
        if self.closure:
            peak = self.peak(x)
            R[nx] = z[nx] - peak[0]
        xn = math.sqrt(float(x @ x))
        r = R[:nx]
        err = math.sqrt(float(r @ r)) / max(abs(self.F), (omega * omega + self.kq) * xn, _TINY)
        if self.closure:
            err = max(err, abs(R[nx]) / max(xn, _TINY))
        if not math.isfinite(err):
            err = np.inf
        ev = {"z": z, "omega": omega, "q": q, "v": v, "dv": dv, "theta": theta, "R": R, "err": err,
              "peak": peak, "J": None, "Jw": None}
        if jacobian or domega:
            self.jacobian(ev, domega)
        return ev

    def jacobian(self, ev, domega=False):
        """Add ``J = dR/dz`` (and ``Jw = dR/domega``) to an evaluation ``ev``."""
        nx = self.active.size
        z, omega, q, v, theta = ev["z"], ev["omega"], ev["q"], ev["v"], ev["theta"]
        hq, hv = self._derivatives(q, v, theta)
        J = np.empty((self.m, self.m))
        q_arr, v_arr = isinstance(hq, np.ndarray), isinstance(hv, np.ndarray)
        Jx = J[:nx, :nx]
        if q_arr:
            np.matmul(self.P, hq[:, None] * self.E, out=Jx)
        else:
            Jx[...] = 0.0
            J.ravel()[: nx * (self.m + 1) : self.m + 1] = hq  # P E = I
        if v_arr:
            Jx += self.P @ ((omega * hv)[:, None] * self.ED)
        else:
            Jx += (omega * hv) * self.PED
        J.ravel()[: nx * (self.m + 1) : self.m + 1] -= omega * omega * self.k2
        if self.closure:
            qm = z[nx]
            dh = np.zeros_like(q)
            for j, dpoly in self.law_der:
                d = _horner(dpoly, qm)
                if d != 0.0:
                    dh += d * self.lib.terms[j].func(q, v)
            for j, law in self.law_objects:
                dh += law.derivative(qm) * self.lib.terms[j].func(q, v)
            J[:nx, nx] = self.P @ dh
            peak = ev["peak"]
            J[nx, :nx] = -peak[2] * self.peak_row(peak[1])
            J[nx, nx] = 1.0
        ev["J"] = J
        if domega:
            Jw = np.zeros(self.m)
            Jw[:nx] = (self.P @ (hv * ev["dv"]) if v_arr else hv * (self.PED @ z[:nx])) - (
                2.0 * omega * self.k2 * z[:nx]
            )
            ev["Jw"] = Jw
        return ev

    # -- Newton at fixed frequency ---------------------------------------------------

    def newton(self, z0, omega, tol=1e-12, max_iter=40):
        """Damped Newton; returns ``(z, evaluation, iterations)`` or raises.

        Trial points are evaluated without Jacobian; it is built only for points that
        are accepted and not yet converged.
        """
        z = np.array(z0, float)
        ev = self.evaluate(z, omega, jacobian=False)
        it = 0
        while ev["err"] > tol:
            if it >= max_iter:
                raise ConvergenceError(self._fail_msg(omega, ev["err"], it, tol, "iteration limit reached"))
            it += 1
            if ev["J"] is None:
                self.jacobian(ev)
            try:
                step = _solve(ev["J"], -ev["R"])
            except np.linalg.LinAlgError:
                raise ConvergenceError(self._fail_msg(omega, ev["err"], it, tol, "singular Jacobian")) from None
            if not np.all(np.isfinite(step)):
                raise ConvergenceError(self._fail_msg(omega, ev["err"], it, tol, "non-finite Newton step"))
            lam = 1.0
            for _ in range(12):
                trial = z + lam * step
                ev_t = self.evaluate(trial, omega, jacobian=False)
                if ev_t["err"] < ev["err"] or ev_t["err"] <= tol:
                    break
                lam *= 0.5
            else:
                raise ConvergenceError(
                    self._fail_msg(omega, ev["err"], it, tol, "no decrease of the residual along the Newton step")
                )
            z, ev = trial, ev_t
        return z, ev, it

    # -- many frequencies at once ------------------------------------------------------

    def _product(self, g):
        """``P diag(g) E`` for every row of ``g`` (K, N): ``(K, nx, nx)``.

        From the spectrum of ``g`` by the product-to-sum identities when the grid
        resolves harmonic ``2H`` (then it is the same sum), else as a matrix product.
        """
        if 4 * self.H < self.N:
            i1, w1, i2, w2 = _product_gather(self.H, tuple(self.active.tolist()))
            spec = np.fft.rfft(g, axis=1)[:, : 2 * self.H + 1] * (2.0 / self.N)
            S = np.concatenate([spec.real, -spec.imag], axis=1)
            return S[:, i1] * w1 + S[:, i2] * w2
        return self.P @ (g[:, :, None] * self.E)

    def _thetas(self, qm):
        """Coefficient vectors ``(K, n_terms)`` at amplitudes ``qm`` (the laws' Horner sums)."""
        th = np.empty((qm.size, self.theta0.size))
        th[:] = self.theta0
        for j, poly in self.laws:
            th[:, j] = _horner(poly, qm)
        for j, law in self.law_objects:
            th[:, j] = law.value(qm)
        return th

    def peak_batch(self, X):
        """:func:`_peak` for the rows of ``X``: ``(values, taus, signs)``.

        With ``c_k = a_k - i b_k`` the series is ``q = Re sum c_k e^(i k tau)`` (plus the
        constant), so one complex exponential gives ``q`` and its first three derivatives
        together.  All rows take Newton steps ``s = q' / q''`` until every step is below
        ``PEAK_STEP``; the last step is not taken but the value is carried to ``tau - s``
        by Taylor, ``q - q' s + q'' s^2 / 2 - q''' s^3 / 6``.  The maximum lies about
        ``(q''' / 2 q'') s^2`` from there, where the value differs by ``q''/2`` times its
        square, and the omitted Taylor term is ``q'''' s^4 / 24``: both below ``1e-17`` of
        the value up to harmonic 9.  From the grid's parabola the first step is about
        ``1e-7`` (a nearly sinusoidal response), so one product usually suffices.
        """
        K = X.shape[0]
        qd = X @ self.E_dense.T
        M = qd.shape[1]
        h = 2.0 * np.pi / M
        aq = np.abs(qd)
        i = aq.argmax(axis=1)
        rows = np.arange(K)
        y0, y1, y2 = aq[rows, i - 1], aq[rows, i], aq[rows, (i + 1) % M]
        den = y0 - 2.0 * y1 + y2
        tau0 = i * h
        tau = tau0 + np.divide(0.5 * h * (y0 - y2), den, out=np.zeros(K), where=den < 0.0)
        C = (X[:, self.a_idx] - 1j * X[:, self.b_idx])[:, None, :] * self.peak_rows
        ikh = self.peak_rows[0]
        back = np.zeros(K, bool)  # left the neighbourhood of the grid maximum
        for it in range(8):
            g, d2, d3, q = (C @ np.exp(np.multiply.outer(tau, ikh))[:, :, None])[:, :, 0].real.T
            step = np.divide(g, d2, out=np.zeros(K), where=(d2 != 0.0) & ~back)
            if it == 7 or np.abs(step).max() < PEAK_STEP:
                break
            tau = tau - step
            out = np.abs(tau - tau0) > h
            back |= out
            tau[out] = tau0[out]
        q_tau = q - step * (g - step * (0.5 * d2 - step * d3 / 6.0)) + X[:, self.const_idx].sum(axis=1)
        grid = back | (np.abs(q_tau) < y1)  # never worse than the grid (guards a stray Newton)
        tau = np.where(grid, tau0, tau - step)
        q_tau = np.where(grid, qd[rows, i], q_tau)
        return np.abs(q_tau), tau, np.where(q_tau >= 0, 1.0, -1.0)

    def evaluate_batch(self, Z, W, jacobian=False):
        """:meth:`evaluate` (and :meth:`jacobian`) for rows ``Z`` at frequencies ``W``.

        Returns a dict of arrays: ``R`` (K, m), ``err`` (K,), ``peak`` (three arrays or
        None) and, when asked, ``J`` (K, m, m).
        """
        nx, N = self.active.size, self.N
        X = Z[:, :nx]
        qm = Z[:, nx] if self.closure else None
        th = self._thetas(qm) if self.closure else self.theta0[None, :]
        QD = X @ self.E_ED.T
        q, dv = QD[:, :N], QD[:, N:]
        w = W[:, None]
        v = w * dv
        h = None
        for j, func, _, _ in self.fast_terms:
            if j not in self.zero_terms:
                c = th[:, j : j + 1]
                h = c * func(q, v) if h is None else h + c * func(q, v)
        if h is None:
            h = np.zeros_like(q)
        R = np.empty((Z.shape[0], self.m))
        R[:, :nx] = h @ self.P.T - (w * w) * self.k2 * X - self.f
        xn = np.sqrt(np.einsum("ij,ij->i", X, X))
        sR = np.maximum(np.maximum(abs(self.F), (W * W + self.kq) * xn), _TINY)
        err = np.sqrt(np.einsum("ij,ij->i", R[:, :nx], R[:, :nx])) / sR
        peak = None
        if self.closure:
            peak = self.peak_batch(X)
            R[:, nx] = qm - peak[0]
            err = np.maximum(err, np.abs(R[:, nx]) / np.maximum(xn, _TINY))
        err = np.where(np.isfinite(err), err, np.inf)
        out = {"R": R, "err": err, "peak": peak, "states": (q, v, th)}
        if jacobian:
            out["J"] = self._jacobian_batch(Z, W, q, v, th, peak)
        return out

    def _jacobian_rows(self, ev, Z, W, rows):
        """The Jacobians of the rows ``rows`` of a batch evaluated by :meth:`evaluate_batch`."""
        q, v, th = ev["states"]
        peak = None if ev["peak"] is None else tuple(p[rows] for p in ev["peak"])
        return self._jacobian_batch(Z[rows], W[rows], q[rows], v[rows], th if th.shape[0] == 1 else th[rows], peak)

    def _jacobian_batch(self, Z, W, q, v, th, peak):
        nx, K = self.active.size, Z.shape[0]
        gq, gv = self._derivatives(q, v, th)
        if gq.shape[0] != K:
            gq = np.broadcast_to(gq, (K, gq.shape[1]))
        if gv.shape[0] != K:
            gv = np.broadcast_to(gv, (K, gv.shape[1]))
        J = np.zeros((K, self.m, self.m))
        if gq.shape[1] > 1:
            J[:, :nx, :nx] = self._product(gq)
        else:
            J[:, :nx, :nx] = gq[:, :, None] * self.eye
        if gv.shape[1] > 1:
            J[:, :nx, :nx] += self._product(W[:, None] * gv) @ self.D_active
        else:
            J[:, :nx, :nx] += (W[:, None] * gv)[:, :, None] * self.PED
        J.reshape(K, -1)[:, : nx * (self.m + 1) : self.m + 1] -= (W * W)[:, None] * self.k2  # the diagonal
        if self.closure:
            qm = Z[:, nx]
            dh = np.zeros_like(q)
            for j, dpoly in self.law_der:
                d = _horner(dpoly, qm)
                if d.any():
                    dh += d[:, None] * self.lib.terms[j].func(q, v)
            for j, law in self.law_objects:
                dh += law.derivative(qm)[:, None] * self.lib.terms[j].func(q, v)
            J[:, :nx, nx] = dh @ self.P.T
            _, tau, sign = peak
            row = np.zeros((K, nx))
            row[:, self.a_idx] = np.cos(np.multiply.outer(tau, self.kh))
            row[:, self.b_idx] = np.sin(np.multiply.outer(tau, self.kh))
            row[:, self.const_idx] = 1.0
            J[:, nx, :nx] = -sign[:, None] * row
            J[:, nx, nx] = 1.0
        return J

    def newton_batch(self, Z0, W, tol=1e-12, max_iter=4):
        """Full Newton steps for many frequencies at once.

        Every point takes the step of :meth:`newton` while it decreases the residual;
        a point that would need the damping of :meth:`newton`, or more than
        ``max_iter`` steps, stops there (``converged`` False) for the caller to solve
        it alone.  Returns ``(Z, err, iterations, converged, peaks)``.
        """
        Z = np.array(Z0, float)
        K = Z.shape[0]
        ev = self.evaluate_batch(Z, W)
        err = ev["err"]
        peaks = None if ev["peak"] is None else [p.copy() for p in ev["peak"]]
        its = np.zeros(K, int)
        failed = np.zeros(K, bool)
        act = np.flatnonzero(err > tol)
        if act.size:
            J, R = self._jacobian_rows(ev, Z, W, act), ev["R"][act]
        while act.size:
            if its[act[0]] >= max_iter:
                failed[act] = True
                break
            its[act] += 1
            try:
                step = np.linalg.solve(J, -R[..., None])[..., 0]
            except np.linalg.LinAlgError:
                failed[act] = True
                break
            trial = Z[act] + step
            Wa = W[act]
            et = self.evaluate_batch(trial, Wa)  # the Jacobian only where another step follows
            ok = np.all(np.isfinite(step), axis=1) & ((et["err"] < err[act]) | (et["err"] <= tol))
            failed[act[~ok]] = True
            sel = act[ok]
            Z[sel] = trial[ok]
            err[sel] = et["err"][ok]
            if peaks is not None:
                for p, pt in zip(peaks, et["peak"]):
                    p[sel] = pt[ok]
            more = err[sel] > tol
            act = sel[more]
            if act.size:
                rows = np.flatnonzero(ok)[more]
                J, R = self._jacobian_rows(et, trial, Wa, rows), et["R"][rows]
        return Z, err, its, ~failed & (err <= tol), peaks

    def _fail_msg(self, omega, err, it, tol, why):
        self._last_failure = f"{why} after {it} iterations, scaled residual {err:.3g} > tol {tol:.1g}"
        return (
            f"harmonic balance did not converge at omega={omega:.6g} rad/s, F={self.F:.6g} "
            f"(n_harmonics={self.H}): {why} after {it} iterations, scaled residual {err:.3g} > tol {tol:.1g}. "
            "Try a closer `guess` (e.g. the solution at a neighbouring frequency), more harmonics, "
            "or frequency_response(..., omega_range=...) which follows folds by continuation; "
            "a softening model driven past its escape threshold has no periodic solution."
        )

    # -- initial guesses --------------------------------------------------------------

    def linear_guess(self, omega, force=None):
        F = self.F if force is None else force
        A = _linear_closure_amplitude(self.model, omega, F)
        X = linear_frf(self.model, omega, F, q_max=A)
        full = np.zeros(self.n)
        full[1], full[2] = X.imag, X.real  # q = Im(X e^{i w t}) = Re X sin + Im X cos
        z = full[self.active]
        if self.closure:
            z = np.append(z, A)
        return z

    def describing_guesses(self, omega, n_amplitudes=400, n_phase=64):
        """Single-harmonic (describing-function) solutions, lowest amplitude first.

        With ``q = A sin(psi)`` the restoring force's first harmonic defines an
        equivalent stiffness ``K(A)`` and damping ``C(A)`` (laws evaluated at
        ``q_max = A``); the amplitude equation ``A |K - omega^2 + i omega C| = |F|`` is
        scanned on a log grid of ``A`` and every root refined.  Returns reduced
        unknown vectors.
        """
        F = self.F
        if F == 0.0:
            return [np.zeros(self.m)]
        a_lo = 1e-2 * abs(F) / (self.kq + omega * omega)  # well below any forced response
        A = np.geomspace(a_lo, a_lo * 1e8, n_amplitudes)
        psi = 2.0 * np.pi * np.arange(n_phase) / n_phase
        sn, cs = np.sin(psi), np.cos(psi)
        P_ = np.polynomial.polynomial

        def keq_ceq(A):
            A = np.atleast_1d(A)
            th = np.tile(self.theta0, (A.size, 1))
            for name, law in self.model.amplitude_laws.items():
                th[:, self.lib.index(name)] = P_.polyval(A, law) if isinstance(law, tuple) else law.value(A)
            q = A[:, None] * sn
            v = (A * omega)[:, None] * cs
            h = np.zeros_like(q)
            for j, func, _, _ in self.fast_terms:
                cj = th[:, j]
                if np.any(cj != 0.0):
                    h += cj[:, None] * func(q, v)
            K = (h @ sn) * (2.0 / n_phase) / A
            C = (h @ cs) * (2.0 / n_phase) / (A * omega)
            return K, C

        def g(A):
            K, C = keq_ceq(A)
            return A * np.hypot(K - omega * omega, omega * C) - abs(F)

        gA = g(A)
        ok = np.isfinite(gA)
        roots = []
        for i in np.flatnonzero(ok[:-1] & ok[1:] & (np.sign(gA[:-1]) != np.sign(gA[1:]))):
            try:
                roots.append(optimize.brentq(lambda a: float(g(a)[0]), A[i], A[i + 1], rtol=1e-12))
            except (ValueError, RuntimeError):
                roots.append(0.5 * (A[i] + A[i + 1]))
        out = []
        for a in roots:
            K, C = keq_ceq(a)
            phi = math.atan2(-float(C[0]) * omega * a / F, (float(K[0]) - omega * omega) * a / F)
            full = np.zeros(self.n)
            full[1], full[2] = a * math.sin(phi), a * math.cos(phi)
            z = full[self.active]
            if self.closure:
                z = np.append(z, a)
            out.append(z)
        return out

    def fresh(self, omega, tol=1e-12, max_iter=40):
        """Solve without a guess.

        Tries, in order: the describing-function solutions (lowest amplitude first),
        the linear part's response, and a homotopy in the force level.
        """
        tried = []
        for z0 in self.describing_guesses(omega) + [self.linear_guess(omega)]:
            try:
                return self.newton(z0, omega, tol, max_iter)
            except ConvergenceError:
                tried.append(self._last_failure)
        try:
            return self._force_homotopy(omega, tol, max_iter)
        except ConvergenceError as exc:
            raise ConvergenceError(
                f"harmonic balance found no steady state at omega={omega:.6g} rad/s, F={self.F:.6g} "
                f"(n_harmonics={self.H}, tol={tol:g}, max_iter={max_iter}): Newton failed from {len(tried)} "
                f"starting points (describing-function and linearised; first: {tried[0]}) and {exc}"
            ) from None

    def _force_homotopy(self, omega, tol, max_iter):
        F_target = self.F
        s = 1e-3
        sub = _Problem.__new__(_Problem)
        sub.__dict__.update(self.__dict__)
        sub.f = self.f * s
        sub.F = F_target * s
        try:
            z, _, _ = sub.newton(self.linear_guess(omega, F_target * s), omega, tol, max_iter)
            ds = 0.25
            zprev, sprev = None, None
            while s < 1.0:
                s_new = min(1.0, s * math.exp(ds * math.log(1e3)))
                guess = z if zprev is None else z + (z - zprev) * (s_new - s) / (s - sprev)
                sub.f = self.f * s_new
                sub.F = F_target * s_new
                try:
                    z_new, _, _ = sub.newton(guess, omega, tol, max_iter)
                except ConvergenceError:
                    ds *= 0.5
                    if ds < 1e-3:
                        raise
                    continue
                zprev, sprev, z, s = z, s, z_new, s_new
                ds = min(ds * 1.5, 0.25)
        except ConvergenceError:
            raise ConvergenceError(
                f"the homotopy in the force level stalled at F={s * F_target:.4g}. "
                "Try a closer `guess` (e.g. the solution at a neighbouring frequency), more harmonics, or "
                "frequency_response(..., omega_range=...), which follows folds by continuation; a softening "
                "model driven past its escape threshold has no periodic solution."
            ) from None
        return self.newton(z, omega, tol, max_iter)

    # -- results ------------------------------------------------------------------------

    def _gauss_nodes(self, steps):
        return _gauss_nodes(int(steps))

    def _gauss_basis(self, steps):
        """Basis and its phase derivative at the Gauss nodes, transposed (cached)."""
        return _gauss_basis(self.H, int(steps))

    #: Magnus steps per period of the first monodromy estimate (doubled until converged).
    MONODROMY_STEPS = 32
    #: Change of the monodromy matrix between step counts below which it is accepted.
    MONODROMY_TOL = 1e-6
    #: Elements per temporary array of :meth:`_monodromy` (rows x Gauss nodes): larger arrays
    #: are computed in row blocks, which keeps every temporary below the size (128 KiB) from
    #: which the C allocator maps fresh pages for each one, at twice the cost per element.
    MONODROMY_BLOCK = 16384

    def _monodromy(self, c, w, th, steps):
        """Monodromy matrices ``(K, 2, 2)`` and Liouville determinants of ``K`` steady states."""
        K = c.shape[0]
        blocks = -(-K * 2 * steps // self.MONODROMY_BLOCK)
        if blocks <= 1:
            return self._monodromy_block(c, w, th, steps)
        rows = -(-K // blocks)
        parts = [self._monodromy_block(c[s:s + rows], w[s:s + rows], th[s:s + rows], steps)
                 for s in range(0, c.shape[0], rows)]
        return np.concatenate([m for m, _ in parts]), np.concatenate([d for _, d in parts])

    def _monodromy_block(self, c, w, th, steps):
        EgT, EDgT = self._gauss_basis(steps)
        nodes = self._gauss_nodes(steps)[None, :]
        h = 2.0 * np.pi / steps
        c3 = math.sqrt(3.0) / 12.0 * h * h
        q = c @ EgT
        v = w[:, None] * (c @ EDgT)
        hq, hv = self._derivatives(q, v, th)  # (K, n), or (K, 1) where constant in time
        # y' = A y in the phase tau = omega t, A = [[0, 1], [-hq, -hv]] / omega = A0 + A1(tau),
        # A0 the mean (Gauss nodes integrate the trigonometric polynomials exactly)
        iw = (1.0 / w)[:, None]
        mq = hq.mean(axis=1, keepdims=True)
        mv = hv.mean(axis=1, keepdims=True)
        rq = (mq - hq) * iw  # A1 = e2 [rq, rv]
        rv = (mv - hv) * iw
        # exp(A0 s) = e^{a s} (C(s) I + S(s) P), P = A0 - a I = [[-a, 1/w], [-mq/w, a]], P^2 = delta I
        a = -0.5 * mv * iw
        p00, p01, p10 = -a, iw, -mq * iw
        delta = p00 * p00 + p01 * p10
        rt = np.sqrt(np.abs(delta))
        hyp = delta >= 0
        tiny = rt * (2.0 * np.pi) < 1e-8
        rs = np.where(tiny, 1.0, rt)

        def cos_sin(s):
            C, S = _cos_sin(rs * s, hyp)
            S /= rs
            return C, (np.where(tiny, s, S) if tiny.any() else S)

        C, S = cos_sin(nodes)
        # frame remainder at each node: exp(-A0 s) A1 exp(A0 s) = u w^T, with u = e^{-a s} (u0, u1)
        # and w = e^{a s} (w0, w1); the exponentials cancel in every term of the Magnus step
        # below (each pairs a u with a w at the same node, or two such pairs), so they are left out
        Sp = S * p00
        u0 = S * (-p01)
        u1 = C + Sp
        w0 = rq * u1 + rv * (S * p10)
        w1 = rv * (C - Sp) - rq * u0
        U1, U2 = u0[:, 0::2], u0[:, 1::2]
        V1, V2 = u1[:, 0::2], u1[:, 1::2]
        X1, X2 = w0[:, 0::2], w0[:, 1::2]
        Y1, Y2 = w1[:, 0::2], w1[:, 1::2]
        g21 = c3 * (X2 * U1 + Y2 * V1)  # c3 w2 . u1
        g12 = c3 * (X1 * U2 + Y1 * V2)  # c3 w1 . u2
        hh = 0.5 * h
        # Omega = h/2 (u1 w1 + u2 w2) + sqrt(3) h^2 / 12 (u2 (w2.u1) w1 - u1 (w1.u2) w2)
        #       = u1 (h/2 w1 - c3 (w1.u2) w2) + u2 (h/2 w2 + c3 (w2.u1) w1) = u1 A + u2 B
        A0, A1 = hh * X1 - g12 * X2, hh * Y1 - g12 * Y2
        B0, B1 = hh * X2 + g21 * X1, hh * Y2 + g21 * Y1
        o00 = U1 * A0 + U2 * B0
        o01 = U1 * A1 + U2 * B1
        o10 = V1 * A0 + V2 * B0
        o11 = V1 * A1 + V2 * B1
        Mk = _expm2(o00, o01, o10, o11)
        while Mk.shape[1] > 1:  # ordered product: later steps on the left
            Mk = _matmul2(Mk[:, 1::2], Mk[:, 0::2])
        C, S = cos_sin(2.0 * np.pi)
        e = np.exp(2.0 * np.pi * a)
        E = np.empty_like(Mk)
        E[..., 0, 0] = e * (C + S * p00)
        E[..., 0, 1] = e * S * p01
        E[..., 1, 0] = e * S * p10
        E[..., 1, 1] = e * (C - S * p00)
        Phi = _matmul2(E, Mk)[:, 0]
        return Phi, np.exp(4.0 * np.pi * a[:, 0])  # Liouville: exp(-integral of h_v over a period)

    def floquet_batch(self, coefs, omegas, thetas, chunk=1024):
        """Floquet exponents of many steady states from their monodromy matrices.

        A single degree of freedom perturbed about its periodic orbit obeys
        ``dq'' + h_v(t) dq' + h_q(t) dq = 0``, a 2x2 linear system ``y' = A(t) y`` with
        periodic coefficients.  Its monodromy matrix is integrated in the frame of the
        mean system ``exp(A0 t)``, where the remainder is a small rank-one matrix: a
        product of fourth-order Magnus steps (two Gauss points each, closed-form 2x2
        exponentials) formed for all states at once by pairwise products.  The step
        count doubles from ``MONODROMY_STEPS`` until two counts agree to
        ``MONODROMY_TOL``; the last two are combined by Richardson extrapolation (the
        scheme is symmetric, its error even in the step), which leaves about
        ``1e-9`` of the matrix.  Its determinant is ``exp(-integral of h_v)``
        (Liouville) and its trace fixes the two multipliers ``mu``; the exponents are
        ``log(mu) / T`` (imaginary parts within ``omega / 2``, as Hill's method keeps
        them), largest real part first.  The amplitude closure is frozen: ``thetas``
        stay fixed.  The exponents agree with :meth:`hill_batch` (spectrally accurate,
        but an eigenvalue problem per state) to the accuracy above.

        Returns a complex array ``(n_points, 2)``.
        """
        coefs = np.asarray(coefs, float)
        omegas = np.asarray(omegas, float)
        thetas = np.asarray(thetas, float)
        out = np.empty((coefs.shape[0], 2), complex)
        for s0 in range(0, coefs.shape[0], chunk):
            sl = slice(s0, s0 + chunk)
            c, w, th = coefs[sl], omegas[sl], thetas[sl]
            steps = int(self.MONODROMY_STEPS)
            prev, det = self._monodromy(c, w, th, steps // 2)
            Phi = np.empty_like(prev)
            todo = np.arange(c.shape[0])
            while todo.size:
                cur, _ = self._monodromy(c[todo], w[todo], th[todo], steps)
                change = np.abs(cur - prev[todo]).max(axis=(1, 2))
                done = (change <= self.MONODROMY_TOL * np.maximum(1.0, np.abs(cur).max(axis=(1, 2)))) | (
                    steps >= 1 << 14
                )
                Phi[todo[done]] = (16.0 * cur[done] - prev[todo[done]]) / 15.0
                prev[todo[~done]] = cur[~done]
                todo = todo[~done]
                steps *= 2
            tr = Phi[:, 0, 0] + Phi[:, 1, 1]
            disc = tr * tr - 4.0 * det
            root = np.sqrt(np.abs(disc))
            big = 0.5 * (tr + np.where(tr >= 0, root, -root))
            with np.errstate(divide="ignore", invalid="ignore"):
                real_pair = np.stack([big, det / big], axis=1).astype(complex)
            cplx = 0.5 * tr[:, None] + 0.5j * root[:, None] * np.array([1.0, -1.0])
            mu = np.where((disc >= 0)[:, None], real_pair, cplx)
            lam = np.log(mu) * (w / (2.0 * np.pi))[:, None]
            out[sl] = np.take_along_axis(lam, np.argsort(-lam.real, axis=1, kind="stable"), axis=1)
        return out

    def hill(self, x_full, omega, theta):
        """Floquet exponents of one steady state (see :meth:`hill_batch`)."""
        return self.hill_batch(np.atleast_2d(x_full), np.atleast_1d(omega), np.atleast_2d(theta))[0]

    def hill_batch(self, coefs, omegas, thetas, chunk=256):
        """Floquet exponents by Hill's method for many steady states at once.

        Perturbations ``e^{lambda t} p(t)`` with ``p`` a harmonic series give the
        quadratic eigenvalue problem ``(lambda^2 I + lambda (2 omega D + C_v) + J) p = 0``
        (``J`` the harmonic-balance Jacobian without closure, ``C_v`` the projected
        ``dh/dq'``), solved in companion form; the two exponents with the smallest
        ``|imag|`` are kept (largest real part first).  With odd symmetry the matrix
        splits into odd and even harmonic blocks whose spectra are pooled.  The
        amplitude closure is frozen: ``thetas`` stay fixed.

        Returns a complex array ``(n_points, 2)``.
        """
        coefs = np.asarray(coefs, float)
        omegas = np.asarray(omegas, float)
        thetas = np.asarray(thetas, float)
        out = np.empty((coefs.shape[0], 2), complex)
        E, ED, D = self.E_full, self.ED_full, self.D_full
        kk = harmonic_index(self.H).astype(float) ** 2
        for s0 in range(0, coefs.shape[0], chunk):
            sl = slice(s0, s0 + chunk)
            c, w, th = coefs[sl], omegas[sl], thetas[sl]
            q = c @ E.T
            v = w[:, None] * (c @ ED.T)
            hq, hv = (np.broadcast_to(g, q.shape) for g in self._derivatives(q, v, th))
            L = 2 * self.H + 1
            spec_q = np.fft.rfft(hq, axis=1)[:, :L] * (2.0 / self.N)
            spec_v = np.fft.rfft(hv, axis=1)[:, :L] * (2.0 / self.N)
            Sq = np.concatenate([spec_q.real, -spec_q.imag], axis=1)
            Sv = np.concatenate([spec_v.real, -spec_v.imag], axis=1)
            lams = []
            for idx in self.hill_blocks:
                n = idx.size
                Db = D[np.ix_(idx, idx)]
                i1, w1, i2, w2 = _product_gather(self.H, tuple(idx.tolist()))
                Cv = Sv[:, i1] * w1 + Sv[:, i2] * w2  # P diag(hv) E, block rows/cols
                Cq = Sq[:, i1] * w1 + Sq[:, i2] * w2
                J0 = Cq + w[:, None, None] * (Cv @ Db)
                J0[:, np.arange(n), np.arange(n)] -= (w * w)[:, None] * kk[idx]
                A = np.zeros((c.shape[0], 2 * n, 2 * n))
                A[:, :n, n:] = np.eye(n)
                A[:, n:, :n] = -J0
                A[:, n:, n:] = -(2.0 * w[:, None, None] * Db + Cv)
                lams.append(np.linalg.eigvals(A))
            lam = np.concatenate(lams, axis=1)
            lam = np.take_along_axis(lam, np.argsort(np.abs(lam.imag), axis=1, kind="stable")[:, :2], axis=1)
            out[sl] = np.take_along_axis(lam, np.argsort(-lam.real, axis=1, kind="stable"), axis=1)
        return out

    def state(self, z, omega, ev, iterations, stability=True):
        nx = self.active.size
        x_full = self.full(z[:nx])
        if self.closure:
            q_max = float(z[nx])
        else:
            q_max = float(ev["peak"][0]) if ev.get("peak") is not None else float(self.peak(z[:nx])[0])
        theta = self.model.coefficients_at(q_max) if self.closure else self.theta0.copy()
        stable = floquet = None
        if stability:
            floquet = self.floquet_batch(x_full[None, :], np.array([float(omega)]), theta[None, :])[0]
            stable = bool(np.max(floquet.real) < 0.0)
        return SteadyState(
            omega=float(omega),
            force_amplitude=self.F,
            coefficients=_readonly(x_full),
            n_harmonics=self.H,
            q_max=q_max,
            theta=_readonly(theta),
            residual_norm=float(ev["err"]),
            stable=stable,
            iterations=int(iterations),
            model=self.model,
            floquet_exponents=None if floquet is None else _readonly(floquet),
        )


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


def _linear_closure_amplitude(model, omega, F):
    """Amplitude of the linear part with its laws closed on its own amplitude.

    Only the ``q`` and ``q'`` coefficients are kept; used for initial guesses.
    """
    F = abs(F)
    if F == 0.0:
        return 0.0
    if not model.depends_on_amplitude:
        return float(abs(linear_frf(model, omega, F, q_max=0.0)))

    def g(A):
        return A * abs(1.0 / linear_frf(model, omega, 1.0, q_max=A)) - F

    lo, hi = 0.0, F / max(abs(1.0 / linear_frf(model, omega, 1.0, q_max=0.0)), _TINY)
    for _ in range(200):
        if g(hi) > 0.0:
            break
        lo, hi = hi, hi * 2.0
    else:
        return hi
    try:
        return float(optimize.brentq(g, lo, hi, xtol=1e-14 * hi, rtol=1e-12))
    except (ValueError, RuntimeError):
        return hi


# ----------------------------------------------------------------------------------------
# Results
# ----------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class SteadyState:
    """A periodic steady state found by harmonic balance.

    Attributes
    ----------
    omega : float
        Excitation frequency [rad/s].
    force_amplitude : float
        ``F`` in ``Q(t) = F sin(omega t)``.
    coefficients : ndarray
        Harmonic vector of ``q``, ``[a0, a1, b1, ..., aH, bH]`` (conventions.py).
    n_harmonics : int
    q_max : float
        ``max_t |q(t)|`` of the harmonic series (machine precision).
    theta : ndarray
        Coefficients of the restoring force used, ``model.coefficients_at(q_max)``.
    residual_norm : float
        Scaled norm of the harmonic-balance residual at the solution.
    stable : bool or None
        Floquet stability from the monodromy matrix (``None`` when not computed).  With
        an amplitude closure the coefficients are frozen at ``theta`` for the stability
        analysis.
    iterations : int
        Newton iterations used.
    model : SingleModeModel
    floquet_exponents : ndarray or None
        The two Floquet exponents, imaginary parts within ``omega / 2`` (largest real
        part first).
    """

    omega: float
    force_amplitude: float
    coefficients: np.ndarray
    n_harmonics: int
    q_max: float
    theta: np.ndarray
    residual_norm: float
    stable: bool | None
    iterations: int
    model: SingleModeModel | None = None
    floquet_exponents: np.ndarray | None = None

    # time functions ------------------------------------------------------------------

    def _series(self, t, order):
        tau = self.omega * np.asarray(t, float)
        H = self.n_harmonics
        c = self.coefficients
        kt = np.multiply.outer(tau, np.arange(1, H + 1))
        a, b = c[1::2], c[2::2]
        k = np.arange(1, H + 1, dtype=float)
        w = self.omega
        if order == 0:
            return c[0] + np.cos(kt) @ a + np.sin(kt) @ b
        if order == 1:
            return np.cos(kt) @ (w * k * b) - np.sin(kt) @ (w * k * a)
        return -(np.cos(kt) @ ((w * k) ** 2 * a) + np.sin(kt) @ ((w * k) ** 2 * b))

    def q(self, t):
        """Displacement ``q(t)`` of the harmonic series (time ``t`` in seconds)."""
        return self._series(t, 0)

    def velocity(self, t):
        """``dq/dt`` at times ``t``."""
        return self._series(t, 1)

    def acceleration(self, t):
        """``d2q/dt2`` at times ``t``."""
        return self._series(t, 2)

    def force(self, t):
        """Applied force ``Q(t) = F sin(omega t)``."""
        return self.force_amplitude * np.sin(self.omega * np.asarray(t, float))

    def restoring_force(self, t):
        """``h(q, q')`` with the steady state's coefficients ``theta``."""
        if self.model is None:
            raise RecordError("this SteadyState carries no model; restoring_force needs one")
        return self.model.terms.restoring_force(self.q(t), self.velocity(t), self.theta)

    # scalars ---------------------------------------------------------------------------

    @property
    def amplitude(self) -> float:
        """Amplitude of the fundamental harmonic, ``sqrt(a1^2 + b1^2)``."""
        return float(np.hypot(self.coefficients[1], self.coefficients[2]))

    @property
    def phase(self) -> float:
        """Phase ``phi`` of the fundamental, ``q1 = A sin(omega t + phi)`` (lag < 0)."""
        return float(np.arctan2(self.coefficients[1], self.coefficients[2]))

    @property
    def period(self) -> float:
        return 2.0 * np.pi / self.omega

    def summary(self) -> dict:
        """JSON-safe dictionary of the steady state."""
        names = self.model.terms.coefficient_names if self.model is not None else range(len(self.theta))
        return {
            "omega": self.omega,
            "force_amplitude": self.force_amplitude,
            "n_harmonics": self.n_harmonics,
            "q_max": self.q_max,
            "amplitude": self.amplitude,
            "phase": self.phase,
            "theta": {str(k): float(v) for k, v in zip(names, self.theta)},
            "coefficients": [float(c) for c in self.coefficients],
            "residual_norm": self.residual_norm,
            "stable": self.stable,
            "iterations": self.iterations,
        }

    def report(self) -> str:
        s = self.summary()
        stab = {None: "not computed", True: "stable", False: "unstable"}[self.stable]
        return (
            f"SteadyState at omega = {self.omega:.6g} rad/s, F = {self.force_amplitude:.6g}\n"
            f"  q_max = {self.q_max:.10g}, fundamental amplitude = {self.amplitude:.10g}, "
            f"phase = {self.phase:.6g} rad\n"
            f"  theta = {s['theta']}\n"
            f"  {stab}; residual {self.residual_norm:.2g} after {self.iterations} Newton iterations "
            f"(H = {self.n_harmonics})"
        )

    def _repr_html_(self):
        return "<pre>" + self.report().replace("&", "&amp;").replace("<", "&lt;") + "</pre>"


@dataclass(frozen=True, eq=False)
class FrequencyResponse:
    """Steady states of a frequency sweep or continuation.

    Attributes
    ----------
    omega : ndarray
        Frequencies [rad/s] in the order computed (not monotonic past a fold).
    q_max : ndarray
        ``max |q|`` of each steady state.
    amplitude, phase : ndarray
        Fundamental amplitude and phase (``q1 = A sin(omega t + phi)``).
    stable : ndarray of bool or None
        Floquet stability (closure frozen), ``None`` when not computed.
    folds : tuple of int
        Indices of fold (turning) points found by continuation (empty for sweeps).
    coefficients : ndarray
        ``(n_points, 2H + 1)`` harmonic vectors of ``q``.
    theta : ndarray
        ``(n_points, n_terms)`` coefficients used at each point.
    force_amplitude : float
    n_harmonics : int
    method : {"sweep", "continuation"}
    residual_norm, iterations : ndarray
    floquet_exponents : ndarray or None
        ``(n_points, 2)`` complex.
    model : SingleModeModel
    """

    omega: np.ndarray
    q_max: np.ndarray
    amplitude: np.ndarray
    phase: np.ndarray
    stable: np.ndarray | None
    folds: tuple
    coefficients: np.ndarray
    theta: np.ndarray
    force_amplitude: float
    n_harmonics: int
    method: str
    residual_norm: np.ndarray
    iterations: np.ndarray
    floquet_exponents: np.ndarray | None = None
    model: SingleModeModel | None = None

    def __len__(self):
        return int(self.omega.size)

    def state(self, i: int) -> SteadyState:
        """The :class:`SteadyState` of point ``i``."""
        i = range(len(self))[i]
        return SteadyState(
            omega=float(self.omega[i]),
            force_amplitude=self.force_amplitude,
            coefficients=self.coefficients[i],
            n_harmonics=self.n_harmonics,
            q_max=float(self.q_max[i]),
            theta=self.theta[i],
            residual_norm=float(self.residual_norm[i]),
            stable=None if self.stable is None else bool(self.stable[i]),
            iterations=int(self.iterations[i]),
            model=self.model,
            floquet_exponents=None if self.floquet_exponents is None else self.floquet_exponents[i],
        )

    @property
    def states(self) -> list:
        """All points as a list of :class:`SteadyState`."""
        return [self.state(i) for i in range(len(self))]

    @property
    def fold_omegas(self) -> np.ndarray:
        return self.omega[list(self.folds)]

    def linear(self, q_max=0.0) -> np.ndarray:
        """Complex linear-part FRF at this response's frequencies (see :func:`linear_frf`)."""
        return linear_frf(self.model, self.omega, self.force_amplitude, q_max=q_max)

    def summary(self) -> dict:
        """JSON-safe dictionary (arrays as lists)."""
        i_peak = int(np.argmax(self.q_max)) if len(self) else None
        return {
            "method": self.method,
            "force_amplitude": self.force_amplitude,
            "n_harmonics": self.n_harmonics,
            "n_points": len(self),
            "omega_range": [float(np.min(self.omega)), float(np.max(self.omega))] if len(self) else None,
            "peak": None if i_peak is None else {"omega": float(self.omega[i_peak]), "q_max": float(self.q_max[i_peak])},
            "folds": [{"index": int(i), "omega": float(self.omega[i]), "q_max": float(self.q_max[i])} for i in self.folds],
            "n_unstable": None if self.stable is None else int(np.count_nonzero(~self.stable)),
            "max_residual": float(np.max(self.residual_norm)) if len(self) else None,
            "omega": self.omega.tolist(),
            "q_max_values": self.q_max.tolist(),
            "amplitude": self.amplitude.tolist(),
            "phase": self.phase.tolist(),
            "stable": None if self.stable is None else self.stable.tolist(),
        }

    def report(self) -> str:
        s = self.summary()
        lines = [
            f"FrequencyResponse ({self.method}) of {len(self)} points, F = {self.force_amplitude:.6g}, "
            f"H = {self.n_harmonics}",
        ]
        if len(self):
            lines.append(
                f"  omega {s['omega_range'][0]:.6g} .. {s['omega_range'][1]:.6g} rad/s; "
                f"peak q_max {s['peak']['q_max']:.6g} at {s['peak']['omega']:.6g} rad/s"
            )
        for f in s["folds"]:
            lines.append(f"  fold at omega = {f['omega']:.8g} rad/s, q_max = {f['q_max']:.6g}")
        if s["n_unstable"] is not None:
            lines.append(f"  {s['n_unstable']} unstable points (Floquet, closure frozen)")
        return "\n".join(lines)

    def _repr_html_(self):
        return "<pre>" + self.report().replace("&", "&amp;").replace("<", "&lt;") + "</pre>"

    def plot(self, ax=None, **kwargs):
        """Plot with :func:`jointid.report.frf_plots.plot_frequency_response`; returns ``(fig, ax)``."""
        from ..report.frf_plots import plot_frequency_response

        return plot_frequency_response(self, ax=ax, **kwargs)


# ----------------------------------------------------------------------------------------
# Public functions
# ----------------------------------------------------------------------------------------


def linear_frf(model, omega, force_amplitude=1.0, q_max=0.0):
    """Complex response of the model's linear part, ``F / (k - omega^2 + i c omega)``.

    ``k`` is the coefficient of the term ``q`` (``omega1^2``) and ``c`` that of ``q'``,
    both evaluated at ``q_max`` (so an amplitude-dependent damping can be frozen at a
    chosen amplitude); every other term is dropped.  With ``Q = F sin(omega t)`` the
    response is ``q(t) = |X| sin(omega t + angle(X))``.

    Parameters
    ----------
    model : SingleModeModel
    omega : float or array_like
        Frequencies [rad/s].
    force_amplitude : float
    q_max : float or array_like
        Amplitude at which amplitude laws are evaluated (broadcast with ``omega``).

    Returns
    -------
    complex ndarray (or complex scalar)

    Examples
    --------
    >>> from jointid.simulate.model import seed_model
    >>> X = linear_frf(seed_model(), 170.0)
    >>> round(float(abs(X)), 6)       # 1 / (c0 * omega1)
    0.073529
    """
    omega = np.asarray(omega, float)
    qm = np.asarray(q_max, float)
    names = model.terms.names
    i_q = names.index("q") if "q" in names else None
    i_v = names.index("q'") if "q'" in names else None
    if qm.ndim == 0:
        theta = model.coefficients_at(float(qm))
        k = theta[i_q] if i_q is not None else 0.0
        c = theta[i_v] if i_v is not None else 0.0
    else:
        thetas = np.array([model.coefficients_at(float(a)) for a in qm.ravel()]).reshape(qm.shape + (len(names),))
        k = thetas[..., i_q] if i_q is not None else 0.0
        c = thetas[..., i_v] if i_v is not None else 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        out = force_amplitude / (k - omega**2 + 1j * c * omega)
    return out[()] if np.ndim(out) == 0 else out


def _check_omega(omega):
    w = float(omega)
    if not (np.isfinite(w) and w > 0):
        raise RecordError(f"omega must be a positive finite frequency in rad/s, got {omega!r}")
    return w


def _guess_vector(problem, guess):
    """Reduced unknown vector from a user guess (SteadyState or coefficient vector)."""
    if isinstance(guess, SteadyState):
        coefs, qm = guess.coefficients, guess.q_max
    else:
        coefs = np.asarray(guess, float)
        qm = None
    z = problem.reduce(coefs)
    if problem.closure:
        if qm is None:
            qm = problem.peak(z)[0]
        z = np.append(z, qm)
    return z


@single_threaded  # thousands of tiny dense solves: threaded BLAS only adds overhead
@np.errstate(all="ignore")  # diverging Newton trials are caught by their residual
def steady_state(
    model,
    omega,
    force_amplitude,
    n_harmonics=9,
    guess=None,
    tol=1e-12,
    *,
    stability=True,
    n_time=None,
    max_iter=40,
    odd=None,
) -> SteadyState:
    """Periodic steady state of ``q'' + h(q, q') = F sin(omega t)`` by harmonic balance.

    Parameters
    ----------
    model : SingleModeModel
        Restoring force and optional amplitude laws (closed on the solution's own
        ``q_max``, see the module docstring).
    omega : float
        Excitation frequency [rad/s].
    force_amplitude : float
        ``F``.
    n_harmonics : int, default 9
        Harmonics kept.  For odd libraries only the odd harmonics are solved for (the
        even ones are zero by symmetry); the stability analysis perturbs all of them.
    guess : SteadyState or array_like, optional
        Starting point (a neighbouring solution, or a coefficient vector of any length).
        Without it Newton starts from the linearised response and falls back to a
        homotopy in the force level.
    tol : float, default 1e-12
        Tolerance on the scaled residual (``|R| / max(F, (omega^2 + omega1^2) |x|)``
        and, with a closure, ``|q_max - max|q|| / |x|``).
    stability : bool, default True
        Compute the Floquet stability (monodromy matrix of the linearisation, see
        ``_Problem.floquet_batch``).  The amplitude closure is frozen (coefficients
        fixed at ``theta``) for the stability analysis.
    n_time : int, optional
        Time samples per period for the AFT (default :func:`default_n_time`).
    max_iter : int, default 40
    odd : bool, optional
        Force (or forbid) the odd-harmonic reduction; default: the library's symmetry.

    Returns
    -------
    SteadyState

    Raises
    ------
    jointid.errors.ConvergenceError
        When Newton (and the force homotopy) fail.
    """
    w = _check_omega(omega)
    problem = _Problem(model, force_amplitude, n_harmonics, n_time, odd)
    if guess is not None:
        try:
            z, ev, it = problem.newton(_guess_vector(problem, guess), w, tol, max_iter)
        except ConvergenceError:
            z, ev, it = problem.fresh(w, tol, max_iter)
    else:
        z, ev, it = problem.fresh(w, tol, max_iter)
    return problem.state(z, w, ev, it, stability)


@single_threaded  # thousands of tiny dense solves: threaded BLAS only adds overhead
@np.errstate(all="ignore")  # diverging Newton trials are caught by their residual
def frequency_response(
    model,
    force_amplitude,
    omegas=None,
    *,
    omega_range=None,
    n_harmonics=9,
    stability=True,
    tol=1e-12,
    n_time=None,
    odd=None,
    ds=0.02,
    ds_max=0.1,
    max_steps=5000,
) -> FrequencyResponse:
    """Frequency response by harmonic balance: a sweep or a continuation.

    Parameters
    ----------
    model : SingleModeModel
    force_amplitude : float
        ``F`` in ``Q = F sin(omega t)``.
    omegas : array_like, optional
        Sequential sweep at exactly these frequencies (in the given order), each point
        started from a polynomial predictor through the previous four solutions, runs of
        points it predicts well solved together.  This is the fast path.  Past a fold it
        lands on whichever branch Newton reaches (the jump of a physical sweep); use
        ``omega_range`` to follow the folds.
    omega_range : (float, float), optional
        Pseudo-arclength continuation in (harmonics, [q_max], omega) from
        ``omega_range[0]`` to ``omega_range[1]``, with step control (on the number of
        Newton iterations and the turning angle of the tangent).  The predictor is the
        polynomial through the last ``CONT_HISTORY`` points in their chord length (the
        tangent for the first step, and always with amplitude laws, whose frozen-closure
        stability near a fold depends on where the points fall).  Folds (turning points
        in omega) are located to tolerance and reported in ``folds``.
    n_harmonics : int, default 9
    stability : bool, default True
        Floquet stability of each point from the monodromy matrix of the linearisation
        about the periodic solution (two multipliers for one degree of freedom; the
        exponents agree with Hill's method, which keeps the two of smallest
        ``|imag|``).  The amplitude closure is frozen for stability (the
        coefficients stay at the point's ``theta``), as ``q_max`` is a property of the
        steady state, not a state variable.
    tol : float, default 1e-12
    n_time : int, optional
    odd : bool, optional
    ds, ds_max : float
        Initial and largest continuation step in the scaled (coefficient / amplitude
        scale, omega / range width) space.
    max_steps : int
        Continuation step limit (a :class:`~jointid.errors.ConvergenceWarning` is issued
        and the partial curve returned when reached).

    Returns
    -------
    FrequencyResponse

    Examples
    --------
    >>> import numpy as np
    >>> from jointid.simulate.model import seed_model
    >>> r = frequency_response(seed_model(), 1.0, np.linspace(160, 180, 401))
    >>> len(r), bool(r.stable.all())
    (401, True)
    """
    if (omegas is None) == (omega_range is None):
        raise RecordError("give exactly one of `omegas` (sweep) or `omega_range=(w0, w1)` (continuation)")
    problem = _Problem(model, force_amplitude, n_harmonics, n_time, odd)
    if omegas is not None:
        w = np.atleast_1d(np.asarray(omegas, float))
        if w.ndim != 1 or w.size == 0 or not np.all(np.isfinite(w)) or np.any(w <= 0):
            raise RecordError(f"omegas must be a non-empty 1-D array of positive frequencies, got {omegas!r}")
        blocks = _sweep(problem, w, tol)
        method, folds = "sweep", ()
    else:
        try:
            w0, w1 = (float(v) for v in omega_range)
        except (TypeError, ValueError):
            raise RecordError(f"omega_range must be a pair (w0, w1), got {omega_range!r}") from None
        _check_omega(w0), _check_omega(w1)
        if w0 == w1:
            raise RecordError(f"omega_range must span a non-empty interval, got {omega_range!r}")
        pts, folds = _continuation(problem, w0, w1, tol, ds, ds_max, max_steps)
        blocks = [_block(pts)]
        method = "continuation"
    return _assemble(problem, blocks, folds, method, stability)


def _block(pts):
    """Points ``(omega, z, evaluation, iterations)`` as one block of arrays ``(omegas, Z,
    residual norms, peak values (NaN where not evaluated), iterations)``."""
    return (
        np.array([p[0] for p in pts], float),
        np.array([p[1] for p in pts], float),
        np.array([p[2]["err"] for p in pts], float),
        np.array([np.nan if p[2].get("peak") is None else p[2]["peak"][0] for p in pts], float),
        np.array([p[3] for p in pts], int),
    )


def _assemble(problem, blocks, folds, method, stability):
    """Build the FrequencyResponse from consecutive blocks of points (see :func:`_block`)."""
    omega, Z, res, qmax, its = (np.concatenate(parts) for parts in zip(*blocks))
    n_pts = omega.size
    nx = problem.active.size
    coefs = np.zeros((n_pts, problem.n))
    coefs[:, problem.active] = Z[:, :nx]
    if problem.closure:  # the amplitude is an unknown; the laws at every point's amplitude at once
        qmax = Z[:, nx].copy()
        theta = problem._thetas(qmax)
    else:
        missing = np.isnan(qmax)
        if missing.any():  # q_max of all the points at once
            qmax[missing] = problem.peak_batch(coefs[missing][:, problem.active])[0]
        theta = np.tile(problem.theta0, (n_pts, 1))
    stable = floquet = None
    if stability:
        floquet = problem.floquet_batch(coefs, omega, theta)
        stable = floquet.real.max(axis=1) < 0.0
    amp = np.hypot(coefs[:, 1], coefs[:, 2])
    phase = np.arctan2(coefs[:, 1], coefs[:, 2])
    return FrequencyResponse(
        omega=_readonly(omega),
        q_max=_readonly(qmax),
        amplitude=_readonly(amp),
        phase=_readonly(phase),
        stable=None if stable is None else _readonly(stable),
        folds=tuple(int(i) for i in folds),
        coefficients=_readonly(coefs),
        theta=_readonly(theta),
        force_amplitude=problem.F,
        n_harmonics=problem.H,
        method=method,
        residual_norm=_readonly(res),
        iterations=_readonly(its),
        floquet_exponents=None if floquet is None else _readonly(floquet),
        model=problem.model,
    )


# ----------------------------------------------------------------------------------------
# Sequential sweep (fast path)
# ----------------------------------------------------------------------------------------


#: Predictor error (relative) up to which frequencies are solved together in a sweep: four
#: full Newton steps take such a start below the tolerance (5e-2 -> 2.5e-3 -> 6e-6 -> 4e-11 ->
#: ...); a point that does not converge, or lands off the branch, is solved alone.  On the
#: tests' sweeps the batched solutions differ from the point-by-point ones by at most 8e-11
#: of the largest coefficient, as with 1e-2 (the Newton tolerance's footprint).
BATCH_GUESS = 5e-2
#: Solutions the sweep's predictor extrapolates through (polynomial of degree HISTORY - 1).
HISTORY = 4
#: Longest batch of a sweep.
BATCH_MAX = 64
#: Relative distance from the one-step predictor within which a batched solution is the
#: one the point-by-point sweep reaches (another branch lies much farther away).
SAME_BRANCH = 0.02


def _sweep(problem, omegas, tol):
    """Sequential solutions at ``omegas``; predictor: polynomial extrapolation through the
    last ``HISTORY`` solutions (secant, quadratic, then cubic: on the seed's sweep the
    cubic's one-step error is 25 times the quadratic's smaller), falling back to the
    previous solution and to a fresh start.

    Where the response is smooth the predictor stays accurate many points ahead: the
    last one-step predictor error ``e`` grows about as ``binomial(k + HISTORY, HISTORY) e``
    over ``k`` steps, and while that stays below ``BATCH_GUESS`` the next points are solved together by
    :meth:`_Problem.newton_batch`.  A batched solution is kept while it converged with
    full steps and lies within ``SAME_BRANCH`` of the one-step predictor (the branch the
    point-by-point sweep follows); the first other point is solved alone as before,
    jumps included.  Returns the points as consecutive blocks of arrays (see
    :func:`_block`): a batch stays one block, without a Python object per point.
    """
    omegas = [float(w) for w in omegas]
    blocks = []  # consecutive points as arrays (see _block)
    hist_w, hist_z = [], []
    err1 = np.inf  # relative error of the last one-step prediction
    i, n = 0, len(omegas)
    nh = HISTORY
    while i < n:
        k = 0
        while len(hist_z) == nh and k < min(BATCH_MAX, n - i) and err1 * math.comb(k + nh, nh) <= BATCH_GUESS:
            k += 1
        if k >= 4:
            ws = np.array(omegas[i : i + k])
            Hz = np.array(hist_z)
            Z0 = _extrapolate(np.broadcast_to(hist_w, (k, nh)), Hz[None], ws)
            Z, err, its, ok, peaks = problem.newton_batch(Z0, ws, tol)
            # each point's one-step predictor from the points before it (history, then batch)
            allw, allz = np.concatenate([hist_w, ws]), np.concatenate([Hz, Z])
            win = np.arange(k)[:, None] + np.arange(nh)
            d = Z - _extrapolate(allw[win], allz[win], ws)
            dist = np.sqrt(np.einsum("ij,ij->i", d, d)) / np.maximum(np.sqrt(np.einsum("ij,ij->i", Z, Z)), _TINY)
            bad = ~ok | ~(dist <= SAME_BRANCH)
            taken = int(np.argmax(bad)) if bad.any() else k
            if taken:
                peak = np.full(taken, np.nan) if peaks is None else peaks[0][:taken]
                blocks.append((ws[:taken], Z[:taken], err[:taken], peak, its[:taken]))
                hist_w, hist_z = [float(w) for w in allw[taken : taken + nh]], list(allz[taken : taken + nh])
                err1 = float(dist[taken - 1])
            i += taken
            if taken == k:
                continue
        w = omegas[i]
        if not hist_z:
            z, ev, it = problem.fresh(w, tol)
            jumped = False
        else:
            guess = _extrapolate_one(hist_w, hist_z, w)
            jumped = False
            try:
                z, ev, it = problem.newton(guess, w, tol)
            except ConvergenceError:
                try:
                    z, ev, it = problem.newton(hist_z[-1], w, tol)
                except ConvergenceError:
                    z, ev, it = problem.fresh(w, tol)
                jumped = True
            d = z - guess
            err1 = np.inf if jumped else math.sqrt(d @ d) / max(math.sqrt(z @ z), _TINY)
        blocks.append(_block([(w, z, ev, it)]))
        if jumped:
            hist_w, hist_z = [], []  # a jump: restart the predictor
        hist_w = (hist_w + [w])[-nh:]
        hist_z = (hist_z + [z])[-nh:]
        i += 1
    return blocks


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


# ----------------------------------------------------------------------------------------
# Pseudo-arclength continuation
# ----------------------------------------------------------------------------------------


class _Arclength:
    """Scaled augmented system ``G(u, nu) = 0`` with ``z = zs u``, ``omega = w0 + W nu``."""

    def __init__(self, problem, w0, w1, zs, tol):
        self.p = problem
        self.w0, self.W = w0, w1 - w0
        self.zs = zs
        self.tol = tol
        self.rs = np.ones(problem.m)
        self.rs[: problem.active.size] = 1.0 / max(abs(problem.F), _TINY)
        if problem.closure:
            self.rs[-1] = 1.0 / zs
        self.scale_z = (self.rs * zs)[:, None]  # dG/du = rs J zs
        self.scale_w = self.rs * self.W  # dG/dnu = rs Jw W

    def split(self, y):
        return y[:-1] * self.zs, self.w0 + self.W * float(y[-1])

    def join(self, z, w):
        return np.append(z / self.zs, (w - self.w0) / self.W)

    def residual(self, y):
        """Scaled residual ``G(y)`` and the evaluation behind it."""
        z, w = self.split(y)
        ev = self.p.evaluate(z, w, jacobian=False)
        return self.rs * ev["R"], ev

    def derivative(self, ev):
        """``dG/dy`` at an evaluation of :meth:`residual`."""
        self.p.jacobian(ev, domega=True)
        Gy = np.empty((self.p.m, self.p.m + 1))
        np.multiply(ev["J"], self.scale_z, out=Gy[:, :-1])
        np.multiply(ev["Jw"], self.scale_w, out=Gy[:, -1])
        return Gy

    def eval(self, y):
        G, ev = self.residual(y)
        return G, self.derivative(ev), ev

    @staticmethod
    def tangent(Gy, t_prev):
        A = np.empty((Gy.shape[0] + 1, Gy.shape[1]))
        A[:-1] = Gy
        A[-1] = t_prev
        rhs = np.zeros(A.shape[0])
        rhs[-1] = 1.0
        t = _solve(A, rhs)
        return t / math.sqrt(float(t @ t))

    def correct(self, yp, t, max_iter=10, exact=False):
        """Newton on ``[G(y); t.(y - yp)] = 0``; returns ``(y, Gy, ev, its)`` or None.

        ``Gy`` (for the tangent) is the derivative at the last Newton iterate before the
        solution, one converged step away (a relative change of about the square root of
        the tolerance), unless ``exact``: then it is evaluated at the solution.
        """
        y = yp.copy()
        Gy = None
        for it in range(max_iter + 1):
            G, ev = self.residual(y)
            if ev["err"] <= self.tol and it > 0:
                return y, (self.derivative(ev) if exact else Gy), ev, it
            if not np.isfinite(ev["err"]):
                return None
            Gy = self.derivative(ev)
            A = np.empty((Gy.shape[0] + 1, Gy.shape[1]))
            A[:-1] = Gy
            A[-1] = t
            rhs = np.empty(A.shape[0])
            rhs[:-1] = -G
            rhs[-1] = -float(t @ (y - yp))
            try:
                dy = _solve(A, rhs)
            except np.linalg.LinAlgError:
                return None
            y = y + dy
            if ev["err"] <= self.tol:
                G, ev = self.residual(y)
                return y, (self.derivative(ev) if exact else Gy), ev, it + 1
        return None


def _amplitude_scale(problem, w0, w1, tol):
    """Typical size of the unknown vector over the range (it sets the metric of the steps).

    Without amplitude laws: the largest response of the model's linear part at the ends
    of the range and at its resonance when that lies inside, found without solving
    anything (the nonlinear response peaks at about the same size).  With amplitude
    laws the frozen-closure stability changes away from the folds, so which points a
    curve holds matters more; the scale stays the one of the earlier releases, the
    largest coefficient of a coarse 21-point sweep, so those curves keep their points.
    """
    if problem.closure:
        zmax = 0.0
        try:
            for _, Z, _, _, _ in _sweep(problem, np.linspace(w0, w1, 21), max(tol, 1e-10)):
                zmax = max(zmax, float(np.max(np.abs(Z))))
        except ConvergenceError:
            pass
        return zmax if zmax > 0.0 else max(abs(problem.F) / max(w0, w1) ** 2, _TINY)
    ws = [w0, w1]
    kq = problem.theta0[problem.i_q] if problem.i_q is not None else 0.0
    if kq > 0 and min(w0, w1) < math.sqrt(kq) < max(w0, w1):
        ws.append(math.sqrt(kq))
    with np.errstate(all="ignore"):
        amps = [_linear_closure_amplitude(problem.model, w, problem.F) for w in ws]
    amps = [a for a in amps if np.isfinite(a) and a > 0.0]
    if not amps:
        return max(abs(problem.F) / max(w0, w1) ** 2, _TINY)
    return float(max(amps))


#: Points of the continuation's predictor (a cubic in chord length: on the named Duffing
#: curve 4 Newton evaluations per point instead of 4.4 with the tangent, and steps that
#: grow to ``ds_max`` where the tangent's stayed at half of it: 51 points instead of 67).
CONT_HISTORY = 4


def _continuation(problem, w0, w1, tol, ds, ds_max, max_steps):
    zs = _amplitude_scale(problem, w0, w1, tol)
    arc = _Arclength(problem, w0, w1, zs, tol)
    z, ev, it = problem.fresh(w0, tol)
    pts = [(w0, z, ev, it)]
    folds = []
    y = arc.join(z, w0)
    _, Gy, _ = arc.eval(y)
    e_nu = np.zeros(y.size)
    e_nu[-1] = 1.0
    t = arc.tangent(Gy, e_nu)
    ds_min = 1e-9
    cos_max = math.cos(math.radians(20.0))
    steps = 0
    hist_s, hist_y = [0.0], [y]  # accepted points along the curve, by chord length
    while True:
        steps += 1
        if steps > max_steps:
            warnings.warn(
                f"continuation stopped after {max_steps} steps at omega={pts[-1][0]:.6g} rad/s "
                f"before reaching the end of the range ({w0:.6g}, {w1:.6g}); returning the partial curve",
                ConvergenceWarning,
                stacklevel=4,
            )
            break
        if len(hist_y) >= 2 and not problem.closure:
            yp = _extrapolate_one(hist_s, hist_y, hist_s[-1] + ds)
        else:
            yp = y + ds * t
        out = arc.correct(yp, t)
        if out is not None:
            y_new, Gy_new, ev_new, its = out
            t_new = arc.tangent(Gy_new, t)
            if t_new @ t < cos_max and ds > 1e3 * ds_min:
                out = None
        if out is None:
            ds *= 0.5
            if ds < ds_min:
                raise ConvergenceError(
                    f"continuation stalled at omega={pts[-1][0]:.6g} rad/s (F={problem.F:.6g}): "
                    f"step size fell below {ds_min:g}; try more harmonics or a smaller range"
                )
            continue
        # fold: the omega component of the tangent changes sign
        if np.sign(t_new[-1]) != np.sign(t[-1]) and t[-1] != 0.0:
            fold = _locate_fold(arc, y, t, ds, t_new)
            if fold is not None:
                yf, evf, itf = fold
                zf, wf = arc.split(yf)
                folds.append(len(pts))
                pts.append((wf, zf, evf, itf))
        nu = y_new[-1]
        if nu > 1.0 or nu < 0.0:
            # land exactly on the end of the range by interpolation + fixed-frequency Newton
            nu_end = 1.0 if nu > 1.0 else 0.0
            frac = (nu_end - y[-1]) / (nu - y[-1])
            y_end = y + frac * (y_new - y)
            z_end, w_end = arc.split(y_end)
            w_end = w1 if nu_end == 1.0 else w0
            try:
                z_e, ev_e, it_e = problem.newton(z_end, w_end, tol)
                pts.append((w_end, z_e, ev_e, it_e))
            except ConvergenceError:
                pass
            break
        z_new, w_new = arc.split(y_new)
        pts.append((w_new, z_new, ev_new, its))
        hist_s = (hist_s + [hist_s[-1] + float(np.linalg.norm(y_new - y))])[-CONT_HISTORY:]
        hist_y = (hist_y + [y_new])[-CONT_HISTORY:]
        y, t = y_new, t_new
        if its <= 2:
            ds = min(ds * 1.6, ds_max)
        elif its >= 5:
            ds *= 0.6
    return pts, folds


def _locate_fold(arc, y, t, ds, t_new):
    """Regula falsi (Illinois) on the step length for ``t_omega = 0`` from point ``y``."""
    a, fa = 0.0, t[-1]
    b, fb = ds, t_new[-1]
    best = None
    side = 0
    for _ in range(30):
        c = b - fb * (b - a) / (fb - fa)
        out = arc.correct(y + c * t, t, exact=True)
        if out is None:
            return best
        yc, Gyc, evc, its = out
        fc = arc.tangent(Gyc, t)[-1]
        best = (yc, evc, its)
        if abs(fc) < 1e-9:
            break
        if np.sign(fc) == np.sign(fb):
            b, fb = c, fc
            if side == -1:
                fa *= 0.5
            side = -1
        else:
            a, fa = c, fc
            if side == 1:
                fb *= 0.5
            side = 1
    return best
