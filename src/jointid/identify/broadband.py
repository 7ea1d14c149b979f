"""Force-state mapping of broadband records, with the inertia term when the force gain is unknown.

The equation of motion of the response coordinate is written with an explicit inertia
coefficient ``m``::

    m q'' + sum_j theta_j phi_j(q, q') = u

where ``u`` is the recorded excitation.  When ``u`` is a force in the units of a
mass-normalised modal model, ``m = 1`` and this is the seed's ``Q - q'' = h(q, q')``
(Eq 15); when ``u`` is a voltage (an electrodynamic shaker without force transducer, an
electronic circuit), ``m`` is the unknown inverse gain and is identified together with the
restoring-force terms.  Gain-free results follow from ratios::

    omega1 = sqrt(theta_q / m),   zeta = theta_c / (2 m omega1),   k3 / k = theta_k3 / theta_q,

and the seed's mass-normalised coefficients are ``theta_j / m`` (``k3 / m`` is the seed's
``k3``).  Their standard errors come from the coefficient covariance by the delta method.

How the equation is fitted
    Every regressor column (``q''`` and each term ``phi_j(q, q')``) and the force are
    band-limited with the *same* linear filter before the least squares, so that the
    equation holds exactly for the filtered quantities.  For an averaged period
    (:func:`~jointid.signal.broadband.periodic_states`) this is done in the frequency
    domain: the rows are the real and imaginary parts of the DFT lines in ``fit_band``
    (all of them, excited or not: for an odd multisine the even lines carry what
    identifies an even term such as ``q^2``).  For a random record
    (:func:`~jointid.signal.broadband.random_states`) the columns are band-filtered in time
    and only the valid samples are used.  Several records (realisations) can be fitted
    together; they share all coefficients.

The nonlinear terms are evaluated on the band-limited states, so the model is exact when
the response has no significant content outside ``band``: choose ``band`` to cover the
response, ``fit_band`` to cover the lines with a good signal-to-noise ratio.

Estimator in the scikit-learn style: parameters in ``__init__``, :meth:`fit` returns
``self``, learned values end in ``_``; the frozen result is ``result_``
(:class:`BroadbandFit`).
"""

from __future__ import annotations

import html
import warnings
from dataclasses import dataclass, field

import numpy as np

from .._blas import single_threaded
from ..errors import IdentificationError, IllConditionedWarning, RecordError
from ..signal.broadband import BroadbandStates
from .regression import LstsqResult, lstsq_from_reduced, qr_reduce
from .terms import TermLibrary, library

__all__ = [
    "BroadbandFit",
    "BroadbandForceStateMapping",
    "EquivalentLinearTrack",
    "equivalent_linear_track",
    "delta_method",
    "simulate_response",
]

#: Scaled condition number above which a fit warns.
COND_LIMIT = 1e8
#: Name of the inertia coefficient.
INERTIA = "m"
#: Name of the constant (static offset) coefficient.
OFFSET = "u0"


# ----------------------------------------------------------------------------- delta method
def delta_method(func, theta, cov, *, rel_step=1e-6):
    """Value and standard error of ``func(theta)`` by first-order error propagation.

    Parameters
    ----------
    func : callable
        ``func(theta) -> float``.
    theta : array
        Estimates.
    cov : array
        Their covariance matrix.
    rel_step : float
        Relative step of the central differences for the gradient.

    Returns
    -------
    (float, float)
        ``func(theta)`` and ``sqrt(g^T C g)`` with ``g`` the gradient.

    Examples
    --------
    >>> value, se = delta_method(lambda p: p[0] / p[1], np.array([2.0, 4.0]), np.diag([0.01, 0.04]))
    >>> round(value, 6), round(se, 6)   # sqrt((0.1/4)^2 + (2*0.2/16)^2)
    (0.5, 0.035355)
    """
    theta = np.asarray(theta, float)
    value = float(func(theta))
    g = np.zeros(theta.size)
    for i in range(theta.size):
        h = rel_step * max(abs(theta[i]), np.finfo(float).tiny ** 0.25)
        up, dn = theta.copy(), theta.copy()
        up[i] += h
        dn[i] -= h
        g[i] = (func(up) - func(dn)) / (2 * h)
    var = float(g @ np.asarray(cov, float) @ g)
    return value, float(np.sqrt(var)) if var >= 0 and np.isfinite(var) else float("nan")


# ----------------------------------------------------------------------------- simulation
def simulate_response(lib: TermLibrary, coefficients, m, u, fs, *, offset=0.0, oversample=8, q0=0.0, v0=0.0):
    """Simulate ``m q'' + sum theta_j phi_j(q, q') = u(t) - offset`` from sampled ``u``.

    Fixed-step fourth-order Runge-Kutta at ``oversample`` times the sampling rate; the
    input between samples is the band-limited (polyphase) interpolation of ``u``, which
    is what a sampled band-limited excitation is.

    Parameters
    ----------
    lib : TermLibrary
    coefficients : array
        ``theta_j`` in the library's order.
    m : float
        Inertia coefficient (> 0).
    u : array
        Input samples.
    fs : float
        Sampling rate [Hz].
    offset : float
        Static input offset subtracted from ``u``.
    oversample : int
        Even integer >= 2 (each RK4 step spans two interpolated samples).
    q0, v0 : float
        Initial state.

    Returns
    -------
    (q, v) : arrays
        Displacement and velocity at the sample times of ``u``.
    """
    from scipy.signal import resample_poly

    u = np.asarray(u, float)
    oversample = int(oversample)
    if oversample < 2 or oversample % 2:
        raise ValueError(f"oversample must be an even integer >= 2, got {oversample}")
    if not m > 0:
        raise IdentificationError(f"the inertia coefficient must be positive to simulate, got m = {m!r}")
    uu = resample_poly(u, oversample, 1) - offset
    uu = np.concatenate([uu, np.full(2, uu[-1])])
    hh = 2.0 / (fs * oversample)
    funcs = [(float(c), t.func) for t, c in zip(lib, coefficients) if c != 0.0]
    inv_m = 1.0 / float(m)

    def acc(q, v, f):
        r = f
        for c, fn in funcs:
            r -= c * fn(q, v)
        return r * inv_m

    q, v = float(q0), float(v0)
    n = u.size
    qs = np.empty(n)
    vs = np.empty(n)
    half = 0.5 * hh
    sixth = hh / 6.0
    for i in range(n):
        qs[i] = q
        vs[i] = v
        base = i * oversample
        for j in range(0, oversample, 2):
            f1 = uu[base + j]
            f2 = uu[base + j + 1]
            f3 = uu[base + j + 2]
            a1 = acc(q, v, f1)
            v2 = v + half * a1
            a2 = acc(q + half * v, v2, f2)
            v3 = v + half * a2
            a3 = acc(q + half * v2, v3, f2)
            v4 = v + hh * a3
            a4 = acc(q + hh * v3, v4, f3)
            q += sixth * (v + 2 * v2 + 2 * v3 + v4)
            v += sixth * (a1 + 2 * a2 + 2 * a3 + a4)
            if not (abs(q) < 1e300):
                raise IdentificationError(
                    f"the identified model diverges in simulation at sample {i} of {n} (unstable for this input)"
                )
    return qs, vs


# ----------------------------------------------------------------------------- result
def _find(names, *candidates):
    for c in candidates:
        if c in names:
            return names.index(c)
    return None


@dataclass(frozen=True)
class BroadbandFit:
    """Result of a broadband force-state mapping: ``m q'' + sum theta_j phi_j(q, q') (+ u0) = u``.

    Attributes
    ----------
    terms : tuple of str
        Restoring-force term names (library order).
    coefficient_names : tuple of str
        Names of all fitted coefficients: ``"m"`` first when the inertia was fitted, then
        the term coefficients, then ``"u0"`` when a static offset was fitted.
    coefficients, stderr : array
    covariance : array
        Covariance of the fitted coefficients (ordinary least-squares formula).
    mass : float
        The inertia coefficient: fitted (``fit_inertia``) or given.
    fit_inertia : bool
    condition_number : float
        Of the column-scaled regression.
    residual_rms : float
        RMS of the equation error over the rows (force units; frequency-domain rows of a
        periodic record are scaled to time-domain RMS).
    force_rms : float
        RMS of the band-limited force (same scaling), for a relative residual.
    n_rows : int
    n_records : int
    fit_band : tuple
    response_mean : float
        Mean of the measured response removed from the states (averaged over the records),
        added back by :meth:`simulate`.
    q_max : float
        Largest ``|q|`` of the fitted records.
    warnings : tuple of str
    """

    terms: tuple
    coefficient_names: tuple
    coefficients: np.ndarray
    stderr: np.ndarray
    covariance: np.ndarray = field(repr=False)
    mass: float
    fit_inertia: bool
    condition_number: float
    residual_rms: float
    force_rms: float
    n_rows: int
    n_records: int
    fit_band: tuple
    response_mean: float = 0.0
    q_max: float = float("nan")
    warnings: tuple = ()

    # -- access
    def get(self, name) -> float:
        """A fitted coefficient by coefficient or term name (``"m"``, ``"omega1^2"``, ``"q"``, ``"k3"``...)."""
        i = self._index(name)
        if i is None:
            raise KeyError(f"no coefficient {name!r}; fitted: {self.coefficient_names}")
        return float(self.coefficients[i])

    def get_stderr(self, name) -> float:
        i = self._index(name)
        if i is None:
            raise KeyError(f"no coefficient {name!r}; fitted: {self.coefficient_names}")
        return float(self.stderr[i])

    def _index(self, name):
        if name in self.coefficient_names:
            return self.coefficient_names.index(name)
        if name in self.terms:
            return self.coefficient_names.index(library(self.terms)[name].coefficient)
        return None

    @property
    def library(self) -> TermLibrary:
        return library(self.terms)

    @property
    def theta(self) -> np.ndarray:
        """Restoring-force coefficients ``theta_j`` in the library's order."""
        return np.array([self.get(c) for c in self.library.coefficient_names])

    @property
    def offset(self) -> float:
        """Fitted static input offset ``u0`` (0 when not fitted)."""
        return self.get(OFFSET) if OFFSET in self.coefficient_names else 0.0

    @property
    def gain(self) -> float:
        """``1 / m``: force per unit of the recorded excitation (for a mass-normalised coordinate)."""
        return 1.0 / self.mass

    # -- derived, gain-free quantities
    def _m(self, p):
        return p[self.coefficient_names.index(INERTIA)] if self.fit_inertia else self.mass

    def _derived_funcs(self):
        names = self.coefficient_names
        iq = _find(names, "omega1^2")
        ic = _find(names, "c")
        out = {}
        if iq is not None:
            out["omega1"] = lambda p: np.sqrt(p[iq] / self._m(p)) if p[iq] / self._m(p) > 0 else np.nan
            out["f1_hz"] = lambda p: out["omega1"](p) / (2 * np.pi)
            if ic is not None:
                out["zeta"] = lambda p: p[ic] / (2 * np.sqrt(p[iq] * self._m(p))) if p[iq] * self._m(p) > 0 else np.nan
        if ic is not None:
            out["c/m"] = lambda p: p[ic] / self._m(p)
        for t in self.library:
            j = names.index(t.coefficient)
            if t.coefficient in ("omega1^2",):
                continue
            out[f"{t.coefficient}/m"] = (lambda jj: lambda p: p[jj] / self._m(p))(j)
            if iq is not None and t.kind == "stiffness":
                out[f"{t.coefficient}/k"] = (lambda jj: lambda p: p[jj] / p[iq])(j)
        if self.fit_inertia:
            out["gain"] = lambda p: 1.0 / self._m(p)
        return out

    def derived(self) -> dict:
        """Gain-free quantities with delta-method standard errors: ``{name: (value, stderr)}``.

        ``omega1`` [rad/s], ``f1_hz``, ``zeta`` (damping ratio of the ``q'`` term),
        ``<coef>/m`` (the seed's mass-normalised coefficients, e.g. ``k3/m``),
        ``<coef>/k`` for stiffness terms (e.g. ``k3/k``) and ``gain`` (``1/m``).
        """
        return {k: delta_method(f, self.coefficients, self.covariance) for k, f in self._derived_funcs().items()}

    def value(self, name) -> float:
        """A derived quantity (see :meth:`derived`) without its standard error."""
        funcs = self._derived_funcs()
        if name not in funcs:
            raise KeyError(f"no derived quantity {name!r}; available: {sorted(funcs)}")
        return float(funcs[name](self.coefficients))

    @property
    def omega1(self) -> float:
        return self.value("omega1") if "omega1" in self._derived_funcs() else float("nan")

    @property
    def f1_hz(self) -> float:
        return self.omega1 / (2 * np.pi)

    @property
    def zeta(self) -> float:
        return self.value("zeta") if "zeta" in self._derived_funcs() else float("nan")

    @property
    def k3_over_k(self) -> float:
        return self.value("k3/k") if "k3/k" in self._derived_funcs() else float("nan")

    @property
    def k3_over_m(self) -> float:
        return self.value("k3/m") if "k3/m" in self._derived_funcs() else float("nan")

    # -- model use
    def restoring_force(self, q, v) -> np.ndarray:
        """``sum theta_j phi_j(q, v)`` (recorded-excitation units)."""
        return self.library.restoring_force(q, v, self.theta)

    def simulate(self, u, fs, *, oversample=8, q0=0.0, v0=0.0, add_mean=True) -> np.ndarray:
        """Simulated response to the input samples ``u`` (see :func:`simulate_response`).

        The fitted offset ``u0`` is subtracted from ``u`` and, with ``add_mean``, the mean of
        the measured response of the fit is added back, so the output is comparable with
        the raw measured response.
        """
        q, _ = simulate_response(self.library, self.theta, self.mass, u, fs, offset=self.offset,
                                 oversample=oversample, q0=q0, v0=v0)
        return q + (self.response_mean if add_mean else 0.0)

    # -- reporting
    def equation(self) -> str:
        lhs = "u" + (" - u0" if OFFSET in self.coefficient_names else "")
        head = f"{lhs} = m·[q''] + " + " + ".join(f"{t.coefficient}·[{t.name}]" for t in self.library)
        lines = [head]
        for n, c, s in zip(self.coefficient_names, self.coefficients, self.stderr):
            err = f" ± {s:.2g}" if np.isfinite(s) else ""
            lines.append(f"  {n} = {c:.8g}{err}")
        if not self.fit_inertia:
            lines.append(f"  m = {self.mass:.8g} (given)")
        return "\n".join(lines)

    def summary(self) -> dict:
        d = self.derived()
        return {
            "terms": list(self.terms),
            "coefficients": {n: float(v) for n, v in zip(self.coefficient_names, self.coefficients)},
            "stderr": {n: float(v) for n, v in zip(self.coefficient_names, self.stderr)},
            "derived": {k: float(v[0]) for k, v in d.items()},
            "derived_stderr": {k: float(v[1]) for k, v in d.items()},
            "mass": float(self.mass),
            "fit_inertia": bool(self.fit_inertia),
            "condition_number": float(self.condition_number),
            "residual_rms": float(self.residual_rms),
            "relative_residual": float(self.residual_rms / self.force_rms) if self.force_rms > 0 else None,
            "n_rows": int(self.n_rows),
            "n_records": int(self.n_records),
            "fit_band_hz": [float(x) for x in self.fit_band],
            "response_mean": float(self.response_mean),
            "q_max": float(self.q_max),
            "warnings": list(self.warnings),
        }

    def report(self) -> str:
        lines = [
            f"broadband force-state mapping: {self.n_records} record(s), {self.n_rows} rows, band "
            f"{self.fit_band[0]:.4g}-{self.fit_band[1]:.4g} Hz, condition number {self.condition_number:.3g}, "
            f"relative residual {self.residual_rms / self.force_rms if self.force_rms > 0 else float('nan'):.3g}",
            self.equation(),
        ]
        for k, (v, s) in self.derived().items():
            lines.append(f"  {k:>12} = {v:.6g} ± {s:.2g}")
        lines += [f"  warning: {w}" for w in self.warnings]
        return "\n".join(lines)

    def _repr_html_(self):
        return "<pre>" + html.escape(self.report()) + "</pre>"

    def plot(self, ax=None, q=None):
        """Restoring force against displacement at zero velocity (stiffness curve)."""
        from .. import plotting

        return plotting.draw("data_plots.plot_broadband_fit", self, ax=ax, q=q)


# ----------------------------------------------------------------------------- estimator
def _columns(lib, states: BroadbandStates, fit_inertia):
    """Regressor columns (time domain) ``[q''?, phi_1, ..., phi_p]`` of one record."""
    cols = [states.acceleration] if fit_inertia else []
    return np.column_stack(cols + [lib.evaluate(states.displacement, states.velocity)])


def _periodic_rows(states: BroadbandStates, X, y, lines, offset):
    """Real rows (Re and Im of the DFT lines) of a periodic record; scaled to time-domain RMS."""
    n = states.n_samples
    Xf = np.fft.rfft(X, axis=0)
    yf = np.fft.rfft(y)
    Xl, yl = Xf[lines], yf[lines]
    # Parseval: a line k (0 < k < n/2) carries 2|X_k|^2 / n^2 of the mean square
    s = np.sqrt(2.0) / n
    A = np.vstack([Xl.real, Xl.imag]) * s
    b = np.concatenate([yl.real, yl.imag]) * s
    if offset:
        A = np.column_stack([A, np.zeros(A.shape[0])])
        dc = np.concatenate([Xf[0].real / n, [1.0]])
        A = np.vstack([A, dc])
        b = np.concatenate([b, [yf[0].real / n]])
    return A, b


class BroadbandForceStateMapping:
    """Force-state mapping of broadband records, optionally with the inertia term.

    Parameters
    ----------
    terms : str or TermLibrary
        Restoring-force terms, ``"q + -q^3 + q'"`` by default.
    fit_inertia : bool
        Fit the inertia coefficient ``m`` (unknown force gain).  When False, ``mass`` is
        used and ``u - mass q''`` is the regressed restoring force (seed Eq 15).
    mass : float
        The known inertia coefficient when ``fit_inertia`` is False.
    offset : bool
        Fit a static input offset ``u0`` (the DC line of a periodic record).  Needed to
        simulate a model with even terms (``q^2``) from a raw input with a DC level.  For
        random records the band-limited force has no DC and ``u0`` comes out near zero.
    weighting : {"none", "noise"}
        ``"noise"`` weights every line of a periodic record by the inverse standard
        deviation of its equation error, ``sqrt(var_u + |Z|^2 var_y')`` with ``Z`` the
        linear dynamic stiffness of a first unweighted fit, using the noise variances
        estimated from the spread between periods (ignored for random records).
    cond_limit : float
        Scaled condition number above which the fit warns.

    Attributes
    ----------
    result_ : BroadbandFit
    coef_, stderr_ : array
    covariance_ : array
    condition_number_ : float

    Examples
    --------
    >>> from jointid.signal.broadband import periodic_states
    >>> fs, n = 200.0, 400
    >>> t = np.arange(n) / fs
    >>> w = 2 * np.pi * np.arange(1, 20) * fs / n
    >>> q = sum(np.cos(wk * t + k) / (1 + k) for k, wk in enumerate(w)) * 1e-2
    >>> v = sum(-wk * np.sin(wk * t + k) / (1 + k) for k, wk in enumerate(w)) * 1e-2
    >>> a = sum(-wk**2 * np.cos(wk * t + k) / (1 + k) for k, wk in enumerate(w)) * 1e-2
    >>> u = 2.5 * (a + 900.0 * q + 1.2 * v)            # gain 0.4: m = 2.5
    >>> est = BroadbandForceStateMapping("q + q'").fit(periodic_states(u, q, fs, band=(0.5, 10)))
    >>> round(est.result_.mass, 6), round(est.result_.omega1, 6)
    (2.5, 30.0)
    """

    def __init__(self, terms="q + -q^3 + q'", fit_inertia=True, mass=1.0, offset=False, weighting="none",
                 cond_limit=COND_LIMIT):
        self.terms = terms
        self.fit_inertia = fit_inertia
        self.mass = mass
        self.offset = offset
        self.weighting = weighting
        self.cond_limit = cond_limit

    def _rows(self, lib, states, weights=None):
        X = _columns(lib, states, self.fit_inertia)
        y = np.asarray(states.force, float)
        if not self.fit_inertia:
            y = y - float(self.mass) * states.acceleration
        if states.periodic:
            lines = states.fit_lines()
            if lines.size == 0:
                raise RecordError(
                    f"channel {states.channels[1]!r}: no DFT line of the record lies in fit_band {states.fit_band} Hz"
                )
            A, b = _periodic_rows(states, X, y, lines, self.offset)
            if weights is not None:
                w = np.concatenate([weights, weights, [1.0]] if self.offset else [weights, weights])
                A, b = A * w[:, None], b * w
            return A, b
        if self.offset:
            X = np.column_stack([X, np.ones(states.n_samples)])
        Xf = states.filter(X, axis=0)
        if self.offset:
            Xf[:, -1] = 1.0  # the constant is not band-limited; band-limited data have zero mean
        yf = states.filter(y)
        sl = states.valid
        return Xf[sl], yf[sl]

    def _noise_weights(self, lib, states, theta):
        """Inverse standard deviation of the equation error at each fit line (periodic records)."""
        if not states.periodic or states.force_noise_var is None or states.response_noise_var is None:
            return None
        lines = states.fit_lines()
        f = states.frequencies[lines]
        jw = 2j * np.pi * f
        names = (["m"] if self.fit_inertia else []) + list(lib.coefficient_names)
        p = dict(zip(names, theta))
        m = p.get("m", float(self.mass))
        Z = -m * (2 * np.pi * f) ** 2 + p.get("omega1^2", 0.0) + jw * p.get("c", 0.0)
        # the measured response spectrum relates to q by (i omega)^k
        k = {"displacement": 0, "velocity": 1, "acceleration": 2}[states.measured]
        var_q = states.response_noise_var[lines] / np.abs(jw) ** (2 * k)
        var = states.force_noise_var[lines] + np.abs(Z) ** 2 * var_q
        var = np.where(np.isfinite(var) & (var > 0), var, np.nan)
        if np.all(np.isnan(var)):
            return None
        var = np.where(np.isnan(var), np.nanmax(var), var)
        w = 1.0 / np.sqrt(var)
        return w / np.median(w)

    @single_threaded
    def fit(self, states, *, context=""):
        """Fit one record or a sequence of records (shared coefficients).

        Parameters
        ----------
        states : BroadbandStates or sequence of BroadbandStates
        context : str
            Prefix of warning messages (e.g. the record name).
        """
        recs = [states] if isinstance(states, BroadbandStates) else list(states)
        if not recs:
            raise IdentificationError("broadband force-state mapping needs at least one record")
        for s in recs:
            if not isinstance(s, BroadbandStates):
                raise IdentificationError(f"expected BroadbandStates records, got {type(s).__name__}")
        if self.weighting not in ("none", "noise"):
            raise IdentificationError(f"weighting must be 'none' or 'noise', got {self.weighting!r}")
        if not self.fit_inertia and not (np.isfinite(self.mass) and self.mass > 0):
            raise IdentificationError(f"mass must be a positive number when fit_inertia=False, got {self.mass!r}")
        lib = library(self.terms)
        res, rows = self._solve(lib, recs)
        if self.weighting == "noise":
            ws = [self._noise_weights(lib, s, res.coefficients) for s in recs]
            if any(w is not None for w in ws):
                res, rows = self._solve(lib, recs, ws)
        names = ((INERTIA,) if self.fit_inertia else ()) + lib.coefficient_names + ((OFFSET,) if self.offset else ())
        warn = []
        if not np.isfinite(res.condition_number) or res.condition_number > self.cond_limit:
            warn.append(f"{context}regression too ill-conditioned (condition number {res.condition_number:.3g} > "
                        f"{self.cond_limit:.3g}); coefficients are not resolved")
        mass = float(res.coefficients[0]) if self.fit_inertia else float(self.mass)
        if self.fit_inertia and not mass > 0:
            warn.append(f"{context}the fitted inertia coefficient is not positive (m = {mass:.4g}); the force gain "
                        f"and the derived frequencies are meaningless")
        for w in warn:
            warnings.warn(w, IllConditionedWarning, stacklevel=3)
        A_all, b_all = rows
        force_rms = float(np.sqrt(np.mean(b_all**2))) if b_all.size else float("nan")
        self.library_ = lib
        self.lstsq_ = res
        self.coef_ = res.coefficients
        self.stderr_ = res.stderr
        self.covariance_ = res.covariance
        self.condition_number_ = res.condition_number
        self.result_ = BroadbandFit(
            lib.names, names, res.coefficients, res.stderr, res.covariance, mass, bool(self.fit_inertia),
            res.condition_number, float(np.sqrt(res.rss / max(res.n_samples, 1))), force_rms, res.n_samples,
            len(recs), tuple(float(x) for x in recs[0].fit_band), float(np.mean([s.response_mean for s in recs])),
            float(max(s.q_max() for s in recs)), tuple(warn),
        )
        return self

    def _solve(self, lib, recs, weights=None) -> tuple[LstsqResult, tuple]:
        blocks, As, bs = [], [], []
        n = 0
        for i, s in enumerate(recs):
            A, b = self._rows(lib, s, None if weights is None else weights[i])
            if not np.all(np.isfinite(A)) or not np.all(np.isfinite(b)):
                raise RecordError(f"channel {s.channels[1]!r}: non-finite regressors (check the states and the terms)")
            blocks.append(qr_reduce(A, b))
            As.append(A)
            bs.append(b)
            n += A.shape[0]
        R = np.vstack(blocks)
        p = R.shape[1] - 1
        res = lstsq_from_reduced(R[:, :p], R[:, p], n)
        return res, (np.vstack(As), np.concatenate(bs))


# ----------------------------------------------------------------------------- sliding fits
@dataclass(frozen=True)
class EquivalentLinearTrack:
    """Equivalent linear stiffness and damping fitted in sliding windows along a record.

    In each window ``f ≈ k_eq q + c_eq q' + f0``.  For a nonlinear joint, ``k_eq`` against
    the window's displacement amplitude shows softening (decreasing) or hardening.

    Attributes
    ----------
    t : array
        Window centres [s].
    amplitude : array
        Largest ``|q|`` in each window.
    frequency_hz : array
        Dominant frequency of ``q`` in each window (zero crossings).
    k, c : array
        Equivalent stiffness and damping (force units per q, per q').
    r2 : array
        Fraction of the window's force variance explained.
    window_s : float
    """

    t: np.ndarray
    amplitude: np.ndarray
    frequency_hz: np.ndarray
    k: np.ndarray
    c: np.ndarray
    r2: np.ndarray
    window_s: float

    def select(self, mask) -> "EquivalentLinearTrack":
        m = np.asarray(mask, bool)
        return EquivalentLinearTrack(self.t[m], self.amplitude[m], self.frequency_hz[m], self.k[m], self.c[m],
                                     self.r2[m], self.window_s)

    def spearman_k_amplitude(self) -> float:
        """Rank correlation of ``k_eq`` with amplitude (negative: softening)."""
        from scipy.stats import spearmanr

        if self.k.size < 3:
            return float("nan")
        return float(spearmanr(self.amplitude, self.k).statistic)

    def summary(self) -> dict:
        return {
            "n_windows": int(self.t.size),
            "window_s": self.window_s,
            "amplitude_range": [float(np.min(self.amplitude)), float(np.max(self.amplitude))] if self.t.size else [],
            "k_range": [float(np.min(self.k)), float(np.max(self.k))] if self.t.size else [],
            "spearman_k_amplitude": self.spearman_k_amplitude(),
        }

    def report(self) -> str:
        s = self.summary()
        return (f"equivalent linear track: {s['n_windows']} windows of {self.window_s:g} s, amplitude "
                f"{s['amplitude_range']}, k_eq {s['k_range']}, rank correlation(k_eq, amplitude) "
                f"{s['spearman_k_amplitude']:.3f}")

    def _repr_html_(self):
        return "<pre>" + html.escape(self.report()) + "</pre>"


def equivalent_linear_track(q, v, force, fs, *, window_s, step_s=None, valid=slice(None)) -> EquivalentLinearTrack:
    """Sliding-window least squares ``force ≈ k q + c q' + f0`` (see :class:`EquivalentLinearTrack`).

    Parameters
    ----------
    q, v, force : array
        Displacement, velocity and restoring force (equal lengths).
    fs : float
        Sampling rate [Hz].
    window_s : float
        Window length [s] (a few periods of the motion).
    step_s : float, optional
        Step between windows (default half a window).
    valid : slice
        Samples to use.
    """
    q = np.asarray(q, float)[valid]
    v = np.asarray(v, float)[valid]
    f = np.asarray(force, float)[valid]
    if not (q.size == v.size == f.size):
        raise RecordError("q, v and force must have the same length")
    nw = int(round(window_s * fs))
    step = int(round((window_s / 2 if step_s is None else step_s) * fs))
    if nw < 8 or step < 1 or nw > q.size:
        raise RecordError(f"window of {window_s} s ({nw} samples) does not fit a record of {q.size} samples")
    off = (valid.start or 0) if isinstance(valid, slice) else 0
    rows = []
    for s in range(0, q.size - nw + 1, step):
        sl = slice(s, s + nw)
        X = np.column_stack([q[sl], v[sl], np.ones(nw)])
        th, *_ = np.linalg.lstsq(X, f[sl], rcond=None)
        r = f[sl] - X @ th
        var = np.var(f[sl])
        zc = np.count_nonzero(np.diff(np.signbit(q[sl] - q[sl].mean())))
        rows.append(((off + s + nw / 2) / fs, np.max(np.abs(q[sl])), zc / 2 / (nw / fs), th[0], th[1],
                     1 - np.var(r) / var if var > 0 else np.nan))
    a = np.array(rows)
    return EquivalentLinearTrack(a[:, 0], a[:, 1], a[:, 2], a[:, 3], a[:, 4], a[:, 5], float(window_s))
