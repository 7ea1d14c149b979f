"""The batched twins of :class:`~jointid.simulate.hbm.problem._Problem`: many frequencies at once.

``evaluate_batch``/``newton_batch``/``peak_batch`` solve the same equations as the
single-point ``evaluate``/``newton``/``peak`` for a stack of ``K`` frequencies, with the
Jacobian from the spectrum of the derivative samples (product-to-sum identities) and
stacked LAPACK solves.  They are kept as deliberate twins of the single-point methods:
one point through the batch costs a multiple of the single-point path (the sweep and the
continuation call the latter thousands of times), so the two are tested to agree to
rounding (``tests/test_hbm_speed.py``) instead of being one function.
"""

from __future__ import annotations

import numpy as np

from .kernels import PEAK_STEP, _TINY, _horner, _product_gather


class _BatchMixin:
    """Methods of :class:`_Problem` that take many frequencies at once (see the module docstring)."""

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
