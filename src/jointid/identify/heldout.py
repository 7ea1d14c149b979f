"""Held-out prediction of a force level: steady-state amplitudes and the peak, on the measured branch.

The model selection of :mod:`jointid.identify.selection` fits every candidate without one
force level and scores how it predicts that level.  The prediction here is the first-harmonic
balance of the single-mode model ``q'' + h(q, q') = Q cos(omega t)``: with ``q = a cos(theta)``
the restoring force's first harmonic is ``a Kc(a, omega) cos(theta) - a Ks(a, omega) sin(theta)``
and the amplitude solves

``G(a, omega) = a^2 ((Kc - omega^2)^2 + Ks^2) - Q^2 = 0``.

``Kc`` and ``Ks`` come from the model's own terms: for a polynomial model with amplitude laws
(:mod:`jointid.identify.model`) by projecting every term over one period of the harmonic
motion, its coefficients taken at ``q_max = a``; for a hysteretic joint law
(:mod:`jointid.identify.hysteretic`) from the law's own first harmonic.  Several roots at one
frequency are the branches of a fold; a measured dwell is compared with the root nearest its
own amplitude (its own branch).  The peak is the largest ``a`` for which some ``omega`` solves
``G = 0`` (no continuation through folds needed).

Nothing here solves a multi-harmonic balance: the core numerics of ``identify`` do not depend on
``simulate``.  A caller may inject another predictor (:func:`level_errors` ``predictor``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize

from ..errors import IdentificationError
from ..numerics.peaks import parabolic_peak
from .model import expand

__all__ = ["PolynomialFirstHarmonic", "HystereticFirstHarmonic", "LevelPrediction", "level_errors",
           "measured_fundamental", "N_PHASE"]

#: Samples of one period used to project polynomial terms on the first harmonic.
N_PHASE = 256


class _FirstHarmonic:
    """``Kc(a, omega)``, ``Ks(a, omega)`` of a single-mode model; response roots and peak."""

    def kc_ks(self, a, omega):  # pragma: no cover - abstract
        raise NotImplementedError

    def g(self, a, omega, Q):
        kc, ks = self.kc_ks(a, omega)
        return a * a * ((kc - omega * omega) ** 2 + ks * ks) - Q * Q

    def g_grid(self, grid, omega, Q):
        return np.array([self.g(a, omega, Q) for a in grid])

    def response(self, Q, omega, a_hint=None, n_grid=300):
        """Every first-harmonic amplitude at the forcing frequency ``omega`` [rad/s] (increasing)."""
        Q, w = float(Q), float(omega)
        kc, ks = self.kc_ks(max(a_hint or 0.0, 1e-12), w)
        hi = 4.0 * Q / max(abs(ks), 1e-12 * max(abs(kc), 1.0))
        if a_hint is not None and np.isfinite(a_hint):
            hi = max(hi, 20.0 * a_hint)
        lo = hi * 1e-7
        grid = np.geomspace(lo, hi, int(n_grid))
        vals = self.g_grid(grid, w, Q)
        out = []
        for i in np.flatnonzero(np.sign(vals[:-1]) * np.sign(vals[1:]) < 0):
            out.append(optimize.brentq(self.g, grid[i], grid[i + 1], args=(w, Q), xtol=1e-300, rtol=1e-12))
        return np.array(out)

    def _best_omega(self, a, w0):
        def f(w):
            kc, ks = self.kc_ks(a, w)
            return (kc - w * w) ** 2 + ks * ks

        kc, _ = self.kc_ks(a, w0)
        wn = math.sqrt(kc) if kc > 0 else w0
        r = optimize.minimize_scalar(f, bounds=(0.7 * wn, 1.3 * wn), method="bounded",
                                     options={"xatol": 1e-10 * wn})
        return float(r.x), float(r.fun)

    def peak(self, Q, omega_guess):
        """``(omega_peak, a_peak)``: the largest amplitude of the response at force amplitude ``Q``."""
        Q = float(Q)

        def h(a):
            return a * a * self._best_omega(a, omega_guess)[1] - Q * Q

        lo = 1e-15
        hi = Q / max(omega_guess**2, 1e-300)
        n = 0
        while h(hi) < 0:
            lo, hi = hi, 2.0 * hi
            n += 1
            if n > 80:
                raise IdentificationError(f"no peak at force amplitude {Q:g}: the response grows without bound")
        a = optimize.brentq(h, lo, hi, xtol=1e-300, rtol=1e-11)
        return self._best_omega(a, omega_guess)[0], float(a)

    def acceleration_peak(self, Q, omega_guess):
        """``(omega, omega^2 a)``: the peak of the fundamental of the acceleration at force amplitude ``Q``.

        An accelerometer's FRF peaks a little above the displacement's (by about ``zeta^2``): the
        largest ``omega^2 a(omega)`` on the upper branch is found about :meth:`peak` by a bounded
        search (relative tolerance 1e-10 in frequency).
        """
        wp, ap = self.peak(Q, omega_guess)

        def neg(w):
            roots = self.response(Q, w, a_hint=ap)
            return -w * w * float(roots.max()) if roots.size else 0.0

        _, ks = self.kc_ks(ap, wp)
        half = max(2.0 * abs(ks) / (wp * wp), 1e-6)  # a -3 dB width either side
        r = optimize.minimize_scalar(neg, bounds=(wp * (1 - half), wp * (1 + half)), method="bounded",
                                     options={"xatol": 1e-10 * wp})
        return float(r.x), float(-r.fun)


class PolynomialFirstHarmonic(_FirstHarmonic):
    """First harmonic of ``h = sum_j theta_j(q_max) phi_j(q, q')`` with amplitude laws (``q_max = a``)."""

    def __init__(self, lib, orders, theta):
        self.lib, self.orders, self.theta = lib, tuple(orders), np.asarray(theta, float)
        th = 2 * np.pi * np.arange(N_PHASE) / N_PHASE
        self._c, self._s = np.cos(th), np.sin(th)

    def coefficients(self, a):
        return expand(self.orders, a, self.theta)[0]

    def kc_ks(self, a, omega):
        q = a * self._c
        v = -a * omega * self._s
        h = self.lib.restoring_force(q, v, self.coefficients(a))
        # h = a Kc cos - a Ks sin
        kc = 2.0 * float(h @ self._c) / (N_PHASE * a)
        ks = -2.0 * float(h @ self._s) / (N_PHASE * a)
        return kc, ks

    def stiffness0(self):
        if "q" not in self.lib.names:
            return float("nan")
        return float(self.coefficients(0.0)[self.lib.index("q")])


class HystereticFirstHarmonic(_FirstHarmonic):
    """First harmonic of ``k q + c q' + f_joint(q) - k3 q^3`` (a :class:`~jointid.identify.hysteretic.HystereticFit`)."""

    def __init__(self, fit):
        self.fit = fit
        # the law as fitted: a four-parameter Iwan model is evaluated on its discretisation
        self.law = getattr(fit.law, "sliders", fit.law)

    def kc_ks(self, a, omega):
        k_eq, k_loss = self.law.first_harmonic(a)
        return self.fit.k + float(k_eq) - 0.75 * self.fit.k3 * a * a, self.fit.c * omega + float(k_loss)

    def g_grid(self, grid, omega, Q):
        grid = np.asarray(grid, float)
        k_eq, k_loss = self.law.first_harmonic(grid)
        kc = self.fit.k + np.asarray(k_eq, float) - 0.75 * self.fit.k3 * grid**2
        ks = self.fit.c * omega + np.asarray(k_loss, float)
        return grid * grid * ((kc - omega * omega) ** 2 + ks * ks) - Q * Q

    def stiffness0(self):
        return self.fit.k + float(self.law.first_harmonic(1e-15)[0])


def measured_fundamental(sig):
    """Fundamental amplitude of ``q`` of a steady-state record (its acceleration's first harmonic / omega^2)."""
    c = np.asarray(sig.acceleration.coefficients, float)
    return float(np.hypot(c[1], c[2]) / sig.omega**2)


@dataclass(frozen=True)
class LevelPrediction:
    """How a model fitted without a force level predicts it.

    Attributes
    ----------
    dwell_errors_percent : array
        Per dwell, the predicted fundamental amplitude on the dwell's own branch (the root
        nearest the measured amplitude) against the measured one [%] (``inf``: no steady state).
    n_branches : array of int
        Steady states of the model at each dwell's frequency (3: a fold).
    peak_resolved : bool
        The dwells resolve the measured peak: the largest dwell has a lower one on each side,
        the dwells about it are at most half the model's -3 dB width apart, and the model has a
        single steady state at each of the three.
    peak_frequency_error_percent, peak_amplitude_error_percent : float
        The parabola through the largest three dwells against the parabola through the model's
        amplitudes at the same three frequencies, on the same branch (``nan`` when not resolved).
    half_width_percent : float
        Half the model's -3 dB width at the peak, relative to the peak frequency [%].
    score : float
        ``hypot(peak amplitude error, peak frequency error / half width)`` when the dwells
        resolve the peak (bracketed, at most the half width apart; also when the model has a
        fold among the three dwells, compared on their own branch: the kind of score is the
        data's, the same for every model), else the rms of the dwell errors (both as fractions).
    far_from_branch : bool
        Some dwell is further than 10 % from every steady state of the model.
    """

    dwell_errors_percent: np.ndarray
    n_branches: np.ndarray
    peak_resolved: bool
    peak_frequency_error_percent: float
    peak_amplitude_error_percent: float
    half_width_percent: float
    score: float
    far_from_branch: bool


#: A dwell further than this from every steady state of the model is "far from the branch".
FAR_FROM_BRANCH = 0.10


def level_errors(model, forcing, omegas, a_measured, predictor=None) -> LevelPrediction:
    """Score the prediction of one held-out force level (see :class:`LevelPrediction`).

    Parameters
    ----------
    model : PolynomialFirstHarmonic or HystereticFirstHarmonic
    forcing : float
        Fundamental force amplitude of the level (its dwells' mean).
    omegas, a_measured : array
        The dwells' frequencies [rad/s] and measured fundamental amplitudes.
    predictor : callable, optional
        ``predictor(omegas, a_measured) -> amplitudes`` replacing the first-harmonic roots for
        the dwell errors (e.g. a multi-harmonic balance injected by the application).
    """
    w = np.asarray(omegas, float)
    am = np.asarray(a_measured, float)
    order = np.argsort(w)
    w, am = w[order], am[order]
    pred = np.full(w.size, np.inf)
    nb = np.zeros(w.size, int)
    for i, (wi, ai) in enumerate(zip(w, am)):
        roots = model.response(forcing, wi, a_hint=ai)
        nb[i] = roots.size
        if roots.size:
            pred[i] = roots[int(np.argmin(np.abs(np.log(roots / ai))))]
    if predictor is not None:
        pred = np.asarray(predictor(w, am), float)
    err = pred / am - 1.0
    far = bool(np.any(~np.isfinite(err)) or np.any(np.abs(err) > FAR_FROM_BRANCH))
    inv = np.empty_like(order)
    inv[order] = np.arange(order.size)
    # the measured peak, where the dwells resolve it
    km = int(np.argmax(am))
    fe = ae = hw = float("nan")
    resolved = False
    try:
        wp, ap = model.peak(forcing, float(w[km]))
        kc, ks = model.kc_ks(ap, wp)
        hw = 0.5 * abs(ks) / (wp * wp)  # half the -3 dB width over omega (full width Ks / omega^2, linear: 2 zeta)
    except (IdentificationError, ValueError, ArithmeticError):
        wp = ap = float("nan")
    compared = False
    if 0 < km < w.size - 1 and am[km - 1] < am[km] > am[km + 1] and np.isfinite(hw):
        spacing = float(np.max(np.diff(w[km - 1: km + 2]))) / float(w[km])
        three = pred[km - 1: km + 2]
        if spacing <= hw and np.all(np.isfinite(three)):
            # the dwells resolve the peak: every model is scored on it, on the dwells' own branch; a model
            # with a fold among the three dwells is not let off to the milder rms of the dwells (the score
            # must not change its kind with the model), but its peak is not quoted as resolved
            compared = True
            resolved = bool(np.all(nb[km - 1: km + 2] == 1))
            fm, amx = parabolic_peak(w[km - 1: km + 2], am[km - 1: km + 2])
            fp, apx = parabolic_peak(w[km - 1: km + 2], three)
            fe = 100.0 * (fp / fm - 1.0)
            ae = 100.0 * (apx / amx - 1.0)
    if compared:
        score = float(math.hypot(ae / 100.0, fe / 100.0 / hw))
        if not resolved:
            fe = ae = float("nan")
    else:
        score = float(np.sqrt(np.mean(err**2))) if np.all(np.isfinite(err)) else float("inf")
    return LevelPrediction(100.0 * err[inv], nb[inv], resolved, fe, ae, 100.0 * hw,
                           score, far)
