"""Force-state mapping: regression of the restoring force on named terms (seed Eq 21-23).

For every steady-state record the restoring force ``Q(t) - q''(t)`` (measured force minus
the harmonic-filtered acceleration) is regressed on the term library evaluated at the
analytically integrated displacement and velocity.

* :class:`ForceStateMapping` fits one record (seed Eq 23) and
  :func:`band_average` averages such fits over a frequency band (seed Tables 1 and 3).
* :class:`PooledForceStateMapping` fits all records of a group together: stiffness terms
  (``omega1^2``, ``k3``) are shared, damping terms get one coefficient per record.  The
  shared coefficients then draw on the amplitude spread across the records, which
  conditions ``k3`` far better than averaging single-record fits.

Both follow the scikit-learn convention: parameters in ``__init__``, ``fit`` returns
``self``, learned values end in ``_``.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field, replace

import numpy as np

from .._blas import single_threaded
from ..errors import IdentificationError, IllConditionedWarning
from ..rounding import format_ci, format_pm
from ..signal.harmonics import StateSignals
from .regression import LstsqResult, lstsq_from_reduced, pooled_solve
from .terms import TermLibrary, library
from .uncertainty import (
    PooledCovariance,
    RecordScores,
    ci95,
    pooled_covariance,
    record_pass,
    sandwich,
    whitening,
)

__all__ = [
    "RecordFit",
    "PooledFit",
    "ForceStateMapping",
    "PooledForceStateMapping",
    "band_average",
]

#: Default limit on the scaled condition number above which a fit warns.
COND_LIMIT = 1e8
#: A nonlinear stiffness coefficient closer to zero than this many standard errors is "not resolved".
RESOLVED_T = 3.0


def _named(names, coefficients, name, transform=None):
    for n, c in zip(names, coefficients):
        if n == name:
            return transform(c) if transform else float(c)
    return None


def _omega1(value):
    return float(np.sqrt(value)) if value is not None and value > 0 else float("nan")


def _ci_text(value, stderr) -> str:
    ci = ci95(value, stderr)
    if ci is None:
        return ""
    return f", 95 % {format_ci(ci, stderr)}"  # rounded like the value (two digits of the standard error)


def _pm(value, stderr) -> str:
    """``value ± stderr`` rounded to two significant digits of the standard error."""
    return format_pm(value, stderr)


def record_whitenings(fits, weighting, thetas=None) -> list:
    """Weight of each record in a pooled regression, from its own fit.

    ``"noise"``: the inverse of the white-noise level that carries the same information as
    the record's own fit under the noise model (evaluated at the record's own coefficients,
    so the weights do not depend on the pooled estimate), see
    :func:`~jointid.identify.uncertainty.whitening`: records count by the information their
    own regression holds, whatever their noise levels.  ``"none"``: all records count alike.

    ``thetas`` (one coefficient vector per record) replaces the records' own coefficients in
    the noise model.  (Weighting again at a pooled fit's first estimate was tried: slightly
    better calibrated, but several times larger errors where that estimate is poor.)
    """
    out = []
    for r, f in enumerate(fits):
        p = len(f.coefficients)
        floor = 1e-13 * float(np.abs(f.reduced[:, p]).max()) / np.sqrt(f.n_samples)
        theta = f.coefficients if thetas is None else thetas[r]
        out.append(whitening(f.reduced, f.scores, theta, weighting=weighting, floor=floor))
    return out


@dataclass(frozen=True)
class RecordFit:
    """Force-state mapping of one record.

    Attributes
    ----------
    terms : tuple of str
        Term names, in the library's order.
    coefficient_names : tuple of str
    coefficients, stderr : array
        Estimates and standard errors from the noise model of
        :mod:`jointid.identify.uncertainty` (white force noise entering the restoring force,
        white acceleration noise entering through the harmonic fit).
    condition_number : float
        Of the column-scaled regression matrix.
    q_max : float
        Steady-state amplitude of the reconstructed displacement.
    frequency_hz : float
    residual_rms : float
        RMS of the regression residual (force units).
    n_samples : int
    """

    terms: tuple
    coefficient_names: tuple
    coefficients: np.ndarray
    stderr: np.ndarray
    condition_number: float
    q_max: float
    frequency_hz: float
    residual_rms: float
    n_samples: int
    warnings: tuple = ()
    covariance: np.ndarray | None = field(default=None, repr=False)
    reduced: np.ndarray | None = field(default=None, repr=False, compare=False)  # R of [X, y_fit, y_raw]
    scores: RecordScores | None = field(default=None, repr=False, compare=False)

    def get(self, name):
        """Coefficient by coefficient or term name."""
        for i, (t, c) in enumerate(zip(self.terms, self.coefficient_names)):
            if name in (t, c):
                return float(self.coefficients[i])
        raise KeyError(name)

    @property
    def omega1(self) -> float:
        """Identified linear natural frequency [rad/s] (``sqrt`` of the ``q`` coefficient)."""
        return _omega1(_named(self.coefficient_names, self.coefficients, "omega1^2"))

    @property
    def k3(self):
        return _named(self.coefficient_names, self.coefficients, "k3")

    @property
    def c(self):
        return _named(self.coefficient_names, self.coefficients, "c")

    @property
    def c_stderr(self):
        return _named(self.coefficient_names, self.stderr, "c")

    @property
    def omega1_stderr(self) -> float:
        s = _named(self.coefficient_names, self.stderr, "omega1^2")
        return s / (2 * self.omega1) if s is not None and np.isfinite(self.omega1) else float("nan")

    def equation(self) -> str:
        return library(self.terms).equation(self.coefficients, self.stderr)

    def summary(self) -> dict:
        return {
            "frequency_hz": self.frequency_hz,
            "q_max": self.q_max,
            "omega1": self.omega1,
            "f1_hz": self.omega1 / (2 * np.pi),
            "k3": self.k3,
            "c": self.c,
            "terms": list(self.terms),
            "coefficients": {n: float(v) for n, v in zip(self.coefficient_names, self.coefficients)},
            "stderr": {n: float(v) for n, v in zip(self.coefficient_names, self.stderr)},
            "ci95": {n: ci95(v, e) for n, v, e in zip(self.coefficient_names, self.coefficients, self.stderr)},
            "omega1_stderr": self.omega1_stderr,
            "omega1_ci95": ci95(self.omega1, self.omega1_stderr),
            "c_stderr": self.c_stderr,
            "c_ci95": ci95(self.c, self.c_stderr),
            "condition_number": self.condition_number,
            "residual_rms": self.residual_rms,
            "n_samples": self.n_samples,
            "warnings": list(self.warnings),
        }

    def report(self) -> str:
        lines = [
            f"force-state mapping at {self.frequency_hz:.6g} Hz, q_max = {self.q_max:.6g}, "
            f"{self.n_samples} samples, condition number {self.condition_number:.3g}",
            self.equation(),
        ]
        if np.isfinite(self.omega1):
            lines.append(f"  omega1 = {self.omega1:.8g} rad/s ({self.omega1 / (2 * np.pi):.8g} Hz)")
        lines += [f"  warning: {w}" for w in self.warnings]
        return "\n".join(lines)

    def __repr__(self):
        coef = ", ".join(f"{n}={v:.4g}" for n, v in zip(self.coefficient_names, self.coefficients))
        return (f"RecordFit({self.frequency_hz:.6g} Hz, q_max={self.q_max:.4g}: {coef}; "
                f"{len(self.warnings)} warnings)")

    def _repr_html_(self):
        from .. import plotting

        return plotting.draw("notebook.result_html", self)


def _check_terms(lib: TermLibrary, n_harmonics: int):
    if n_harmonics < 3 and any(t.kind == "stiffness" and t.name not in ("q",) for t in lib):
        raise IdentificationError(
            f"a nonlinear stiffness term ({[t.name for t in lib if t.kind == 'stiffness' and t.name != 'q']}) "
            f"needs at least 3 fitted harmonics to be seen, got n_harmonics={n_harmonics}"
        )


def _resolution_warnings(terms, res: LstsqResult, cond_limit, context=""):
    """Warnings for a fit whose nonlinear coefficients the data cannot resolve."""
    out = []
    if not np.isfinite(res.condition_number) or res.condition_number > cond_limit:
        out.append(
            f"{context}regression too ill-conditioned (condition number {res.condition_number:.3g} > "
            f"{cond_limit:.3g}); coefficients are not resolved"
        )
    for t, c, s in zip(terms, res.coefficients, res.stderr):
        if t.name in ("q", "q'"):
            continue
        if t.kind == "stiffness" and np.isfinite(s) and RESOLVED_T * s > abs(c):
            out.append(
                f"{context}{t.coefficient} not resolved by the data: {t.coefficient} = {c:.4g} ± {s:.2g}, "
                f"less than {RESOLVED_T:g} standard errors from zero (condition number {res.condition_number:.3g})"
            )
    return tuple(out)


class ForceStateMapping:
    """Per-record force-state mapping (seed Eq 23).

    Parameters
    ----------
    terms : str or TermLibrary
        Restoring-force terms, ``"q + -q^3 + q'"`` (seed Eq 21) by default.
    cond_limit : float
        Scaled condition number above which the fit warns.
    filtered : bool
        Use the harmonic-filtered acceleration in ``Q - q''`` (the seed's choice).

    Attributes
    ----------
    result_ : RecordFit
    coef_, stderr_ : array
    condition_number_ : float

    Examples
    --------
    >>> from jointid.signal.harmonics import steady_state_signals
    >>> t = np.arange(4000) / 2000.0
    >>> w, A = 30.0, 0.01
    >>> q = A * np.cos(w * t); v = -A * w * np.sin(w * t); a = -A * w**2 * np.cos(w * t)
    >>> Q = a + 900.0 * q + 0.5 * v          # linear oscillator, omega1 = 30, c = 0.5
    >>> sig = steady_state_signals(t, Q, a, frequency_hz=w / (2 * np.pi), n_harmonics=3)
    >>> fsm = ForceStateMapping("q + q'").fit(sig)
    >>> np.round(fsm.coef_, 8).tolist()
    [900.0, 0.5]
    """

    def __init__(self, terms="q + -q^3 + q'", cond_limit=COND_LIMIT, filtered=True):
        self.terms = terms
        self.cond_limit = cond_limit
        self.filtered = filtered

    @single_threaded
    def fit(self, signals: StateSignals, *, context=""):
        lib = library(self.terms)
        _check_terms(lib, signals.acceleration.n_harmonics)
        R, scores = record_pass(lib, signals, self.filtered)
        p = len(lib)
        res = lstsq_from_reduced(R[:, :p], R[:, p], signals.t.size, R[:, p + 1])
        if scores.omega_variance > 0:
            scores = replace(scores, omega_score=scores.frequency_score(res.coefficients))
        cov = sandwich(R[:, :p].T @ R[:, :p], scores.covariance(res.coefficients))
        res = replace(res, covariance=cov, stderr=np.sqrt(np.clip(np.diag(cov), 0.0, None)))
        warn = _resolution_warnings(list(lib), res, self.cond_limit, context)
        for w in warn:
            warnings.warn(w, IllConditionedWarning, stacklevel=3)
        self.library_ = lib
        self.lstsq_ = res
        self.coef_ = res.coefficients
        self.stderr_ = res.stderr
        self.condition_number_ = res.condition_number
        self.result_ = RecordFit(
            lib.names,
            lib.coefficient_names,
            res.coefficients,
            res.stderr,
            res.condition_number,
            signals.q_max(),
            signals.frequency_hz,
            float(np.sqrt(res.rss / max(res.n_samples, 1))),
            res.n_samples,
            warn,
            cov,
            R,
            scores,
        )
        return self


def pooled_inputs(signals_list, weighting, what) -> list:
    """Check the arguments of a pooled estimator: a non-empty list of records, a known weighting."""
    sigs = list(signals_list)
    if not sigs:
        raise IdentificationError(f"the {what} needs at least one record")
    if weighting not in ("noise", "none"):
        raise IdentificationError(f"weighting must be 'noise' or 'none', got {weighting!r}")
    for s in sigs:
        if not isinstance(s, StateSignals):
            raise IdentificationError(f"the {what} expects StateSignals records, got {type(s).__name__}")
    return sigs


def split_terms(lib, per_record=None):
    """Indices of the shared and of the per-record terms of a pooled regression.

    ``per_record`` names the per-record terms (or coefficients); by default the
    damping-kind terms are per record and the stiffness terms shared.
    """
    if per_record is None:
        own = [i for i, t in enumerate(lib) if t.kind == "damping"]
    else:
        own = [lib.index(n) for n in per_record]
    return [i for i in range(len(lib)) if i not in own], own


def band_average(fits) -> dict:
    """Average of single-record coefficients over a band of records (seed Tables 1, 3).

    ``omega1`` is averaged as a frequency (the mean of the per-record square roots).
    """
    fits = list(fits)
    if not fits:
        raise IdentificationError("band_average needs at least one record fit")
    names = fits[0].coefficient_names
    C = np.array([f.coefficients for f in fits])
    out = {n: float(v) for n, v in zip(names, C.mean(axis=0))}
    out["omega1"] = float(np.mean([f.omega1 for f in fits]))
    out["n_records"] = len(fits)
    return out


@dataclass(frozen=True)
class PooledFit:
    """Pooled force-state mapping over the records of a group.

    Attributes
    ----------
    shared_names, shared, shared_stderr
        Coefficients common to all records (``omega1^2``, ``k3`` ...).
    own_names, own, own_stderr
        Per-record coefficients, arrays ``(n_records, n_own)`` (``c`` ...).
    q_max : array
        Amplitude of each record.
    frequency_hz : array
    condition_number : float
        Of the column-scaled pooled regression.
    weights : array
        Weight of each record (:func:`record_whitenings`).
    covariance : PooledCovariance or None
        Sandwich covariance of the shared and per-record coefficients (linear in the number
        of records); ``shared_stderr`` and ``own_stderr`` come from it.
    """

    terms: tuple
    shared_names: tuple
    shared: np.ndarray
    shared_stderr: np.ndarray
    own_names: tuple
    own: np.ndarray
    own_stderr: np.ndarray
    q_max: np.ndarray
    frequency_hz: np.ndarray
    condition_number: float
    weights: np.ndarray = field(repr=False)
    n_samples: int = 0
    warnings: tuple = ()
    covariance: PooledCovariance | None = field(default=None, repr=False, compare=False)

    def get(self, name):
        """A shared coefficient (float) or a per-record one (array) by name."""
        if name in self.shared_names:
            return float(self.shared[self.shared_names.index(name)])
        if name in self.own_names:
            return self.own[:, self.own_names.index(name)]
        raise KeyError(name)

    def get_stderr(self, name):
        if name in self.shared_names:
            return float(self.shared_stderr[self.shared_names.index(name)])
        return self.own_stderr[:, self.own_names.index(name)]

    @property
    def omega1(self) -> float:
        return _omega1(self.get("omega1^2")) if "omega1^2" in self.shared_names else float("nan")

    @property
    def omega1_stderr(self) -> float:
        return self.get_stderr("omega1^2") / (2 * self.omega1) if np.isfinite(self.omega1) else float("nan")

    @property
    def k3(self):
        return self.get("k3") if "k3" in self.shared_names else None

    @property
    def c(self):
        return self.get("c") if "c" in self.own_names else None

    def summary(self) -> dict:
        return {
            "omega1": self.omega1,
            "omega1_stderr": self.omega1_stderr,
            "omega1_ci95": ci95(self.omega1, self.omega1_stderr),
            "f1_hz": self.omega1 / (2 * np.pi),
            "k3": self.k3,
            "shared": {n: float(v) for n, v in zip(self.shared_names, self.shared)},
            "shared_stderr": {n: float(v) for n, v in zip(self.shared_names, self.shared_stderr)},
            "shared_ci95": {n: ci95(v, s) for n, v, s in zip(self.shared_names, self.shared, self.shared_stderr)},
            "shared_covariance": (self.covariance.shared.tolist() if self.covariance is not None else None),
            "per_record": {n: self.own[:, i].tolist() for i, n in enumerate(self.own_names)},
            "per_record_stderr": {n: self.own_stderr[:, i].tolist() for i, n in enumerate(self.own_names)},
            "per_record_ci95": {n: [ci95(v, s) for v, s in zip(self.own[:, i], self.own_stderr[:, i])]
                                for i, n in enumerate(self.own_names)},
            "q_max": self.q_max.tolist(),
            "frequency_hz": self.frequency_hz.tolist(),
            "condition_number": self.condition_number,
            "n_records": int(len(self.q_max)),
            "warnings": list(self.warnings),
        }

    def report(self) -> str:
        lines = [
            f"pooled force-state mapping over {len(self.q_max)} records "
            f"(condition number {self.condition_number:.3g})"
        ]
        for n, v, s in zip(self.shared_names, self.shared, self.shared_stderr):
            lines.append(f"  {n:>10} = {_pm(v, s)}   (shared){_ci_text(v, s)}")
        if np.isfinite(self.omega1):
            lines.append(f"  {'omega1':>10} = {_pm(self.omega1, self.omega1_stderr)} rad/s = "
                         f"{_pm(self.omega1 / (2 * np.pi), self.omega1_stderr / (2 * np.pi))} Hz"
                         f"{_ci_text(self.omega1, self.omega1_stderr)}")
        for i, n in enumerate(self.own_names):
            lines.append(
                f"  {n:>10} per record: {np.min(self.own[:, i]):.4g} .. {np.max(self.own[:, i]):.4g} "
                f"over q_max {np.min(self.q_max):.4g} .. {np.max(self.q_max):.4g}"
            )
        lines += [f"  warning: {w}" for w in self.warnings]
        return "\n".join(lines)

    def __repr__(self):
        shared = ", ".join(f"{n}={v:.6g}" for n, v in zip(self.shared_names, self.shared))
        return (f"PooledFit({len(self.q_max)} records: {shared}; per record: {', '.join(self.own_names)}; "
                f"{len(self.warnings)} warnings)")

    def _repr_html_(self):
        from .. import plotting

        return plotting.draw("notebook.result_html", self)

    def plot(self, ax=None, name="c"):
        """Per-record coefficient ``name`` against ``q_max`` (seed Fig 12)."""
        from .. import plotting

        return plotting.draw("identify_plots.plot_per_record", self, name=name, ax=ax)


class PooledForceStateMapping:
    """Pooled force-state mapping over a group of records.

    Parameters
    ----------
    terms : str or TermLibrary
    per_record : sequence of str or None
        Terms (names or coefficient names) that get one coefficient per record.  By
        default every damping-kind term (``q'``, ``|q'|q'`` ...) does and the stiffness
        terms are shared.
    weighting : {"noise", "none"}
        ``"noise"``: each record is weighted by the inverse of the white-noise level that
        carries the information of its own fit under the noise model (:func:`record_whitenings`).
    cond_limit : float

    Attributes
    ----------
    result_ : PooledFit
    coef_ : array
        The shared coefficients.
    solution_ : PooledSolution
        The pooled least-squares solution (shared and per-record coefficients, the
        per-record elimination factors).
    """

    def __init__(self, terms="q + -q^3 + q'", per_record=None, weighting="noise", cond_limit=COND_LIMIT, filtered=True):
        self.terms = terms
        self.per_record = per_record
        self.weighting = weighting
        self.cond_limit = cond_limit
        self.filtered = filtered

    @single_threaded
    def fit(self, signals_list, *, context="", fits=None):
        """Fit the pooled regression.

        Parameters
        ----------
        signals_list : sequence of StateSignals
        context : str
            Prefix of warning messages.
        fits : sequence of RecordFit, optional
            The records' own fits with the same terms (from :class:`ForceStateMapping`);
            their reduced factors and noise sums are reused instead of reading the samples again.
        """
        signals_list = pooled_inputs(signals_list, self.weighting, "pooled regression")
        lib = library(self.terms)
        for s in signals_list:
            _check_terms(lib, s.acceleration.n_harmonics)
        fits = own_fits(lib, signals_list, fits, self.filtered)
        shared_idx, own_idx = split_terms(lib, self.per_record)
        ns, no, nr = len(shared_idx), len(own_idx), len(signals_list)
        nt = len(lib)
        wh = record_whitenings(fits, self.weighting)
        sol = pooled_solve([(w.rows, f.n_samples) for w, f in zip(wh, fits)], shared_idx, own_idx, nt, np.ones(nr))
        weights = np.array([w.scalar for w in wh])
        order = shared_idx + own_idx
        V_list, g_list = [], []
        for r, f in enumerate(fits):
            theta = np.empty(nt)
            theta[shared_idx] = sol.shared
            theta[own_idx] = sol.own[r]
            V = wh[r].score_covariance(f.scores.covariance(theta))
            V_list.append(V[np.ix_(order, order)])
            g_list.append(wh[r].score_cross(f.scores.score_q_max_covariance(theta))[order])
        cov = pooled_covariance(sol, V_list, ns, g_list, [f.scores.q_max_variance() for f in fits])
        shared_se = np.sqrt(np.clip(np.diag(cov.shared), 0.0, None))
        own_se = np.sqrt(np.clip(np.diagonal(cov.own, axis1=1, axis2=2), 0.0, None)).reshape(nr, no)
        n_total = sol.n_samples
        shared_part = LstsqResult(sol.shared, shared_se, cov.shared, sol.condition_number, float("nan"), n_total)
        warn = _resolution_warnings([lib[i] for i in shared_idx], shared_part, self.cond_limit, context)
        for w in warn:
            warnings.warn(w, IllConditionedWarning, stacklevel=3)
        self.library_ = lib
        self.solution_ = sol
        self.result_ = PooledFit(
            lib.names,
            tuple(lib[i].coefficient for i in shared_idx),
            sol.shared,
            shared_se,
            tuple(lib[i].coefficient for i in own_idx),
            sol.own,
            own_se,
            np.array([s.q_max() for s in signals_list]),
            np.array([s.frequency_hz for s in signals_list]),
            sol.condition_number,
            weights,
            n_total,
            warn,
            cov,
        )
        self.coef_ = self.result_.shared
        return self


def own_fits(lib, signals_list, fits=None, filtered=True) -> list:
    """Each record's own :class:`RecordFit` with ``lib``'s terms (reused when given and matching)."""
    if fits is not None:
        fits = list(fits)
        if len(fits) != len(signals_list):
            raise IdentificationError(f"{len(fits)} record fits given for {len(signals_list)} records")
        if all(f is not None and f.terms == lib.names and f.scores is not None and f.reduced is not None
               and f.scores.filtered == filtered for f in fits):
            return fits
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IllConditionedWarning)
        return [ForceStateMapping(lib, filtered=filtered).fit(s).result_ for s in signals_list]
