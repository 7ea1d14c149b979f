"""Model-term selection: which restoring-force model does a preload's data support?

The seed paper chooses ``q, -q^3, q'`` by hand.  :func:`select_model` ranks candidate
models of one preload (terms plus amplitude laws, as fitted by
:class:`~jointid.identify.model.PreloadForceStateMapping`) by two measures:

* an information criterion on the **calibrated chi-square** of the regression.  Every
  candidate is fitted in the reduced space of one common library (the union of all
  candidates' terms), where record ``r`` contributes the rows ``W_r [R_r z_r]`` of its own
  fit with the weights of :func:`~jointid.identify.fsm.record_whitenings`.  Under the
  noise model of :mod:`jointid.identify.uncertainty` the error ``e_r = z_r - R_r theta`` has
  covariance ``S_r = R_r^-T V_r R_r^-1``, so the weighted residual sum
  ``sum |W_r e_r|^2 = sum lambda_i chi^2_1`` with ``lambda`` the eigenvalues of
  ``W_r S_r W_r^T``.  Dividing by ``c = sum lambda^2 / sum lambda`` (Satterthwaite) gives a
  chi-square with ``nu = (sum lambda)^2 / sum lambda^2`` degrees of freedom:
  ``AIC = chi^2 / c + 2 P`` and ``BIC = chi^2 / c + P ln(nu)`` for a model of ``P`` parameters;
* **leave-one-force-level-out cross-validation**: the model is fitted on the other force
  levels and predicts the held-out level's restoring force (its calibrated chi-square per
  record and degree of freedom, ``1`` for a model that explains the held-out level to the
  noise) and its steady-state amplitudes at the held-out records' frequencies and forcing
  (first-harmonic balance; a caller may inject a multi-harmonic predictor).

Hysteretic candidates (a Jenkins element, the four-parameter Iwan joint) are fitted to the loops
by :class:`~jointid.identify.hysteretic.HystereticForceStateMapping` and predicted the same way.

The model picked is the simplest one within noise of the best held-out prediction
(:mod:`jointid.identify.heldout`: each held-out dwell on its own branch, the peak only where the
dwells resolve it): a candidate with a nonlinear parameter less than three standard errors from
zero is not considered (its term is not resolved by the data); of the others, those whose
held-out score is at most ``HELDOUT_RATIO`` times the best plus ``HELDOUT_FLOOR`` are kept, and of
these the one with the fewest parameters wins (at equal counts a model linear in its parameters
before one with fitted power-law exponents or a hysteretic shape).  Without held-out
predictions (broadband records) the criterion decides: those within ``delta`` (2) of the lowest,
of these those whose cross-validated restoring-force score is within one standard error of the
best, and the fewest parameters.  The selected model's flags (a damping law reaching zero, a
held-out level beyond the fitted amplitudes, a dwell far from every steady state) are raised as
:class:`~jointid.errors.ExtrapolationWarning`.  With many candidate terms, :func:`forward_selection` grows the model
one term or law order at a time while the criterion drops by more than ``delta``.
"""

from __future__ import annotations

import html
import math
import warnings
from dataclasses import dataclass, field

import numpy as np
from scipy import linalg

from .._blas import single_threaded
from ..errors import ExtrapolationWarning, IdentificationError, JointidError, JointidWarning
from .fsm import own_fits, pooled_inputs, record_whitenings
from .heldout import (FAR_FROM_BRANCH, HystereticFirstHarmonic, LevelPrediction, PolynomialFirstHarmonic, level_errors,
                      measured_fundamental)
from .hysteretic import HystereticForceStateMapping
from .model import (PreloadForceStateMapping, expand, fit_laws, in_band_rows, law_orders, law_size, parameter_names,
                    score_covariance, use_in_band)
from .powerlaw import POWER, is_power
from .regression import lstsq_from_reduced
from .terms import TermLibrary, library

__all__ = [
    "Candidate",
    "DEFAULT_CANDIDATES",
    "FORWARD_POOL",
    "CandidateScore",
    "SelectionResult",
    "select_model",
    "select_broadband",
    "broadband_candidates",
    "forward_selection",
    "damping_law_flags",
]

#: A nonlinear parameter closer to zero than this many standard errors is not resolved.
RESOLVED_T = 3.0


@dataclass(frozen=True)
class Candidate:
    """One candidate model: restoring-force terms and amplitude laws.

    Parameters
    ----------
    name : str
        Family name shown in the ranking (``"cubic"``).
    terms : str
        Term specification (:func:`~jointid.identify.terms.library`).
    amplitude_laws : tuple of (str, int)
        ``(term or coefficient, order)`` pairs; the other terms are constant.
    """

    name: str
    terms: str
    amplitude_laws: tuple = ()
    hysteretic: str | None = None

    @property
    def library(self) -> TermLibrary:
        return library(self.terms)

    @property
    def laws(self) -> dict:
        return dict(self.amplitude_laws)

    def orders(self) -> tuple:
        return law_orders(self.library, self.laws)

    @property
    def n_parameters(self) -> int:
        if self.hysteretic is not None:  # k, c, the law's force scale and its nonlinear parameters
            return 3 + HYSTERETIC_NONLINEAR[self.hysteretic]
        return int(sum(law_size(L) for L in self.orders()))

    @property
    def n_exponents(self) -> int:
        """Parameters the model is nonlinear in (power-law exponents; a hysteretic law's shape)."""
        if self.hysteretic is not None:
            return HYSTERETIC_NONLINEAR[self.hysteretic]
        return int(sum(is_power(L) for L in self.orders()))

    def law_specs(self) -> dict:
        """``{term: order or "power"}`` as written in ``results.json``."""
        return {k: (POWER if is_power(v) else int(v)) for k, v in self.amplitude_laws}

    def describe(self) -> str:
        if self.hysteretic is not None:
            return f"k q + c q' + {HYSTERETIC_TEXT[self.hysteretic]} (hysteretic)"
        laws = ", ".join(f"{k}(q_max) power law" if is_power(v) else f"{k}(q_max) order {v}"
                         for k, v in self.amplitude_laws if is_power(v) or v > 0)
        return self.terms + (f"; {laws}" if laws else "")


def _family(name, terms, damping_order=2, stiffness_order=0):
    laws = [("q'", damping_order)]
    if stiffness_order:
        laws.insert(0, ("q", stiffness_order))
    return Candidate(name, terms, tuple(laws))


def default_candidates(damping_order=2, hysteretic=True) -> tuple:
    """The physically motivated families, each with the damping law ``c(q_max)`` of ``damping_order``.

    The micro-slip families carry the power laws of an Iwan joint instead
    (:mod:`jointid.identify.powerlaw`): ``omega^2(q_max) = omega1^2 + s q_max^p'`` and
    ``c(q_max) = c0 + c1 q_max^p``, alone or beside a cubic spring (the joint law of
    :func:`jointid.identify.jointlaw.fit_iwan` with its cubic part).  With ``hysteretic``, a
    Jenkins element and Segalman's four-parameter Iwan joint beside ``k q + c q'``, fitted to the
    loops by :class:`~jointid.identify.hysteretic.HystereticForceStateMapping`.
    """
    hyst = (Candidate("Jenkins", "q + q'", (), "jenkins"), Candidate("Iwan", "q + q'", (), "iwan4")) if hysteretic else ()
    return (
        _family("linear", "q + q'", damping_order),
        _family("cubic", "q - q^3 + q'", damping_order),
        _family("quadratic + cubic", "q + q^2 - q^3 + q'", damping_order),
        _family("cubic + quintic", "q - q^3 + q^5 + q'", damping_order),
        _family("|q|q", "q + |q|q + q'", damping_order),
        _family("Coulomb + viscous", "q + q' + sign(q')", damping_order),
        _family("amplitude-dependent stiffness", "q + q'", damping_order, 2),
        _family("micro-slip", "q + q'", POWER, POWER),
        _family("micro-slip + cubic", "q - q^3 + q'", POWER, POWER),
    ) + hyst


#: Nonlinear parameters of each hysteretic law (Jenkins: slip displacement; Iwan: phi_max, chi, beta).
HYSTERETIC_NONLINEAR = {"jenkins": 1, "iwan4": 3}
HYSTERETIC_TEXT = {"jenkins": "Jenkins element (kt, Fs)", "iwan4": "four-parameter Iwan joint (K_T, F_S, chi, beta)"}
#: The default candidate families (damping law of order 2).
DEFAULT_CANDIDATES = default_candidates()
#: Terms :func:`forward_selection` may add by default.
FORWARD_POOL = ("-q^3", "q^2", "q^5", "|q|q", "sign(q')", "|q'|q'", "q'^3")


@dataclass(frozen=True)
class CandidateScore:
    """How one candidate fits a preload's records.

    Attributes
    ----------
    candidate : Candidate
    parameter_names : tuple of str
    parameters, stderr : array
        Fit to all records (sandwich standard errors, as the preload model's).
    chi2 : float
        Calibrated chi-square of the fit to all records (weighted residual / ``c``).
    dof : float
        Effective degrees of freedom ``nu - P``.
    aic, bic : float
    cv_force, cv_force_se : float
        Leave-one-level-out restoring-force score (calibrated chi-square per held-out record
        and degree of freedom; about 1 when the model explains the held-out level to the noise)
        and its standard error over the held-out records.
    cv_amplitude_rms_percent, cv_amplitude_max_percent : float
        Rms and largest relative error of the held-out records' fundamental amplitude, each
        predicted on its own branch (:mod:`jointid.identify.heldout`) [%] (``nan`` when not
        computed, ``inf`` when a held-out level could not be solved).
    unresolved : tuple of str
        Nonlinear parameters less than ``RESOLVED_T`` standard errors from zero.
    condition_number : float
    error : str or None
        Why the candidate could not be fitted.
    heldout_score : float
        Leave-one-level-out prediction error (rms over the levels of
        :attr:`jointid.identify.heldout.LevelPrediction.score`), the selection's measure.
    heldout_peak_frequency_percent, heldout_peak_amplitude_percent : float
        Largest held-out peak errors over the levels whose dwells resolve the peak (``nan``: none).
    heldout_peaks_resolved : int
        Held-out levels whose measured peak is resolved by the dwells.
    flags : tuple of str
        Warnings about the model: a damping law that reaches zero inside or just beyond the
        measured amplitudes, a held-out level predicted outside the fitted amplitude range, a
        held-out dwell far from every steady state of the model.
    residual_rms : float
        Hysteretic candidates: weighted residual rms of the loop fit (1 = noise).
    """

    candidate: Candidate
    parameter_names: tuple = ()
    parameters: np.ndarray = field(default=None, repr=False)
    stderr: np.ndarray = field(default=None, repr=False)
    chi2: float = float("nan")
    dof: float = float("nan")
    aic: float = float("inf")
    bic: float = float("inf")
    cv_force: float = float("nan")
    cv_force_se: float = float("nan")
    cv_amplitude_rms_percent: float = float("nan")
    cv_amplitude_max_percent: float = float("nan")
    unresolved: tuple = ()
    condition_number: float = float("nan")
    error: str | None = None
    heldout_score: float = float("nan")
    heldout_peak_frequency_percent: float = float("nan")
    heldout_peak_amplitude_percent: float = float("nan")
    heldout_peaks_resolved: int = 0
    flags: tuple = ()
    residual_rms: float = float("nan")
    law_start: tuple = field(default=(), repr=False)  # a hysteretic law's nonlinear parameters (fit's start)

    @property
    def name(self) -> str:
        return self.candidate.name

    @property
    def n_parameters(self) -> int:
        return self.candidate.n_parameters

    def summary(self) -> dict:
        def num(x):
            x = float(x)
            return x if np.isfinite(x) else None

        return {
            "name": self.name,
            "terms": self.candidate.terms,
            "amplitude_laws": self.candidate.law_specs(),
            "n_parameters": self.n_parameters,
            "parameter_names": list(self.parameter_names),
            "parameters": None if self.parameters is None else [float(v) for v in self.parameters],
            "stderr": None if self.stderr is None else [float(v) for v in self.stderr],
            "chi2": num(self.chi2),
            "dof": num(self.dof),
            "aic": num(self.aic),
            "bic": num(self.bic),
            "cv_force": num(self.cv_force),
            "cv_force_se": num(self.cv_force_se),
            "cv_amplitude_rms_percent": num(self.cv_amplitude_rms_percent),
            "cv_amplitude_max_percent": num(self.cv_amplitude_max_percent),
            "unresolved": list(self.unresolved),
            "condition_number": num(self.condition_number),
            "error": self.error,
            "hysteretic_law": self.candidate.hysteretic,
            "heldout_score": num(self.heldout_score),
            "heldout_peak_frequency_percent": num(self.heldout_peak_frequency_percent),
            "heldout_peak_amplitude_percent": num(self.heldout_peak_amplitude_percent),
            "heldout_peaks_resolved": int(self.heldout_peaks_resolved),
            "flags": list(self.flags),
            "residual_rms": num(self.residual_rms),
        }


@dataclass(frozen=True)
class SelectionResult:
    """Ranking of candidate models of one preload and the model picked.

    Attributes
    ----------
    preload : object
    scores : tuple of CandidateScore
        Ranked by the criterion (best first).
    selected : str
        Name of the model picked (simplest within noise of the best).
    criterion : {"bic", "aic"}
    delta : float
        Criterion difference counted as "within noise".
    levels : tuple
        The force levels (cross-validation folds).
    common_terms : tuple of str
        The common library the candidates are compared in.
    scale, nu : float
        Satterthwaite factor ``c`` and degrees of freedom ``nu`` of the calibrated chi-square.
    model : PreloadModel or None
        The selected model fitted to all records by
        :class:`~jointid.identify.model.PreloadForceStateMapping`.
    method : str
        ``"ranking"`` (all candidates) or ``"forward"`` (forward selection path).
    n_records : int
    hysteretic_model : HystereticFit or None
        The selected hysteretic law fitted to all records, when a hysteretic candidate is picked.
    stand_in : str or None
        Then the polynomial candidate (best held-out score) whose ``model`` stands in for it where
        a polynomial model is needed (re-prediction of the FRFs).
    heldout : bool
        The pick was decided by held-out prediction (else by the criterion and the CV force score).
    """

    preload: object
    scores: tuple
    selected: str
    criterion: str
    delta: float
    levels: tuple
    common_terms: tuple
    scale: float
    nu: float
    model: object = field(default=None, repr=False)
    method: str = "ranking"
    n_records: int = 0
    hysteretic_model: object = field(default=None, repr=False)
    stand_in: str | None = None
    heldout: bool = False

    def score(self, name) -> CandidateScore:
        for s in self.scores:
            if s.name == name:
                return s
        raise KeyError(name)

    @property
    def best(self) -> CandidateScore:
        return self.scores[0]

    @property
    def selected_score(self) -> CandidateScore:
        return self.score(self.selected)

    @property
    def candidate(self) -> Candidate:
        return self.selected_score.candidate

    def table(self) -> list:
        """Rows of the ranking table (dicts), best first, with the criterion difference."""
        finite = [getattr(s, self.criterion) for s in self.scores if np.isfinite(getattr(s, self.criterion))]
        ic0 = min(finite) if finite else float("nan")
        rows = []
        for s in self.scores:
            d = s.summary()
            ic = getattr(s, self.criterion)
            d["delta_ic"] = float(ic - ic0) if np.isfinite(ic) and np.isfinite(ic0) else None
            d["selected"] = s.name == self.selected
            rows.append(d)
        return rows

    def summary(self) -> dict:
        return {
            "preload": self.preload,
            "selected": self.selected,
            "verdict": f"selected {self.selected}: {self.candidate.describe()}",
            "selected_terms": self.candidate.terms,
            "selected_amplitude_laws": self.candidate.law_specs(),
            "criterion": self.criterion,
            "delta": float(self.delta),
            "rule": self.rule,
            "decided_by": "held-out prediction" if self.heldout else self.criterion,
            "flags": list(self.selected_score.flags),
            "hysteretic_model": None if self.hysteretic_model is None else self.hysteretic_model.summary(),
            "stand_in": self.stand_in,
            "method": self.method,
            "levels": list(self.levels),
            "n_records": int(self.n_records),
            "common_terms": list(self.common_terms),
            "chi2_scale": float(self.scale),
            "chi2_nu": float(self.nu),
            "ranking": self.table(),
            "model": None if self.model is None else self.model.summary(),
        }

    @property
    def rule(self) -> str:
        if self.heldout:
            return (f"fewest parameters among the fully resolved models whose leave-one-level-out prediction score "
                    f"(peak amplitude and frequency on the measured branch where the dwells resolve the peak, else "
                    f"the dwells' amplitudes) is within {HELDOUT_RATIO:g} x the best + {HELDOUT_FLOOR:g}")
        return (f"fewest parameters among the models with {self.criterion.upper()} within {self.delta:g} of the "
                f"lowest and a cross-validated restoring-force score within one standard error of the best "
                f"of them")

    def report(self) -> str:
        head = f"preload {self.preload}: " if self.preload is not None else ""
        lines = [f"{head}model selection over {len(self.levels)} force levels ({self.n_records} records), "
                 + ("ranked by held-out prediction; " if self.heldout else f"ranked by {self.criterion.upper()} ")
                 + f"(calibrated chi-square, scale {self.scale:.3g}, nu {self.nu:.4g})",
                 f"  {'model':<30} {'P':>2} {'chi2':>10} {'d' + self.criterion.upper():>8} {'CV force':>14} "
                 f"{'CV ampl. %':>10} {'held-out':>9} {'peak f %':>9} {'peak A %':>9}  unresolved"]
        for row in self.table():
            mark = "*" if row["selected"] else " "
            cv = "-" if row["cv_force"] is None else (f"{row['cv_force']:.3g}±{row['cv_force_se']:.2g}"
                                                        if row["cv_force_se"] is not None else f"{row['cv_force']:.3g}")
            amp = "-" if row["cv_amplitude_rms_percent"] is None else f"{row['cv_amplitude_rms_percent']:.3g}"
            chi = "-" if row["chi2"] is None else f"{row['chi2']:.5g}"
            dic = "-" if row["delta_ic"] is None else f"{row['delta_ic']:.4g}"
            extra = ", ".join(row["unresolved"]) if row["error"] is None else f"failed: {row['error']}"

            def g(x, fmt):
                return "-" if x is None else format(x, fmt)

            lines.append(f"{mark} {row['name']:<30} {row['n_parameters']:>2} {chi:>10} {dic:>8} {cv:>14} "
                         f"{amp:>10} {g(row['heldout_score'], '.3g'):>9} "
                         f"{g(row['heldout_peak_frequency_percent'], '.3g'):>9} "
                         f"{g(row['heldout_peak_amplitude_percent'], '.3g'):>9}  {extra}")
        lines.append(f"  selected: {self.selected} ({self.candidate.describe()}), the simplest model within noise "
                     f"of the best")
        if self.stand_in:
            lines.append(f"  polynomial stand-in for re-prediction: {self.stand_in}")
        lines += [f"  warning: {f}" for f in self.selected_score.flags]
        return "\n".join(lines)

    def _repr_html_(self):
        return "<pre>" + html.escape(self.report()) + "</pre>"

    def plot(self, ax=None):
        """Criterion differences and cross-validation scores of the ranking (bar chart)."""
        from .. import plotting

        return plotting.draw("selection_plots.plot_selection", self, ax=ax)


# ----------------------------------------------------------------------------------------------
# the common reduced space
# ----------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Record:
    rows: np.ndarray  # W [R z] in the common library, (p, p + 1)
    q_max: float
    omega: float
    forcing: float  # fundamental amplitude of the force
    fit: object  # RecordFit in the common library
    a1: float  # fundamental amplitude of q
    whitening: object  # its Whitening (record weight)


class _Space:
    """Records of one preload reduced once in the common library of all candidates."""

    def __init__(self, lib, sigs, fits, weighting):
        self.lib = lib
        self.sigs = list(sigs)
        wh = record_whitenings(fits, weighting)
        self.records = []
        lam = []
        # within the fitted harmonics when a term (sign(q')) has energy beyond them; the rows of the
        # other terms are the same either way
        self.in_band = use_in_band(fits)
        for s, f, w in zip(sigs, fits, wh):
            fc = f.scores.force_coefficients
            forcing = float(np.hypot(fc[1], fc[2])) if fc is not None and np.all(np.isfinite(fc[:3])) else float("nan")
            rows = np.column_stack(in_band_rows(f, w)) if self.in_band else w.rows
            self.records.append(_Record(rows, float(f.q_max), float(s.omega), forcing, f, measured_fundamental(s), w))
            # covariance of the weighted reduced error W (z - R theta) under the noise model
            V = f.scores.covariance(f.coefficients)
            A = linalg.solve_triangular(w.R, V, trans="T", check_finite=False)
            S = linalg.solve_triangular(w.R, A.T, trans="T", check_finite=False).T
            S = w.W @ S @ w.W.T
            lam.append(np.clip(linalg.eigvalsh(0.5 * (S + S.T)), 0.0, None))
        lam = np.concatenate(lam)
        s1, s2 = float(np.sum(lam)), float(np.sum(lam**2))
        self.scale = s2 / s1 if s1 > 0 else 1.0
        self.nu = s1**2 / s2 if s2 > 0 else float(lam.size)
        self.p = len(lib)

    def columns(self, cand_lib):
        try:
            return [self.lib.index(t.name) for t in cand_lib]
        except KeyError as exc:
            raise IdentificationError(f"candidate term not in the common library {self.lib.names}: {exc}") from exc

    def residuals(self, cols, orders, theta, idx):
        """Weighted residual sum of every record of ``idx``."""
        out = []
        for i in idx:
            r = self.records[i]
            e = r.rows[:, cols] @ expand(orders, r.q_max, theta)[0] - r.rows[:, self.p]
            out.append(float(e @ e))
        return np.array(out)

    def fit(self, cols, orders, idx):
        """``(theta, condition number, Jacobian of the stacked weighted rows)`` over the records ``idx``."""
        recs = [self.records[i] for i in idx]
        n = int(sum(r.fit.n_samples for r in recs))
        return fit_laws([r.rows[:, cols] for r in recs], [r.rows[:, self.p] for r in recs],
                        [r.q_max for r in recs], orders, n)

    def covariance(self, cols, orders, theta, A, idx):
        """Sandwich covariance of ``theta`` (score covariances of the common library)."""
        from .uncertainty import sandwich

        P = A.shape[1]
        V = np.zeros((P, P))
        for i in idx:
            r = self.records[i]
            coef, E, slope = expand(orders, r.q_max, theta)
            Ec = np.zeros((self.p, P))
            Ec[cols] = E
            cc, sc = np.zeros(self.p), np.zeros(self.p)
            cc[cols], sc[cols] = coef, slope
            Vs = score_covariance(r.whitening, r.fit.scores.covariance(cc, sc),
                                  r.rows[:, :self.p] if self.in_band else None)
            V += Ec.T @ Vs @ Ec
        return sandwich(A.T @ A, V)


#: Evaluations of each coarse local search and of the final search of a hysteretic candidate's fit.
HYSTERETIC_SEARCH = 30
HYSTERETIC_EVALUATIONS = 60
#: Samples of a period for a hysteretic candidate's law force (the selection's fits; the final fit uses the default).
HYSTERETIC_N_TIME = 256
#: Models whose held-out score is within this factor of the best (plus ``HELDOUT_FLOOR``) are within noise.
HELDOUT_RATIO = 1.5
#: Held-out score differences below this (0.2 % of an amplitude) are not told apart.
HELDOUT_FLOOR = 0.002
#: A damping law checked for ``c(q_max) <= 0`` up to this multiple of the largest measured amplitude.
DAMPING_CHECK_REACH = 1.5
#: A held-out level whose amplitudes exceed the fitted ones by more than this fraction is an extrapolation.
EXTRAPOLATION_MARGIN = 0.05


def damping_law_flags(lib, orders, theta, q_max_measured, reach=DAMPING_CHECK_REACH) -> tuple:
    """Messages for a viscous-damping law ``c(q_max)`` that is not positive from zero up to ``reach`` times the
    largest measured amplitude (an unresolved law extrapolated: the model would feed energy in)."""
    if "q'" not in lib.names:
        return ()
    i = lib.index("q'")
    q_hi = float(np.max(q_max_measured))
    grid = np.linspace(0.0, reach * q_hi, 301)
    c = np.array([expand(orders, q, theta)[0][i] for q in grid])
    bad = np.flatnonzero(~(c > 0))
    if not bad.size:
        return ()
    q0 = float(grid[bad[0]])
    where = "inside the measured amplitudes" if q0 <= q_hi else f"at {q0 / q_hi:.2g} x the largest measured amplitude"
    return (f"the damping law c(q_max) reaches {float(c[bad[0]]):.3g} <= 0 at q_max = {q0:.3g} ({where}, largest "
            f"measured {q_hi:.3g}): its coefficients are not resolved and the law must not be extrapolated",)


def _fold_scores(level_preds):
    """Aggregate of the held-out levels' :class:`~jointid.identify.heldout.LevelPrediction`."""
    scores = np.array([lp.score for lp in level_preds], float)
    dwell = np.concatenate([lp.dwell_errors_percent for lp in level_preds])
    res = [lp for lp in level_preds if lp.peak_resolved]
    fe = max((abs(lp.peak_frequency_error_percent) for lp in res), default=float("nan"))
    ae = max((abs(lp.peak_amplitude_error_percent) for lp in res), default=float("nan"))
    out = dict(heldout_score=float(np.sqrt(np.mean(scores**2))) if np.all(np.isfinite(scores)) else float("inf"),
               heldout_peak_frequency_percent=float(fe), heldout_peak_amplitude_percent=float(ae),
               heldout_peaks_resolved=len(res))
    if np.all(np.isfinite(dwell)):
        out.update(cv_amplitude_rms_percent=float(np.sqrt(np.mean(dwell**2))),
                   cv_amplitude_max_percent=float(np.max(np.abs(dwell))))
    else:
        out.update(cv_amplitude_rms_percent=float("inf"), cv_amplitude_max_percent=float("inf"))
    return out


def _no_prediction(preds, flags, test, lev, exc):
    """Record a held-out level that could not be predicted: an infinite score and a flag naming the level."""
    preds.append(LevelPrediction(np.full(len(test), np.inf), np.zeros(len(test), int), False, float("nan"),
                                 float("nan"), float("nan"), float("inf"), True))
    flags.append(f"held out at force level {lev}: no prediction ({exc})")


def _predict_level(fh, space, test, fitted_amax, predictor, cand, fitted):
    """Held-out prediction of one level; ``(LevelPrediction, flags)``."""
    recs = [space.records[i] for i in test]
    F = float(np.nanmean([r.forcing for r in recs]))
    w = np.array([r.omega for r in recs])
    am = np.array([r.a1 for r in recs])
    inj = None if predictor is None else (lambda ww, aa: predictor(cand, fitted, F, ww, aa))
    lp = level_errors(fh, F, w, am, inj)
    flags = []
    if np.max(am) > (1.0 + EXTRAPOLATION_MARGIN) * fitted_amax:
        flags.append(f"held out at force {F:.4g}: amplitudes up to {np.max(am) / fitted_amax:.3g} x the fitted range "
                     "(the laws are extrapolated there)")
    if lp.far_from_branch:
        flags.append(f"held out at force {F:.4g}: a dwell lies more than {100 * FAR_FROM_BRANCH:g} % from every "
                     "steady state the model predicts")
    return lp, flags


def _score(space, cand, levels_of, level_values, criterion_only, n_harmonics, cv_amplitude, predictor=None):
    if cand.hysteretic is not None:
        return _score_hysteretic(space, cand, levels_of, level_values, criterion_only or not cv_amplitude)
    lib = cand.library
    cols = space.columns(lib)
    orders = law_orders(lib, cand.laws)
    names = parameter_names(lib, orders)
    P = len(names)
    all_idx = list(range(len(space.records)))
    if len(all_idx) * space.p <= P:
        return CandidateScore(cand, names, error=f"{P} parameters from {len(all_idx)} records")
    theta, cond, A = space.fit(cols, orders, all_idx)
    if not np.all(np.isfinite(theta)):
        return CandidateScore(cand, names, error="singular regression")
    chi2 = float(np.sum(space.residuals(cols, orders, theta, all_idx))) / space.scale
    aic = chi2 + 2.0 * P
    bic = chi2 + P * math.log(max(space.nu, 2.0))
    cov = space.covariance(cols, orders, theta, A, all_idx)
    se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    unresolved = tuple(n for n, v, s, (t, j) in zip(names, theta, se, _param_terms(lib, orders))
                       if j is not None and (t.name not in ("q", "q'") or (t.name == "q" and j > 0))
                       and not (abs(v) > RESOLVED_T * s))
    qm = np.array([r.q_max for r in space.records])
    flags = list(damping_law_flags(lib, orders, theta, qm))
    kw = dict(parameter_names=names, parameters=theta, stderr=se, chi2=chi2, dof=space.nu - P, aic=aic, bic=bic,
              unresolved=unresolved, condition_number=float(cond))
    if criterion_only or len(level_values) < 2:
        return CandidateScore(cand, flags=tuple(flags), **kw)
    per_record, preds = [], []
    for lev in level_values:
        test = [i for i in all_idx if levels_of[i] == lev]
        train = [i for i in all_idx if levels_of[i] != lev]
        if len(train) * space.p <= P:
            per_record += [np.inf] * len(test)
            continue
        th, _, _ = space.fit(cols, orders, train)
        per_record += list(space.residuals(cols, orders, th, test) / space.p)
        if cv_amplitude:
            try:
                fh = PolynomialFirstHarmonic(lib, orders, th)
                if not fh.stiffness0() > 0:
                    raise IdentificationError("no positive linear stiffness")
                amax = max(space.records[i].a1 for i in train)
                lp, fl = _predict_level(fh, space, test, amax, predictor, cand, (lib, orders, th))
                preds.append(lp)
                flags += fl
            except (JointidError, ArithmeticError, ValueError, np.linalg.LinAlgError) as exc:
                _no_prediction(preds, flags, test, lev, exc)
    e = np.asarray(per_record, float)
    cvf = float(np.mean(e))
    cvse = float(np.std(e, ddof=1) / np.sqrt(e.size)) if e.size > 1 and np.all(np.isfinite(e)) else float("nan")
    if preds:
        kw.update(_fold_scores(preds))
    return CandidateScore(cand, cv_force=cvf, cv_force_se=cvse, flags=tuple(dict.fromkeys(flags)), **kw)


def _hysteretic_fit(law, sigs, start=None):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", JointidWarning)
        fit = HystereticForceStateMapping(law, n_time=HYSTERETIC_N_TIME, start=start, search_evaluations=HYSTERETIC_SEARCH,
                                          max_evaluations=HYSTERETIC_EVALUATIONS).fit(sigs)
    return fit, [str(c.message) for c in caught if issubclass(c.category, JointidWarning)]


def _score_hysteretic(space, cand, levels_of, level_values, criterion_only):
    """Score of a hysteretic candidate: its loop fit to all records and its held-out levels."""
    sigs = space.sigs
    try:
        est, warn = _hysteretic_fit(cand.hysteretic, sigs)
    except (JointidError, ArithmeticError, ValueError, np.linalg.LinAlgError) as exc:
        return CandidateScore(cand, error=str(exc))
    res = est.result_
    unresolved = [n for n in res.names[2:]
                  if n not in ("chi", "beta") and not abs(res.get(n)) > RESOLVED_T * res.get_stderr(n)]
    if any(("edge of its range" in w) or ("beyond the largest measured amplitude" in w) for w in warn):
        unresolved += [n for n in res.names[3:] if n not in unresolved]  # the law's shape is not resolved
    kw = dict(parameter_names=tuple(res.names), parameters=np.asarray(res.values, float), stderr=np.asarray(res.stderr),
              unresolved=tuple(dict.fromkeys(unresolved)), residual_rms=float(res.residual_rms),
              law_start=tuple(float(x) for x in est.parameters_[3:]))
    flags = list(warn)
    if criterion_only or len(level_values) < 2:
        return CandidateScore(cand, flags=tuple(flags), **kw)
    preds = []
    all_idx = list(range(len(sigs)))
    for lev in level_values:
        test = [i for i in all_idx if levels_of[i] == lev]
        train = [i for i in all_idx if levels_of[i] != lev]
        try:
            if len(train) < 3:
                raise IdentificationError(f"{len(train)} records to fit")
            sub, _ = _hysteretic_fit(cand.hysteretic, [sigs[i] for i in train], start=est.parameters_[3:])
            amax = max(space.records[i].a1 for i in train)
            lp, fl = _predict_level(HystereticFirstHarmonic(sub.result_), space, test, amax, None, cand, sub.result_)
            preds.append(lp)
            flags += fl
        except (JointidError, ArithmeticError, ValueError, np.linalg.LinAlgError) as exc:
            _no_prediction(preds, flags, test, lev, exc)
    kw.update(_fold_scores(preds))
    return CandidateScore(cand, flags=tuple(dict.fromkeys(flags)), **kw)


def _param_terms(lib, orders):
    """``(term, power of q_max)`` of every parameter (a power law: 0, 1 and ``None`` for its exponent)."""
    return [(t, j) for t, L in zip(lib, orders) for j in ((0, 1, None) if is_power(L) else range(L + 1))]


def _pick(scores, criterion, delta):
    """The simplest model within noise of the best (see the module notes).

    Models with a nonlinear parameter the data do not resolve (less than ``RESOLVED_T``
    standard errors from zero, or a hysteretic law's shape at the edge of its range or beyond
    the measured amplitudes) are left out when any model is fully resolved.

    With held-out predictions (:mod:`jointid.identify.heldout`): the models whose held-out score
    is at most ``HELDOUT_RATIO`` times the best plus ``HELDOUT_FLOOR`` are within noise of the
    best; the one with the fewest parameters wins (then the fewest parameters it is nonlinear
    in, then the score).  Without them (broadband records, ``cv_amplitude=False``): among the
    models whose criterion is within ``delta`` of the lowest, those whose cross-validated
    restoring-force score is within one standard error of the best among them are kept; the one
    with the fewest parameters (then the lowest criterion) wins.
    """
    ok = [s for s in scores if s.error is None]
    held = [s for s in ok if np.isfinite(s.heldout_score)]
    if held:
        held = [s for s in held if not s.unresolved] or held  # a term the data do not resolve is not within noise
        b = min(s.heldout_score for s in held)
        near = [s for s in held if s.heldout_score <= HELDOUT_RATIO * b + HELDOUT_FLOOR]
        return min(near, key=lambda s: (s.n_parameters, s.candidate.n_exponents, s.heldout_score)).name
    ok = [s for s in ok if np.isfinite(getattr(s, criterion))]
    if not ok:
        raise IdentificationError("no candidate model could be fitted")
    ok = [s for s in ok if not s.unresolved] or ok
    ic0 = min(getattr(s, criterion) for s in ok)
    near = [s for s in ok if getattr(s, criterion) <= ic0 + delta]
    cv = [s for s in near if np.isfinite(s.cv_force)]
    if cv:
        b = min(cv, key=lambda s: s.cv_force)
        limit = b.cv_force + (b.cv_force_se if np.isfinite(b.cv_force_se) else 0.0)
        near = [s for s in cv if s.cv_force <= limit]
    # equal parameter counts: a model linear in its parameters before one with fitted exponents
    return min(near, key=lambda s: (s.n_parameters, s.candidate.n_exponents, getattr(s, criterion))).name


def _prepare(signals_list, levels, candidate_libs, weighting, filtered, fits):
    sigs = pooled_inputs(signals_list, weighting, "model selection")
    levels = list(levels)
    if len(levels) != len(sigs):
        raise IdentificationError(f"{len(levels)} force levels given for {len(sigs)} records")
    terms = {}
    for lib in candidate_libs:
        for t in lib:
            terms.setdefault(t.name, t)
    common = library(list(terms.values()))
    fits = own_fits(common, sigs, fits, filtered)
    return sigs, levels, common, _Space(common, sigs, fits, weighting)


def _unique_levels(levels):
    out = []
    for v in levels:
        if v not in out:
            out.append(v)
    return out


def _candidates(candidates, damping_order):
    if candidates is None:
        return default_candidates(damping_order)
    out = []
    for c in candidates:
        if isinstance(c, Candidate):
            out.append(c)
        elif isinstance(c, str):
            out.append(Candidate(c, c, tuple((t.name, damping_order) for t in library(c) if t.name == "q'")))
        else:
            name, terms, laws = c
            out.append(Candidate(name, terms, tuple(dict(laws).items())))
    names = [c.name for c in out]
    if len(set(names)) != len(names):
        raise IdentificationError(f"candidate names must be distinct, got {names}")
    return tuple(out)


@single_threaded
def select_model(signals_list, levels, candidates=None, *, criterion="bic", delta=2.0, damping_order=2,
                 weighting="noise", filtered=True, cross_validate=True, cv_amplitude=True, n_harmonics=5,
                 preload=None, fit_selected=True, predictor=None) -> SelectionResult:
    """Rank candidate models of one preload and pick the simplest within noise of the best.

    Parameters
    ----------
    signals_list : sequence of StateSignals
        The usable records of one preload.
    levels : sequence
        Force level of each record (the cross-validation folds).
    candidates : sequence, optional
        :class:`Candidate` objects, term strings (damping law of ``damping_order`` on ``q'``)
        or ``(name, terms, {term: order})`` tuples; default :func:`default_candidates`.
    criterion : {"bic", "aic"}
    delta : float
        Criterion difference counted as within noise.
    cross_validate, cv_amplitude : bool
        Leave-one-force-level-out scores (restoring force; held-out steady-state amplitudes and
        peaks, :mod:`jointid.identify.heldout`, which decide the pick).  Without ``cv_amplitude``
        the hysteretic candidates are fitted but not cross-validated, and the pick falls back on
        the criterion and the restoring-force score.
    n_harmonics : int
        Kept for compatibility (the held-out prediction is a first-harmonic balance).
    preload : object
        Label stored on the result.
    fit_selected : bool
        Fit the selected model to all records with
        :class:`~jointid.identify.model.PreloadForceStateMapping` (stored as ``model``); a
        hysteretic pick is refitted by :class:`~jointid.identify.hysteretic.HystereticForceStateMapping`
        (``hysteretic_model``) and ``model`` is then the best polynomial candidate (``stand_in``).
    predictor : callable, optional
        ``predictor(candidate, (lib, orders, theta), forcing, omegas, a_measured) -> amplitudes``:
        the held-out dwells' amplitudes of a polynomial candidate by another solver (the
        application injects a multi-harmonic balance this way); default the first-harmonic roots
        on each dwell's own branch.

    Returns
    -------
    SelectionResult
    """
    if criterion not in ("aic", "bic"):
        raise IdentificationError(f"criterion must be 'aic' or 'bic', got {criterion!r}")
    cands = _candidates(candidates, damping_order)
    sigs, levels, common, space = _prepare(signals_list, levels, [c.library for c in cands], weighting, filtered,
                                           None)
    lv = _unique_levels(levels)
    scores = [_score(space, c, levels, lv, not cross_validate, n_harmonics, cv_amplitude, predictor) for c in cands]
    return _result(scores, criterion, delta, lv, common, space, sigs, preload, weighting, filtered, fit_selected,
                   "ranking")


def _result(scores, criterion, delta, lv, common, space, sigs, preload, weighting, filtered, fit_selected, method):
    heldout = any(s.error is None and np.isfinite(s.heldout_score) for s in scores)
    if heldout:
        scores = sorted(scores, key=lambda s: (s.error is not None, not np.isfinite(s.heldout_score), s.heldout_score,
                                               s.n_parameters))
    else:
        scores = sorted(scores, key=lambda s: (getattr(s, criterion), s.n_parameters))
    chosen = _pick(scores, criterion, delta)
    picked = next(s for s in scores if s.name == chosen)
    model = hyst = stand_in = None
    if fit_selected:
        cand = picked.candidate
        if cand.hysteretic is not None:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", JointidWarning)  # its warnings are the candidate's flags
                hyst = HystereticForceStateMapping(cand.hysteretic, start=list(picked.law_start) or None
                                                  ).fit(sigs).result_
            poly = [s for s in scores if s.candidate.hysteretic is None and s.error is None]
            if poly:
                cand = min(poly, key=lambda s: (s.heldout_score if heldout else getattr(s, criterion))).candidate
                stand_in = cand.name
            else:
                cand = None
        if cand is not None:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", JointidWarning)
                model = PreloadForceStateMapping(cand.terms, amplitude_laws=cand.laws, weighting=weighting,
                                                 filtered=filtered, preload=preload).fit(sigs).result_
    head = f"preload {preload}: " if preload is not None else ""
    for f in picked.flags:
        warnings.warn(f"{head}selected {chosen}: {f}", ExtrapolationWarning, stacklevel=3)
    return SelectionResult(preload, tuple(scores), chosen, criterion, float(delta), tuple(lv), common.names,
                           space.scale, space.nu, model, method, len(sigs), hyst, stand_in, heldout)


@single_threaded
def forward_selection(signals_list, levels, *, base="q + q'", pool=FORWARD_POOL, stiffness_law_max=2,
                      criterion="bic", delta=2.0, damping_order=2, weighting="noise", filtered=True,
                      cross_validate=True, cv_amplitude=True, n_harmonics=5, preload=None,
                      fit_selected=True) -> SelectionResult:
    """Sparse search: grow the model from ``base`` one term (or stiffness-law order) at a time.

    At each step every remaining term of ``pool`` and one more order of the law of the
    linear stiffness (up to ``stiffness_law_max``) are tried; the move that lowers the
    criterion most is taken while it lowers it by more than ``delta``.  The models of the
    path are then ranked as in :func:`select_model` (with cross-validation).
    """
    if criterion not in ("aic", "bic"):
        raise IdentificationError(f"criterion must be 'aic' or 'bic', got {criterion!r}")
    base_lib = library(base)
    pool_lib = library(pool)
    libs = [base_lib, pool_lib]
    sigs, levels, common, space = _prepare(signals_list, levels, libs, weighting, filtered, None)
    lv = _unique_levels(levels)

    def make(terms, s_order):
        lib = library(terms)
        laws = [(t.name, damping_order) for t in lib if t.kind == "damping" and t.name == "q'"]
        if s_order:
            laws.insert(0, ("q", s_order))
        name = " + ".join(terms) + (f"; q(q_max) order {s_order}" if s_order else "")
        return Candidate(name, " + ".join(terms), tuple(laws))

    terms, s_order = list(base_lib.names), 0
    current = _score(space, make(terms, s_order), levels, lv, True, n_harmonics, False)
    path = [current]
    while True:
        moves = [(terms + [t], s_order) for t in pool_lib.names if t not in terms]
        if "q" in terms and s_order < stiffness_law_max:
            moves.append((terms, s_order + 1))
        trial = [_score(space, make(t, s), levels, lv, True, n_harmonics, False) for t, s in moves]
        trial = [(s, m) for s, m in zip(trial, moves) if s.error is None]
        if not trial:
            break
        best, move = min(trial, key=lambda x: getattr(x[0], criterion))
        if getattr(best, criterion) >= getattr(current, criterion) - delta:
            break
        terms, s_order = list(move[0]), move[1]
        current = best
        path.append(best)
    if cross_validate:
        path = [_score(space, s.candidate, levels, lv, False, n_harmonics, cv_amplitude) for s in path]
    return _result(path, criterion, delta, lv, common, space, sigs, preload, weighting, filtered, fit_selected,
                   "forward")


def broadband_candidates(damping_order=None) -> tuple:
    """The default families without amplitude laws (a broadband record has no single ``q_max``)."""
    return tuple(Candidate(c.name, c.terms) for c in DEFAULT_CANDIDATES if "q" not in c.laws and c.hysteretic is None)


@single_threaded
def select_broadband(states_list, levels, candidates=None, *, criterion="bic", delta=2.0,
                     preload=None) -> SelectionResult:
    """Rank candidate models of periodic broadband records (multisines at several levels).

    Each record's lines are the rows of :class:`~jointid.identify.broadband.BroadbandForceStateMapping`
    with the inertia column and the noise weights of the common library (the union of the
    candidates' terms) fitted to that record alone; the rows are divided by that fit's
    residual standard deviation, so that a candidate's residual sum is a chi-square in the
    units of each record's own noise level (the common library holds every candidate).
    Candidates are fitted to all records in these rows (``AIC``, ``BIC`` with ``nu`` the
    number of rows) and, leaving one level out, to the other levels: the cross-validation
    score is the held-out level's chi-square per row (about 1 when the model explains it).
    The pick is as in :func:`select_model`.

    Parameters
    ----------
    states_list : sequence of BroadbandStates
        Periodic records (one or more per level).
    levels : sequence
        Level of each record.
    candidates : sequence, optional
        Term strings or :class:`Candidate` objects without amplitude laws; default
        :func:`broadband_candidates`.
    """
    from .broadband import BroadbandForceStateMapping

    if criterion not in ("aic", "bic"):
        raise IdentificationError(f"criterion must be 'aic' or 'bic', got {criterion!r}")
    cands = broadband_candidates() if candidates is None else _candidates(candidates, 0)
    if any(c.amplitude_laws for c in cands):
        raise IdentificationError("broadband candidates take no amplitude laws")
    states_list, levels = list(states_list), list(levels)
    if len(levels) != len(states_list):
        raise IdentificationError(f"{len(levels)} levels given for {len(states_list)} records")
    terms = {}
    for c in cands:
        for t in c.library:
            terms.setdefault(t.name, t)
    common = library(list(terms.values()))
    rows = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", JointidWarning)
        for s in states_list:
            est = BroadbandForceStateMapping(common, fit_inertia=True, weighting="noise")
            est.fit(s)
            w = est._noise_weights(common, s, est.coef_)
            A, b = est._rows(common, s, w)
            res = lstsq_from_reduced(A, b, A.shape[0])
            sigma = np.sqrt(res.rss / max(A.shape[0] - A.shape[1], 1))
            rows.append((A / sigma, b / sigma))
    lv = _unique_levels(levels)
    n_rows = sum(a.shape[0] for a, _ in rows)
    scores = []
    for c in cands:
        cols = [0] + [1 + common.index(t.name) for t in c.library]
        names = ("m",) + c.library.coefficient_names

        def fit(idx):
            A = np.vstack([rows[i][0][:, cols] for i in idx])
            b = np.concatenate([rows[i][1] for i in idx])
            r = lstsq_from_reduced(A, b, A.shape[0])
            return r.coefficients, A, r.condition_number

        theta, A, cond = fit(range(len(rows)))
        chi2 = float(np.sum((A @ theta - np.concatenate([r[1] for r in rows])) ** 2))
        from .uncertainty import scaled_inverse

        se = np.sqrt(np.clip(np.diag(scaled_inverse(A.T @ A)), 0.0, None))
        unresolved = tuple(n for n, t, v, e in zip(names[1:], c.library, theta[1:], se[1:])
                           if t.name not in ("q", "q'") and not abs(v) > RESOLVED_T * e)
        cv = []
        if len(lv) >= 2:
            for L in lv:
                test = [i for i, x in enumerate(levels) if x == L]
                th, _, _ = fit([i for i, x in enumerate(levels) if x != L])
                r2 = sum(float(np.sum((rows[i][0][:, cols] @ th - rows[i][1]) ** 2)) for i in test)
                cv.append(r2 / sum(rows[i][0].shape[0] for i in test))
        P = len(cols)
        cvf = float(np.mean(cv)) if cv else float("nan")
        cvse = float(np.std(cv, ddof=1) / np.sqrt(len(cv))) if len(cv) > 1 else float("nan")
        scores.append(CandidateScore(c, names, theta, se, chi2, n_rows - P, chi2 + 2.0 * P,
                                     chi2 + P * math.log(n_rows), cvf, cvse, unresolved=unresolved,
                                     condition_number=float(cond)))
    scores = sorted(scores, key=lambda s: (getattr(s, criterion), s.n_parameters))
    return SelectionResult(preload, tuple(scores), _pick(scores, criterion, delta), criterion, float(delta),
                           tuple(lv), common.names, 1.0, float(n_rows), None, "broadband", len(states_list))
