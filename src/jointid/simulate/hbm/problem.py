"""The harmonic-balance problem of one model, force level and truncation: residual, Jacobian, Newton.

:class:`_Problem` holds everything that does not change with the frequency (bases,
index sets, the terms' callables) and evaluates the AFT residual and its analytic
Jacobian at one frequency (``evaluate``, ``jacobian``, ``newton``, ``peak``); the
batched twins live in :mod:`.batch`, the stability methods in :mod:`.stability`.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import optimize

from ...conventions import harmonic_index, n_coefficients
from ...errors import ConvergenceError, RecordError
from ...numerics.aft import resize_harmonics
from ...identify.terms import STANDARD_TERMS
from ..model import SingleModeModel
from ..newton import damped_newton
from .batch import _BatchMixin
from .kernels import _TINY, _basis, _basis_at, _horner, _peak, _readonly, _solve, default_n_time
from .results import SteadyState, linear_frf
from .stability import _StabilityMixin


class _Problem(_BatchMixin, _StabilityMixin):
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
        return resize_harmonics(coefficients, self.H)[self.active]

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
        """Damped Newton (:func:`jointid.simulate.newton.damped_newton`); returns ``(z, evaluation,
        iterations)`` or raises :class:`ConvergenceError`.

        Trial points are evaluated without Jacobian; it is built only for points that are
        accepted and not yet converged.  A trial is accepted when the scaled error decreases;
        after eleven halvings without decrease the iteration fails (callers then try the next
        start).
        """

        def residual(z):
            ev = self.evaluate(z, omega, jacobian=False)
            return ev["R"], None, ev["err"], ev

        out = damped_newton(np.array(z0, float), residual, tol, max_iter, jacobian=self._jacobian_of,
                            merit="error", on_stall="fail", halvings=11, solve=_solve)
        if not out.converged:
            raise ConvergenceError(self._fail_msg(omega, out.error, out.iterations, tol, out.reason))
        return out.x, out.state, out.iterations

    def _jacobian_of(self, ev):
        return self.jacobian(ev)["J"]

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
