"""Hysteretic force-state mapping: a joint law fitted to the restoring force of all records at once.

The single-mode model of a preload is

``q'' + c q' + k q + f_joint(q) = Q(t)``,

with ``f_joint`` a hysteretic joint law of :mod:`jointid.joints` (Jenkins or Segalman's
four-parameter Iwan) acting on the modal coordinate.  Every steady-state record is reduced
by the multi-harmonic fit of :func:`jointid.signal.harmonics.steady_state_signals` to the
periodic ``q(t)``, ``q'(t)`` and the filtered ``q''(t)``; the force is fitted on the same
harmonics.  The restoring force ``Q - q''`` then holds the harmonics ``1..H`` only, so the
model is compared with it harmonic by harmonic (a Galerkin projection, as in harmonic
balance): the law's force over the reconstructed period is evaluated by its ``aft`` (the
slip history carried through the period twice, Masing) and projected on the same
harmonics.  Comparing time samples instead would fit the law's harmonics above ``H``
against nothing, which biases the force scale.

The parameters split into a linear part (``k``, ``c`` and the law's force scale: ``kt`` of
Jenkins, ``K_T`` of Iwan) solved by least squares at every value of the nonlinear part
(Jenkins: the slip displacement; Iwan: ``phi_max``, ``chi``, ``beta``), which is found by
variable projection (a coarse grid, then Gauss-Newton on the projected residual with its
exact Jacobian: an element's force depends on its slip displacement through the sign of its
last slip only, so the law's sampled force is differentiated in closed form per element).

Standard errors come from the sandwich covariance of all parameters, nonlinear ones
included (their columns the same derivatives of the law's projected force), with the
noise model of the records: white force noise on the force's harmonic coefficients and
white acceleration noise on those of ``q''``, which also moves ``q`` and ``q'`` and
through the law's exact ``aft`` Jacobian its force.  The noise levels are the residual
rms of fits with many harmonics.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field, replace

import numpy as np
from scipy import optimize

from .._blas import single_threaded
from ..errors import IdentificationError, IllConditionedWarning
from ..joints import Iwan4, Jenkins
from ..joints.sliders import BLOCK_ELEMENTS, play_block
from ..signal.harmonics import StateSignals
from ..numerics.intervals import Z95 as _Z95

__all__ = ["HystereticForceStateMapping", "HystereticFit", "LAWS", "first_harmonic_peak", "first_harmonic_response"]

#: Joint laws this estimator fits; ``"<law>+cubic"`` adds a cubic spring ``-k3 q^3`` beside the law.
LAWS = ("jenkins", "iwan4", "jenkins+cubic", "iwan4+cubic")
#: Suffix of a law name that adds the cubic spring.
CUBIC = "+cubic"
#: Harmonics used to estimate a channel's noise level (fewer when the sampling does not allow them).
NOISE_HARMONICS = 25
#: Local searches started from the coarse grid's best distinct points.
N_STARTS = 3
#: Evaluations of a probe of the second and later starts: a search that has not converged then goes on only
#: while its cost is below ``PROBE_RATIO`` times the best found (on the test campaigns the other basins stall
#: at 10-350 times the best cost, and the searches there took two thirds of the evaluations).
PROBE_EVALUATIONS = 10
PROBE_RATIO = 2.0
#: Tolerances of those searches: they only choose the basin that the final search (full period, tolerances
#: 1e-12) refines, and a relative cost change of 1e-8 is ~1e-6 in chi-square, far below one standard error.
SEARCH_TOL = 1e-8


def _basis(tau, omega, n_harmonics, dc=True):
    """``[1, cos wt, sin wt, cos 2wt, ...]`` (harmonics by repeated complex products, exact to a few ulp)."""
    z = np.exp(1j * omega * np.asarray(tau, float))
    Z = np.cumprod(np.broadcast_to(z[:, None], (z.size, n_harmonics)), axis=1)
    cols = np.empty((z.size, 2 * n_harmonics))
    cols[:, 0::2] = Z.real
    cols[:, 1::2] = Z.imag
    return np.column_stack([np.ones(z.size), cols]) if dc else cols


def _noise_level(tau, x, omega, n_harmonics, dt):
    """Residual rms of each column of ``x`` (samples, signals) outside ``n_harmonics`` harmonics (below
    Nyquist), corrected for the fitted columns."""
    nh = int(max(1, min(n_harmonics, math.ceil(0.5 / (dt * omega / (2 * np.pi))) - 1)))
    B = _basis(tau, omega, nh)
    coef = np.linalg.solve(B.T @ B, B.T @ x)
    r = x - B @ coef
    return np.sqrt(np.sum(r * r, axis=0) / max(x.shape[0] - B.shape[1], 1))


@dataclass
class _Record:
    H: int
    omega: float
    y: np.ndarray  # (2H,) force minus acceleration coefficients, harmonics 1..H
    d: np.ndarray  # displacement coefficients (2H+1)
    v: np.ndarray  # velocity coefficients (2H+1)
    Ld: np.ndarray  # d = Ld a (2H+1, 2H+1)
    Lv: np.ndarray
    C: np.ndarray  # (B^T B)^-1 over the record (2H+1 square)
    U: np.ndarray  # Cholesky factor of the Gram of harmonics 1..H
    s_force: float
    s_accel: float
    q_max: float
    frequency_hz: float
    n_samples: int

    @property
    def rows(self) -> int:
        """Coefficients of the restoring force compared (harmonics ``1..`` of ``U``'s size)."""
        return self.U.shape[0]

    def fitted_on(self, n_harmonics):
        """The record compared on its first ``n_harmonics`` harmonics only (``None``: all of them)."""
        if n_harmonics is None or n_harmonics >= self.H:
            return self
        m = 2 * int(n_harmonics)
        G = self.U.T @ self.U
        return replace(self, U=np.linalg.cholesky(G[:m, :m]).T)


def _prepare(sig: StateSignals, i: int) -> _Record:
    if not isinstance(sig, StateSignals):
        raise IdentificationError(f"record {i}: the hysteretic force-state mapping expects StateSignals, "
                                  f"got {type(sig).__name__}")
    acc = sig.acceleration
    H, w = acc.n_harmonics, sig.omega
    t = np.asarray(sig.t, float)
    tau = t - acc.t0
    B = _basis(tau, w, H)
    G = B.T @ B
    F = np.linalg.solve(G, B.T @ np.asarray(sig.force, float))
    a = np.asarray(acc.coefficients, float)
    h = np.repeat(np.arange(1, H + 1), 2) * w
    Lv = np.zeros((2 * H + 1, 2 * H + 1))  # integral: v_cos = -a_sin / (h w), v_sin = a_cos / (h w)
    for j in range(H):
        Lv[1 + 2 * j, 2 + 2 * j] = -1.0 / h[2 * j]
        Lv[2 + 2 * j, 1 + 2 * j] = 1.0 / h[2 * j]
    Ld = Lv @ Lv
    dt = (t[-1] - t[0]) / (t.size - 1)
    s_f, s_a = (float(v) for v in _noise_level(tau, np.column_stack([np.asarray(sig.force, float),
                                                                     np.asarray(sig.accel_measured, float)]),
                                               w, NOISE_HARMONICS, dt))
    C = np.linalg.inv(G)
    return _Record(H, w, (F - a)[1:], Ld @ a, Lv @ a, Ld, Lv, C, np.linalg.cholesky(G[1:, 1:]).T, s_f, s_a,
                   sig.q_max(), sig.frequency_hz, t.size)


# --- the laws: unit-scale shapes of their nonlinear parameters -------------------------------------------------
class _JenkinsShape:
    names = ("log_slip_displacement",)
    scale_name = "kt"

    def __init__(self, **_):
        pass

    def unit(self, eta):
        return Jenkins(1.0, math.exp(eta[0]))

    @staticmethod
    def reach(eta):
        return ("the slip displacement", math.exp(eta[0]), "slip")

    def law(self, scale, eta):
        return Jenkins(scale, scale * math.exp(eta[0]))

    @staticmethod
    def unit_sliders(eta):
        """``(k, phi, dk, dphi)``: the unit law's elements and their derivatives by ``eta`` (``(ne, m)``)."""
        a_s = math.exp(eta[0])
        return np.ones(1), np.array([a_s]), np.zeros((1, 1)), np.array([[a_s]])

    def bounds(self, qmax):
        return [math.log(qmax.min() * 1e-3)], [math.log(qmax.max() * 10.0)]

    def grid(self, qmax):
        return [np.array([e]) for e in np.linspace(math.log(qmax.min() / 30), math.log(qmax.max() * 2), 28)]

    def physical(self, p):
        """(names, values, Jacobian from ``p``, units) of the physical parameters from ``(k, c, kt, log a_s)``."""
        k, c, kt, la = p
        a_s = math.exp(la)
        J = np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, a_s, kt * a_s], [0, 0, 0, a_s]], float)
        return (("k", "c", "kt", "Fs", "slip_displacement"), np.array([k, c, kt, kt * a_s, a_s]), J,
                ("N/m", "N s/m", "N/m", "N", "m"))


class _Iwan4Shape:
    names = ("log_phi_max", "chi", "beta")
    scale_name = "K_T"

    def __init__(self, n_sliders=60, phi_min_ratio=1e-4, **_):
        self.n_sliders = int(n_sliders)
        self.phi_min_ratio = float(phi_min_ratio)

    @staticmethod
    def _fs_per_kt(eta):
        pm, chi, beta = math.exp(eta[0]), eta[1], eta[2]
        return pm * (beta + (chi + 1.0) / (chi + 2.0)) / (1.0 + beta)

    def law(self, scale, eta):
        return Iwan4(F_S=scale * self._fs_per_kt(eta), K_T=scale, chi=eta[1], beta=max(eta[2], 0.0),
                     n_sliders=self.n_sliders, phi_min_ratio=self.phi_min_ratio)

    def unit(self, eta):
        return self.law(1.0, eta)

    def _elements(self, eta):
        sl = self.unit(eta).sliders
        k, phi = sl.stiffness, sl.slip_displacement
        if k.size == self.n_sliders:  # no delta element (beta = 0): one of zero stiffness keeps the shapes
            k, phi = np.append(k, 0.0), np.append(phi, math.exp(eta[0]))
        return k, phi

    def unit_sliders(self, eta):
        """``(k, phi, dk, dphi)``: the unit law's elements and their derivatives by ``eta`` (``(3, m)``).

        The derivatives are central differences of the discretisation's closed-form weights
        (no force evaluation; one-sided at ``beta = 0``, where the law clips ``beta``).
        """
        eta = np.asarray(eta, float)
        k, phi = self._elements(eta)
        dk, dphi = np.empty((3, k.size)), np.empty((3, k.size))
        for i in range(3):
            h = 1e-6 * max(1.0, abs(eta[i]))
            e1, e2 = eta.copy(), eta.copy()
            e1[i] += h
            e2[i] -= h
            if i == 2:
                e2[i] = max(e2[i], 0.0)
            (k1, p1), (k2, p2) = self._elements(e1), self._elements(e2)
            dk[i], dphi[i] = (k1 - k2) / (e1[i] - e2[i]), (p1 - p2) / (e1[i] - e2[i])
        return k, phi, dk, dphi

    @staticmethod
    def reach(eta):
        return ("phi_max", math.exp(eta[0]), "macro-slip")

    def bounds(self, qmax):
        return [math.log(qmax.min() * 1e-2), -0.95, 0.0], [math.log(qmax.max() * 20.0), 0.95, 20.0]

    def grid(self, qmax):
        # phi_max inside the measured amplitudes (where the delta element's slip shows, beta is seen) and one
        # value beyond them (micro-slip only); starting beyond the data, beta has no gradient and the search stalls
        out = []
        for pm in list(np.geomspace(qmax.min(), qmax.max(), 6)) + [3.0 * qmax.max()]:
            for chi in (-0.6, -0.2, 0.3):
                for beta in (0.3, 1.5):
                    out.append(np.array([math.log(pm), chi, beta]))
        return out

    def physical(self, p):
        k, c, kt = p[:3]
        eta = p[3:]
        r = self._fs_per_kt(eta)
        g = np.zeros(3)
        h = 1e-6
        for i in range(3):
            e1, e2 = eta.copy(), eta.copy()
            e1[i] += h
            e2[i] -= h
            g[i] = (self._fs_per_kt(e1) - self._fs_per_kt(e2)) / (2 * h)
        pm = math.exp(eta[0])
        J = np.zeros((7, 6))
        J[0, 0] = J[1, 1] = J[2, 2] = 1.0
        J[3, 2] = r
        J[3, 3:] = kt * g
        J[4, 4] = J[5, 5] = 1.0
        J[6, 3] = pm
        return (("k", "c", "K_T", "F_S", "chi", "beta", "phi_max"), np.array([k, c, kt, kt * r, eta[1], eta[2], pm]),
                J, ("N/m", "N s/m", "N/m", "N", "1", "1", "m"))


_SHAPES = {"jenkins": _JenkinsShape, "iwan4": _Iwan4Shape}


@dataclass(frozen=True)
class HystereticFit:
    """A hysteretic joint law fitted over the records of a preload.

    Attributes
    ----------
    law_name : str
        ``"jenkins"`` or ``"iwan4"``.
    names, values, stderr, units : tuple / array
        The physical parameters: ``k`` (linear stiffness besides the joint), ``c`` (viscous
        damping) and the law's own (Jenkins ``kt``, ``Fs``, ``slip_displacement``; Iwan
        ``K_T``, ``F_S``, ``chi``, ``beta``, ``phi_max``), modal units per unit mass.
    covariance : array
        Sandwich covariance of ``values``.
    law : JointLaw
        The fitted joint law.
    q_max, frequency_hz : array
        Per record.
    residual_rms : float
        RMS of the weighted harmonic residual over the noise expected from the records (about one
        for an adequate model).
    """

    law_name: str
    names: tuple
    values: np.ndarray
    stderr: np.ndarray
    units: tuple
    covariance: np.ndarray = field(repr=False)
    law: object = field(repr=False)
    q_max: np.ndarray = field(repr=False)
    frequency_hz: np.ndarray = field(repr=False)
    residual_rms: float = float("nan")
    n_records: int = 0
    warnings: tuple = ()

    def get(self, name) -> float:
        return float(self.values[self.names.index(name)])

    def get_stderr(self, name) -> float:
        return float(self.stderr[self.names.index(name)])

    def ci95(self, name) -> tuple:
        v, s = self.get(name), self.get_stderr(name)
        return (v - _Z95 * s, v + _Z95 * s)

    @property
    def k(self) -> float:
        return self.get("k")

    @property
    def c(self) -> float:
        return self.get("c")

    @property
    def k3(self) -> float:
        """Cubic spring beside the law (``-k3 q^3``; 0 for a law fitted without it)."""
        return self.get("k3") if "k3" in self.names else 0.0

    @property
    def stiffness0(self) -> float:
        """Stiffness at vanishing amplitude: ``k`` plus the law's stuck stiffness."""
        return self.k + float(self.law.first_harmonic(1e-15)[0])

    def restoring_force(self, u_t, v_t):
        """``k u + c v + f_joint(u) - k3 u^3`` over one sampled period (time on the last axis)."""
        u = np.asarray(u_t)
        return self.k * u + self.c * np.asarray(v_t) + self.law.aft(u_t, jacobian=False)[0] - self.k3 * u**3

    def first_harmonic(self, a):
        """``(K(a), L(a))``: stiffness and loss stiffness of the model's first harmonic at amplitude ``a``."""
        k_eq, k_loss = self.law.first_harmonic(a)
        return self.k + k_eq - 0.75 * self.k3 * np.asarray(a) ** 2, k_loss

    def peak(self, force_amplitude):
        """Peak of the frequency response at a force amplitude by first-harmonic balance.

        See :func:`first_harmonic_peak`; returns ``(peak_frequency_hz, peak_q_max)``.
        """
        return first_harmonic_peak(self.k, self.c, self.law, force_amplitude, k3=self.k3)

    def loop(self, signals, n_time=512):
        """A record's filtered hysteresis loop (:class:`~jointid.identify.hysteresis.HysteresisLoop`) with this model.

        Over one period of the record's harmonic fits (``n_time`` equal steps; the force and
        the acceleration on the harmonics ``1..H`` of the fit, as in the polynomial models'
        filtered loops), the measured ``Q - q'' - K0 q`` against the model's
        ``k q + c q' + f_joint(q) - k3 q^3 - K0 q``, with ``K0`` the model's stiffness at
        vanishing amplitude (:attr:`stiffness0`: the linear part left out of both, as
        ``omega1^2 q`` is for the polynomial models).  The law's force is its periodic
        (Masing) force over that period.
        """
        from .hysteresis import HysteresisLoop

        r = _prepare(signals, 0)
        E = _basis(2 * np.pi * np.arange(int(n_time)) / int(n_time), 1.0, r.H)
        q, v = E @ r.d, E @ r.v
        k0 = self.stiffness0
        measured = E[:, 1:] @ r.y - k0 * q
        return HysteresisLoop(q, measured, self.restoring_force(q, v) - k0 * q, True, float(signals.frequency_hz))

    def summary(self) -> dict:
        return {
            "law": self.law_name,
            "parameters": {n: float(v) for n, v in zip(self.names, self.values)},
            "stderr": {n: float(s) for n, s in zip(self.names, self.stderr)},
            "ci95": {n: [float(v - _Z95 * s), float(v + _Z95 * s)] for n, v, s in zip(self.names, self.values, self.stderr)},
            "units": dict(zip(self.names, self.units)),
            "covariance": self.covariance.tolist(),
            "joint_law": self.law.summary(),
            "q_max": self.q_max.tolist(),
            "frequency_hz": self.frequency_hz.tolist(),
            "residual_rms": float(self.residual_rms),
            "n_records": int(self.n_records),
            "warnings": list(self.warnings),
        }

    def report(self) -> str:
        lines = [f"hysteretic force-state mapping ({self.law_name}) over {self.n_records} records, "
                 f"q_max {self.q_max.min():.4g} .. {self.q_max.max():.4g}, "
                 f"weighted residual rms {self.residual_rms:.3g} (1 = noise)"]
        for n, v, s, u in zip(self.names, self.values, self.stderr, self.units):
            lo, hi = v - _Z95 * s, v + _Z95 * s
            lines.append(f"  {n:>18} = {v:.6g} ± {s:.2g} {u}   95 % [{lo:.6g}, {hi:.6g}]")
        lines += [f"  warning: {w}" for w in self.warnings]
        return "\n".join(lines)


def first_harmonic_peak(k, c, law, force_amplitude, *, k3=0.0):
    """Peak ``(frequency_hz, q_max)`` of ``q'' + c q' + k q + f_joint(q) = Q cos(omega t)`` (first harmonic).

    With the law's first-harmonic stiffness ``K(a) = k + k_eq(a) - 3/4 k3 a^2`` (``k3``: a cubic spring
    ``-k3 q^3`` beside the law) and loss ``L(a) = k_loss(a)``,
    the response amplitude ``a`` at ``omega`` solves ``Q^2 = a^2 ((K - omega^2)^2 + (c omega + L)^2)``.
    The peak is the largest ``a`` for which some ``omega`` solves it: ``a*`` with
    ``min_omega a^2 (...) = Q^2``, found by a root in ``a`` (folds need no continuation).
    """
    Q = float(force_amplitude)

    def best(a):
        k_eq, k_loss = law.first_harmonic(a)
        K, L = k + float(k_eq) - 0.75 * k3 * a * a, float(k_loss)
        # d/dw [(K - w^2)^2 + (c w + L)^2] = 0: 4 w^3 + (2 c^2 - 4 K) w + 2 c L = 0
        roots = np.roots([4.0, 0.0, 2.0 * c * c - 4.0 * K, 2.0 * c * L])
        ws = [r.real for r in roots if abs(r.imag) <= 1e-9 * abs(r) and r.real > 0]
        if not ws:
            ws = [math.sqrt(max(K, 1e-300))]
        g = [(K - w * w) ** 2 + (c * w + L) ** 2 for w in ws]
        i = int(np.argmin(g))
        return a * a * g[i] - Q * Q, ws[i]

    lo = 1e-12
    hi = Q / max(k, 1e-300)
    while best(hi)[0] < 0:
        lo, hi = hi, hi * 2.0
        if hi > 1e12:
            raise IdentificationError(f"no peak found at force amplitude {Q:g}: the response grows without bound")
    try:
        a = optimize.brentq(lambda x: best(x)[0], lo, hi, xtol=1e-15, rtol=1e-13)
    except (RuntimeError, ValueError) as exc:
        raise IdentificationError(f"no peak found at force amplitude {Q:g}: {exc}") from None
    return best(a)[1] / (2 * np.pi), a


def first_harmonic_response(k, c, law, force_amplitude, omega, a_range=None, n_grid=400, *, k3=0.0):
    """Steady-state first-harmonic amplitudes at one forcing frequency ``omega`` [rad/s], every branch.

    The roots ``a`` of ``a^2 ((K(a) - omega^2)^2 + (c omega + L(a))^2) = Q^2`` (see
    :func:`first_harmonic_peak`), located on a logarithmic grid of amplitudes over ``a_range``
    (default ``Q / (k + K_T) * 1e-3`` to ``Q / (c omega) * 2``, the largest possible) and refined by
    Brent's method; increasing order.  Three roots mean a fold: the middle one is unstable.
    Pick the branch of a measured dwell by the root nearest its amplitude.
    """
    Q, w = float(force_amplitude), float(omega)

    def g(a):
        k_eq, k_loss = law.first_harmonic(a)
        K, L = k + float(k_eq) - 0.75 * k3 * a * a, float(k_loss)
        return a * a * ((K - w * w) ** 2 + (c * w + L) ** 2) - Q * Q

    if a_range is None:
        hi = 2.0 * Q / max(c * w, 1e-300)
        lo = hi * 1e-7
    else:
        lo, hi = (float(x) for x in a_range)
    grid = np.geomspace(lo, hi, int(n_grid))
    vals = np.array([g(a) for a in grid])
    out = []
    for i in np.flatnonzero(np.sign(vals[:-1]) * np.sign(vals[1:]) < 0):
        out.append(optimize.brentq(g, grid[i], grid[i + 1], xtol=1e-300, rtol=1e-13))
    return np.array(out)


class HystereticForceStateMapping:
    """Fit a hysteretic joint law to the restoring force of a preload's records (all levels at once).

    Parameters
    ----------
    law : {"jenkins", "iwan4", "jenkins+cubic", "iwan4+cubic"}
        The joint law: a Jenkins element (``kt``, ``Fs``) or Segalman's four-parameter Iwan
        model (``K_T``, ``F_S``, ``chi``, ``beta``, evaluated on its discretisation).  With
        ``+cubic`` a cubic spring ``-k3 q^3`` (seed sign: ``k3 > 0`` softens) acts beside it: a
        joint whose stiffness also changes elastically with amplitude (the contact's geometry),
        which the law alone would imitate by slip and extrapolate wrongly.  ``k3`` is one more
        linear parameter of the variable projection.
    n_time : int
        Samples of the period at which the law's force is evaluated (``aft``).
    n_sliders, phi_min_ratio : int, float
        Discretisation of the four-parameter Iwan model (:func:`jointid.joints.discretize_iwan4`).
    start : sequence of float, optional
        Starting nonlinear parameters (Jenkins: ``log`` slip displacement; Iwan: ``log phi_max``,
        ``chi``, ``beta``) instead of the coarse grid.
    search_evaluations, max_evaluations : int
        Evaluations allowed to each local search from the coarse grid and to the final one.
    fit_harmonics : int, optional
        Compare the restoring force on its first ``fit_harmonics`` harmonics only (default: all
        the records' harmonics).  A single-mode model of a structure represents the fundamental;
        the higher harmonics of measured responses also carry the higher modes (on the virtual
        rig the 5th and 6th harmonics of mode 1 lie near mode 2), which no single-mode law can
        follow and which then bias its parameters.
    micro_slip_reach : float, optional
        For the Iwan law: when the fitted macro-slip onset ``phi_max`` lies below this multiple
        of the largest measured amplitude, the fit is repeated with ``phi_max`` held at or above
        it, and that micro-slip law is kept if it fits as well (chi-square increase below 4 on the
        calibrated residual).  Records that do not show the joint's macro-slip cannot place its
        onset; a law that ends its micro-slip just beyond the data would change regime where
        nothing supports it, and extrapolate with too little dissipation.  A warning says so.
    jacobian : {"exact", "2-point", "3-point"}
        Jacobian of the projected residual in the searches: ``"exact"`` (default) differentiates
        the law's sampled force in its nonlinear parameters (the element positions' piecewise
        dependence on the slip displacements) and projects it (Golub-Pereyra), at about the cost
        of one force evaluation; the others are ``least_squares``' finite differences (each
        column one or two more evaluations) with the earlier search (every start to convergence at
        tolerances 1e-12, the sandwich's columns by central differences), kept to compare.

    Attributes
    ----------
    result_ : HystereticFit
    coef_, stderr_ : array
        Physical parameters and their standard errors (``result_.names``).
    """

    def __init__(self, law="jenkins", n_time=512, n_sliders=60, phi_min_ratio=1e-4, start=None, search_evaluations=200,
                 max_evaluations=400, fit_harmonics=None, micro_slip_reach=None, jacobian="exact"):
        if jacobian not in ("exact", "2-point", "3-point"):
            raise IdentificationError(f"jacobian must be 'exact', '2-point' or '3-point', got {jacobian!r}")
        self.jacobian = jacobian
        self.fit_harmonics = None if fit_harmonics is None else int(fit_harmonics)
        if self.fit_harmonics is not None and self.fit_harmonics < 1:
            raise IdentificationError(f"fit_harmonics must be at least 1, got {fit_harmonics!r}")
        self.micro_slip_reach = None if micro_slip_reach is None else float(micro_slip_reach)
        self.search_evaluations = int(search_evaluations)
        self.max_evaluations = int(max_evaluations)
        self.law = law
        self.n_time = n_time
        self.n_sliders = n_sliders
        self.phi_min_ratio = phi_min_ratio
        self.start = start

    # --- model pieces -----------------------------------------------------------------
    def _periods(self, recs, n=None):
        n = int(self.n_time if n is None else n)
        th = 2 * np.pi * np.arange(n) / n
        Hm = max(r.H for r in recs)
        E = _basis(th, 1.0, Hm)  # (n, 2Hm+1) at phase theta
        U = np.array([E[:, : 2 * r.H + 1] @ r.d for r in recs])  # displacement over one period
        P = E[:, 1:].T * (2.0 / n)  # projection on harmonics 1..Hm
        return U, P, E

    def _law_coeffs(self, shape, eta, U, P, recs, jac=False):
        f, D = shape.unit(eta).aft(U, jacobian=jac)
        out = f @ P.T  # (nr, 2Hm)
        return out, D

    @staticmethod
    def _law_coeffs_d(shape, eta, U, P):
        """The unit law's projected force ``(nr, 2Hm)`` and its exact derivatives by ``eta`` ``(ne, nr, 2Hm)``.

        The elements' positions over the two sweeps of :meth:`JointLaw.aft` (virgin start, the
        second sweep periodic); an element's force ``k (u - x)`` depends on its stiffness
        directly and on its slip displacement through the last slip: ``x = u_j -+ phi`` there and
        constant since, so ``d (u - x) / d phi`` is the sign of that slip (zero if it never slipped).
        The signs are read from the positions' change under a relative change of ``phi`` of 1e-6
        (``-+ 1e-6 phi`` exactly, rounded; the slips' instants do not move), the stiffnesses' and
        slip displacements' derivatives by ``eta`` come from ``shape.unit_sliders``.
        """
        k, phi, dk, dphi = shape.unit_sliders(eta)
        nr, n = U.shape
        m = k.size
        kd = np.ascontiguousarray((k * dphi).T)  # (m, ne): the force's change per unit slip sign
        dkT = np.ascontiguousarray(dk.T)
        phi2 = phi * (1.0 + 1e-6)  # the slip signs, from the positions' change with phi (x = u_j -+ phi)
        inv = 1.0 / (phi2 - phi)
        x = play_block(U, np.zeros((nr, m)), phi, end_only=True)  # the first sweep's end states
        x2 = play_block(U, np.zeros((nr, m)), phi2, end_only=True)
        f, df = np.empty((n, nr)), np.empty((n, nr, dk.shape[0]))
        tb = max(2, BLOCK_ELEMENTS // max(nr * m, 1))
        for t0 in range(0, n, tb):  # the periodic sweep a block of samples at a time (as aft)
            t1 = min(n, t0 + tb)
            X = play_block(U[:, t0:t1], x, phi)  # (tb, nr, m)
            X2 = play_block(U[:, t0:t1], x2, phi2)
            sg = np.rint((X - X2) * inv).reshape(-1, m)  # -1, 0 (never slipped) or 1
            e = (U[:, t0:t1].T[:, :, None] - X).reshape(-1, m)  # the elements' deflection
            f[t0:t1] = (e @ k).reshape(t1 - t0, nr)
            df[t0:t1] = (e @ dkT + sg @ kd).reshape(t1 - t0, nr, -1)
            x, x2 = X[-1], X2[-1]
        f, df = f.T, df.transpose(2, 1, 0)  # (nr, n), (ne, nr, n)
        return f @ P.T, df @ P.T

    def _objective(self, shape, U, P, recs, W, c3=None):
        """``(fun, jac)`` of the projected residual over ``eta`` for ``least_squares``.

        ``jac`` is the exact variable-projection Jacobian (Golub and Pereyra):
        ``-(I - X X^+) dX beta - (X^+)^T dX^T r``, with ``dX`` the law column's derivative; it
        costs about two force evaluations and is computed only where the search asks for it.
        """
        def fun(eta):
            return self._projected(shape, np.asarray(eta, float), U, P, recs, W, c3)[0]

        def jac(eta):  # only where the search takes it (after a step is accepted), not at every trial point
            eta = np.asarray(eta, float)
            fc, dfc = self._law_coeffs_d(shape, eta, U, P)
            X, y = self._assemble(fc, recs, W, c3)
            beta, *_ = np.linalg.lstsq(X, y, rcond=None)
            r = y - X @ beta
            Xp = np.linalg.pinv(X)
            J = np.empty((r.size, eta.size))
            for j in range(eta.size):
                dcol = self._assemble(dfc[j], recs, W, None, law_only=True)
                a = beta[2] * dcol
                J[:, j] = -(a - X @ (Xp @ a)) - Xp[2] * (dcol @ r)
            return J

        return fun, jac

    @staticmethod
    def _cubic_coeffs(U, P):
        """Harmonics of ``-q^3`` over each record's period (the column of ``k3``)."""
        return -(U**3) @ P.T

    def _design(self, shape, eta, U, P, recs, W, c3=None):
        fc, _ = self._law_coeffs(shape, eta, U, P, recs)
        return self._assemble(fc, recs, W, c3)

    @staticmethod
    def _assemble(fc, recs, W, c3=None, law_only=False):
        """Weighted design and data from the law's projected force ``fc`` (``law_only``: its column alone)."""
        blocks, ys = [], []
        for i, r in enumerate(recs):
            m, n = 2 * r.H, r.rows
            if law_only:
                blocks.append(W[i] * (r.U @ fc[i, :m][:n]))
                continue
            cols = [r.d[1:], r.v[1:], fc[i, :m]] + ([] if c3 is None else [c3[i, :m]])
            X = np.column_stack(cols)[:n]
            blocks.append(W[i] * (r.U @ X))
            ys.append(W[i] * (r.U @ r.y[:n]))
        if law_only:
            return np.concatenate(blocks)
        return np.vstack(blocks), np.concatenate(ys)

    def _projected(self, shape, eta, U, P, recs, W, c3=None):
        X, y = self._design(shape, eta, U, P, recs, W, c3)
        beta, *_ = np.linalg.lstsq(X, y, rcond=None)
        return y - X @ beta, beta

    # --- fit --------------------------------------------------------------------------
    @single_threaded
    def fit(self, signals_list, *, context=""):
        if self.law not in LAWS:
            raise IdentificationError(f"law must be one of {LAWS}, got {self.law!r}")
        base, cubic = self.law.removesuffix(CUBIC), self.law.endswith(CUBIC)
        sigs = list(signals_list)
        if len(sigs) < 3:
            raise IdentificationError(f"{context}the hysteretic force-state mapping needs at least 3 records, got "
                                      f"{len(sigs)}")
        shape = _SHAPES[base](n_sliders=self.n_sliders, phi_min_ratio=self.phi_min_ratio)
        recs = [_prepare(s, i).fitted_on(self.fit_harmonics) for i, s in enumerate(sigs)]
        qmax = np.array([r.q_max for r in recs])
        W = np.array([1.0 / math.sqrt(r.s_force**2 + r.s_accel**2) for r in recs])
        U, P, E = self._periods(recs)
        c3 = self._cubic_coeffs(U, P) if cubic else None
        lo, hi = shape.bounds(qmax)

        exact = self.jacobian == "exact"

        def objective(Uo, Po, c3o):
            if exact:
                return self._objective(shape, Uo, Po, recs, W, c3o)
            return (lambda eta: self._projected(shape, np.asarray(eta, float), Uo, Po, recs, W, c3o)[0]), self.jacobian

        proj, proj_jac = objective(U, P, c3)
        lo_a, hi_a = np.array(lo) + 1e-9, np.array(hi) - 1e-9
        opts = dict(bounds=(lo, hi), method="trf", x_scale=1.0, xtol=1e-12, ftol=1e-12, gtol=1e-12)
        if self.start is not None:
            eta0 = np.clip(np.asarray(self.start, float), lo_a, hi_a)
        else:  # coarse grid and local searches on a short period, then the full period from the best of them
            Uc, Pc, _ = self._periods(recs, min(128, int(self.n_time)))
            c3c = self._cubic_coeffs(Uc, Pc) if cubic else None

            coarse, coarse_jac = objective(Uc, Pc, c3c)
            cands = [np.clip(g, lo_a, hi_a) for g in shape.grid(qmax)]
            costs = np.array([float(np.sum(self._projected(shape, g, Uc, Pc, recs, W, c3c)[0] ** 2)) for g in cands])
            starts = []
            for i in np.argsort(costs):
                if all(np.max(np.abs(cands[i] - s0)) > 0.6 for s0 in starts):
                    starts.append(cands[i])
                if len(starts) == N_STARTS:
                    break
            tol = SEARCH_TOL if exact else opts["xtol"]
            search = {**opts, "xtol": tol, "ftol": tol, "gtol": tol}
            best = optimize.least_squares(coarse, starts[0], jac=coarse_jac, max_nfev=self.search_evaluations, **search)
            for s0 in starts[1:]:  # the others probed first; searched on only while they can compete
                budget = self.search_evaluations
                probe = min(PROBE_EVALUATIONS, budget) if exact else budget
                r = optimize.least_squares(coarse, s0, jac=coarse_jac, max_nfev=probe, **search)
                if r.status == 0 and r.cost < PROBE_RATIO * best.cost and budget > r.nfev:
                    r = optimize.least_squares(coarse, np.clip(r.x, lo_a, hi_a), jac=coarse_jac,
                                               max_nfev=budget - r.nfev, **search)
                best = r if r.cost < best.cost else best
            eta0 = np.clip(best.x, lo_a, hi_a)
        opts["jac"] = proj_jac
        sol = optimize.least_squares(proj, eta0, max_nfev=self.max_evaluations, **opts)
        warn = []
        sol, lo = self._micro_slip(shape, sol, proj, opts, lo, hi, qmax, context, warn)
        eta = np.asarray(sol.x, float)
        res, beta = self._projected(shape, eta, U, P, recs, W, c3)
        p = np.concatenate([beta[:3], eta, beta[3:]])  # (k, c, scale, eta..., [k3])
        at_bound = [n for n, v, l, h in zip(shape.names, eta, lo, hi) if min(v - l, h - v) <= 1e-6 * (1 + abs(v))]
        if at_bound:
            warn.append(f"{context}{', '.join(at_bound)} at the edge of its range: the parameter is not resolved "
                        "and its standard error does not hold")
        reach = shape.reach(eta)
        if reach is not None and reach[1] > qmax.max():
            warn.append(f"{context}{reach[0]} = {reach[1]:.4g} lies beyond the largest measured amplitude "
                        f"{qmax.max():.4g}: the records do not reach the joint's {reach[2]}, which the fit extrapolates "
                        "(its parameters are not resolved and a prediction above the measured levels is not supported)")
        if beta[0] < 0:
            warn.append(f"{context}the linear stiffness k = {beta[0]:.4g} besides the joint is negative: the joint law "
                        "and k are not separated by these records")
        if beta[2] <= 0:
            warn.append(f"{context}the joint's force scale {shape.scale_name} = {beta[2]:.4g} is not positive: "
                        f"the {self.law} law does not describe these records")
            raise IdentificationError(warn[-1])
        cov = self._sandwich(shape, p, U, P, E, recs, W, cubic)
        n_law = 3 + eta.size
        names, vals, J, units = shape.physical(p[:n_law])
        if cubic:  # k3 passes through, last
            J = np.block([[J, np.zeros((J.shape[0], 1))], [np.zeros((1, n_law)), np.ones((1, 1))]])
            names, vals, units = names + ("k3",), np.append(vals, p[-1]), units + ("N/m^3",)
        pcov = J @ cov @ J.T
        se = np.sqrt(np.clip(np.diag(pcov), 0.0, None))
        dof = max(res.size - p.size, 1)
        rms = float(np.sqrt(res @ res / dof))
        for w in warn:
            warnings.warn(w, IllConditionedWarning, stacklevel=2)
        law = shape.law(beta[2], eta)
        self.result_ = HystereticFit(self.law, names, vals, se, units, pcov, law, qmax,
                                     np.array([r.frequency_hz for r in recs]), rms, len(recs), tuple(warn))
        self.coef_ = vals
        self.stderr_ = se
        self.parameters_ = p
        self.shape_parameters_ = eta
        self.covariance_ = cov
        return self

    def _micro_slip(self, shape, sol, proj, opts, lo, hi, qmax, context, warn):
        """``(solution, lower bounds)``: the fit with the macro-slip onset beyond ``micro_slip_reach`` times the
        largest amplitude when it fits as well (see the class notes), else the free one."""
        reach = shape.reach(np.asarray(sol.x, float))
        if self.micro_slip_reach is None or reach is None or reach[2] != "macro-slip":
            return sol, lo
        floor = self.micro_slip_reach * float(qmax.max())
        if reach[1] >= floor:
            return sol, lo
        lo2 = list(lo)
        lo2[0] = max(lo[0], math.log(floor))
        if lo2[0] >= hi[0]:
            return sol, lo
        # starts at, and well beyond, the floor (the micro-slip shape hardly depends on phi_max there)
        starts = []
        for lp in (lo2[0] + 0.05, lo2[0] + math.log(3.0), lo2[0] + math.log(10.0)):
            x0 = np.clip(np.asarray(sol.x, float), np.array(lo2) + 1e-9, np.array(hi) - 1e-9)
            x0[0] = min(lp, hi[0] - 1e-6)
            starts.append(x0)
        alt = min((optimize.least_squares(proj, x0, max_nfev=self.max_evaluations, **{**opts, "bounds": (lo2, hi)})
                   for x0 in starts), key=lambda r: r.cost)
        n_res = proj(sol.x).size
        scale = 2.0 * sol.cost / max(n_res - 3 - sol.x.size, 1)  # calibrated residual variance
        dchi2 = 2.0 * (alt.cost - sol.cost) / max(scale, 1e-300)
        if dchi2 < 4.0:
            warn.append(f"{context}{reach[0]} = {reach[1]:.4g} (inside {self.micro_slip_reach:g} x the largest measured "
                        f"amplitude) is not resolved: a law in micro-slip up to {floor:.4g} fits as well (chi-square "
                        f"+{dchi2:.2g}) and is kept, the joint extrapolated in micro-slip")
            return alt, lo2
        return sol, lo

    def _sandwich(self, shape, p, U, P, E, recs, W, cubic=False):
        """Sandwich covariance of ``(k, c, scale, eta..., [k3])`` under the records' noise model."""
        beta, eta = p[:3], p[3: p.size - int(cubic)]
        k3 = float(p[-1]) if cubic else 0.0
        c3 = self._cubic_coeffs(U, P) if cubic else None
        ne = eta.size
        fc, D = self._law_coeffs(shape, eta, U, P, recs, jac=True)
        if self.jacobian == "exact":  # columns of the nonlinear parameters: the projected law force's derivatives
            dF = list(self._law_coeffs_d(shape, eta, U, P)[1])
        else:  # central differences
            dF = []
            for i in range(ne):
                h = 1e-5 * max(1.0, abs(eta[i]))
                e1, e2 = eta.copy(), eta.copy()
                e1[i] += h
                e2[i] -= h
                dF.append((self._law_coeffs(shape, e1, U, P, recs)[0] - self._law_coeffs(shape, e2, U, P, recs)[0])
                          / (2 * h))
        npar = p.size
        JtJ = np.zeros((npar, npar))
        meat = np.zeros((npar, npar))
        for i, r in enumerate(recs):
            m, n = 2 * r.H, r.rows
            J = np.column_stack([r.d[1:], r.v[1:], fc[i, :m]] + [beta[2] * d[i, :m] for d in dF]
                                + ([c3[i, :m]] if cubic else []))
            J = W[i] * (r.U @ J[:n])
            JtJ += J.T @ J
            # d(model coeffs)/d(acceleration coeffs), harmonics 1..H: k Ld + c Lv + scale * (P D E) Ld
            G = P[:m] @ D[i] @ E[:, : m + 1]  # d law coeffs / d displacement coeffs
            M = beta[0] * r.Ld[1:] + beta[1] * r.Lv[1:] + beta[2] * (G @ r.Ld)
            if cubic:  # d(-k3 q^3 harmonics)/d(displacement coefficients)
                M -= k3 * ((P[:m] * (3.0 * U[i] ** 2)) @ E[:, : m + 1]) @ r.Ld
            M[:, 1:] += np.eye(m)  # y = F - a: the acceleration enters with -1 as well
            S = r.s_force**2 * r.C[1:, 1:] + r.s_accel**2 * (M @ r.C @ M.T)
            Ue = W[i] * r.U
            Sr = Ue @ S[:n, :n] @ Ue.T
            meat += J.T @ Sr @ J
        # columns scaled to unit norm before the pseudo-inverse: k3's column (q^3) is many decades
        # smaller than the others, and pinv's relative cut-off would otherwise drop it (a zero variance)
        sc = np.sqrt(np.diag(JtJ))
        sc = np.where(sc > 0, 1.0 / np.where(sc > 0, sc, 1.0), 1.0)
        Hinv = sc[:, None] * np.linalg.pinv(sc[:, None] * JtJ * sc[None, :]) * sc[None, :]
        return Hinv @ meat @ Hinv
