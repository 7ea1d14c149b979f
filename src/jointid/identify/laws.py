"""Amplitude laws: damping ``c(q_max)``, energy dissipated per cycle, power law ``U = alpha F^n``.

Damping law (seed Eq 25-26, Table 2, Fig 6)
    ``c(q_max) = c0 + c1 q_max + c2 q_max^2 + ...`` fitted by weighted least squares to
    the per-record damping coefficients, each weighted by the inverse of its standard
    error (records far from resonance see the damping force through a small quadrature
    component and carry large errors).

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

import html
from dataclasses import dataclass

import numpy as np

from ..errors import IdentificationError
from ..signal.harmonics import HarmonicSeries

__all__ = [
    "DampingLaw",
    "fit_damping_law",
    "PowerLaw",
    "fit_power_law",
    "dissipated_energy",
    "elastic_force_amplitude",
]


@dataclass(frozen=True)
class DampingLaw:
    """``c(q_max) = sum_k coefficients[k] q_max^k`` with standard errors."""

    coefficients: np.ndarray
    stderr: np.ndarray
    q_max: np.ndarray
    c: np.ndarray
    c_stderr: np.ndarray

    @property
    def order(self) -> int:
        return len(self.coefficients) - 1

    def __call__(self, q_max):
        return np.polynomial.polynomial.polyval(np.asarray(q_max, float), self.coefficients)

    def summary(self) -> dict:
        return {
            "order": self.order,
            "coefficients": [float(v) for v in self.coefficients],
            "stderr": [float(v) for v in self.stderr],
            "n_records": int(len(self.q_max)),
        }

    def report(self) -> str:
        terms = " + ".join(
            f"({c:.6g} ± {s:.2g})" + ("" if k == 0 else " q_max" if k == 1 else f" q_max^{k}")
            for k, (c, s) in enumerate(zip(self.coefficients, self.stderr))
        )
        return f"c(q_max) = {terms}   [{len(self.q_max)} records]"

    def _repr_html_(self):
        return "<pre>" + html.escape(self.report()) + "</pre>"

    def plot(self, ax=None, **kw):
        from ..report.identify_plots import plot_damping_law

        return plot_damping_law(self, ax=ax, **kw)


def fit_damping_law(q_max, c, c_stderr=None, order=2) -> DampingLaw:
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
    V = np.vander(qs / scale, order + 1, increasing=True) / ss[:, None]
    coef_s, *_ = np.linalg.lstsq(V, cs / ss, rcond=None)
    resid = cs / ss - V @ coef_s
    dof = max(len(cs) - (order + 1), 1)
    # with weights from standard errors the residual variance should be ~1; scale by it
    # when larger (errors understated) but never shrink below the stated errors
    s2 = max(float(resid @ resid) / dof, 1.0) if c_stderr is not None else float(resid @ resid) / dof
    cov_s = np.linalg.pinv(V.T @ V) * s2
    powers = scale ** np.arange(order + 1)
    coef = coef_s / powers
    se = np.sqrt(np.clip(np.diag(cov_s), 0, None)) / powers
    return DampingLaw(coef, se, q_max, c, s if c_stderr is not None else np.full_like(c, np.nan))


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
            "within_2_3": self.within_bounds,
            "force": self.force.tolist(),
            "energy": self.energy.tolist(),
        }

    def report(self) -> str:
        flag = "within" if self.within_bounds else "OUTSIDE"
        return f"U = {self.alpha:.4g} F^{self.n:.4f} (± {self.n_stderr:.2g}); n {flag} [2, 3]"

    def plot(self, ax=None, **kw):
        from ..report.identify_plots import plot_power_law

        return plot_power_law(self, ax=ax, **kw)


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
