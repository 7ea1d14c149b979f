"""Amplitude laws: damping ``c(q_max)``, energy dissipated per cycle, power law ``U = alpha F^n``.

Damping law (seed Eq 25-26, Table 2, Fig 6) -- the paper's two-step method
    ``c(q_max) = c0 + c1 q_max + c2 q_max^2 + ...`` fitted by weighted least squares to
    the per-record damping coefficients, each weighted by the inverse of its standard
    error (records far from resonance see the damping force through a small quadrature
    component and carry large errors).  The estimate is linear in the per-record values,
    ``coef = L c``; with their full covariance ``C`` (correlated through the shared
    stiffness of a pooled fit) its covariance is ``L C L^T``, and the law's fit is judged
    by the generalised ``chi^2 = r^T C^-1 r`` with its p-value, never by inflating errors.

Energy per cycle and power law (seed Figs 15-16)
    For every record of a group and the identified model of that group (``omega1``,
    ``k3`` of the group and the preload's damping law), the damping force over one
    steady-state period is ``F_d(t) = c(q_max) q'(t)`` and the dissipated energy is
    ``U = integral_0^T F_d q' dt`` evaluated on the reconstructed (harmonic-series)
    velocity by the periodic trapezoidal rule, which is exact for a trigonometric
    polynomial.  The force ``F`` of the power law is the amplitude of the modal elastic
    restoring force the joint carries, ``F = max_t |omega1^2 q(t) - k3 q(t)^3|`` (for an
    Iwan joint the dissipation per cycle grows as this force to the power ``3 + chi``).
    ``log U = log alpha + n log F`` is then fitted over the records of the group.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import IdentificationError
from ..rounding import format_ci, format_pm, format_value
from ..signal.harmonics import HarmonicSeries
from .uncertainty import LowRankCovariance, ci95

__all__ = [
    "DampingLaw",
    "fit_damping_law",
    "PowerLaw",
    "fit_power_law",
    "dissipated_energy",
    "elastic_force_amplitude",
    "cycle_energy",
    "model_power_law",
]


@dataclass(frozen=True)
class DampingLaw:
    """``c(q_max) = sum_k coefficients[k] q_max^k`` with standard errors."""

    coefficients: np.ndarray
    stderr: np.ndarray
    q_max: np.ndarray
    c: np.ndarray
    c_stderr: np.ndarray
    covariance: np.ndarray | None = field(default=None, repr=False)
    chi2: float = float("nan")
    dof: int = 0

    @property
    def p_value(self) -> float:
        """Probability of a ``chi^2`` at least as large if the law and the errors were right."""
        from scipy.stats import chi2 as _chi2

        return float(_chi2.sf(self.chi2, self.dof)) if self.dof > 0 and np.isfinite(self.chi2) else float("nan")

    @property
    def order(self) -> int:
        return len(self.coefficients) - 1

    def __call__(self, q_max):
        return np.polynomial.polynomial.polyval(np.asarray(q_max, float), self.coefficients)

    def summary(self) -> dict:
        return {
            "order": self.order,
            "method": "two-step (seed Eq 26): polynomial fitted to the per-record pooled c",
            "coefficients": [float(v) for v in self.coefficients],
            "stderr": [float(v) for v in self.stderr],
            "ci95": [ci95(v, s) for v, s in zip(self.coefficients, self.stderr)],
            "covariance": None if self.covariance is None else np.asarray(self.covariance).tolist(),
            "chi2_dof": float(self.chi2 / self.dof) if self.dof > 0 and np.isfinite(self.chi2) else None,
            "p_value": self.p_value if np.isfinite(self.p_value) else None,
            "n_records": int(len(self.q_max)),
        }

    def report(self) -> str:
        terms = " + ".join(
            f"({format_pm(c, s)})" + ("" if k == 0 else " q_max" if k == 1 else f" q_max^{k}")
            for k, (c, s) in enumerate(zip(self.coefficients, self.stderr))
        )
        fit = (f"; chi^2/dof {format_value(self.chi2 / self.dof, 3)}, p = {format_value(self.p_value, 2)}"
               if self.dof > 0 and np.isfinite(self.chi2) else "")
        return f"c(q_max) = {terms}   [{len(self.q_max)} records{fit}]"

    def __repr__(self):
        coef = ", ".join(f"c{k}={v:.4g}" for k, v in enumerate(self.coefficients))
        return f"DampingLaw(c(q_max): {coef}; {len(self.q_max)} records)"

    def _repr_html_(self):
        from .. import plotting

        return plotting.draw("notebook.result_html", self)

    def plot(self, ax=None, **kw):
        from .. import plotting

        return plotting.draw("identify_plots.plot_damping_law", self, ax=ax, **kw)


def fit_damping_law(q_max, c, c_stderr=None, order=2, c_covariance=None, q_max_variance=None,
                    c_q_max_covariance=None) -> DampingLaw:
    """Fit ``c(q_max)`` of the given polynomial order (seed Eq 26).

    Parameters
    ----------
    q_max, c : array
        Amplitude and damping coefficient of each record.
    c_stderr : array, optional
        Standard errors of ``c``; when given (and positive) the fit is weighted by their
        inverse.  Errors are floored at ``1e-9`` of the largest ``|c|`` so that noise-free
        data keeps finite weights.
    order : int
        Polynomial order (0 = constant).
    c_covariance : array or LowRankCovariance, optional
        Full covariance of ``c`` (records correlated through shared coefficients).  The
        coefficients' covariance is then ``L C L^T`` and ``chi^2`` the generalised one.
        Without it, ``C = diag(c_stderr^2)``; without either, the errors come from the
        scatter of the residuals (ordinary least squares).
    q_max_variance, c_q_max_covariance : array, optional
        Variance of each record's ``q_max`` and its covariance with the record's ``c`` (both
        come from the same harmonic fit).  The abscissa errors then enter as
        ``c_r - law(q_max_r)`` errors: ``var += s^2 var(q_max) - 2 s cov(c, q_max)`` with ``s``
        the slope of the fitted law at the record (errors in variables, first order).

    Examples
    --------
    >>> q = np.linspace(1e-3, 6e-3, 12)
    >>> law = fit_damping_law(q, 0.08 + 70 * q + 1e4 * q**2, order=2)
    >>> np.round(law.coefficients, 6).tolist()
    [0.08, 70.0, 10000.0]
    """
    q_max = np.asarray(q_max, float)
    c = np.asarray(c, float)
    order = int(order)
    if order < 0:
        raise IdentificationError(f"damping-law order must be >= 0, got {order}")
    ok = np.isfinite(q_max) & np.isfinite(c)
    if ok.sum() < order + 1:
        raise IdentificationError(
            f"a damping law of order {order} needs at least {order + 1} records with a damping estimate, got {int(ok.sum())}"
        )
    if c_stderr is None:
        s = np.ones_like(c)
    else:
        s = np.asarray(c_stderr, float).copy()
        floor = 1e-9 * np.nanmax(np.abs(c[ok]))
        s[~np.isfinite(s)] = np.inf
        s = np.maximum(s, floor)
    ok &= np.isfinite(s)
    qs, cs, ss = q_max[ok], c[ok], s[ok]
    scale = np.max(np.abs(qs)) or 1.0
    Vd = np.vander(qs / scale, order + 1, increasing=True)
    V = Vd / ss[:, None]
    coef_s, *_ = np.linalg.lstsq(V, cs / ss, rcond=None)
    L = np.linalg.pinv(V) / ss[None, :]  # coef_s = L @ cs
    n_ok, dof = len(cs), len(cs) - (order + 1)
    if c_covariance is not None:
        C = c_covariance if isinstance(c_covariance, LowRankCovariance) else np.asarray(c_covariance, float)
        size = C.d.shape[0] if isinstance(C, LowRankCovariance) else C.shape[0]
        if size != len(c):
            raise IdentificationError(f"c_covariance is for {size} records, c has {len(c)}")
        C = (LowRankCovariance(C.d[ok], C.U[ok], C.W, C.W_inv) if isinstance(C, LowRankCovariance)
             else _Dense(C[np.ix_(ok, ok)]))
    elif c_stderr is not None:
        C = LowRankCovariance(ss**2, np.zeros((n_ok, 0)), np.zeros((0, 0)))
    else:
        C = None
    if C is not None and q_max_variance is not None:
        slope = np.polynomial.polynomial.polyval(qs / scale, np.polynomial.polynomial.polyder(coef_s)) / scale
        qv = np.asarray(q_max_variance, float)[ok]
        cq = np.zeros_like(qv) if c_q_max_covariance is None else np.asarray(c_q_max_covariance, float)[ok]
        extra = slope**2 * qv - 2 * slope * cq
        C = C.add_diagonal(extra)
    if C is not None:
        cov_s = C.congruence(L)
        # generalised least squares residual: chi^2 with n - p degrees of freedom under the law
        Ci_V, Ci_c = C.solve(Vd), C.solve(cs)
        b = np.linalg.lstsq(Vd.T @ Ci_V, Vd.T @ Ci_c, rcond=None)[0]
        r = cs - Vd @ b
        chi2 = float(r @ C.solve(r)) if dof > 0 else float("nan")
    else:
        resid = cs - Vd @ coef_s
        cov_s = np.linalg.pinv(Vd.T @ Vd) * float(resid @ resid) / max(dof, 1)
        chi2 = float("nan")
    powers = scale ** np.arange(order + 1)
    coef = coef_s / powers
    cov = cov_s / np.outer(powers, powers)
    se = np.sqrt(np.clip(np.diag(cov), 0, None))
    return DampingLaw(coef, se, q_max, c, s if c_stderr is not None else np.full_like(c, np.nan), cov, chi2,
                      max(dof, 0))


class _Dense:
    """A dense covariance with the two operations the damping law needs."""

    def __init__(self, C):
        C = 0.5 * (C + C.T)
        self.C = C + np.eye(len(C)) * (1e-300 + 1e-15 * np.max(np.abs(np.diag(C)), initial=0.0))

    def congruence(self, L):
        return L @ self.C @ L.T

    def solve(self, b):
        return np.linalg.solve(self.C, b)

    def add_diagonal(self, extra):
        return _Dense(self.C + np.diag(extra))


def _one_period(coefficients, n_points):
    """Values of a harmonic series (unit frequency) on ``n`` uniform points of one period."""
    c = np.asarray(coefficients, float)
    n = max(int(n_points), 16 * ((len(c) - 1) // 2 + 1))
    return HarmonicSeries(1.0, c)(np.arange(n) * (2 * np.pi / n))


def dissipated_energy(velocity_coefficients, omega, damping, n_points=1024) -> float:
    """Energy dissipated in one period by the damping force ``damping(v)`` [J per modal unit].

    ``velocity_coefficients`` is a harmonic vector of ``q'`` (conventions), ``damping`` a
    function of the velocity giving the damping force (e.g. ``lambda v: c * v``).  The
    periodic trapezoidal rule is exact for a trigonometric polynomial.
    """
    v = _one_period(velocity_coefficients, n_points)
    return float(np.mean(damping(v) * v) * 2 * np.pi / omega)


def elastic_force_amplitude(displacement_coefficients, omega1, k3=0.0, n_points=1024) -> float:
    """``max_t |omega1^2 q - k3 q^3|`` over one period of a harmonic-series displacement."""
    q = _one_period(displacement_coefficients, n_points)
    return float(np.max(np.abs(omega1**2 * q - (k3 or 0.0) * q**3)))


@dataclass(frozen=True)
class PowerLaw:
    """``U = alpha F^n`` fitted in log-log coordinates."""

    alpha: float
    n: float
    n_stderr: float
    force: np.ndarray
    energy: np.ndarray
    q_max: np.ndarray | None = field(default=None, repr=False)
    n_local: np.ndarray | None = field(default=None, repr=False)  # model's d log U / d log F at each record
    energy_measured: np.ndarray | None = field(default=None, repr=False)
    method: str = "log-log least squares; stderr from the scatter about the line"

    @property
    def n_ci95(self):
        return ci95(self.n, self.n_stderr)

    @property
    def within_bounds(self) -> bool:
        """Whether ``2 <= n <= 3`` (Smallwood et al. 2000, seed Section 6)."""
        return bool(2.0 <= self.n <= 3.0)

    def __call__(self, F):
        return self.alpha * np.asarray(F, float) ** self.n

    def summary(self) -> dict:
        return {
            "alpha": self.alpha,
            "n": self.n,
            "n_stderr": self.n_stderr,
            "n_ci95": self.n_ci95,
            "within_2_3": self.within_bounds,
            "force": self.force.tolist(),
            "energy": self.energy.tolist(),
            "method": self.method,
            "force_range": [float(np.min(self.force)), float(np.max(self.force))],
            "q_max_range": None if self.q_max is None else [float(np.min(self.q_max)), float(np.max(self.q_max))],
            "n_model": None if self.n_local is None else float(np.median(self.n_local)),
            "n_model_range": None if self.n_local is None else [float(np.min(self.n_local)), float(np.max(self.n_local))],
            "n_local": None if self.n_local is None else self.n_local.tolist(),
            "energy_measured": None if self.energy_measured is None else self.energy_measured.tolist(),
        }

    def report(self) -> str:
        flag = "within" if self.within_bounds else "OUTSIDE"
        ci = self.n_ci95
        dof = len(self.force) - 2  # two parameters: a two-record group is an exact fit
        txt = f"U = {format_value(self.alpha)} F^n, n = {format_pm(self.n, self.n_stderr, dof=dof)}"
        txt += f", 95 % {format_ci(ci, self.n_stderr)}" if ci and dof > 0 else ""
        txt += f"; n {flag} [2, 3]; F {format_value(np.min(self.force))} .. {format_value(np.max(self.force))}"
        if self.n_local is not None:
            txt += f"; model's local n {format_value(np.min(self.n_local))} .. {format_value(np.max(self.n_local))}"
        return txt

    def __repr__(self):
        return f"PowerLaw(U = {self.alpha:.4g} F^{self.n:.4f} ± {self.n_stderr:.2g}; {len(self.force)} records)"

    def _repr_html_(self):
        from .. import plotting

        return plotting.draw("notebook.result_html", self)

    def plot(self, ax=None, **kw):
        from .. import plotting

        return plotting.draw("identify_plots.plot_power_law", self, ax=ax, **kw)


def fit_power_law(force, energy) -> PowerLaw:
    """Fit ``U = alpha F^n`` by linear least squares on ``log U = log alpha + n log F``."""
    F = np.asarray(force, float)
    U = np.asarray(energy, float)
    ok = np.isfinite(F) & np.isfinite(U) & (F > 0) & (U > 0)
    if ok.sum() < 2 or np.ptp(np.log(F[ok])) == 0:
        raise IdentificationError(
            f"a power law needs at least two records with distinct positive force and energy, got {int(ok.sum())}"
        )
    x, y = np.log(F[ok]), np.log(U[ok])
    A = np.column_stack([np.ones_like(x), x])
    coef, *_ = np.linalg.lstsq(A, y, rcond=None)
    r = y - A @ coef
    dof = max(len(x) - 2, 1)
    cov = np.linalg.inv(A.T @ A) * float(r @ r) / dof
    return PowerLaw(float(np.exp(coef[0])), float(coef[1]), float(np.sqrt(cov[1, 1])), F, U)


def cycle_energy(force_coefficients, velocity_coefficients, omega) -> float:
    """Input work per period ``closed integral of Q dq = integral_0^T Q q' dt`` of two harmonic series.

    In a steady state the work of the inertia and of any conservative force over a period
    is zero, so this is the energy the joint dissipates, measured without a model.
    """
    a = np.asarray(force_coefficients, float)
    b = np.asarray(velocity_coefficients, float)
    m = min(a.size, b.size)
    return float(np.pi / omega * np.dot(a[1:m], b[1:m]))


class _ModelCycle:
    """Term values over one period of each state: energy and elastic force for any coefficients.

    The energy of the damping terms is linear in their coefficients, so it is kept per unit
    coefficient; the elastic force amplitude needs the stiffness terms' values on the period.
    """

    def __init__(self, lib, orders, states):
        self.orders = orders
        self.q_max = [qm for _, _, _, qm in states]
        damp = np.array([t.kind == "damping" for t in lib])
        self.unit_energy, self.stiff = [], []
        for qc, vc, omega, _ in states:
            q, v = _one_period(qc, 1024), _one_period(vc, 1024)
            Phi = lib.evaluate(q, v)
            self.unit_energy.append(np.where(damp, Phi.T @ v / q.size * 2 * np.pi / omega, 0.0))
            self.stiff.append(Phi[:, ~damp])
        self.damp = damp

    def __call__(self, theta):
        U, F = [], []
        from .model import expand

        for qm, ue, S in zip(self.q_max, self.unit_energy, self.stiff):
            th = expand(self.orders, qm, theta)[0]
            U.append(float(ue @ th))
            F.append(float(np.max(np.abs(S @ th[~self.damp]))))
        return np.array(U), np.array(F)


def _loglog_slope(F, U):
    ok = (F > 0) & (U > 0) & np.isfinite(F) & np.isfinite(U)
    x, y = np.log(F[ok]), np.log(U[ok])
    A = np.column_stack([np.ones_like(x), x])
    coef = np.linalg.lstsq(A, y, rcond=None)[0]
    return float(coef[1]), float(np.exp(coef[0]))


def model_power_law(model, states, energy_measured=None, rel_step=1e-4) -> PowerLaw:
    """``U = alpha F^n`` over a group's records from a preload model, with a propagated interval.

    Parameters
    ----------
    model : PreloadModel
        Terms, amplitude laws, parameters and their covariance.
    states : sequence of (displacement coefficients, velocity coefficients, omega, q_max)
        The measured steady states of the group (harmonic series).
    energy_measured : array, optional
        Model-free energy per cycle of each record (:func:`cycle_energy`), stored alongside.

    Notes
    -----
    ``U`` is the energy the model's damping terms dissipate over the measured period and
    ``F`` the amplitude of its elastic (stiffness) force.  ``n`` is the log-log slope over
    the records; its standard error propagates the model's covariance through the whole
    computation with a central-difference Jacobian.  ``n_local`` is the slope the model
    implies at each record (the state scaled by ``1 +- rel_step``): when the damping
    depends on the amplitude, ``n`` itself does.
    """
    from .terms import library

    lib = library(model.terms)
    states = list(states)
    if len(states) < 2:
        raise IdentificationError(f"a power law needs at least two records, got {len(states)}")
    cycle = _ModelCycle(lib, model.law_orders, states)

    def n_of(theta):
        U, F = cycle(theta)
        if np.sum((F > 0) & (U > 0)) < 2 or np.ptp(np.log(F[F > 0])) == 0:
            raise IdentificationError("a power law needs at least two records with distinct positive force and energy")
        return _loglog_slope(F, U)

    theta = np.asarray(model.parameters, float)
    n, alpha = n_of(theta)
    J = np.zeros(theta.size)
    for i in range(theta.size):
        h = 1e-3 * model.stderr[i] if model.stderr[i] > 0 else 1e-7 * max(abs(theta[i]), 1e-30)
        tp, tm = theta.copy(), theta.copy()
        tp[i] += h
        tm[i] -= h
        J[i] = (n_of(tp)[0] - n_of(tm)[0]) / (2 * h)
    n_se = float(np.sqrt(max(J @ model.covariance @ J, 0.0)))
    U, F = cycle(theta)
    ends = []
    for s in (1 + rel_step, 1 - rel_step):
        u, f = _ModelCycle(lib, model.law_orders,
                           [(s * np.asarray(qc), s * np.asarray(vc), om, s * qm) for qc, vc, om, qm in states])(theta)
        ends.append((np.log(np.abs(u)), np.log(f)))
    local = (ends[0][0] - ends[1][0]) / (ends[0][1] - ends[1][1])
    em = None if energy_measured is None else np.asarray(energy_measured, float)
    return PowerLaw(alpha, n, n_se, F, U, np.array([s[3] for s in states]), np.asarray(local, float), em,
                    "log-log least squares over the records of the preload model's energy and elastic force; "
                    "stderr propagated from the model's covariance")
