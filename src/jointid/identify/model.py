"""One model per preload: a single weighted regression over all its records with amplitude laws.

The paper identifies ``omega1`` and ``k3`` per force level (Table 5) and fits the damping
law ``c(q_max)`` in a second step (Eq 26).  Yet ``omega1``, ``k3`` and the law are one
physical model of the preload; :class:`PreloadForceStateMapping` fits it in one regression

    ``Q - q'' = omega1^2 q - k3 q^3 + (c0 + c1 q_max + c2 q_max^2) q'``

(any terms, any law on any term).  Because ``q_max`` is constant within a record, the
columns of record ``r`` are its term columns times powers of its ``q_max``: the model is
assembled from each record's reduced factor ``R`` (no new pass over the samples), and the
covariance is the sandwich of :mod:`jointid.identify.uncertainty`, including the change of
``q_max`` with the harmonic fit (envelope theorem).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from .._blas import single_threaded
from ..errors import IdentificationError, IllConditionedWarning
from .fsm import COND_LIMIT, _check_terms, _ci_text, _pm, own_fits, pooled_inputs, record_whitenings
from .regression import lstsq_from_reduced
from .terms import library
from .uncertainty import ci95, sandwich

__all__ = ["PreloadModel", "PreloadForceStateMapping", "law_orders", "parameter_names"]


def law_orders(lib, amplitude_laws=None, damping_order=2) -> tuple:
    """Polynomial order of the amplitude law of every term (0: a constant coefficient).

    ``amplitude_laws`` maps term or coefficient names to orders; by default every
    damping-kind term follows a law of ``damping_order`` and the stiffness terms are constant.
    """
    if amplitude_laws is None:
        return tuple(int(damping_order) if t.kind == "damping" else 0 for t in lib)
    orders = [0] * len(lib)
    for name, order in dict(amplitude_laws).items():
        try:
            i = lib.index(name)
        except KeyError as exc:
            raise IdentificationError(f"amplitude law for {name!r}, which is no term of {lib.names}") from exc
        if int(order) < 0:
            raise IdentificationError(f"amplitude-law order of {name!r} must be >= 0, got {order}")
        orders[i] = int(order)
    return tuple(orders)


def parameter_names(lib, orders) -> tuple:
    """Names of the preload model's parameters: ``c0, c1, c2`` for ``c(q_max)``; a
    stiffness coefficient keeps its name for its constant part (``omega1^2``) and gets
    ``_1, _2 ...`` for the powers of ``q_max``."""
    names = []
    for t, L in zip(lib, orders):
        for j in range(L + 1):
            if L == 0:
                names.append(t.coefficient)
            elif t.kind == "damping" and t.coefficient.isalpha():
                names.append(f"{t.coefficient}{j}")
            else:
                names.append(t.coefficient if j == 0 else f"{t.coefficient}_{j}")
    return tuple(names)


def _expansion(orders, q_max):
    """``E`` (term columns -> model columns) and ``dE/dq_max`` at one amplitude."""
    p, P = len(orders), sum(L + 1 for L in orders)
    E, dE = np.zeros((p, P)), np.zeros((p, P))
    col = 0
    for k, L in enumerate(orders):
        for j in range(L + 1):
            E[k, col] = q_max**j
            dE[k, col] = j * q_max ** (j - 1) if j > 0 else 0.0
            col += 1
    return E, dE


@dataclass(frozen=True)
class PreloadModel:
    """The identified single-mode model of one preload, with its covariance.

    Attributes
    ----------
    preload : object
        The preload label (``None`` when fitted outside a campaign).
    terms : tuple of str
    law_orders : tuple of int
        Amplitude-law order of each term (0: constant).
    parameter_names : tuple of str
    parameters, stderr : array
    covariance : array
        Sandwich covariance of the parameters.
    q_max, frequency_hz, weights : array
        Amplitude, excitation frequency and weight of each record.
    condition_number : float
    n_samples : int
    warnings : tuple of str
    """

    preload: object
    terms: tuple
    coefficient_names: tuple
    law_orders: tuple
    parameter_names: tuple
    parameters: np.ndarray
    stderr: np.ndarray
    covariance: np.ndarray = field(repr=False)
    q_max: np.ndarray = field(default=None, repr=False)
    frequency_hz: np.ndarray = field(default=None, repr=False)
    weights: np.ndarray = field(default=None, repr=False)
    condition_number: float = float("nan")
    n_samples: int = 0
    warnings: tuple = ()

    @property
    def n_records(self) -> int:
        return int(len(self.q_max))

    def get(self, name) -> float:
        return float(self.parameters[self.parameter_names.index(name)])

    def get_stderr(self, name) -> float:
        return float(self.stderr[self.parameter_names.index(name)])

    def _law_slice(self, coefficient):
        k = self.coefficient_names.index(coefficient)
        start = sum(L + 1 for L in self.law_orders[:k])
        return slice(start, start + self.law_orders[k] + 1)

    def law(self, coefficient="c"):
        """``(coefficients, stderr, covariance)`` of ``coefficient(q_max)``, lowest power first."""
        s = self._law_slice(coefficient)
        return self.parameters[s].copy(), self.stderr[s].copy(), self.covariance[s, s].copy()

    def coefficients_at(self, q_max) -> np.ndarray:
        """Term coefficients of a steady state of amplitude ``q_max``."""
        E, _ = _expansion(self.law_orders, float(q_max))
        return E @ self.parameters

    def coefficient_at(self, coefficient, q_max):
        """``(value, stderr)`` of one term coefficient at the amplitudes ``q_max``."""
        s = self._law_slice(coefficient)
        q = np.atleast_1d(np.asarray(q_max, float))
        V = np.vander(q, s.stop - s.start, increasing=True)
        val = V @ self.parameters[s]
        se = np.sqrt(np.clip(np.einsum("ij,jk,ik->i", V, self.covariance[s, s], V), 0.0, None))
        return (val, se) if np.ndim(q_max) else (float(val[0]), float(se[0]))

    @property
    def omega1(self) -> float:
        w2 = self.get("omega1^2") if "omega1^2" in self.parameter_names else float("nan")
        return float(np.sqrt(w2)) if w2 > 0 else float("nan")

    @property
    def omega1_stderr(self) -> float:
        if not np.isfinite(self.omega1):
            return float("nan")
        return self.get_stderr("omega1^2") / (2 * self.omega1)

    @property
    def k3(self):
        return self.get("k3") if "k3" in self.parameter_names else None

    @property
    def k3_stderr(self):
        return self.get_stderr("k3") if "k3" in self.parameter_names else None

    @property
    def damping_coefficients(self):
        """Coefficients of the law of ``c`` (``[c0, c1, ...]``; ``[c]`` without a law)."""
        return self.law("c")[0] if "c" in self.coefficient_names else None

    @property
    def damping_stderr(self):
        return self.law("c")[1] if "c" in self.coefficient_names else None

    def summary(self) -> dict:
        def lst(a):
            return None if a is None else [float(v) for v in a]

        dc, ds = self.damping_coefficients, self.damping_stderr
        return {
            "preload": self.preload,
            "terms": list(self.terms),
            "amplitude_laws": {c: int(L) for c, L in zip(self.coefficient_names, self.law_orders) if L > 0},
            "omega1": self.omega1,
            "omega1_stderr": self.omega1_stderr,
            "omega1_ci95": ci95(self.omega1, self.omega1_stderr),
            "f1_hz": self.omega1 / (2 * np.pi),
            "k3": self.k3,
            "k3_stderr": self.k3_stderr,
            "k3_ci95": ci95(self.k3, self.k3_stderr),
            "damping_coefficients": lst(dc),
            "damping_stderr": lst(ds),
            "damping_ci95": None if dc is None else [ci95(v, s) for v, s in zip(dc, ds)],
            "parameter_names": list(self.parameter_names),
            "parameters": lst(self.parameters),
            "stderr": lst(self.stderr),
            "ci95": [ci95(v, s) for v, s in zip(self.parameters, self.stderr)],
            "covariance": self.covariance.tolist(),
            "n_records": self.n_records,
            "n_samples": int(self.n_samples),
            "q_max_range": [float(np.min(self.q_max)), float(np.max(self.q_max))],
            "frequency_hz_range": [float(np.min(self.frequency_hz)), float(np.max(self.frequency_hz))],
            "condition_number": float(self.condition_number),
            "warnings": list(self.warnings),
        }

    def report(self) -> str:
        laws = {c: L for c, L in zip(self.coefficient_names, self.law_orders) if L > 0}
        head = f"preload {self.preload}: " if self.preload is not None else ""
        lines = [
            f"{head}one model over {self.n_records} records (q_max {np.min(self.q_max):.4g} .. "
            f"{np.max(self.q_max):.4g}; condition number {self.condition_number:.3g}"
            + (f"; laws in q_max: {', '.join(f'{c} order {L}' for c, L in laws.items())})" if laws else ")")
        ]
        for n, v, s in zip(self.parameter_names, self.parameters, self.stderr):
            lines.append(f"  {n:>12} = {_pm(v, s)}{_ci_text(v, s)}")
        if np.isfinite(self.omega1):
            lines.append(f"  {'omega1':>12} = {_pm(self.omega1, self.omega1_stderr)} rad/s"
                         f"{_ci_text(self.omega1, self.omega1_stderr)}")
        lines += [f"  warning: {w}" for w in self.warnings]
        return "\n".join(lines)

    def __repr__(self):
        pars = ", ".join(f"{n}={v:.4g}" for n, v in zip(self.parameter_names, self.parameters))
        return f"PreloadModel(preload {self.preload!r}, {self.n_records} records: {pars})"

    def _repr_html_(self):
        from ..report.notebook import result_html

        return result_html(self)

    def plot(self, ax=None, coefficient="c"):
        """``coefficient(q_max)`` of the model with its 95 % band over the measured amplitudes."""
        from ..report.identify_plots import new_axes

        ax = new_axes(ax)
        qq = np.linspace(np.min(self.q_max), np.max(self.q_max), 200)
        val, se = self.coefficient_at(coefficient, qq)
        (line,) = ax.plot(qq, val, "-", label=f"preload {self.preload} model")
        ax.fill_between(qq, val - 1.96 * se, val + 1.96 * se, color=line.get_color(), alpha=0.25, label="95 %")
        ax.set_xlabel("q_max")
        ax.set_ylabel(f"{coefficient}(q_max)")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
        return ax


class PreloadForceStateMapping:
    """One weighted regression over all records of a preload with amplitude laws inside.

    Parameters
    ----------
    terms : str or TermLibrary
    amplitude_laws : mapping, optional
        ``{term or coefficient name: order}``; by default every damping-kind term follows a
        law of order ``damping_order`` and the stiffness terms are constant.  A stiffness
        law (``{"q": 2}``: ``omega^2(q_max) = omega1^2 + s1 q_max + s2 q_max^2``) works alike.
    damping_order : int
    weighting : {"noise", "none"}
        Record weights as in :class:`~jointid.identify.fsm.PooledForceStateMapping`
        (:func:`~jointid.identify.fsm.record_whitenings`).
    cond_limit : float
    filtered : bool
    preload : object
        Label stored on the result.

    Attributes
    ----------
    result_ : PreloadModel
    coef_, stderr_, covariance_ : array
    """

    def __init__(self, terms="q + -q^3 + q'", amplitude_laws=None, damping_order=2, weighting="noise",
                 cond_limit=COND_LIMIT, filtered=True, preload=None):
        self.terms = terms
        self.amplitude_laws = amplitude_laws
        self.damping_order = damping_order
        self.weighting = weighting
        self.cond_limit = cond_limit
        self.filtered = filtered
        self.preload = preload

    @single_threaded
    def fit(self, signals_list, *, context="", fits=None):
        """Fit the model to the records (``fits``: their own fits, reused when given)."""
        sigs = pooled_inputs(signals_list, self.weighting, "preload model")
        lib = library(self.terms)
        for s in sigs:
            _check_terms(lib, s.acceleration.n_harmonics)
        orders = law_orders(lib, self.amplitude_laws, self.damping_order)
        names = parameter_names(lib, orders)
        P = len(names)
        if len(sigs) < max(orders) + 1:
            raise IdentificationError(
                f"{context}an amplitude law of order {max(orders)} needs at least {max(orders) + 1} records, got {len(sigs)}"
            )
        fits = own_fits(lib, sigs, fits, self.filtered)
        p = len(lib)
        q_max = np.array([f.q_max for f in fits])
        Es = [_expansion(orders, q) for q in q_max]
        n_total = int(sum(f.n_samples for f in fits))

        def solve(wh):
            rows = [w.rows for w in wh]
            A = np.vstack([r[:, :p] @ E for r, (E, _) in zip(rows, Es)])
            b = np.concatenate([r[:, p] for r in rows])
            return A, lstsq_from_reduced(A, b, n_total)

        wh = record_whitenings(fits, self.weighting)
        A, res = solve(wh)
        weights = np.array([w.scalar for w in wh])
        theta = res.coefficients
        M = A.T @ A
        V = np.zeros((P, P))
        for w, f, (E, dE) in zip(wh, fits, Es):
            V += E.T @ w.score_covariance(f.scores.covariance(E @ theta, dE @ theta)) @ E
        cov = sandwich(M, V)
        se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
        warn = []
        if not np.isfinite(res.condition_number) or res.condition_number > self.cond_limit:
            warn.append(f"{context}preload model too ill-conditioned (condition number {res.condition_number:.3g} > "
                        f"{self.cond_limit:.3g}); its parameters are not resolved")
        for w_ in warn:
            warnings.warn(w_, IllConditionedWarning, stacklevel=3)
        self.library_ = lib
        self.coef_, self.stderr_, self.covariance_ = theta, se, cov
        self.result_ = PreloadModel(
            self.preload, lib.names, lib.coefficient_names, orders, names, theta, se, cov, q_max,
            np.array([s.frequency_hz for s in sigs]), weights, res.condition_number, n_total, tuple(warn),
        )
        return self
