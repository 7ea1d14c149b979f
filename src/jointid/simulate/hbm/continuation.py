"""Pseudo-arclength continuation in ``(harmonics, [q_max], omega)`` with fold location."""

from __future__ import annotations

import math
import warnings

import numpy as np

from ...errors import ConvergenceError, ConvergenceWarning
from .kernels import _TINY, _extrapolate_one, _solve
from .problem import _linear_closure_amplitude
from .sweep import _sweep


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

    def land(z_end, w_end):
        z_e, ev_e, it_e = problem.newton(z_end, w_end, tol)
        return (w_end, z_e, ev_e, it_e)

    return _follow(
        arc, (w0, z, ev, it), z, w0, w1, ds, ds_max, max_steps,
        extrapolate=not problem.closure,
        point=lambda z, w, ev, its: (w, z, ev, its),
        land=land,
        stopped=lambda last: (f"continuation stopped after {max_steps} steps at omega={last[0]:.6g} rad/s "
                              f"before reaching the end of the range ({w0:.6g}, {w1:.6g}); returning the partial curve"),
        stalled=lambda last, ds_min: (f"continuation stalled at omega={last[0]:.6g} rad/s (F={problem.F:.6g}): "
                                      f"step size fell below {ds_min:g}; try more harmonics or a smaller range"),
        stacklevel=6,  # _follow, _continuation, frequency_response, errstate, single_threaded: the caller
    )


def _follow(arc, first, z0, w0, w1, ds, ds_max, max_steps, *, extrapolate, point, land, stopped, stalled, stacklevel):
    """The pseudo-arclength loop of both harmonic-balance engines, from ``first`` (a curve point,
    joint or harmonic unknowns ``z0`` at ``w0``) until the curve leaves ``[w0, w1]``.

    Each step is :func:`_step` (halved when it fails, until ``1e-9``: ``ConvergenceError`` with
    ``stalled(last point, 1e-9)``); a sign change of the tangent's ``omega`` component is a fold,
    located by :func:`_locate_fold` and added to the curve; the end of the range is reached by
    interpolation and ``land(z, omega_end)`` (a point, or ``ConvergenceError``: the curve ends
    before it); step lengths follow :func:`_accept`.  ``point(z, omega, evaluation, iterations)``
    makes the curve's points.  After ``max_steps`` a ``ConvergenceWarning`` with ``stopped(last
    point)`` and the partial curve.  Returns ``(points, fold indices)``.
    """
    pts = [first]
    folds = []
    y = arc.join(z0, w0)
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
            warnings.warn(stopped(pts[-1]), ConvergenceWarning, stacklevel=stacklevel)
            break
        out = _step(arc, y, t, ds, hist_s, hist_y, extrapolate, cos_max, ds_min)
        if out is None:
            ds *= 0.5
            if ds < ds_min:
                raise ConvergenceError(stalled(pts[-1], ds_min))
            continue
        y_new, t_new, ev_new, its = out
        # fold: the omega component of the tangent changes sign
        if np.sign(t_new[-1]) != np.sign(t[-1]) and t[-1] != 0.0:
            fold = _locate_fold(arc, y, t, ds, t_new)
            if fold is not None:
                yf, evf, itf = fold
                zf, wf = arc.split(yf)
                folds.append(len(pts))
                pts.append(point(zf, wf, evf, itf))
        nu = y_new[-1]
        if nu > 1.0 or nu < 0.0:
            # land exactly on the end of the range by interpolation + fixed-frequency Newton
            nu_end = 1.0 if nu > 1.0 else 0.0
            frac = (nu_end - y[-1]) / (nu - y[-1])
            z_end, _ = arc.split(y + frac * (y_new - y))
            try:
                pts.append(land(z_end, w1 if nu_end == 1.0 else w0))
            except ConvergenceError:
                pass
            break
        z_new, w_new = arc.split(y_new)
        pts.append(point(z_new, w_new, ev_new, its))
        hist_s, hist_y, ds = _accept(hist_s, hist_y, y, y_new, its, ds, ds_max)
        y, t = y_new, t_new
    return pts, folds


def _step(arc, y, t, ds, hist_s, hist_y, extrapolate, cos_max, ds_min):
    """One predictor-corrector step of length ``ds`` from ``y`` along tangent ``t``.

    The predictor is the cubic through the accepted points ``hist_y`` (``extrapolate`` and two
    or more points) or the tangent.  ``(y_new, t_new, ev_new, iterations)``, or ``None`` when the
    corrector fails or the tangent turns by more than ``acos(cos_max)`` on a step above ``1e3 ds_min``.
    """
    if extrapolate and len(hist_y) >= 2:
        yp = _extrapolate_one(hist_s, hist_y, hist_s[-1] + ds)
    else:
        yp = y + ds * t
    out = arc.correct(yp, t)
    if out is None:
        return None
    y_new, Gy_new, ev_new, its = out
    t_new = arc.tangent(Gy_new, t)
    if t_new @ t < cos_max and ds > 1e3 * ds_min:
        return None
    return y_new, t_new, ev_new, its


def _accept(hist_s, hist_y, y, y_new, its, ds, ds_max):
    """The predictor history after accepting ``y_new`` and the next step length (by corrector iterations)."""
    hist_s = (hist_s + [hist_s[-1] + math.sqrt(float((y_new - y) @ (y_new - y)))])[-CONT_HISTORY:]
    hist_y = (hist_y + [y_new])[-CONT_HISTORY:]
    if its <= 2:
        ds = min(ds * 1.6, ds_max)
    elif its >= 5:
        ds *= 0.6
    return hist_s, hist_y, ds


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
