"""Model-adequacy diagnostics: does the identified model hold for a preload's data?

Three checks, each with the calibrated covariances of :mod:`jointid.identify.uncertainty`:

* **equality across force levels** of the parameters a group fit shares (``omega1^2``,
  ``k3`` ...; those without an amplitude law in the preload model): with ``theta_g`` and ``C_g`` the pooled fit of force level ``g`` (independent
  records), ``chi^2 = sum_g (theta_g - theta_bar)^T C_g^-1 (theta_g - theta_bar)`` with
  ``theta_bar`` the covariance-weighted mean, on ``(G - 1) k`` degrees of freedom, jointly and
  per parameter.  A model that holds gives the same parameters at every level; a friction
  joint fitted as a cubic spring gives a ``k3`` that falls with the level;
* **per-record residual against the preload model**: each record's weighted misfit
  ``|W_r (z_r - R_r theta_r)|^2 / p`` in its reduced space (about 1 when the model explains
  the record to the noise, with a calibrated p-value; a median above ``MISFIT_LIMIT`` says
  the model misses a part of the restoring force); a record beyond the noise
  (``p < P_LIMIT / n_records``) and far above the median of a level the model explains to
  the noise (median misfit at most 3) is an outlier, and a trend of the records' own
  ``omega1`` with the acquisition order (beside ``q_max``) is a drift;
* **explained fractions**: of the restoring force ``Q - q''`` (energy), and of its
  harmonics above the first (where the nonlinear terms show): ``explained_harmonics`` is
  ``1 - residual / measured`` energy there, a coefficient of determination that is negative
  when the model's harmonics are further from the measured ones than none at all (a cubic
  spring's third harmonic against a friction joint's); reports show ``residual / measured``.

A term with energy beyond the fitted harmonics (``sign(q')``) is compared with the records
within the fitted harmonics (:func:`~jointid.identify.model.in_band_rows`): the filtered
restoring force holds nothing beyond them, so a fit over all harmonics biases such a term and
would call the model that made the data inadequate.  A model with a law on the stiffness is
compared across levels through the preload model fitted to each level with its laws.
"""

from __future__ import annotations

import html
from dataclasses import dataclass, field, replace

import numpy as np
from scipy import linalg, stats

from ..conventions import harmonic_index
from ..errors import IdentificationError
from .fsm import record_whitenings, split_terms
from .model import OUT_OF_BAND_LIMIT, in_band_rows, out_of_band_fraction, score_covariance
from .powerlaw import is_power
from .terms import library
from .uncertainty import sandwich, scaled_inverse

__all__ = ["ParameterEquality", "RecordAdequacy", "AdequacyResult", "level_equality", "record_adequacy",
           "assess_preload", "assess_hysteretic", "check_adequacy", "P_LIMIT"]

#: p-value below which a check says the model does not hold.
P_LIMIT = 1e-3
#: A record whose misfit is this many times its level's median (and beyond the noise) is an outlier.
OUTLIER_FACTOR = 5.0
#: Outliers are only sought in a level whose median misfit is at most this (explained to the noise).
OUTLIER_MEDIAN_LIMIT = 3.0
#: A median record misfit above this (the noise gives about 1) says terms are missing.
MISFIT_LIMIT = 10.0
#: Relative resolution of a parameter's value (about the square root of the float64 epsilon): the
#: equality test across levels does not call smaller relative differences a change.
NUMERICAL_RESOLUTION = 1e-8
#: |t| of the order trend of the own omega1 above which a group drifts.
DRIFT_T = 5.0


def _p_text(p) -> str:
    if not np.isfinite(p):
        return "p unknown"
    return "p < 1e-6" if p < 1e-6 else f"p = {p:.2g}"


def model_name(terms, power_laws=False, stiffness_law=None) -> str:
    """A family name for a term set (``"cubic"`` for ``q, -q^3, q'``), else the terms themselves.

    ``power_laws``: the model has micro-slip power laws (the micro-slip families of the same terms).
    ``stiffness_law``: whether the model has an amplitude law on its stiffness (``q + q'`` with one is
    the amplitude-dependent stiffness, not the linear model); ``None`` does not tell them apart.
    """
    from .selection import DEFAULT_CANDIDATES
    from .terms import library

    names = set(library(list(terms)).names)
    for c in DEFAULT_CANDIDATES:
        if c.hysteretic is None and set(c.library.names) == names and bool(c.n_exponents) == bool(power_laws) \
                and (stiffness_law is None or bool(c.laws.get("q", 0)) == bool(stiffness_law)):
            return c.name
    return " + ".join(terms) + ("; power laws" if power_laws else "")


@dataclass(frozen=True)
class ParameterEquality:
    """Test that one shared parameter is the same at every force level."""

    name: str
    levels: tuple
    values: np.ndarray
    stderr: np.ndarray
    common: float
    ratio: float
    chi2: float
    dof: int
    p_value: float

    @property
    def differs(self) -> bool:
        return bool(self.p_value < P_LIMIT)

    def describe(self) -> str:
        v = self.values
        if (np.all(v > 0) or np.all(v < 0)) and self.ratio < 1.5:
            change = f"changes by {100 * (self.ratio - 1):.2g} % across levels"
        elif np.all(v > 0) or np.all(v < 0):
            change = f"changes {self.ratio:.3g}x across levels"
        else:
            change = "changes sign across levels"
        return f"{self.name} {change} ({_p_text(self.p_value)})"

    def summary(self) -> dict:
        return {"name": self.name, "levels": list(self.levels), "values": [float(x) for x in self.values],
                "stderr": [float(x) for x in self.stderr], "common": float(self.common),
                "ratio": float(self.ratio) if np.isfinite(self.ratio) else None, "chi2": float(self.chi2),
                "dof": int(self.dof), "p_value": float(self.p_value), "differs": self.differs}


@dataclass(frozen=True)
class RecordAdequacy:
    """One record against its preload model."""

    record: object
    level: object
    q_max: float
    misfit: float
    explained_force: float
    explained_harmonics: float
    harmonic_share: float
    outlier: bool = False
    outlier_ratio: float = float("nan")
    p_value: float = float("nan")
    energies: tuple = field(default=(np.nan,) * 5, repr=False)  # force, its residual, harmonics above
    # the first, their residual, and the residual the noise alone leaves there (sums of squares over the record)

    def summary(self) -> dict:
        def num(x):
            return float(x) if np.isfinite(x) else None

        return {"record": self.record, "level": self.level, "q_max": num(self.q_max), "misfit": num(self.misfit),
                "explained_force": num(self.explained_force), "explained_harmonics": num(self.explained_harmonics),
                "harmonic_share": num(self.harmonic_share), "outlier": bool(self.outlier),
                "outlier_ratio": num(self.outlier_ratio), "p_value": num(self.p_value)}


@dataclass(frozen=True)
class AdequacyResult:
    """Adequacy of one preload's model.

    Attributes
    ----------
    preload : object
    terms : tuple of str
    model_name : str
    equality : tuple of ParameterEquality
        Per shared parameter, across force levels.
    joint_chi2, joint_dof, joint_p : float, int, float
        Joint equality test of all shared parameters.
    records : tuple of RecordAdequacy
    drift : dict
        Force level -> ``{"t": ..., "slope_per_record": ..., "drifts": bool}`` of the own ``omega1``.
    adequate : bool or None
        No check says the model does not hold (``None``: no check could be made).
    messages : tuple of str
    """

    preload: object
    terms: tuple
    model_name: str
    equality: tuple
    joint_chi2: float
    joint_dof: int
    joint_p: float
    records: tuple = ()
    drift: dict = field(default_factory=dict)
    adequate: bool = True
    messages: tuple = ()
    #: With a hysteretic pick: the adequacy of its polynomial stand-in (an AdequacyResult), kept
    #: apart; it is never the selected model's verdict.
    stand_in: object = field(default=None, repr=False)

    @property
    def verdict(self) -> str:
        """One line: the model holds, or the first reason it does not."""
        if self.adequate is None:
            return self.messages[0] if self.messages else "not assessed"
        if self.adequate:
            return f"the {self.model_name} model holds" + (f" ({self.messages[0]})" if self.messages else "")
        return self.messages[0] if self.messages else f"the {self.model_name} model does not hold"

    @property
    def outliers(self) -> tuple:
        return tuple(r.record for r in self.records if r.outlier)

    def _fractions(self, attr):
        """Energy-weighted fraction over all records and the lowest record's."""
        v = np.array([getattr(r, attr) for r in self.records], float)
        e = np.array([r.energies for r in self.records], float).reshape(-1, 5)
        j = 0 if attr == "explained_force" else 2
        ok = np.isfinite(e[:, j]) & np.isfinite(e[:, j + 1])
        tot = 1.0 - float(np.sum(e[ok, j + 1]) / np.sum(e[ok, j])) if ok.any() and np.sum(e[ok, j]) > 0 else np.nan
        v = v[np.isfinite(v)]
        return (tot, float(np.min(v))) if v.size else (float("nan"), float("nan"))

    @property
    def harmonic_residual_to_noise(self) -> float:
        """Residual of the harmonics above the first over what the noise alone leaves there (about 1
        when the model explains them to the noise, much more when it misses or invents them)."""
        e = np.array([r.energies for r in self.records], float).reshape(-1, 5)
        ok = np.isfinite(e[:, 3]) & np.isfinite(e[:, 4])
        return float(np.sum(e[ok, 3]) / np.sum(e[ok, 4])) if ok.any() and np.sum(e[ok, 4]) > 0 else float("nan")

    def summary(self) -> dict:
        def num(x):
            return float(x) if np.isfinite(x) else None

        ef, efmin = self._fractions("explained_force")
        eh, ehmin = self._fractions("explained_harmonics")
        mis = np.array([r.misfit for r in self.records], float)
        return {
            "preload": self.preload,
            "terms": list(self.terms),
            "model": self.model_name,
            "adequate": None if self.adequate is None else bool(self.adequate),
            "verdict": self.verdict,
            "messages": list(self.messages),
            "level_equality": {"chi2": num(self.joint_chi2), "dof": int(self.joint_dof), "p_value": num(self.joint_p),
                               "parameters": [e.summary() for e in self.equality]},
            "misfit_median": num(float(np.median(mis[np.isfinite(mis)]))) if np.any(np.isfinite(mis)) else None,
            "outliers": list(self.outliers),
            "drift": {str(k): v for k, v in self.drift.items()},
            "explained_force": num(ef),
            "explained_force_min": num(efmin),
            "explained_harmonics": num(eh),
            "explained_harmonics_min": num(ehmin),
            "harmonic_residual_to_noise": num(self.harmonic_residual_to_noise),
            "records": [r.summary() for r in self.records],
            **({} if self.stand_in is None else {"stand_in_adequacy": self.stand_in.summary()}),
        }

    def report(self) -> str:
        head = f"preload {self.preload}: " if self.preload is not None else ""
        verdict = "not assessed" if self.adequate is None else "holds" if self.adequate else "does NOT hold"
        lines = [f"{head}adequacy of the {self.model_name} model ({' + '.join(self.terms)}): {verdict}"]
        if self.joint_dof:
            lines.append(f"  equality across force levels: chi2 = {self.joint_chi2:.4g} on {self.joint_dof} dof "
                         f"({_p_text(self.joint_p)})")
        for e in self.equality:
            vals = ", ".join(f"{v:.4g} ± {s:.2g}" for v, s in zip(e.values, e.stderr))
            lines.append(f"    {e.describe()}: {vals}")
        if self.records:
            ef, efmin = self._fractions("explained_force")
            eh, ehmin = self._fractions("explained_harmonics")
            m = np.array([r.misfit for r in self.records], float)
            mis = float(np.median(m[np.isfinite(m)])) if np.any(np.isfinite(m)) else float("nan")
            lines.append(f"  records: misfit median {mis:.3g} (1 = explained to the noise); restoring force explained "
                         f"{100 * ef:.6g} % (lowest record {100 * efmin:.6g} %); harmonics above the first: residual / "
                         f"measured energy {1 - eh:.3g} over all records (0 = explained, 1 = as if left out; residual "
                         f"{self.harmonic_residual_to_noise:.3g} times the noise's)")
        if self.outliers:
            lines.append(f"  outlier records: {', '.join(str(o) for o in self.outliers)}")
        lines += [f"  {m}" for m in self.messages]
        if self.stand_in is not None:
            s = self.stand_in
            v = "not assessed" if s.adequate is None else "holds" if s.adequate else "does NOT hold"
            lines.append(f"  polynomial stand-in (re-prediction only, not the selected model): {s.model_name}: {v}")
        return "\n".join(lines)

    def _repr_html_(self):
        return "<pre>" + html.escape(self.report()) + "</pre>"

    def plot(self, ax=None):
        """Shared parameters at each force level with their 95 % intervals, relative to the common value."""
        from .. import plotting

        return plotting.draw("selection_plots.plot_level_equality", self, ax=ax)


def level_equality(level_fits, names=None) -> tuple:
    """Equality tests of the shared parameters across force levels.

    Parameters
    ----------
    level_fits : sequence of (level, PooledFit)
        The pooled fit of each force level (with its covariance).
    names : sequence of str, optional
        The shared parameters to test (default all); a coefficient that follows an amplitude
        law is expected to differ between levels and is left out by :func:`assess_preload`.

    Returns
    -------
    (tuple of ParameterEquality, joint chi2, joint dof, joint p)
    """
    level_fits = [(lv, f) for lv, f in level_fits if f is not None and f.covariance is not None]
    if len(level_fits) < 2:
        return (), float("nan"), 0, float("nan")
    all_names = level_fits[0][1].shared_names
    if any(f.shared_names != all_names for _, f in level_fits):
        raise IdentificationError("the force levels' pooled fits have different shared parameters")
    sel = [j for j, n in enumerate(all_names) if names is None or n in names]
    if not sel:
        return (), float("nan"), 0, float("nan")
    return _equality(tuple(lv for lv, _ in level_fits), tuple(all_names[j] for j in sel),
                     [np.asarray(f.shared, float)[sel] for _, f in level_fits],
                     [np.asarray(f.covariance.shared)[np.ix_(sel, sel)] for _, f in level_fits])


def _equality(levels, names, th, covs):
    """The equality tests of :func:`level_equality` from each level's values and covariance.

    Each variance gets a floor of ``NUMERICAL_RESOLUTION`` relative to the parameter's largest
    value: below it a difference is the arithmetic's, not the data's (noise-free records give
    standard errors of 1e-16 relative, and differences of that order would otherwise be "p < 1e-6").
    """
    floor = np.diag((NUMERICAL_RESOLUTION * np.max(np.abs(np.array(th, float)), axis=0)) ** 2)
    covs = [np.asarray(c, float) + floor for c in covs]
    Ci = [scaled_inverse(c) for c in covs]
    S = sum(Ci)
    bar = scaled_inverse(S) @ sum(c @ t for c, t in zip(Ci, th))
    chi2 = float(sum((t - bar) @ c @ (t - bar) for c, t in zip(Ci, th)))
    dof = (len(th) - 1) * len(names)
    out = []
    for j, n in enumerate(names):
        v = np.array([t[j] for t in th])
        s = np.array([np.sqrt(max(c[j, j], 0.0)) for c in covs])
        w = 1.0 / np.maximum(s, 1e-300) ** 2
        m = float(np.sum(w * v) / np.sum(w))
        c2 = float(np.sum(w * (v - m) ** 2))
        a = np.abs(v)
        ratio = float(a.max() / a.min()) if a.min() > 0 else float("inf")
        out.append(ParameterEquality(n, levels, v, s, m, ratio, c2, len(v) - 1, float(stats.chi2.sf(c2, len(v) - 1))))
    return tuple(out), chi2, dof, float(stats.chi2.sf(chi2, dof))


def record_adequacy(model, fits, signals_list, levels, labels=None, weighting="noise", in_band=False) -> tuple:
    """Each record against a preload model: misfit, explained fractions, outliers.

    Parameters
    ----------
    model : PreloadModel
    fits : sequence of RecordFit
        The records' own fits with the model's terms (their reduced factors and noise sums).
    signals_list : sequence of StateSignals
    levels : sequence
        Force level of each record (outliers are judged within a level).
    labels : sequence, optional
        Record labels (default the positions).
    in_band : bool
        Compare within the fitted harmonics (:func:`~jointid.identify.model.in_band_rows`).
    """
    labels = list(range(len(fits))) if labels is None else list(labels)
    wh = record_whitenings(fits, weighting)
    p = len(model.terms)
    out = []
    for f, s, w, lab, lv in zip(fits, signals_list, wh, labels, levels):
        if tuple(f.terms) != tuple(model.terms):
            raise IdentificationError(f"record {lab}: its fit has terms {f.terms}, the model {model.terms}")
        theta = model.coefficients_at(f.q_max)
        D, z = in_band_rows(f, w) if in_band else (w.rows[:, :p], w.rows[:, p])
        e = D @ theta - z
        misfit = float(e @ e) / p
        # calibrated chi-square: the weighted error has covariance W S W^T (S = R^-T V R^-1), whose
        # eigenvalues give the Satterthwaite scale and degrees of freedom of |e|^2
        V = f.scores.covariance(theta)
        A = linalg.solve_triangular(w.R, V, trans="T", check_finite=False)
        S = w.W @ linalg.solve_triangular(w.R, A.T, trans="T", check_finite=False).T @ w.W.T
        lam = np.clip(linalg.eigvalsh(0.5 * (S + S.T)), 0.0, None)
        s1, s2 = float(np.sum(lam)), float(np.sum(lam**2))
        # the weights make tr(W S W^T) = p unless a noise-free record's weight was floored: then the
        # record has no noise to measure its misfit against
        pv = float("nan")
        if s1 > 0.5 * p and s2 > 0 and np.isfinite(s1 + s2):
            pv = float(stats.chi2.sf(float(e @ e) / (s2 / s1), s1**2 / s2))
        else:
            misfit = float("nan")
        R = f.reduced
        yy = float(np.sum(R[: p + 1, p] ** 2))
        rss = float(np.sum((R[:p, :p] @ theta - R[:p, p]) ** 2) + R[p, p] ** 2)
        ef = 1.0 - rss / yy if yy > 0 else float("nan")
        eh, share, yh, rh, nh = _harmonic_fractions(f, s, theta)
        out.append(RecordAdequacy(lab, lv, float(f.q_max), misfit, ef, eh, share, p_value=pv,
                                  energies=(yy, rss, yh, rh, nh)))
    # outliers within each level: a misfit the noise does not explain (calibrated chi-square, Bonferroni
    # over the records), far above the level's median, in a level the model explains to the noise
    # (where the model fails everywhere, the worst records are its failures, not bad records)
    n = len(out)
    for lv in dict.fromkeys(levels):
        idx = [i for i, x in enumerate(levels) if x == lv]
        mis = np.array([out[i].misfit for i in idx], float)
        med = float(np.median(mis[np.isfinite(mis)])) if np.any(np.isfinite(mis)) else float("nan")
        if not med <= OUTLIER_MEDIAN_LIMIT:
            continue
        for i in idx:
            r = out[i]
            if r.p_value < P_LIMIT / n and r.misfit > OUTLIER_FACTOR * med:
                out[i] = replace(r, outlier=True, outlier_ratio=r.misfit / med)
    return tuple(out)


def _harmonic_fractions(fit, signals, theta):
    """Explained fraction of the restoring force's harmonics above the first, their share of it,
    and the energies: of these harmonics, of the model's residual there, of the noise alone there."""
    sc = fit.scores
    if sc is None or sc.force_coefficients is None or signals is None:
        return (float("nan"),) * 5
    alpha = np.asarray(signals.acceleration.coefficients, float)
    y = np.asarray(sc.force_coefficients, float) - alpha
    G = sc.basis_gram
    m = np.linalg.solve(G, sc.phi_b.T @ theta)
    k = harmonic_index((len(alpha) - 1) // 2)
    hi = k >= 2
    r = (y - m)[hi]
    Gh = G[np.ix_(hi, hi)]
    yh = float(y[hi] @ Gh @ y[hi])
    total = float(y @ G @ y)
    rh = float(r @ Gh @ r)
    frac = 1.0 - rh / yh if yh > 0 else float("nan")
    # what the white noise of both channels alone leaves there: cov of y's coefficients (sF^2 + sa^2) G^-1
    noise = (sc.sigma_force**2 + sc.sigma_accel**2) * float(np.trace(Gh @ np.linalg.inv(G)[np.ix_(hi, hi)]))
    return frac, (float(np.sqrt(yh / total)) if total > 0 else float("nan")), yh, rh, noise


def _drift(fits, levels, labels):
    """Trend of the records' own ``omega1`` with the acquisition order, beside ``q_max`` and ``q_max^2``."""
    out = {}
    for lv in dict.fromkeys(levels):
        idx = [i for i, x in enumerate(levels) if x == lv]
        w1 = np.array([fits[i].omega1 for i in idx])
        se = np.array([fits[i].omega1_stderr for i in idx])
        if len(idx) < 6 or not np.all(np.isfinite(w1)) or not np.all(se > 0):
            continue
        order = np.argsort(np.argsort([labels[i] for i in idx]))
        q = np.array([fits[i].q_max for i in idx])
        qs = q / np.max(q)
        X = np.column_stack([np.ones(len(idx)), qs, qs**2, order]) / se[:, None]
        b = w1 / se
        coef, *_ = np.linalg.lstsq(X, b, rcond=None)
        res = b - X @ coef
        dof = max(len(idx) - 4, 1)
        s2 = max(float(res @ res) / dof, 1.0)  # never below the calibrated noise
        cov = s2 * scaled_inverse(X.T @ X)
        t = float(coef[3] / np.sqrt(cov[3, 3])) if cov[3, 3] > 0 else 0.0
        out[lv] = {"t": t, "slope_per_record": float(coef[3]), "drifts": bool(abs(t) > DRIFT_T)}
    return out


def _sampling_error_score(lib, theta, fit, whitening, signals):
    """Whitened error of a record's rows that the sampling of a jump leaves (zero without one).

    ``sign(q')`` makes the acceleration jump by ``2 f_c`` where the velocity changes sign; sampled
    at ``dt``, the jump's instant is known to a sample only, and the harmonics fitted to the sampled
    acceleration carry the alias of the square wave: its fundamental is shifted in phase by ``delta``
    (uniform over one sample, ``omega dt / sqrt(12)`` standard deviation), an error ``(4 f_c / pi) delta``
    in phase with the motion.  The motion is the acceleration's harmonics over ``-(k omega)^2``, so
    the regression's residual carries it times ``omega1^2 / omega^2``: deterministic for a record,
    random across records, and beyond the noise model's covariance (5e-5 of ``omega1^2`` at 128 samples
    a period on a Coulomb joint near resonance).  Returned as one vector of the whitened rows'
    space with that standard deviation.
    """
    j = [k for k, t in enumerate(lib) if t.name == "sign(q')"]
    if not j or fit.scores is None or signals is None or len(signals.t) < 2:
        return np.zeros(len(lib))
    dt = float(np.median(np.diff(signals.t)))
    w = signals.omega
    stiff = [k for k, t in enumerate(lib) if t.name == "q"]
    ratio = abs(theta[stiff[0]]) / w**2 if stiff else 1.0
    sd = ratio * 4.0 * abs(theta[j[0]]) / np.pi * w * dt / np.sqrt(12.0)
    cq = np.asarray(signals.displacement.coefficients, float)
    c = np.zeros_like(cq)
    c[1:3] = cq[1:3] / max(float(np.hypot(cq[1], cq[2])), 1e-300)  # unit first harmonic in phase with q
    u = linalg.solve_triangular(whitening.R, fit.scores.phi_b @ c, trans="T", check_finite=False)
    return sd * (whitening.W @ u)


def in_band_level_fits(fits, levels, names=None, weighting="noise", signals_list=None) -> tuple:
    """Each force level's fit within the fitted harmonics: shared stiffness terms, own damping per record.

    The pooled fit of a level (:class:`~jointid.identify.fsm.PooledForceStateMapping`, default
    split of the terms) on the rows of :func:`~jointid.identify.model.in_band_rows`, with the
    sandwich covariance of the records' score covariances; with ``signals_list`` (the records' signals) the
    covariance also counts the error the sampling of a jump leaves (:func:`_sampling_error_score`).  Returns
    ``(levels, names, values, covariances)`` of the shared parameters ``names`` (default all).
    """
    lib = library(list(fits[0].terms))
    p = len(lib)
    shared, own = split_terms(lib)
    all_names = tuple(lib.coefficient_names[i] for i in shared)
    sel = [j for j, n in enumerate(all_names) if names is None or n in names]
    wh = record_whitenings(fits, weighting)
    out_lv, out_th, out_cov = [], [], []
    for lv in dict.fromkeys(levels):
        idx = [i for i, x in enumerate(levels) if x == lv]
        k, d = len(shared), len(own)
        P = k + d * len(idx)
        if len(idx) * p <= P:
            continue
        Es, rows = [], []
        for j, i in enumerate(idx):
            E = np.zeros((p, P))
            E[shared, :k] = np.eye(k)
            E[own, k + j * d:k + (j + 1) * d] = np.eye(d)
            Es.append(E)
            rows.append(in_band_rows(fits[i], wh[i]))
        A = np.vstack([D @ E for (D, _), E in zip(rows, Es)])
        b = np.concatenate([z for _, z in rows])
        x = np.linalg.lstsq(A, b, rcond=None)[0]
        V = np.zeros((P, P))
        for (D, _), E, i in zip(rows, Es, idx):
            V += E.T @ score_covariance(wh[i], fits[i].scores.covariance(E @ x), D) @ E
            if signals_list is not None:
                u = _sampling_error_score(lib, E @ x, fits[i], wh[i], signals_list[i])
                V += np.outer(E.T @ (D.T @ u), E.T @ (D.T @ u))
        cov = sandwich(A.T @ A, V)
        out_lv.append(lv)
        out_th.append(x[:k][sel])
        out_cov.append(cov[:k, :k][np.ix_(sel, sel)])
    return tuple(out_lv), tuple(all_names[j] for j in sel), out_th, out_cov


def _refit(model, signals_list, fits, weighting, in_band):
    """``model``'s terms and laws fitted again to ``signals_list`` (warnings silenced)."""
    import warnings

    from ..errors import JointidWarning
    from .model import PreloadForceStateMapping

    laws = {c: L for c, L in zip(model.coefficient_names, model.law_orders) if L != 0}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", JointidWarning)
        return PreloadForceStateMapping(list(model.terms), amplitude_laws=laws, weighting=weighting,
                                        preload=model.preload, in_band=in_band).fit(signals_list, fits=fits).result_


def _level_models(model, fits, signals_list, levels, names, weighting, in_band):
    """The preload model's structure fitted to each force level alone: ``(levels, names, values, covariances)``."""
    sel = [model.parameter_names.index(n) for n in names]
    out_lv, out_th, out_cov = [], [], []
    for lv in dict.fromkeys(levels):
        idx = [i for i, x in enumerate(levels) if x == lv]
        try:
            m = _refit(model, [signals_list[i] for i in idx], [fits[i] for i in idx], weighting, in_band)
        except IdentificationError:
            continue  # too few records for the laws at this level
        out_lv.append(lv)
        out_th.append(m.parameters[sel])
        out_cov.append(m.covariance[np.ix_(sel, sel)])
    return tuple(out_lv), tuple(names), out_th, out_cov


def _in_band_model(model, fits, signals_list, weighting, truncated):
    """The preload model within the fitted harmonics, and a note on what a fit over all harmonics changes."""
    band = model if model.in_band else _refit(model, signals_list, fits, weighting, True)
    full = model if not model.in_band else _refit(model, signals_list, fits, weighting, False)
    H = fits[0].scores.phi_b.shape[1] // 2
    what = ", ".join(f"{t} {100 * x:.2g} %" for t, x in truncated.items())
    note = (f"terms with energy beyond the {H} fitted harmonics ({what}): the records are compared with the model "
            f"within the fitted harmonics")
    z = (full.parameters - band.parameters) / np.where(band.stderr > 0, band.stderr, np.inf)
    biased = [f"{n} {v:.4g} (within the band {b:.4g} ± {e:.2g})" for n, v, b, e, t in
              zip(full.parameter_names, full.parameters, band.parameters, band.stderr, z) if abs(t) > 3]
    if biased:
        note += f"; a fit over all harmonics (as the records' own fits) biases {'; '.join(biased)}"
    return band, note


def assess_preload(model, fits, signals_list, levels, level_fits, labels=None, weighting="noise",
                   preload=None) -> AdequacyResult:
    """All adequacy checks of one preload (see the module notes).

    Parameters
    ----------
    model : PreloadModel or None
        The preload model (per-record checks are skipped without it).
    fits, signals_list, levels, labels
        The preload's usable records: own fits with the model's terms, signals, force level, label.
    level_fits : sequence of (level, PooledFit)
        The pooled fit of each force level.
    """
    constant = None
    if model is not None:  # coefficients with an amplitude law may differ between levels
        constant = [c for c, L in zip(model.coefficient_names, model.law_orders) if L == 0]
    # terms with harmonics beyond the fitted ones (sign(q')): compare within the fitted harmonics
    truncated = {}
    if model is not None and fits and all(f.scores is not None and f.scores.filtered for f in fits):
        frac = np.max([out_of_band_fraction(f) for f in fits], axis=0)
        truncated = {t: float(x) for t, x in zip(model.terms, frac) if x > OUT_OF_BAND_LIMIT}
    stiffness_law = model is not None and any(
        L != 0 for t, L in zip(library(list(model.terms)), model.law_orders) if t.kind != "damping")
    per_level = None  # (levels, names, values, covariances) when the levels' pooled fits do not serve
    if stiffness_law and constant and fits:
        # a level's pooled fit has no law on the stiffness, which would then leak into the constant
        # parameters: each level gets the preload model itself (its laws, fitted to the level alone)
        per_level = _level_models(model, fits, signals_list, levels, constant, weighting, bool(truncated))
    elif truncated:
        per_level = in_band_level_fits(fits, levels, constant, weighting, signals_list)
    if per_level is None:
        eq, chi2, dof, p = level_equality(level_fits, constant)
    elif len(per_level[0]) >= 2 and per_level[1]:
        eq, chi2, dof, p = _equality(*per_level)
    else:
        eq, chi2, dof, p = (), float("nan"), 0, float("nan")
    terms = tuple(model.terms) if model is not None else tuple(level_fits[0][1].terms) if level_fits else ()
    power = model is not None and any(is_power(L) for L in model.law_orders)
    name = model_name(terms, power, stiffness_law if model is not None else None) if terms else "?"
    msgs, adequate = [], True
    differ = [e for e in eq if e.differs]
    if dof and p < P_LIMIT:
        adequate = False
        what = "; ".join(e.describe() for e in differ) if differ else \
            f"the shared parameters differ jointly ({_p_text(p)})"
        msgs.append(f"{what}: the {name} model does not hold at this preload")
    recs = ()
    drift = {}
    if model is not None and fits:
        checked = model
        if truncated:
            checked, note = _in_band_model(model, fits, signals_list, weighting, truncated)
            msgs.append(note)
        recs = record_adequacy(checked, fits, signals_list, levels, labels, weighting, in_band=bool(truncated))
        mis = np.array([r.misfit for r in recs], float)
        med = float(np.median(mis[np.isfinite(mis)])) if np.any(np.isfinite(mis)) else float("nan")
        if med > MISFIT_LIMIT:
            adequate = False
            msgs.append(f"the median record leaves a residual {med:.3g} times what the noise explains: the "
                        f"{name} model misses a part of the restoring force at this preload")
        out = [r.record for r in recs if r.outlier]
        if out:
            msgs.append(f"{len(out)} record(s) far off the model: {', '.join(str(o) for o in out)} (misfit more than "
                        f"{OUTLIER_FACTOR:g} times their level's median)")
        drift = _drift(fits, levels, labels if labels is not None else list(range(len(fits))))
        dl = [lv for lv, d in drift.items() if d["drifts"]]
        if dl:
            msgs.append(f"own omega1 trends with the record order at force level(s) {', '.join(str(x) for x in dl)}: "
                        f"drift during the test, or a dependence the model lacks")
    if not dof:
        why = ("fewer than two force levels with a calibrated pooled fit" if len(level_fits) < 2 else
               "no shared parameter without an amplitude law")
        if not recs:
            adequate = None
            msgs.append(f"not assessed: {why}, and no preload model (e.g. an unknown force gain)")
        else:
            msgs.append(f"equality across force levels not tested: {why}")
    return AdequacyResult(preload, terms, name, eq, chi2, dof, p, recs, drift, adequate, tuple(msgs))


def assess_hysteretic(hfit, signals_list, levels, labels=None, preload=None) -> AdequacyResult:
    """Adequacy of a hysteretic law fitted over a preload's records (a
    :class:`~jointid.identify.hysteretic.HystereticFit`), on the records it was fitted to.

    Per record: the law's restoring force over the record's period projected on its harmonics,
    against the measured ``Q - q''`` (the quantities the hysteretic fit weighs, whitened by the
    record's noise); ``misfit`` is the rms of that residual over the noise (1 = explained to the
    noise, mean square as there), the explained fractions as in :func:`record_adequacy`.  The median misfit above
    ``MISFIT_LIMIT`` says the law does not hold.  The law is one fit over all levels (no per-level
    fits), so equality across force levels is not assessed.
    """
    from .hysteretic import _basis, _prepare

    recs, n = [], 512
    th = 2 * np.pi * np.arange(n) / n
    labels = list(labels) if labels is not None else list(range(len(signals_list)))
    for i, (sig, lv, lab) in enumerate(zip(signals_list, levels, labels)):
        r = _prepare(sig, i)
        E = _basis(th, 1.0, r.H)
        f = hfit.restoring_force(E @ r.d, E @ r.v)
        m = (E[:, 1:].T * (2.0 / n)) @ f  # harmonics 1..H of the model's force
        w = 1.0 / np.sqrt(r.s_force**2 + r.s_accel**2)
        res, y = w * (r.U @ (r.y - m)), w * (r.U @ r.y)
        rows = res.size
        e_h, e_hr = float(y[2:] @ y[2:]), float(res[2:] @ res[2:])  # upper-triangular U: rows 2.. are harmonics >= 2
        energies = (float(y @ y), float(res @ res), e_h, e_hr, float(max(rows - 2, 0)))
        recs.append(RecordAdequacy(lab, lv, float(r.q_max), float(res @ res) / max(rows, 1),
                                   1.0 - energies[1] / energies[0] if energies[0] > 0 else float("nan"),
                                   1.0 - e_hr / e_h if e_h > 0 else float("nan"),
                                   e_h / energies[0] if energies[0] > 0 else float("nan"), energies=energies))
    name = f"{hfit.law_name} (hysteretic)"
    mis = np.array([r.misfit for r in recs], float)
    med = float(np.median(mis[np.isfinite(mis)])) if np.any(np.isfinite(mis)) else float("nan")
    msgs, adequate = [], None if not recs else True
    if med > MISFIT_LIMIT:
        adequate = False
        msgs.append(f"the median record leaves a residual {med:.3g} times what the noise explains: the {name} law "
                    f"misses a part of the restoring force at this preload")
    msgs.append("equality across force levels: not assessed (the law is one fit over all levels, no per-level fits)")
    return AdequacyResult(preload, ("k q", "c q'", f"{hfit.law_name}(q)"), name, (), float("nan"), 0, float("nan"), tuple(recs), {},
                          adequate, tuple(msgs))


def check_adequacy(signals_list, levels, terms="q + -q^3 + q'", *, amplitude_laws=None, damping_order=2,
                   weighting="noise", labels=None, preload=None) -> AdequacyResult:
    """Fit the per-level pooled models and the preload model, then :func:`assess_preload`.

    Parameters
    ----------
    signals_list : sequence of StateSignals
    levels : sequence
        Force level of each record.
    terms, amplitude_laws, damping_order, weighting
        As in :class:`~jointid.identify.model.PreloadForceStateMapping`.
    """
    import warnings

    from ..errors import JointidWarning
    from .fsm import PooledForceStateMapping, own_fits
    from .model import PreloadForceStateMapping
    from .terms import library

    sigs = list(signals_list)
    levels = list(levels)
    if len(levels) != len(sigs):
        raise IdentificationError(f"{len(levels)} force levels given for {len(sigs)} records")
    lib = library(terms)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", JointidWarning)
        fits = own_fits(lib, sigs)
        level_fits = []
        for lv in dict.fromkeys(levels):
            idx = [i for i, x in enumerate(levels) if x == lv]
            level_fits.append((lv, PooledForceStateMapping(lib, weighting=weighting).fit(
                [sigs[i] for i in idx], fits=[fits[i] for i in idx]).result_))
        model = PreloadForceStateMapping(lib, amplitude_laws=amplitude_laws, damping_order=damping_order,
                                         weighting=weighting, preload=preload).fit(sigs, fits=fits).result_
    return assess_preload(model, fits, sigs, levels, level_fits, labels, weighting, preload)
