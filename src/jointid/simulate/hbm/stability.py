"""Stability of the steady states: Floquet exponents by a Magnus monodromy, and Hill's method.

Methods of :class:`~jointid.simulate.hbm.problem._Problem` (a mixin): the monodromy
matrix of the linearised one-degree-of-freedom equation over one period from two-point
Gauss-Magnus steps (the step count doubled until the matrix changes by less than
``MONODROMY_TOL``), and the Hill matrix of the same linearisation in the harmonic basis;
the tests check that the two give the same exponents.
"""

from __future__ import annotations

import math

import numpy as np

from ...conventions import harmonic_index
from .kernels import _cos_sin, _expm2, _gauss_basis, _gauss_nodes, _matmul2, _product_gather, hill_companion


class _StabilityMixin:
    """Floquet and Hill methods of :class:`_Problem` (see the module docstring)."""

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
                lams.append(np.linalg.eigvals(hill_companion(J0, 2.0 * w[:, None, None] * Db + Cv)))
            lam = np.concatenate(lams, axis=1)
            lam = np.take_along_axis(lam, np.argsort(np.abs(lam.imag), axis=1, kind="stable")[:, :2], axis=1)
            out[sl] = np.take_along_axis(lam, np.argsort(-lam.real, axis=1, kind="stable"), axis=1)
        return out
