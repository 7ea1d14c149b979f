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

A law may also be the micro-slip power law ``c0 + c1 q_max^p`` (``{"q'": "power"}``,
:mod:`jointid.identify.powerlaw`).  Its exponent is fitted by variable projection (the
other parameters by the same linear least squares at every trial exponent); the
Jacobian of the model at the solution, with the exponent's column ``c1 q_max^p ln q_max``,
takes the place of the design matrix in the sandwich covariance.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
from scipy import linalg, optimize

from .._blas import single_threaded
from ..errors import IdentificationError, IllConditionedWarning
from .fsm import COND_LIMIT, _check_terms, _ci_text, _pm, own_fits, pooled_inputs, record_whitenings
from .powerlaw import EXPONENT_BOUNDS, POWER, PowerLaw, is_power
from .regression import lstsq_from_reduced
from .terms import library
from .uncertainty import ci95, sandwich, scaled_inverse

__all__ = ["PreloadModel", "PreloadForceStateMapping", "law_orders", "law_size", "parameter_names", "expand",
           "fit_laws", "in_band_rows", "out_of_band_fraction", "use_in_band"]


def law_size(order) -> int:
    """Number of parameters of an amplitude law (``order + 1``; 3 for the power law)."""
    return 3 if is_power(order) else int(order) + 1


def law_orders(lib, amplitude_laws=None, damping_order=2) -> tuple:
    """Polynomial order of the amplitude law of every term (0: a constant coefficient).

    ``amplitude_laws`` maps term or coefficient names to orders, or to ``"power"`` for the
    micro-slip law ``c0 + c1 q_max^p`` (:mod:`jointid.identify.powerlaw`); by default every
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
        if is_power(order):
            orders[i] = POWER
            continue
        if isinstance(order, str) or int(order) < 0:
            raise IdentificationError(f"amplitude-law order of {name!r} must be >= 0, got {order}")
        orders[i] = int(order)
    return tuple(orders)


def parameter_names(lib, orders) -> tuple:
    """Names of the preload model's parameters: ``c0, c1, c2`` for ``c(q_max)``; a
    stiffness coefficient keeps its name for its constant part (``omega1^2``) and gets
    ``_1, _2 ...`` for the powers of ``q_max``."""
    names = []
    for t, L in zip(lib, orders):
        if is_power(L):  # base, coefficient of q_max^p, exponent
            base = f"{t.coefficient}0" if t.kind == "damping" and t.coefficient.isalpha() else t.coefficient
            one = f"{t.coefficient}1" if t.kind == "damping" and t.coefficient.isalpha() else f"{t.coefficient}_1"
            names += [base, one, f"p({t.coefficient})"]
            continue
        for j in range(L + 1):
            if L == 0:
                names.append(t.coefficient)
            elif t.kind == "damping" and t.coefficient.isalpha():
                names.append(f"{t.coefficient}{j}")
            else:
                names.append(t.coefficient if j == 0 else f"{t.coefficient}_{j}")
    return tuple(names)


def _expansion(orders, q_max):
    """``E`` (term columns -> model columns) and ``dE/dq_max`` at one amplitude (polynomial laws)."""
    if any(is_power(L) for L in orders):
        raise IdentificationError("a power law's coefficients depend on its exponent: use expand()")
    p, P = len(orders), sum(L + 1 for L in orders)
    E, dE = np.zeros((p, P)), np.zeros((p, P))
    col = 0
    for k, L in enumerate(orders):
        for j in range(L + 1):
            E[k, col] = q_max**j
            dE[k, col] = j * q_max ** (j - 1) if j > 0 else 0.0
            col += 1
    return E, dE


def expand(orders, q_max, theta):
    """Term coefficients of a steady state of amplitude ``q_max``, their Jacobian and slope.

    Returns
    -------
    coefficients : ndarray, shape (p,)
        Value of every term coefficient at ``q_max``.
    E : ndarray, shape (p, P)
        ``d coefficients / d theta`` (for polynomial laws the matrix of powers of ``q_max``,
        for a power law ``1, q_max^p, c1 q_max^p ln q_max``).
    slope : ndarray, shape (p,)
        ``d coefficients / d q_max``.
    """
    theta = np.asarray(theta, float)
    if not any(is_power(L) for L in orders):
        E, dE = _expansion(orders, q_max)
        return E @ theta, E, dE @ theta
    p, P = len(orders), sum(law_size(L) for L in orders)
    E, coef, slope = np.zeros((p, P)), np.zeros(p), np.zeros(p)
    col = 0
    for k, L in enumerate(orders):
        n = law_size(L)
        if is_power(L):
            law = PowerLaw(*theta[col:col + 3])
            coef[k], slope[k] = law.value(q_max), law.derivative(q_max)
            E[k, col:col + 3] = law.jacobian(q_max)
        else:
            v = float(q_max) ** np.arange(n)
            E[k, col:col + n] = v
            coef[k] = v @ theta[col:col + n]
            slope[k] = (np.arange(1, n) * v[:-1]) @ theta[col + 1:col + n] if n > 1 else 0.0
        col += n
    return coef, E, slope


def _exponent_positions(orders):
    pos, col = [], 0
    for L in orders:
        if is_power(L):
            pos.append(col + 2)
        col += law_size(L)
    return pos


def fit_laws(term_rows, rhs, q_max, orders, n_samples):
    """Least squares of a preload model over records given as weighted reduced rows.

    Parameters
    ----------
    term_rows, rhs : sequence of arrays
        Record ``r``'s rows in the term columns ``(n_r, p)`` and its right-hand side ``(n_r,)``.
    q_max : sequence of float
    orders : tuple
        Law of every term (:func:`law_orders`).
    n_samples : int

    Returns
    -------
    theta : ndarray
    condition_number : float
        Of the linear least squares (at the fitted exponents).
    J : ndarray
        Jacobian of the stacked rows with respect to ``theta`` (the design matrix for
        polynomial laws).

    Notes
    -----
    Power-law exponents are found by variable projection: for given exponents the model
    is linear in the other parameters; the residual sum is minimised over the exponents
    (a coarse grid in ``EXPONENT_BOUNDS``, then Nelder-Mead within the bounds).
    """
    b = np.concatenate(rhs)
    pos = _exponent_positions(orders)
    P = sum(law_size(L) for L in orders)
    lin = [i for i in range(P) if i not in pos]

    # at fixed exponents a power law is linear: the columns 1 and q_max^p (an order-1 law
    # with q_max^p in place of q_max)
    lin_orders = tuple(1 if is_power(L) else L for L in orders)
    power_cols = [(k, int(np.cumsum([law_size(L) for L in lin_orders])[k]) - 1)
                  for k, L in enumerate(orders) if is_power(L)]

    bases = [_expansion(lin_orders, q)[0] for q in q_max]  # the same at every trial exponent

    def design(exps):
        out = []
        for R, q, base in zip(term_rows, q_max, bases):
            E = base.copy()
            for (k, j), c in zip(power_cols, exps):
                E[k, j] = abs(q) ** c
            out.append(R @ E)
        return np.vstack(out)

    def solve(exps):
        A = design(exps)
        res = lstsq_from_reduced(A, b, n_samples)
        r = A @ res.coefficients - b
        return res, A, float(r @ r)

    if not pos:
        res, A, _ = solve(())
        return res.coefficients, res.condition_number, A
    lo, hi = EXPONENT_BOUNDS

    def cost(x):
        c = solve(np.clip(x, lo, hi))[2]
        return c if np.isfinite(c) else np.inf

    grid = np.geomspace(lo, hi, 13 if len(pos) == 1 else 7)
    starts = np.array(np.meshgrid(*[grid] * len(pos), indexing="ij")).reshape(len(pos), -1).T
    x0 = min(starts, key=cost)
    c0 = cost(x0)
    sol = optimize.minimize(cost, x0, method="Nelder-Mead", bounds=[(lo, hi)] * len(pos),
                            options={"xatol": 1e-7, "fatol": 1e-12 * max(c0, 1e-300), "maxiter": 2000 * len(pos)})
    exps = np.clip(sol.x if sol.fun <= c0 else x0, lo, hi)
    res, _, _ = solve(exps)
    theta = np.zeros(P)
    theta[pos] = exps
    theta[lin] = res.coefficients
    J = np.vstack([R @ expand(orders, q, theta)[1] for R, q in zip(term_rows, q_max)])
    return theta, res.condition_number, J


def in_band_rows(fit, whitening):
    """A record's weighted rows with the model seen within the fitted harmonics: ``(W R^-T Phi^T P Phi, W z)``.

    The filtered regression fits the restoring force ``Q - q''_fit``, whose acceleration
    holds only the fitted harmonics, with term columns ``Phi`` evaluated on the fitted
    motion; a term such as ``sign(q')`` has harmonics beyond the fitted ones (a square
    wave: 35 % of its energy above the fundamental lies beyond the 5th harmonic), which
    the data cannot show.  Its expected normal equations are ``Phi^T P Phi theta =
    Phi^T y`` with ``P = B G^-1 B^T`` the projection onto the fitted harmonics
    (``Phi^T B`` and ``G = B^T B`` are the record's noise-model sums); in the record's
    reduced space the rows ``R`` become ``R^-T Phi^T P Phi`` and ``z`` stays.  For terms
    whose columns lie within the fitted harmonics (polynomials of a harmonic motion up to
    its band) the rows are ``R`` again.
    """
    sc = fit.scores
    M = sc.phi_b @ scaled_inverse(sc.basis_gram) @ sc.phi_b.T
    D = linalg.solve_triangular(whitening.R, 0.5 * (M + M.T), trans="T", check_finite=False)
    return whitening.W @ D, whitening.W @ whitening.z


#: A term column with more than this fraction of its energy beyond the fitted harmonics is
#: compared with the records within the fitted harmonics (``sign(q')``: 0.067 with 5 harmonics;
#: ``|q|q``, ``|q'|q'``: about 1e-4; polynomials of the fitted motion: below 1e-6).
OUT_OF_BAND_LIMIT = 1e-3


def use_in_band(fits, in_band="auto") -> bool:
    """Whether records are compared with a model within the fitted harmonics.

    ``"auto"``: when every record fits the filtered restoring force and some term has more
    than ``OUT_OF_BAND_LIMIT`` of its energy beyond the fitted harmonics (for the others the
    in-band rows are the ordinary ones).
    """
    if in_band != "auto":
        return bool(in_band)
    if not fits or not all(f.scores is not None and f.scores.filtered for f in fits):
        return False
    return bool(np.max([out_of_band_fraction(f) for f in fits]) > OUT_OF_BAND_LIMIT)


def out_of_band_fraction(fit) -> np.ndarray:
    """Fraction of each term column's energy beyond the fitted harmonics (``1 - Phi_j^T P Phi_j / Phi_j^T Phi_j``)."""
    sc = fit.scores
    inside = np.einsum("jm,mn,jn->j", sc.phi_b, scaled_inverse(sc.basis_gram), sc.phi_b)
    g = np.diag(sc.gram)
    return np.where(g > 0, 1.0 - inside / np.where(g > 0, g, 1.0), 0.0)


def score_covariance(whitening, V, rows=None) -> np.ndarray:
    """Covariance of the weighted score ``D^T W eps`` of a record (``D``: its weighted rows; default ``W R``)."""
    if rows is None:
        return whitening.score_covariance(V)
    A = linalg.solve_triangular(whitening.R, V, trans="T", check_finite=False)
    S = whitening.W @ linalg.solve_triangular(whitening.R, A.T, trans="T", check_finite=False).T @ whitening.W.T
    out = rows.T @ S @ rows
    return 0.5 * (out + out.T)


def _law_text(coefficient, order) -> str:
    return f"{coefficient} power law" if is_power(order) else f"{coefficient} order {order}"


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
    in_band : bool
        Fitted within the fitted harmonics (:func:`in_band_rows`).
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
    in_band: bool = False

    @property
    def n_records(self) -> int:
        return int(len(self.q_max))

    def get(self, name) -> float:
        return float(self.parameters[self.parameter_names.index(name)])

    def get_stderr(self, name) -> float:
        return float(self.stderr[self.parameter_names.index(name)])

    def _law_slice(self, coefficient):
        k = self.coefficient_names.index(coefficient)
        start = sum(law_size(L) for L in self.law_orders[:k])
        return slice(start, start + law_size(self.law_orders[k]))

    def law(self, coefficient="c"):
        """``(coefficients, stderr, covariance)`` of ``coefficient(q_max)``, lowest power first
        (for a power law ``c0, c1, p`` of ``c0 + c1 q_max^p``)."""
        s = self._law_slice(coefficient)
        return self.parameters[s].copy(), self.stderr[s].copy(), self.covariance[s, s].copy()

    def law_kind(self, coefficient="c") -> str:
        """``"power"`` or ``"polynomial"`` (also for a constant coefficient)."""
        return POWER if is_power(self.law_orders[self.coefficient_names.index(coefficient)]) else "polynomial"

    def coefficients_at(self, q_max) -> np.ndarray:
        """Term coefficients of a steady state of amplitude ``q_max``."""
        return expand(self.law_orders, float(q_max), self.parameters)[0]

    def coefficient_at(self, coefficient, q_max):
        """``(value, stderr)`` of one term coefficient at the amplitudes ``q_max``."""
        s = self._law_slice(coefficient)
        q = np.atleast_1d(np.asarray(q_max, float))
        if self.law_kind(coefficient) == POWER:
            law = PowerLaw(*self.parameters[s])
            V = np.array([law.jacobian(x) for x in q])
            val = law.value(q)
        else:
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
            "amplitude_laws": {c: (POWER if is_power(L) else int(L))
                               for c, L in zip(self.coefficient_names, self.law_orders) if law_size(L) > 1},
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
            "in_band": bool(self.in_band),
        }

    def report(self) -> str:
        laws = {c: L for c, L in zip(self.coefficient_names, self.law_orders) if law_size(L) > 1}
        head = f"preload {self.preload}: " if self.preload is not None else ""
        lines = [
            f"{head}one model over {self.n_records} records (q_max {np.min(self.q_max):.4g} .. "
            f"{np.max(self.q_max):.4g}; condition number {self.condition_number:.3g}"
            + (f"; laws in q_max: {', '.join(_law_text(c, L) for c, L in laws.items())})" if laws else ")")
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
        from .. import plotting

        return plotting.draw("notebook.result_html", self)

    def plot(self, ax=None, coefficient="c"):
        """``coefficient(q_max)`` of the model with its 95 % band over the measured amplitudes."""
        from .. import plotting

        ax = plotting.draw("identify_plots.new_axes", ax)
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
    in_band : bool or "auto"
        Compare the model with the records within the fitted harmonics (:func:`in_band_rows`;
        filtered records only): removes the bias of terms with harmonics beyond the fitted
        ones (``sign(q')``); the same rows for terms within the band.  ``"auto"``
        (:func:`use_in_band`): when a term has energy beyond the fitted harmonics.

    Attributes
    ----------
    result_ : PreloadModel
    coef_, stderr_, covariance_ : array
    """

    def __init__(self, terms="q + -q^3 + q'", amplitude_laws=None, damping_order=2, weighting="noise",
                 cond_limit=COND_LIMIT, filtered=True, preload=None, in_band="auto"):
        self.terms = terms
        self.amplitude_laws = amplitude_laws
        self.damping_order = damping_order
        self.weighting = weighting
        self.cond_limit = cond_limit
        self.filtered = filtered
        self.preload = preload
        self.in_band = in_band

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
        need = max(law_size(L) for L in orders)
        if len(sigs) < need:
            raise IdentificationError(
                f"{context}an amplitude law of {need} parameters needs at least {need} records, got {len(sigs)}"
            )
        fits = own_fits(lib, sigs, fits, self.filtered)
        p = len(lib)
        q_max = np.array([f.q_max for f in fits])
        n_total = int(sum(f.n_samples for f in fits))
        wh = record_whitenings(fits, self.weighting)
        in_band = use_in_band(fits, self.in_band)
        if in_band:
            if not all(f.scores.filtered for f in fits):
                raise IdentificationError(f"{context}in_band needs records fitted to the filtered restoring force")
            rows = [in_band_rows(f, w) for f, w in zip(fits, wh)]
        else:
            rows = [(w.rows[:, :p], w.rows[:, p]) for w in wh]
        theta, cond, A = fit_laws([r[0] for r in rows], [r[1] for r in rows], q_max, orders, n_total)
        weights = np.array([w.scalar for w in wh])
        M = A.T @ A
        V = np.zeros((P, P))
        for w, f, q, r in zip(wh, fits, q_max, rows):
            coef, E, slope = expand(orders, q, theta)
            V += E.T @ score_covariance(w, f.scores.covariance(coef, slope), r[0] if in_band else None) @ E
        cov = sandwich(M, V)
        se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
        warn = []
        if not np.isfinite(cond) or cond > self.cond_limit:
            warn.append(f"{context}preload model too ill-conditioned (condition number {cond:.3g} > "
                        f"{self.cond_limit:.3g}); its parameters are not resolved")
        lo, hi = EXPONENT_BOUNDS
        for n, v in zip(names, theta):
            if n.startswith("p(") and not lo * 1.001 < v < hi / 1.001:
                warn.append(f"{context}power-law exponent {n} = {v:.3g} at the bound of [{lo:g}, {hi:g}]: the "
                            f"power law does not describe these amplitudes")
        for w_ in warn:
            warnings.warn(w_, IllConditionedWarning, stacklevel=3)
        self.library_ = lib
        self.in_band_ = in_band
        self.coef_, self.stderr_, self.covariance_ = theta, se, cov
        self.result_ = PreloadModel(
            self.preload, lib.names, lib.coefficient_names, orders, names, theta, se, cov, q_max,
            np.array([s.frequency_hz for s in sigs]), weights, cond, n_total, tuple(warn), in_band,
        )
        return self
