"""Prediction with the hysteretic joint law that ``identify --terms auto`` selected.

When a preload's model selection (``selection[*]`` of the results) picked a hysteretic joint
law (Jenkins, four-parameter Iwan), its ``hysteretic_model`` holds the law fitted to all the
preload's records: ``k``, ``c`` and the law's parameters with their covariance.  The
single-mode model

``q'' + c q' + k q + f_joint(q) = Q sin(omega t)``

is then solved with that law itself (not the polynomial stand-in of ``models``) by the
multi-mode harmonic balance condensed on the joint coordinates
(:class:`jointid.simulate.structure_hb.CondensedHB`) with one mode: natural frequency
``sqrt(k + K0)`` with the joint stuck (``K0`` its initial stiffness: ``kt`` or ``K_T``),
damping ratio ``c / (2 sqrt(k + K0))``, the joint acting on the modal coordinate with ``K0``
given as the stiffness already in the linear model.  The joint force over a period is the
law's ``aft`` with its exact Jacobian; the curve is continued through the folds.

``q_max`` is ``max_t |q(t)|`` of each steady state (to machine precision); the peak is
located between the continued points as for the polynomial models
(:func:`jointid.app.predict.predict_peak`), then refined: steady states across the band where
``q_max`` is within ``PEAK_BAND`` of the peak, solved again at the fine time samples, and the
maximum of a quartic fitted through them (:func:`_band_peak`; a parabola through close points
followed the sampled force's phase-dependent error, ~1e-4 of the peak frequency).
Stability is read from the folds: on a single-mode forced response the branch between two
folds is the unstable one (saddle-node turning points), the rest stable (Hill's method with
slider laws is not yet checked).  The steady state at the peak is checked by a time integration
(:func:`time_check`).

Standard errors of the peak: the law's parameter covariance (``hysteretic_model.covariance``
over the independent parameters ``k, c, kt, Fs`` or ``k, c, K_T, F_S, chi, beta``)
propagated linearly, the derivatives by central differences over one standard error
(one-sided where the other side leaves the law's domain), each perturbed model solved at the
nominal curve's points about its peak.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

from ..errors import ConvergenceError, JointidError, JointidWarning, RecordError
from ..joints import ExactReversals, Iwan4, Jenkins
from ..numerics.aft import aft_samples

__all__ = ["ExactReversals", "HystereticModel", "hysteretic_model_of", "hysteretic_models", "hysteretic_response"]

#: Independent parameters of each law in the fit's ``names`` (the others are functions of them).
INDEPENDENT = {"jenkins": ("k", "c", "kt", "Fs"), "iwan4": ("k", "c", "K_T", "F_S", "chi", "beta")}
LAW_TEXT = {"jenkins": "Jenkins joint law", "iwan4": "four-parameter Iwan joint law"}


def _time_samples(n_harmonics, fine=False) -> int:
    """AFT samples per period: of the continued curve, or (``fine``) of the points about the peak.

    With the reversals at the exact extrema (:class:`ExactReversals`) the sampled force is
    exact at the samples, but its projection on the harmonics still aliases the kinks of
    stick-slip (Jenkins, H = 5, Q = 14, peak frequency: -0.13 % at 64 samples, -0.056 % at
    128, -0.018 % at 256, about 1e-5 relative at 512 against 1024), so the curve is continued
    at ``16 (H + 1)`` samples and the points about its peak are solved again at ``64 (H + 1)``
    (powers of two).
    """
    return aft_samples(n_harmonics, 64 if fine else 16)


@dataclass(frozen=True)
class HystereticModel:
    """``q'' + c q' + k q + f_joint(q)``: the selected law's single-mode model (modal units per unit mass)."""

    law_name: str
    names: tuple
    values: np.ndarray
    covariance: np.ndarray
    n_sliders: int = 60
    phi_min_ratio: float = 1e-4

    def get(self, name, values=None) -> float:
        v = self.values if values is None else values
        return float(v[self.names.index(name)])

    def law(self, values=None):
        g = (lambda n: self.get(n, values))
        if self.law_name == "jenkins":
            return Jenkins(g("kt"), g("Fs"))
        return Iwan4(g("F_S"), g("K_T"), g("chi"), g("beta"), n_sliders=self.n_sliders,
                     phi_min_ratio=self.phi_min_ratio)

    def stiffness0(self, values=None) -> float:
        """Joint's stiffness when stuck."""
        return self.get("kt" if self.law_name == "jenkins" else "K_T", values)

    def engine(self, values=None):
        """The one-mode :class:`~jointid.simulate.structure_hb.CondensedHB` of these parameters."""
        from ..simulate.structure_hb import CondensedHB

        k, c, k0 = self.get("k", values), self.get("c", values), self.stiffness0(values)
        if not (k + k0 > 0 and c >= 0):
            raise JointidError(f"{self.law_name}: k + {('kt' if self.law_name == 'jenkins' else 'K_T')} = "
                               f"{k + k0:.4g} and c = {c:.4g}: no positive stiffness and non-negative damping")
        w0 = math.sqrt(k + k0)
        return CondensedHB([w0], [c / (2 * w0)], [[1.0]], [1.0], [ExactReversals(self.law(values))], k_model=k0)

    @property
    def f1_hz(self) -> float:
        return math.sqrt(max(self.get("k") + self.stiffness0(), 0.0)) / (2 * np.pi)

    def summary(self, n_harmonics=None) -> dict:
        out = {"law": self.law_name, "parameters": {n: float(v) for n, v in zip(self.names, self.values)},
               "n_sliders": self.n_sliders if self.law_name == "iwan4" else None,
               "phi_min_ratio": self.phi_min_ratio if self.law_name == "iwan4" else None}
        if n_harmonics is not None:
            out.update(n_time_curve=_time_samples(n_harmonics), n_time_peak=_time_samples(n_harmonics, fine=True),
                       reversals="at the exact extrema of the motion")
        return out


def hysteretic_model_of(summary, source="results.json") -> HystereticModel:
    """The :class:`HystereticModel` of a selection's ``hysteretic_model`` summary.

    Raises
    ------
    RecordError
        A summary that does not hold together (naming ``source``).
    """
    try:
        name = summary["law"]
        pars = summary["parameters"]
        names = tuple(pars)
        values = np.array([float(pars[n]) for n in names])
        cov = summary.get("covariance")
        cov = (np.full((len(names), len(names)), np.nan) if cov is None
               else np.array([[np.nan if x is None else float(x) for x in row] for row in cov], float))
        derived = ((summary.get("joint_law") or {}).get("derived") or {})
        model = HystereticModel(name, names, values, cov, int(derived.get("n_sliders", 60)),
                                float(derived.get("phi_min_ratio", 1e-4)))
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise RecordError(f"{source}: selection hysteretic_model: not a fitted joint law ({exc!r})") from None
    if name not in INDEPENDENT or not set(INDEPENDENT[name]) <= set(names):
        raise RecordError(f"{source}: selection hysteretic_model: law {name!r} with parameters {list(names)} is not "
                          f"one predict can solve (expected {sorted(INDEPENDENT)})")
    if cov.shape != (len(names), len(names)):
        raise RecordError(f"{source}: selection hysteretic_model: covariance of shape {cov.shape} for "
                          f"{len(names)} parameters")
    if not np.all(np.isfinite(values)):
        raise RecordError(f"{source}: selection hysteretic_model: parameters not finite: {list(values)}")
    return model


def hysteretic_models(results, source="results.json") -> dict:
    """``{preload: HystereticModel}`` of the preloads whose selection picked a hysteretic law."""
    out = {}
    for s in results.get("selection") or []:
        if isinstance(s, dict) and isinstance(s.get("hysteretic_model"), dict):
            out[s.get("preload")] = hysteretic_model_of(s["hysteretic_model"], source)
    return out


# --- the curve -------------------------------------------------------------------------------------

class _Curve:
    """A continued curve of the condensed engine in the form :func:`jointid.app.predict.predict_peak` reads."""

    def __init__(self, hb_curve):
        from ..signal.harmonics import series_max_abs

        self.points = hb_curve.points
        self.omega = np.array([p.omega for p in self.points])
        self.q_max = np.array([series_max_abs(p.joint[0]) for p in self.points])
        self.folds = tuple(hb_curve.folds)

    def __len__(self):
        return len(self.points)

    @property
    def stable(self):
        """Unstable between each pair of successive folds (the middle branch of a single-mode response)."""
        st = np.ones(len(self), bool)
        f = list(self.folds)
        for a, b in zip(f[0::2], f[1::2]):
            st[a + 1:b] = False
        return st


def _continue(model, Q, n_harmonics, values=None):
    """``(engine, curve)``: ``curve(lo_hz, hi_hz)`` continues the response at the curve's time samples."""
    from .predict_peaks import DS_MAX

    engine = model.engine(values)
    N = _time_samples(n_harmonics)

    def curve(lo, hi):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", JointidWarning)
            with np.errstate(all="ignore"):
                return _Curve(engine.continuation(2 * np.pi * lo, 2 * np.pi * hi, [0.0, 0.0, Q], n_harmonics,
                                                  n_time=N, ds_max=DS_MAX, max_steps=200_000))
    return engine, curve


def _solve_at(engine, Q, omegas, guesses, n_harmonics, n_time=None):
    """Steady states of ``engine`` at ``omegas`` at the fine time samples (or ``n_time``), each from its guess;
    ``None`` when one fails or leaves the branch of its guess (``q_max`` off by 5 %)."""
    from ..signal.harmonics import series_max_abs

    N = _time_samples(n_harmonics, fine=True) if n_time is None else int(n_time)
    out, q = [], []
    for w, g in zip(omegas, guesses):
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", JointidWarning)
                new = engine.solve(float(w), [0.0, 0.0, Q], n_harmonics, n_time=N, guess=g, tol=1e-11)
        except (ConvergenceError, FloatingPointError, np.linalg.LinAlgError):
            return None
        qn = series_max_abs(new.joint[0])
        if not abs(qn / series_max_abs(g.joint[0]) - 1.0) < 0.05:
            return None
        out.append(new)
        q.append(qn)
    return out, np.asarray(q)


def _peak_on(engine, Q, points, n_harmonics, max_shifts=4):
    """Peak ``(frequency_hz, q_max, index)`` of ``engine`` on the evenly spaced frequencies of ``points`` (each
    the guess of its own steady state), or ``None`` (a point failed or left its branch).  When the largest
    point is an end, the frequencies are shifted along the same lattice (whole steps) until it is inside,
    so that every model's peak is located on the same grid."""
    from .predict_peaks import _located_peak

    w = np.array([p.omega for p in points])
    guesses = list(points)
    step = (w[-1] - w[0]) / (w.size - 1)
    for _ in range(max_shifts + 1):
        got = _solve_at(engine, Q, w, guesses, n_harmonics)
        if got is None:
            return None
        sol, q = got
        k = int(np.argmax(q))
        if 0 < k < w.size - 1:
            return _located_peak(w, q)
        w = w + (k - (w.size - 1) // 2) * step
        guesses = [sol[int(np.argmin(np.abs(np.array([p.omega for p in sol]) - x)))] for x in w]
    return None


def _refined_points(engine, Q, points, n_harmonics):
    """Seven steady states at the fine time samples, evenly about the peak (a quarter of the curve's local
    spacing apart), so that the peak's parabola is centred: the curve's points about its peak are solved
    again at the fine samples, the peak located on them, seven points placed about it and shifted along
    their lattice until the largest is the middle one.  ``None`` on failure."""
    from .predict_peaks import _located_peak

    got = _solve_at(engine, Q, [p.omega for p in points], points, n_harmonics)
    if got is None:
        return None
    sol, q = got
    w = np.array([p.omega for p in sol])
    k = int(np.argmax(q))
    if k in (0, w.size - 1):
        return None
    f_star = _located_peak(w, q)[0]
    h = 0.125 * abs(w[k + 1] - w[k - 1])
    ws = 2 * np.pi * f_star + h * np.arange(-3, 4)
    guesses = [sol[int(np.argmin(np.abs(w - x)))] for x in ws]
    for _ in range(5):
        got = _solve_at(engine, Q, ws, guesses, n_harmonics)
        if got is None:
            return None
        sol, q = got
        k = int(np.argmax(q))
        if k == 3:
            return sol
        ws = ws + (k - 3) * h
        guesses = [sol[int(np.argmin(np.abs(np.array([p.omega for p in sol]) - x)))] for x in ws]
    return None


def _points_about(curve, i):
    return curve.points[max(i - 3, 0):min(i + 4, len(curve))]


#: The band of the peak's fit: where the continued curve's ``q_max`` is within this fraction of its largest.
PEAK_BAND = 0.003
#: Steady states solved across that band at the fine time samples.
PEAK_POINTS = 17


def _band_about(curve, i):
    """``(omegas, guesses)``: ``PEAK_POINTS`` frequencies evenly across the band about the curve's peak ``i``
    where ``q_max >= (1 - PEAK_BAND) q_max[i]`` (to the first points below it), each with the nearest curve
    point as its guess; ``None`` when the band reaches an end of the curve or holds a fold."""
    q, w = np.asarray(curve.q_max, float), np.asarray(curve.omega, float)
    floor = (1.0 - PEAK_BAND) * q[i]
    lo, hi = i, i
    while lo > 0 and q[lo] >= floor:
        lo -= 1
    while hi < q.size - 1 and q[hi] >= floor:
        hi += 1
    if q[lo] >= floor or q[hi] >= floor or np.any(np.diff(w[lo:hi + 1]) <= 0):
        return None
    ws = np.linspace(w[lo], w[hi], PEAK_POINTS)
    return ws, [curve.points[lo + int(np.argmin(np.abs(w[lo:hi + 1] - x)))] for x in ws]


def _band_peak(engine, Q, omegas, guesses, n_harmonics, n_time=None):
    """``(frequency_hz, q_max, solutions)``: the peak of a least-squares quartic in frequency through the steady
    states at ``omegas`` (the fine time samples, or ``n_time`` per period), or ``None`` (a point failed, or the
    quartic has no maximum inside).

    Why a fit across the band and not a parabola through the largest points: the sampled projection of a
    slider law's kinked force errs by ``O(N^-2)`` in ``q_max``, oscillating with the motion's phase against the
    sample grid, which turns through resonance; over a few 1e-4 of frequency that is a slope error which moves
    a parabola through close points by ~1e-4 of the peak frequency (Jenkins, 512 samples; tens of its
    standard errors).  Across the band the oscillation averages out: the quartic's peak frequency agrees with
    the one of 2048 samples and with a time integration to a few 1e-6.
    """
    got = _solve_at(engine, Q, omegas, guesses, n_harmonics, n_time)
    if got is None:
        return None
    sol, q = got
    w = np.asarray(omegas, float)
    wc, hw = 0.5 * (w[0] + w[-1]), 0.5 * (w[-1] - w[0])
    c = np.polyfit((w - wc) / hw, q, 4)
    r = np.roots(np.polyder(c))
    r = r[(np.abs(r.imag) < 1e-9) & (np.abs(r.real) < 1.0)].real
    if r.size == 0:
        return None
    x = r[int(np.argmax(np.polyval(c, r)))]
    qp = float(np.polyval(c, x))
    if not (qp > np.polyval(c, -1.0) and qp > np.polyval(c, 1.0) and np.polyval(np.polyder(c, 2), x) < 0):
        return None
    return float((wc + x * hw) / (2 * np.pi)), qp, sol


def _peak_stderr(model, Q, n_harmonics, curve, peak, span, refined, band=None):
    """``(se_frequency_hz, se_q_max, note)`` from the law's covariance (delta method); ``peak`` is the
    curve's, ``refined`` the nominal points about it at the fine time samples (or ``None``): each
    perturbed model is solved on them, the same points for every model.  With ``band`` (``(omegas,
    nominal solutions)`` of :func:`_band_peak`) each perturbed model's peak is the band fit on the same
    frequencies instead."""
    from .predict_peaks import predict_peak

    idx = [model.names.index(n) for n in INDEPENDENT[model.law_name]]
    C = model.covariance[np.ix_(idx, idx)]
    if not np.all(np.isfinite(C)):
        return float("nan"), float("nan"), "the joint law's covariance holds undefined entries: no standard error"
    se = np.sqrt(np.clip(np.diag(C), 0.0, None))
    if band is not None:
        base = _band_peak(model.engine(), Q, band[0], band[1], n_harmonics)
    else:
        base = None if refined is None else _peak_on(model.engine(), Q, refined, n_harmonics)
    J = np.zeros((2, len(idx)))

    def peak_of(values):
        try:
            engine = model.engine(values)
        except (JointidError, ValueError):
            return None, None  # outside the law's domain
        if base is None:
            pk = None
        elif band is not None:
            pk = _band_peak(engine, Q, band[0], base[2], n_harmonics)
        else:
            pk = _peak_on(engine, Q, refined, n_harmonics)
        if pk is not None:
            return np.asarray(pk[:2]) - np.asarray(base[:2]), True
        _, fresh = _continue(model, Q, n_harmonics, values)
        _, pk, _ = predict_peak(None, Q, span, n_harmonics, widen=False, curve=fresh, f1_hz=model.f1_hz)
        return (None, False) if pk is None else (np.asarray(pk[:2]) - np.asarray(peak[:2]), True)

    for j, k in enumerate(idx):
        if not se[j] > 0:
            continue
        d = {}
        for sign in (1.0, -1.0):
            v = model.values.copy()
            v[k] += sign * se[j]
            d[sign], ok = peak_of(v)
            if ok is False:
                return float("nan"), float("nan"), (f"the peak leaves the band when {model.names[k]} moves by one "
                                                    "standard error: no standard error")
        if d[1.0] is not None and d[-1.0] is not None:
            J[:, j] = (d[1.0] - d[-1.0]) / (2 * se[j])
        elif d[1.0] is not None or d[-1.0] is not None:  # one side leaves the law's domain (beta >= 0, |chi| < 1)
            sign = 1.0 if d[1.0] is not None else -1.0
            J[:, j] = sign * d[sign] / se[j]
    V = J @ C @ J.T
    return float(math.sqrt(max(V[0, 0], 0.0))), float(math.sqrt(max(V[1, 1], 0.0))), None


#: Relative difference of ``q_max`` between the harmonic balance and the time integration at the peak above
#: which the prediction warns (as for the polynomial models).
TIME_CHECK_RTOL = 1e-3


def time_check(model: HystereticModel, Q, point, steps=60, periods=40, rtol=1e-9) -> dict:
    """The steady state ``point`` of the harmonic balance integrated in time: its ``q_max`` against the one of
    the last of ``periods`` periods of the structure integrator
    (:func:`jointid.simulate.structure_timeint.integrate_from_point`: DOP853, largest step ``T / steps``) on
    the model's one-mode structure, ``q'' + c q' + k q + f_joint(q) = Q sin(omega t)``, started from the
    point's ``q(0)``, ``q'(0)`` and the slider state its motion leaves; the slider state is held over each
    step and updated at its end and at the reversals inside a step (the play operator, exact).  Independent
    of the harmonic balance: no truncation to harmonics, no AFT.  ``q_max`` of the last period from its
    first 63 harmonics; ``relative_difference_fundamental`` compares the fundamentals."""
    from ..signal.harmonics import series_max_abs
    from ..simulate.structure_timeint import integrate_from_point

    w = float(point.omega)
    out = {"frequency_hz": w / (2 * np.pi), "q_max_harmonic_balance": float(series_max_abs(point.joint[0]))}
    try:
        r = integrate_from_point(model.engine(), point, periods, steps, n_harmonics=63, rtol=rtol,
                                 atol=1e-3 * rtol * out["q_max_harmonic_balance"])
    except (ConvergenceError, FloatingPointError, ValueError) as exc:
        return {**out, "q_max_time_integration": None, "relative_difference": None, "error": str(exc)}
    qt = float(series_max_abs(r.modal[0]))
    return {**out, "q_max_time_integration": qt, "relative_difference": qt / out["q_max_harmonic_balance"] - 1.0,
            "error": None, "steps_per_period": int(steps), "periods": int(periods),
            "relative_difference_fundamental": r.relative_difference, "method": "DOP853, play operator at reversals",
            "n_steps": r.n_steps, "cost_s": r.cost_s}


def hysteretic_response(model: HystereticModel, Q, span_hz, n_harmonics=5, *, widen=True, uncertainty=True) -> dict:
    """The selected law's response at modal force ``Q``: the continued curve over ``span_hz`` (widened to the
    peak when ``widen``), its peak re-solved at the fine time samples, and its standard errors.

    Returns a dict: ``frequency_hz``, ``q_max``, ``stable`` (arrays along the curve), ``folds_hz``,
    ``peak`` (``(frequency_hz, q_max)`` or ``None``), ``stderr`` (two floats, ``nan`` when not
    available), ``span`` (the band used), ``time_check`` (:func:`time_check` of the peak's point),
    ``notes`` and, when the peak is the band fit (:func:`_band_peak`), ``peak_band``: its frequencies
    [rad/s] and steady states.
    """
    from .predict_peaks import predict_peak

    _, curve = _continue(model, Q, n_harmonics)
    r, peak, span = predict_peak(None, Q, span_hz, n_harmonics, widen=widen, curve=curve, f1_hz=model.f1_hz)
    f_hz = r.omega / (2 * np.pi)
    notes = []
    if r.folds:  # sliders have no Hill analysis here
        notes.append("stability from the folds (the branch between two folds unstable)")
    out = {"frequency_hz": f_hz, "q_max": np.asarray(r.q_max, float), "stable": r.stable,
           "folds_hz": tuple(float(f_hz[i]) for i in r.folds), "peak": None,
           "stderr": (float("nan"), float("nan")), "span": tuple(float(v) for v in span), "notes": notes,
           "time_check": None}
    if peak is None:
        notes.append(f"no peak in {span[0]:.6g}-{span[1]:.6g} Hz: the response still grows at the edge of the band")
        return out
    # steady states across the peak's band solved again with more time samples (see _time_samples), the peak
    # that of a quartic fitted through them (_band_peak); else the points about the peak, a parabola
    about = _band_about(r, peak[2])
    band = None if about is None else _band_peak(model.engine(), Q, about[0], about[1], n_harmonics)
    refined = fine = None
    if band is not None:
        fine = band[:2]
        out["peak_band"] = (about[0], band[2])  # the frequencies [rad/s] and steady states of the band fit
        near = band[2][int(np.argmin(np.abs(about[0] - 2 * np.pi * fine[0])))]
        got = _solve_at(model.engine(), Q, [2 * np.pi * fine[0]], [near], n_harmonics)  # the steady state at the peak
        at_peak = near if got is None else got[0][0]
    else:
        refined = _refined_points(model.engine(), Q, _points_about(r, peak[2]), n_harmonics)
        fine = None if refined is None else _peak_on(model.engine(), Q, refined, n_harmonics)
        at_peak = None if fine is None else refined[3]
        notes.append("the peak located by a parabola through close points (no fit across its band): its frequency "
                     "may be off by ~1e-4 from the sampled joint force")
    if fine is None:
        notes.append(f"the peak's points could not be solved again at {_time_samples(n_harmonics, True)} time "
                     f"samples: the peak is the curve's at {_time_samples(n_harmonics)} (about 0.05 % off)")
    out["peak"] = tuple(float(x) for x in (peak if fine is None else fine)[:2])
    check = time_check(model, Q, at_peak if fine is not None else r.points[peak[2]])
    out["time_check"] = check
    if check["error"]:
        notes.append(f"time integration from the peak's steady state failed ({check['error']})")
    elif abs(check["relative_difference"]) > TIME_CHECK_RTOL:
        notes.append(f"at the peak, time integration gives q_max {100 * check['relative_difference']:+.2g} % from "
                     f"the harmonic balance with {n_harmonics} harmonics: give more (--harmonics)")
    if uncertainty:
        try:
            sf, sq, why = _peak_stderr(model, Q, n_harmonics, r, peak, span, refined if fine else None,
                                       None if band is None else (about[0], band[2]))
        except (JointidError, ValueError, FloatingPointError, np.linalg.LinAlgError) as exc:
            sf, sq, why = float("nan"), float("nan"), f"standard error not computed: {exc}"
        out["stderr"] = (sf, sq)
        if why:
            notes.append(why)
    return out
