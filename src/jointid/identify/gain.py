"""Stepped-sine force-state mapping when the recorded "force" has an unknown gain.

Many tests drive an electrodynamic shaker from a voltage and record that voltage, not the
force (no force transducer).  Near a mode the shaker force is, to first order,
proportional to the voltage, ``Q = g V``, so the single-mode equation of motion
``q'' + h(q, q') = Q`` (seed Eq 14) becomes::

    m q'' + sum_j theta_j phi_j(q, q') = V,      m = 1/g,  theta_j = (seed coefficient)_j / g.

The inertia coefficient ``m`` joins the regression as one more column (the harmonic-
filtered acceleration).  Gain-free results are ratios: ``omega1 = sqrt(theta_q / m)``,
``k3/m`` (the seed's ``k3`` for a unit modal mass), ``k3/k = theta_k3 / theta_q``, ``c/m``.

Why pooled
    In a single record the fundamental of ``q''`` is ``-omega^2`` times the fundamental of
    ``q``: the inertia and linear-stiffness columns are collinear except for the higher
    harmonics, which carry only the (small) nonlinear distortion.  ``m`` and
    ``theta_q`` are therefore only separable through the harmonics in one record, and
    that is badly conditioned.  Records at *different* excitation frequencies share ``m``
    and the stiffness terms but have different ``omega^2``, so the pooled regression
    (this module's :class:`PooledGainForceStateMapping`) separates them; damping terms
    keep one coefficient per record (amplitude-dependent damping, seed Eq 20).  The
    pooled form is the intended use; a single record is accepted but warns.

Reduction
    Each record is reduced to the triangular factor ``R`` of ``[X, y]`` in the same streamed
    pass that gathers its noise-model sums (:func:`jointid.identify.uncertainty.record_pass`,
    block by block, never building the full regression matrix); each record's Gram ``R^T R``
    is placed in its shared and per-record columns, weighted and summed.

Errors in variables
    The regressors (``q''_fit``, ``q``, ``q'`` and the terms) are built from the harmonic fit of
    the noisy response, and within a record the inertia separates from the stiffness only
    through the small higher harmonics, where that noise is as large as the signal: plain
    least squares is then biased (the gain by 5-7 standard errors on a 1 % noise campaign).
    Each record's Gram has the expected Gram of the regressors' errors subtracted
    (:func:`eiv_gram`, corrected least squares), and the covariance carries the second-order
    score term (:func:`eiv_score_covariance`) and the error of an estimated frequency
    (:func:`frequency_score`).

Phase of the channels
    A time shift ``tau`` of the response channel behind the excitation channel (``tau > 0``
    when the response lags: a shaker force lagging its recorded voltage through the coil
    inductance, vibrometer decoder latency, anti-alias filters; ``tau < 0`` when it leads,
    e.g. a time-base offset between separately recorded channels) changes the
    apparent per-record damping to about ``c_r/m = c/m + tau (omega1^2 - omega_r^2)``:
    largest away from resonance, of opposite signs below and above it, and possibly
    negative.  The stiffness and inertia (in-phase part) are hardly affected.  Pass a
    known shift as ``delay`` to :func:`sine_dwell_signals`.
"""

from __future__ import annotations

import html
import warnings
from dataclasses import dataclass, field, replace

import numpy as np
from scipy import linalg

from .._blas import single_threaded
from ..errors import IdentificationError, IllConditionedWarning, RecordError
from ..rounding import format_pm, format_value
from ..signal.harmonics import (
    HarmonicSeries,
    StateSignals,
    check_time_base,
    estimate_frequency,
    fit_harmonics,
)
from .broadband import delta_method
from .fsm import COND_LIMIT, pooled_inputs, split_terms
from .regression import lstsq_from_reduced
from .terms import library
from .uncertainty import ci95, record_pass, sandwich, scaled_inverse

__all__ = ["sine_dwell_signals", "GainFit", "PooledGainForceStateMapping"]

#: Units of the coefficients of ``V = m q'' + sum theta_j phi_j(q, q')`` (the excitation in V, q in m).
_RAW_UNITS = {"m": "V s²/m", "omega1^2": "V/m", "k2": "V/m²", "k3": "V/m³", "k5": "V/m⁵", "k_abs": "V/m²"}
#: Units of the gain-free ratios (per unit modal mass: ``k3/m`` is the seed's k3 for one kg).
_DERIVED_UNITS = {"omega1": "rad/s", "f1_hz": "Hz", "gain": "N/V", "k2/m": "1/(m s²)", "k2/k": "1/m",
                  "k3/m": "1/(m² s²)", "k3/k": "1/m²", "k5/m": "1/(m⁴ s²)", "k5/k": "1/m⁴", "k_abs/m": "1/(m s²)",
                  "k_abs/k": "1/m"}

_KINDS = {"displacement": 0, "velocity": 1, "acceleration": 2}


def sine_dwell_signals(t, force, response, *, measured="acceleration", frequency_hz=None, n_harmonics=3,
                       delay=0.0, channels=("time", "force", "response")) -> StateSignals:
    """Reduce a sine dwell to :class:`~jointid.signal.harmonics.StateSignals` from any measured response.

    The response (acceleration, velocity or displacement) is fitted with ``n_harmonics``
    harmonics of the excitation frequency; the acceleration series is its exact
    derivative (or the fit itself), so velocity and displacement follow by the usual
    analytic integration (seed Eq 17-18).  The constant of the fit is dropped (a velocity
    or displacement offset carries no dynamics).

    Parameters
    ----------
    t, force, response : array
        Time [s], excitation (force or voltage) and measured response.
    measured : {"acceleration", "velocity", "displacement"}
    frequency_hz : float, optional
        Excitation frequency; estimated from ``force`` when ``None``.
    n_harmonics : int
        Harmonics fitted.  Keep ``n_harmonics * f`` below the next structural mode: a
        harmonic near another mode is that mode's response, not the joint's.
    delay : float
        Known delay [s] of the response channel behind the excitation channel; the
        response series is advanced by it.
    channels : (str, str, str)
        Names used in error messages.

    Returns
    -------
    StateSignals
        ``accel_measured`` holds the fitted acceleration when the acceleration was not
        measured (there is no measured acceleration to compare with).

    Raises
    ------
    RecordError
        Bad time base, non-finite values, zero force, harmonics above Nyquist, fewer than
        two periods.
    """
    tname, fname, rname = channels
    if measured not in _KINDS:
        raise RecordError(f"measured must be one of {sorted(_KINDS)}, got {measured!r}")
    t = np.asarray(t, float)
    check_time_base(t, channel=tname)
    force = np.asarray(force, float)
    response = np.asarray(response, float)
    for x, name in ((force, fname), (response, rname)):
        if x.shape != t.shape:
            raise RecordError(f"channel {name!r}: has shape {x.shape}, the time column has {t.shape}")
        bad = ~np.isfinite(x)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise RecordError(f"channel {name!r}: non-finite value {x[i]!r} at sample {i}")
    if not np.any(force - force.mean()):
        raise RecordError(f"channel {fname!r}: the excitation is constant; the record carries no excitation")
    given = frequency_hz is not None
    f_hz = float(frequency_hz) if given else estimate_frequency(t, force, channel=fname)
    if not np.isfinite(f_hz) or f_hz <= 0:
        raise RecordError(f"frequency_hz must be a positive number, got {frequency_hz!r}")
    dt = (t[-1] - t[0]) / (t.size - 1)
    if (t[-1] - t[0] + dt) * f_hz < 2:
        raise RecordError(f"channel {tname!r}: the record spans fewer than 2 periods of {f_hz:.6g} Hz")
    omega = 2 * np.pi * f_hz
    series, resid = fit_harmonics(t, response, omega, n_harmonics, channel=rname)
    c = series.coefficients.copy()
    c[0] = 0.0
    s = HarmonicSeries(omega, c, series.t0 - float(delay))
    for _ in range(2 - _KINDS[measured]):
        s = s.derivative()
    accel_measured = response if measured == "acceleration" else s(t)
    return StateSignals(t, force, accel_measured, s, f_hz, given, float(resid))


@dataclass(frozen=True)
class GainFit:
    """Pooled stepped-sine fit with an unknown force gain.

    Attributes
    ----------
    terms : tuple of str
    shared_names : tuple of str
        ``("m", <shared term coefficients>...)``.
    shared, shared_stderr : array
    own_names : tuple of str
        Per-record coefficients (``("c",)`` by default).
    own, own_stderr : array ``(n_records, n_own)``
    covariance : array
        Covariance of all coefficients (shared first, then per record).
    q_max, frequency_hz : array
        Amplitude (in response units) and excitation frequency of each record.
    omega1_per_record : array
        Consistency check: ``sqrt(theta_q,r / m)`` of each record refitted alone with ``m``
        and the nonlinear stiffness terms fixed at the pooled values.
    condition_number : float
    weights : array
    n_samples : int
    warnings : tuple of str
    """

    terms: tuple
    shared_names: tuple
    shared: np.ndarray
    shared_stderr: np.ndarray
    own_names: tuple
    own: np.ndarray
    own_stderr: np.ndarray
    covariance: np.ndarray = field(repr=False)
    q_max: np.ndarray = field(default=None)
    frequency_hz: np.ndarray = field(default=None)
    omega1_per_record: np.ndarray = field(default=None)
    condition_number: float = float("nan")
    weights: np.ndarray = field(default=None, repr=False)
    n_samples: int = 0
    warnings: tuple = ()

    @property
    def n_records(self) -> int:
        return int(self.own.shape[0])

    def _all(self):
        return np.concatenate([self.shared, self.own.ravel()])

    def get(self, name):
        """A shared coefficient (float) or per-record coefficient (array) by name."""
        if name in self.shared_names:
            return float(self.shared[self.shared_names.index(name)])
        if name in self.own_names:
            return self.own[:, self.own_names.index(name)]
        raise KeyError(f"no coefficient {name!r}; shared {self.shared_names}, per record {self.own_names}")

    @property
    def m(self) -> float:
        return self.get("m")

    @property
    def gain(self) -> float:
        """``1 / m``: force per unit of the recorded excitation for a unit modal mass."""
        return 1.0 / self.m

    def _idx(self, name):
        return self.shared_names.index(name)

    def _quantity(self, name):
        """Function of the full coefficient vector for a derived quantity."""
        im = self._idx("m")
        if name in ("omega1", "f1_hz"):
            iq = self._idx("omega1^2")
            scale = 1.0 if name == "omega1" else 1 / (2 * np.pi)
            return lambda p: scale * np.sqrt(p[iq] / p[im]) if p[iq] / p[im] > 0 else np.nan
        if name == "gain":
            return lambda p: 1.0 / p[im]
        if name.endswith("/m") and name[:-2] in self.shared_names:
            j = self._idx(name[:-2])
            return lambda p: p[j] / p[im]
        if name.endswith("/k") and name[:-2] in self.shared_names:
            j, iq = self._idx(name[:-2]), self._idx("omega1^2")
            return lambda p: p[j] / p[iq]
        raise KeyError(name)

    def derived(self) -> dict:
        """Gain-free shared quantities with delta-method standard errors ``{name: (value, stderr)}``.

        ``omega1``, ``f1_hz``, ``gain``, and ``<coef>/m``, ``<coef>/k`` for every shared
        stiffness coefficient (``k3/m`` is the seed's ``k3``; positive is softening).
        """
        names = ["omega1", "f1_hz", "gain"]
        for n in self.shared_names:
            if n not in ("m", "omega1^2"):
                names += [f"{n}/m", f"{n}/k"]
        p, C = self._all(), self.covariance
        return {n: delta_method(self._quantity(n), p, C) for n in names}

    def value(self, name) -> float:
        return float(self._quantity(name)(self._all()))

    @property
    def omega1(self) -> float:
        return self.value("omega1")

    @property
    def f1_hz(self) -> float:
        return self.value("f1_hz")

    @property
    def k3_over_m(self):
        return self.value("k3/m") if "k3" in self.shared_names else None

    @property
    def k3_over_k(self):
        return self.value("k3/k") if "k3" in self.shared_names else None

    def per_record(self, name="c") -> tuple[np.ndarray, np.ndarray]:
        """``name / m`` of every record with delta-method standard errors (e.g. ``c/m``)."""
        j = self.own_names.index(name)
        ns, no = len(self.shared), len(self.own_names)
        im = self._idx("m")
        vals, errs = [], []
        for r in range(self.n_records):
            k = ns + r * no + j
            v, s = delta_method(lambda p: p[k] / p[im], self._all(), self.covariance)
            vals.append(v)
            errs.append(s)
        return np.array(vals), np.array(errs)

    def damping_ratio(self) -> np.ndarray:
        """``zeta_r = (c_r/m) / (2 omega1)`` of every record."""
        cm, _ = self.per_record("c")
        return cm / (2 * self.omega1)

    def omega1_spread(self) -> float:
        """``(max - min) / mean`` of :attr:`omega1_per_record`."""
        w = np.asarray(self.omega1_per_record, float)
        return float((w.max() - w.min()) / w.mean()) if w.size else float("nan")

    def summary(self) -> dict:
        d = self.derived()
        out = {
            "terms": list(self.terms),
            "shared": {n: float(v) for n, v in zip(self.shared_names, self.shared)},
            "shared_stderr": {n: float(v) for n, v in zip(self.shared_names, self.shared_stderr)},
            "shared_ci95": {n: ci95(v, s) for n, v, s in zip(self.shared_names, self.shared, self.shared_stderr)},
            "per_record": {n: self.own[:, i].tolist() for i, n in enumerate(self.own_names)},
            "per_record_stderr": {n: self.own_stderr[:, i].tolist() for i, n in enumerate(self.own_names)},
            "per_record_ci95": {n: [ci95(v, s) for v, s in zip(self.own[:, i], self.own_stderr[:, i])]
                                for i, n in enumerate(self.own_names)},
            "derived": {k: float(v[0]) for k, v in d.items()},
            "derived_stderr": {k: float(v[1]) for k, v in d.items()},
            "derived_ci95": {k: ci95(v[0], v[1]) for k, v in d.items()},
            "q_max": np.asarray(self.q_max).tolist(),
            "frequency_hz": np.asarray(self.frequency_hz).tolist(),
            "omega1_per_record": np.asarray(self.omega1_per_record).tolist(),
            "omega1_spread": self.omega1_spread(),
            "condition_number": float(self.condition_number),
            "n_records": self.n_records,
            "n_samples": int(self.n_samples),
            "warnings": list(self.warnings),
        }
        if "c" in self.own_names:
            cm, cs = self.per_record("c")
            out["c_over_m"] = cm.tolist()
            out["c_over_m_stderr"] = cs.tolist()
            out["c_over_m_ci95"] = [ci95(v, s) for v, s in zip(cm, cs)]
            out["damping_ratio"] = self.damping_ratio().tolist()
        return out

    def report(self) -> str:
        lines = [f"pooled stepped-sine fit with unknown force gain: {self.n_records} records, "
                 f"condition number {format_value(self.condition_number, 3)}"]
        for n, v, s in zip(self.shared_names, self.shared, self.shared_stderr):  # V = m q'' + sum theta_j phi_j
            name = "m" if n == "m" else f"theta({n})"
            lines.append(f"  {name:>14} = {format_pm(v, s, _RAW_UNITS.get(n, ''))}   (shared)")
        for k, (v, s) in self.derived().items():
            lines.append(f"  {k:>14} = {format_pm(v, s, _DERIVED_UNITS.get(k, ''))}")
        has_c = "c" in self.own_names
        cm = self.per_record("c") if has_c else None
        for r in range(self.n_records):
            txt = (f"  record {r}: {format_value(self.frequency_hz[r], 6)} Hz, q_max {format_value(self.q_max[r])} m, "
                   f"omega1 alone {format_value(self.omega1_per_record[r], 7)} rad/s")
            if has_c:
                txt += f", c/m {format_pm(cm[0][r], cm[1][r], '1/s')}"
            lines.append(txt)
        lines.append(f"  spread of the per-record omega1: {format_value(100 * self.omega1_spread(), 3)} %")
        lines += [f"  warning: {w}" for w in self.warnings]
        return "\n".join(lines)

    def _repr_html_(self):
        return "<pre>" + html.escape(self.report()) + "</pre>"

    def plot(self, ax=None):
        """Per-record ``c/m`` and ``omega1`` against amplitude."""
        from .. import plotting

        return plotting.draw("data_plots.plot_gain_fit", self, ax=ax)


class PooledGainForceStateMapping:
    """Pooled force-state mapping of sine dwells whose excitation has an unknown gain.

    Parameters
    ----------
    terms : str or TermLibrary
        Restoring-force terms; must contain ``q`` (``omega1^2``).  Default
        ``"q + -q^3 + q'"``.
    per_record : sequence of str, optional
        Terms with one coefficient per record; default every damping-kind term.
    weighting : {"noise", "none"}
        ``"noise"`` weights each record by the inverse residual standard deviation of its
        own single-record fit.
    cond_limit : float

    Attributes
    ----------
    result_ : GainFit
    coef_ : array
        Shared coefficients (``m`` first).

    Examples
    --------
    >>> from jointid.signal.harmonics import steady_state_signals
    >>> t = np.arange(4000) / 2000.0
    >>> recs = []
    >>> for w in (26.0, 29.0, 33.0):   # linear oscillator omega1 = 30, c = 0.6, gain 0.5
    ...     q = 0.01 * np.cos(w * t); v = -0.01 * w * np.sin(w * t); a = -w**2 * q
    ...     V = (a + 900.0 * q + 0.6 * v) / 0.5
    ...     recs.append(steady_state_signals(t, V, a, frequency_hz=w / (2 * np.pi), n_harmonics=3))
    >>> fit = PooledGainForceStateMapping("q + q'").fit(recs).result_
    >>> round(fit.gain, 6), round(fit.omega1, 6)
    (0.5, 30.0)
    """

    def __init__(self, terms="q + -q^3 + q'", per_record=None, weighting="noise", cond_limit=COND_LIMIT):
        self.terms = terms
        self.per_record = per_record
        self.weighting = weighting
        self.cond_limit = cond_limit

    @single_threaded
    def fit(self, signals_list, *, context=""):
        """Fit a group of :class:`~jointid.signal.harmonics.StateSignals` (one per excitation frequency)."""
        sigs = pooled_inputs(signals_list, self.weighting, "pooled gain regression")
        lib = library(self.terms)
        if "q" not in lib.names:
            raise IdentificationError(f"the term library {lib.names} must contain the linear stiffness term 'q'")
        warn = []
        if len(sigs) == 1:
            warn.append(f"{context}one record only: the inertia (1/gain) and the linear stiffness are separable "
                        f"only through the higher harmonics; pool records at several frequencies")
        elif len({round(s.frequency_hz, 9) for s in sigs}) < 2:
            warn.append(f"{context}all records have the same excitation frequency: the inertia and the linear "
                        f"stiffness are not separable")
        shared_lib, own_lib = split_terms(lib, self.per_record)
        # columns of R: 0 = inertia, 1 + i = library term i, last = excitation
        shared_cols = [0] + [1 + i for i in shared_lib]
        own_cols = [1 + i for i in own_lib]
        ns, no, nr = len(shared_cols), len(own_cols), len(sigs)
        nt = len(lib) + 1
        passes = [record_pass(lib, s, inertia=True) for s in sigs]
        Rs = [R for R, _ in passes]
        weights = np.array([_record_weight(R, s.t.size, shared_cols + own_cols, nt) if self.weighting == "noise"
                            else 1.0 for R, s in zip(Rs, sigs)])
        alpha_covs = [alpha_covariance(s, sc) for s, (_, sc) in zip(sigs, passes)]
        grams = [R.T @ R for R in Rs]
        moments = [error_moments(lib, s, C) for s, C in zip(sigs, alpha_covs)]
        eiv = [eiv_gram(lib, s, C, K) for s, C, K in zip(sigs, alpha_covs, moments)]
        corrected = []
        for M, E in zip(grams, eiv):
            Mc = M.copy()
            Mc[:nt, :nt] -= E
            corrected.append(Mc)
        placement = [_placement(r, nt, shared_cols, own_cols, ns, no) for r in range(nr)]
        coef, cond, ok = _pooled_normal_solve(corrected, placement, weights, nt, ns + no * nr)
        if not ok:  # the harmonics carry less than their own noise: plain least squares
            coef, cond, _ = _pooled_normal_solve(grams, placement, weights, nt, ns + no * nr)
            corrected = grams
            warn.append(f"{context}the errors-in-variables correction leaves the pooled normal matrix without "
                        f"a positive definite part (the fitted harmonics are dominated by their noise); plain "
                        f"least squares is used and the gain may be biased")
        cov = _sandwich_covariance(lib, [sc for _, sc in passes], alpha_covs, corrected, coef, weights, placement, sigs,
                                   moments, Rs)
        se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
        n_total = int(sum(s.t.size for s in sigs))
        if not np.isfinite(cond) or cond > self.cond_limit:
            warn.append(f"{context}pooled regression too ill-conditioned (condition number "
                        f"{cond:.3g} > {self.cond_limit:.3g})")
        shared = coef[:ns]
        if not shared[0] > 0:
            warn.append(f"{context}the fitted inertia coefficient m = {shared[0]:.4g} is not positive; the gain "
                        f"and the derived frequencies are meaningless")
        # consistency: each record alone, with m and the nonlinear stiffness fixed
        iq = lib.index("q")
        w1 = []
        for R in Rs:
            fixed = [0] + [1 + i for i in shared_lib if i != iq]
            fixed_vals = np.array([shared[shared_cols.index(c)] for c in fixed])
            free = [1 + iq] + own_cols
            y = R[:, nt] - R[:, fixed] @ fixed_vals
            th, *_ = np.linalg.lstsq(R[:, free], y, rcond=None)
            ratio = th[0] / shared[0]
            w1.append(float(np.sqrt(ratio)) if ratio > 0 else float("nan"))
        for w_ in warn:
            warnings.warn(w_, IllConditionedWarning, stacklevel=3)
        names_shared = ("m",) + tuple(lib[i].coefficient for i in shared_lib)
        self.library_ = lib
        self.coef_ = shared
        self.result_ = GainFit(
            lib.names, names_shared, shared, se[:ns], tuple(lib[i].coefficient for i in own_lib),
            coef[ns:].reshape(nr, no), se[ns:].reshape(nr, no), cov,
            np.array([s.q_max() for s in sigs]), np.array([s.frequency_hz for s in sigs]), np.array(w1),
            cond, weights, n_total, tuple(warn),
        )
        return self



def _record_weight(R, n, cols, rhs) -> float:
    """Inverse residual standard deviation of the record's own fit on ``cols`` (``weighting="noise"``)."""
    single = lstsq_from_reduced(R[:, cols], R[:, rhs], n)
    floor = 1e-13 * float(np.abs(R[:, rhs]).max()) / np.sqrt(n)
    return 1.0 / max(single.sigma, floor, np.finfo(float).tiny)


def _placement(r, nt, shared_cols, own_cols, ns, no) -> np.ndarray:
    """Position of record ``r``'s columns ``[q'', terms...]`` in the pooled coefficient vector."""
    cols = np.full(nt, -1)
    cols[shared_cols] = np.arange(ns)
    cols[own_cols] = ns + r * no + np.arange(no)
    return cols


def _pooled_normal_solve(grams, placement, weights, nt, P):
    """Solve the pooled normal equations ``sum_r w_r^2 M_r`` placed in the pooled columns.

    Returns ``(coefficients, condition number of the column-scaled design, positive definite)``.
    The condition number is the square root of the scaled normal matrix's (that of the
    stacked, scaled regression matrix).
    """
    A, b = np.zeros((P, P)), np.zeros(P)
    for M, cols, w in zip(grams, placement, weights):
        A[np.ix_(cols, cols)] += w**2 * M[:nt, :nt]
        b[cols] += w**2 * M[:nt, nt]
    d = np.sqrt(np.abs(np.diag(A)))
    d[d == 0] = 1.0
    As = 0.5 * (A + A.T) / np.outer(d, d)
    ev = np.linalg.eigvalsh(As)
    if not np.all(np.isfinite(ev)) or ev[0] <= 1e-14 * ev[-1]:
        return np.full(P, np.nan), float("inf"), False
    coef = linalg.solve(As, b / d, assume_a="pos") / d
    return coef, float(np.sqrt(ev[-1] / ev[0])), True


def alpha_covariance(signals, scores) -> np.ndarray:
    """Covariance ``sigma^2 G^-1`` of the fitted acceleration coefficients under white noise
    (``G`` the fit's basis Gram, ``sigma^2`` the residual variance outside the fitted harmonics,
    as in :class:`~jointid.identify.uncertainty.RecordScores`).

    For a dwell whose velocity or displacement was measured (:func:`sine_dwell_signals`) the
    residual is that of the measured response and is used as it is, like the noise model of
    :mod:`jointid.identify.uncertainty` does.
    """
    C = float(scores.sigma_accel) ** 2 * scaled_inverse(scores.basis_gram)
    return 0.5 * (C + C.T)


def _error_rows(lib, signals, L):
    """Blocks of ``g_j(t)^T L`` (``(rows, 1 + n_terms, rank)``): how each column ``[q''_fit, terms...]``
    moves per unit of the whitened error of the acceleration coefficients (``d alpha = L z``)."""
    p = len(lib) + 1
    Tv = np.column_stack([HarmonicSeries(signals.omega, e).integral().coefficients for e in np.eye(L.shape[0])])
    LTq, LTv = Tv @ Tv @ L, Tv @ L  # B Tq L: the displacement per unit z
    for (sl, q, v, _), (_, A) in zip(signals.blocks(), signals.basis_blocks()):
        Uq, Uv = A @ LTq, A @ LTv
        Gm = np.empty((q.size, p, L.shape[1]))
        Gm[:, 0] = A @ L
        for k, t in enumerate(lib):
            gq, gv = t.derivative_values(q, v)
            Gm[:, 1 + k] = Uq * (np.reshape(gq, (-1, 1)) if np.ndim(gq) else gq)
            Gm[:, 1 + k] += Uv * (np.reshape(gv, (-1, 1)) if np.ndim(gv) else gv)
        yield Gm


def _whitener(alpha_cov) -> np.ndarray:
    """``L`` with ``L L^T = alpha_cov`` (positive semi-definite)."""
    w, V = np.linalg.eigh(0.5 * (alpha_cov + alpha_cov.T))
    return V * np.sqrt(np.clip(w, 0.0, None))


def error_moments(lib, signals, alpha_cov) -> np.ndarray:
    """``K[j, i, k, l] = sum_t (L^T g_j(t))_i (L^T g_k(t))_l`` (``d alpha = L z``, see :func:`eiv_gram`):
    the one pass over the record that both :func:`eiv_gram` and :func:`eiv_score_covariance` need."""
    p, L = len(lib) + 1, _whitener(alpha_cov)
    r = L.shape[1]
    K = np.zeros((p * r, p * r))
    for Gm in _error_rows(lib, signals, L):
        G2 = Gm.reshape(Gm.shape[0], p * r)
        K += G2.T @ G2
    return K.reshape(p, r, p, r)


def eiv_gram(lib, signals, alpha_cov, moments=None) -> np.ndarray:
    """Expected Gram of the regressors' errors, ``E[dX^T dX]``, of the columns ``[q''_fit, terms...]``.

    The regressors are built from the fitted acceleration coefficients ``alpha``, whose
    error ``d alpha`` (covariance ``alpha_cov``) moves every column at once:
    ``dx_j(t) = g_j(t)^T d alpha`` with ``g = B^T`` for the filtered acceleration and
    ``g = phi_q T_q^T B^T + phi_v T_v^T B^T`` for a term ``phi(q, q')`` (``T_q``, ``T_v`` the
    analytic integrations).  Hence ``E[dX^T dX]_jk = sum_t g_j(t)^T C g_k(t)``, summed here
    block by block.

    Least squares on noisy regressors solves ``(X^T X) theta = X^T V`` with ``E[X^T X]`` larger
    than the noise-free Gram by this matrix (errors in variables).  It is negligible for the
    fundamental, but the inertia and the stiffness separate within a record only through the
    higher harmonics, which are small and carry the same noise: subtracting it from each
    record's Gram (corrected least squares) removes the bias of the gain.  The remaining
    second-order terms (the curvature of nonlinear terms) are of the relative size of the
    noise variance to the fundamental and are left out.
    """
    K = error_moments(lib, signals, alpha_cov) if moments is None else moments
    out = np.einsum("jiki->jk", K)
    return 0.5 * (out + out.T)


def eiv_score_covariance(lib, signals, alpha_cov, theta, moments=None) -> np.ndarray:
    """Second-order part of the score covariance that the plug-in noise model leaves out.

    The corrected score of a record is ``X^T eps - X^T dX theta + dX^T eps - (dX^T dX - E) theta``
    (``E`` = :func:`eiv_gram`).  Its first-order part has the covariance of the noise model
    evaluated on the measured regressors, and that plug-in value is itself raised by the
    regressors' errors: by ``sigma_V^2 E`` and by ``tr(A_j A_k^T)``, where
    ``A_j = sum_t L^T g_j(t) g_theta(t)^T L`` makes ``(dX^T dX theta)_j = z^T A_j z`` a quadratic
    form of the whitened coefficient error ``z`` (``d alpha = L z``, see :func:`eiv_gram`).  The
    second-order terms add ``sigma_V^2 E`` (``dX^T eps``) and
    ``cov(z^T A_j z, z^T A_k z) = tr(A_j A_k) + tr(A_j A_k^T)`` (Gaussian ``z``).  What remains to
    add to the plug-in covariance is ``tr(A_j A_k)``, returned here.  Where the harmonics that
    separate the inertia from the stiffness are of the size of their noise it is of the size
    of the first-order term in that direction.
    """
    K = error_moments(lib, signals, alpha_cov) if moments is None else moments
    A = np.einsum("jiul,u->jil", K, np.asarray(theta, float))
    out = np.einsum("jab,kba->jk", A, A)
    return 0.5 * (out + out.T)


def frequency_score(lib, signals, scores, theta, R=None) -> np.ndarray | None:
    """``d(score)/d omega`` of a record whose excitation frequency was estimated (``None`` if given).

    The score ``X^T (V - X theta)`` at fixed ``theta`` is evaluated with the acceleration
    fitted at ``omega + h`` (same time origin) and differenced with its value at ``omega``
    (from the record's factor ``R`` when given).  A wrong frequency moves
    ``q = -q''/omega^2`` against the inertia column, i.e. each record's apparent stiffness
    ``theta_q - m omega_r^2``; across the records of a group that is an error of the gain,
    so the frequency estimate's own variance (:attr:`RecordScores.omega_variance`) enters
    the covariance as ``var(omega) s s^T``.
    """
    if signals.frequency_given or not scores.omega_variance > 0:
        return None
    omega = signals.omega
    h = max(1e-7 * omega, 0.1 * float(np.sqrt(scores.omega_variance)))
    nt = len(lib) + 1
    acc = signals.acceleration
    if R is None:
        R, _ = record_pass(lib, signals, inertia=True)
    series, _ = fit_harmonics(signals.t, signals.accel_measured, omega + h, acc.n_harmonics, t0=acc.t0)
    shifted = replace(signals, acceleration=series, frequency_hz=(omega + h) / (2 * np.pi), frequency_given=True)
    f = []
    for Rw in (record_pass(lib, shifted, inertia=True)[0], R):
        M = Rw.T @ Rw
        f.append(M[:nt, nt] - M[:nt, :nt] @ theta)
    return (f[0] - f[1]) / h


def _sandwich_covariance(lib, scores, alpha_covs, grams, coef, weights, placement, signals=None, moments=None,
                         factors=None):
    """Covariance of the pooled gain fit under the noise model of :mod:`jointid.identify.uncertainty`.

    The excitation noise enters ``V`` directly; the response noise enters through the
    harmonic fit, which moves the inertia column ``q''_fit`` and the states ``q, q'`` together
    (covariance of the acceleration coefficients from :func:`alpha_covariance`).  The bread is
    the corrected normal matrix the coefficients solve.  With the records' ``signals`` the meat
    also has the second-order term of the corrected score (:func:`eiv_score_covariance`) and,
    where the frequency was estimated, the error of that estimate (:func:`frequency_score`).
    """
    P = coef.size
    nt = len(lib) + 1
    A, meat = np.zeros((P, P)), np.zeros((P, P))
    n = len(scores)
    for sc, C, M, w, cols, sig, K, R in zip(scores, alpha_covs, grams, weights, placement, signals or [None] * n,
                                            moments or [None] * n, factors or [None] * n):
        theta = coef[cols]
        S = sc.score_terms(theta)
        V = sc.sigma_force**2 * sc.gram + S @ C @ S.T
        if sig is not None:
            V = V + eiv_score_covariance(lib, sig, C, theta, K)  # second order in the regressors' error
            u = frequency_score(lib, sig, sc, theta, R)
            if u is not None:  # the frequency estimate's own error
                V = V + sc.omega_variance * np.outer(u, u)
        idx = np.ix_(cols, cols)
        A[idx] += w**2 * M[:nt, :nt]
        meat[idx] += w**4 * 0.5 * (V + V.T)
    return sandwich(A, meat)
