"""Prediction at new force levels with the model a saved identification selected (``jointid predict``).

For each preload of a ``results.json`` written by ``jointid identify``, its model (``models``:
the terms, amplitude laws, parameters and covariance fitted over all the preload's records;
with ``--terms auto`` the selected one) is solved by harmonic balance
(:func:`jointid.simulate.hbm.frequency_response`, pseudo-arclength continuation from the low
end of the band through the folds, Floquet stability of every point) at each requested
force level:

``q'' + h(q, q'; theta(q_max)) = Q sin(omega t)``,  ``Q = s F``

where ``F`` is the force level in the units of the campaign's ``force_level`` and ``s`` the
modal force per unit of force level that identify's re-prediction used for the measured
levels (``reprediction.groups[*].forcing / force_level``; the mode shape at the force
point in a physical campaign, the identified gain with an unknown force gain).

A hysteretic joint law
    When ``--terms auto`` picked a hysteretic law (``selection[*].hysteretic_model``: Jenkins
    or four-parameter Iwan, fitted to the records' loops), that law is solved instead of the
    polynomial stand-in in ``models``: ``q'' + c q' + k q + f_joint(q) = Q sin(omega t)`` by the
    harmonic balance of :class:`jointid.simulate.structure_hb.CondensedHB` with one mode
    (:mod:`jointid.app.predict_hysteretic`), its standard errors from the law's covariance.
    Each prediction's ``joint_law`` names the restoring force solved (``"polynomial"``,
    ``"jenkins"``, ``"iwan4"``) and ``joint_law_model`` holds the law's parameters.

The peak
    ``peak_q_max`` is the largest ``q_max`` on the curve continued from below resonance
    (through the folds of a softening or hardening resonance it is the top of the upper
    branch), ``peak_frequency_hz`` its frequency.  It is located between the computed
    points: ``q_max`` and ``omega`` are interpolated by parabolas in the chord length of the
    curve through the largest point and its two neighbours, and the largest value of the
    ``q_max`` parabola is taken (the continuation's step is small enough for this to be
    about 1e-6 of the value).  When the largest point is an end of the band the band is
    widened on that side (only when no ``--frequency-range`` was given) until the peak is
    inside it; otherwise the prediction says "no peak in the band".

Uncertainty
    The standard errors of the peak come from the model's covariance by linear propagation
    (``J C J^T``) with ``J`` the central differences of the peak over one standard error of
    each parameter; the 95 % interval is ``value +- 1.96 se``.

Flags
    ``extrapolated``: the force level lies outside the range of the force levels the model
    was fitted on; ``amplitude_beyond_fitted``: the peak amplitude lies outside the model's
    ``q_max_range`` (its amplitude laws are extrapolated); a damping coefficient that is
    zero or negative at the peak amplitude is a warning.  A prediction that fails (no
    steady state) is reported with its error and the others go on.

Time-integration check
    The computed curve point at the peak is solved again by shooting on a time integration
    (:func:`jointid.simulate.timeint.periodic_orbit`, independent of the harmonic balance):
    ``time_integration_check`` holds both ``q_max``; a difference above 0.1 % is a warning
    to give more harmonics.

Measured dwells
    At a force level the model was fitted on, the measured dwells of that level (from the
    re-prediction in the results) are carried along as fundamental amplitudes
    ``|q''_1| / omega^2`` and drawn over the curve.
"""

from __future__ import annotations

import html
import json
import math
import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..errors import (
    JointidError,
    JointidWarning,
    ManifestError,
    RecordError,
    RecordFileNotFoundError,
)
from ..numerics.intervals import Z95
from .predict_peaks import (  # noqa: F401 (here before)
    DS_MAX,
    MAX_WIDEN,
    WIDEST,
    _curve,
    _located_peak,
    predict_peak,
)

__all__ = [
    "PredictResult",
    "Prediction",
    "fitted_force_levels",
    "force_level_unit",
    "force_scaling",
    "load_results",
    "measured_dwells",
    "model_of_entry",
    "parse_force_levels",
    "predict_from_results",
    "predict_level",
    "predict_peak",
    "usable_models",
    "write_predictions",
]


def _shown(v) -> str:
    r = repr(v)
    return r if len(r) <= 60 else r[:57] + "..."


def load_results(path):
    """Parse a ``results.json`` of ``jointid identify`` (or its folder) and check its models.

    Returns ``(results, file)``.

    Raises
    ------
    RecordFileNotFoundError
        No such file, or a folder without ``results.json``.
    RecordError, ManifestError
        Not JSON, not a results.json of identify, or a ``models`` entry that does not hold
        together (naming the file and the JSON path).
    """
    from .backbones import check_results_for_backbones

    path = Path(path)
    file = path / "results.json" if path.is_dir() else path
    if not file.is_file():
        what = f"{path}: a folder without results.json" if path.is_dir() else f"{path}: no such file or folder"
        raise RecordFileNotFoundError(f"{what}; give the output folder of jointid identify or its results.json")
    try:
        results = json.loads(file.read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError) as exc:
        raise RecordError(f"{file}: not a readable results.json ({str(exc)[:120]})") from None
    if isinstance(results, dict) and "models" not in results:
        results = _identifications(results)
    if not isinstance(results, dict) or "models" not in results:
        raise RecordError(f"{file}: not a results.json of jointid identify or demo (a JSON object with 'models' "
                          "or 'preloads' expected)")
    check_results_for_backbones(results, str(file))
    return results, file


def _identifications(results):
    """The demo's results.json (``preloads[*].identification``, one identify summary per preload)
    as one identify summary; anything else is returned as it is."""
    pre = results.get("preloads")
    if not (isinstance(pre, list) and pre and all(isinstance(e, dict) and isinstance(e.get("identification"), dict)
                                                   for e in pre)):
        return results
    merged = {"models": [], "groups": [], "reprediction": {"groups": []}, "run_id": results.get("run_id")}
    for e in pre:
        ident = e["identification"]
        for key in ("models", "groups"):
            part = ident.get(key)
            merged[key] += part if isinstance(part, list) else []
        rep = ident.get("reprediction")
        if isinstance(rep, dict) and isinstance(rep.get("groups"), list):
            merged["reprediction"]["groups"] += rep["groups"]
    units = {e["identification"].get("force_level_unit") for e in pre}
    merged["force_level_unit"] = units.pop() if len(units) == 1 else None  # the preloads disagree: none
    return merged


def force_level_unit(results):
    """The unit of the force levels identify wrote (``force_level_unit``: ``"N"``, ``"V"``), or ``None``
    (labels, or a results.json written before the key existed)."""
    u = results.get("force_level_unit") if isinstance(results, dict) else None
    return u if isinstance(u, str) and u.strip() else None


def parse_force_levels(text, source="--force-levels") -> tuple:
    """``"1.5, 3, 6"`` (or a sequence of numbers) -> ``(1.5, 3.0, 6.0)``: finite, positive, at least one.

    Raises
    ------
    ManifestError
        Naming ``source`` and the bad entry.
    """
    if isinstance(text, str):
        parts = [p.strip() for p in text.split(",")]
        if not any(parts):
            raise ManifestError(f"{source}: no force level given (expected e.g. 1.5,3,6)")
        values = []
        for p in parts:
            try:
                values.append(float(p))
            except ValueError:
                raise ManifestError(f"{source}: {p!r} is not a number (expected e.g. 1.5,3,6)") from None
    else:
        values = [float(v) for v in text]
        if not values:
            raise ManifestError(f"{source}: no force level given")
    for v in values:
        if not (math.isfinite(v) and v > 0):
            raise ManifestError(f"{source}: force levels must be finite and positive, got {v:g}")
    return tuple(dict.fromkeys(values))


def usable_models(results, source="results.json") -> tuple:
    """``(usable, skipped)``: the ``models`` entries a prediction can solve (terms with the
    linear stiffness ``q`` and finite parameters), and ``{preload: reason}`` for the others."""
    from ..identify.terms import library

    usable, skipped = [], {}
    for m in results.get("models") or []:
        p = m.get("preload")
        if m.get("parameters") is None:
            skipped[p] = m.get("error") or "not identified"
        elif "terms" not in m:
            skipped[p] = "a first-harmonic model (a backbone, no restoring-force terms to solve)"
        elif "q" not in library(m["terms"]).names:
            skipped[p] = "no linear stiffness term 'q'"
        elif (w2 := _constant_stiffness(m)) is not None and not w2 > 0:
            skipped[p] = (f"omega1^2 = {w2:.4g} 1/s^2 <= 0: the model has no oscillation to predict (a statically "
                          "unstable or free structure)")
        else:
            usable.append(m)
    return usable, skipped


def _constant_stiffness(entry):
    """The coefficient of ``q`` (``omega1^2``) of a ``models`` entry when it is a constant, else None."""
    from ..identify.model import law_size

    lib, orders = _orders(entry)
    i = 0
    for t, order in zip(lib, orders):
        if t.name == "q":
            return float(entry["parameters"][i]) if law_size(order) == 1 else None
        i += law_size(order)
    return None


def _orders(entry):
    from ..identify.terms import library

    lib = library(entry["terms"])
    laws = {lib[k].coefficient: (v if isinstance(v, str) else int(v))
            for k, v in (entry.get("amplitude_laws") or {}).items()}
    return lib, [laws.get(t.coefficient, 0) for t in lib]


def model_of_entry(entry, theta=None):
    """The :class:`~jointid.simulate.model.SingleModeModel` of a ``models`` entry (parameters ``theta``
    in its ``parameters`` order instead of the fitted ones when given)."""
    from .heldout_scoring import single_mode_model

    lib, orders = _orders(entry)
    theta = np.asarray(entry["parameters"] if theta is None else theta, float)
    # the parameters run term by term, an amplitude law's coefficients in place of its term's value
    return single_mode_model(lib, orders, theta)


def _numeric(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def fitted_force_levels(results, preload) -> tuple:
    """The numeric force levels of the preload's groups that entered its fits, sorted."""
    levels = {float(g["force_level"]) for g in results.get("groups") or []
              if isinstance(g, dict) and g.get("preload") == preload and _numeric(g.get("force_level"))
              and g.get("pooled") is not None}
    return tuple(sorted(levels))


def force_scaling(results, preload) -> dict:
    """Modal force per unit of force level of a preload, from identify's re-prediction.

    Returns ``{"modal_force_per_unit", "source", "n_levels", "spread"}``; ``spread`` is the
    largest relative difference of the groups' ratios from their median.  Without a
    re-prediction in the results the force level is taken as the modal force (1.0).
    """
    ratios = []
    for g in ((results.get("reprediction") or {}).get("groups") or []):
        if not isinstance(g, dict) or g.get("preload") != preload:
            continue
        F, Q = g.get("force_level"), g.get("forcing")
        if _numeric(F) and _numeric(Q) and F > 0 and Q > 0:
            ratios.append(Q / F)
    if not ratios:
        return {"modal_force_per_unit": 1.0, "n_levels": 0, "spread": None,
                "source": "no re-prediction of a numeric force level in the results: the force level is taken as "
                          "the modal force"}
    s = float(np.median(ratios))
    return {"modal_force_per_unit": s, "n_levels": len(ratios),
            "spread": float(np.max(np.abs(np.asarray(ratios) / s - 1.0))),
            "source": "re-prediction of the measured levels (mean fundamental of the modal force / force level)"}


def measured_dwells(results, preload, force_level):
    """``(frequency_hz, amplitude)`` of the measured dwells of a fitted level (identify's
    re-prediction holds them as ``|q''_1| / |Q_1|``; the amplitude is ``|q''_1| / omega^2`` with
    the group's forcing), or ``None``."""
    for g in ((results.get("reprediction") or {}).get("groups") or []):
        if not (isinstance(g, dict) and g.get("preload") == preload and _numeric(g.get("force_level"))
                and abs(g["force_level"] - force_level) <= 1e-9 * abs(force_level)):
            continue
        f, H, Q = g.get("measured_frequency_hz"), g.get("measured"), g.get("forcing")
        if (g.get("quantity") != "modal acceleration / modal force" or not _numeric(Q) or not isinstance(f, list)
                or not isinstance(H, list) or len(f) != len(H) or not all(map(_numeric, f + H))):
            return None
        f = np.asarray(f, float)
        return f, np.asarray(H, float) * Q / (2 * np.pi * f) ** 2
    return None


# --- one prediction ---------------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class Prediction:
    """The predicted response of one preload's model at one force level.

    Attributes
    ----------
    preload, force_level : object, float
    modal_force : float
        ``Q`` solved for (modal force amplitude).
    frequency_hz, q_max, stable : ndarray
        The continued curve (order of the continuation, through the folds); ``q_max`` in the
        modal coordinate; Floquet stability of each point.
    folds_hz : tuple of float
    peak_frequency_hz, peak_q_max : float
        The peak (``nan`` when none in the band), with standard errors and 95 % intervals
        (``nan`` when not available).
    fitted_levels : tuple of float
        Force levels the model was fitted on.
    extrapolated : bool
        The force level lies outside the fitted levels' range.
    amplitude_beyond_fitted : bool
        The peak amplitude lies outside the model's fitted ``q_max`` range.
    frequency_range_hz : (float, float)
    notes : tuple of str
        Warnings of this prediction.
    error : str or None
        Why there is no prediction (then the arrays are empty).
    joint_law : str
        ``"polynomial"`` (the model's terms) or the hysteretic law solved (``"jenkins"``, ``"iwan4"``,
        :mod:`jointid.app.predict_hysteretic`), with its parameters in ``joint_law_summary``.
    """

    preload: object
    force_level: float
    modal_force: float
    frequency_hz: np.ndarray
    q_max: np.ndarray
    stable: np.ndarray
    folds_hz: tuple = ()
    peak_frequency_hz: float = float("nan")
    peak_q_max: float = float("nan")
    peak_frequency_hz_stderr: float = float("nan")
    peak_q_max_stderr: float = float("nan")
    fitted_levels: tuple = ()
    extrapolated: bool = False
    amplitude_beyond_fitted: bool = False
    frequency_range_hz: tuple = (float("nan"), float("nan"))
    n_harmonics: int = 5
    notes: tuple = ()
    error: str | None = None
    model: object = field(default=None, repr=False)
    measured: tuple | None = None  # (frequency_hz, fundamental amplitude) of the measured dwells at this level
    time_check: dict | None = None  # the curve point at the peak solved again by time integration (shooting)
    joint_law: str = "polynomial"  # the restoring force solved: polynomial terms, or the selected hysteretic law
    joint_law_summary: dict | None = None  # that law's parameters (a hysteretic law)
    force_level_unit: str | None = None  # "N", "V" (identify's force_level_unit), None: levels without a unit

    def __post_init__(self):
        for name in ("frequency_hz", "q_max", "stable"):
            a = np.array(getattr(self, name))
            a.setflags(write=False)
            object.__setattr__(self, name, a)

    @property
    def has_peak(self) -> bool:
        return bool(np.isfinite(self.peak_frequency_hz))

    def ci95(self, name):
        v, s = getattr(self, name), getattr(self, name + "_stderr")
        if not (np.isfinite(v) and np.isfinite(s)):
            return None
        return [float(v - Z95 * s), float(v + Z95 * s)]

    def summary(self) -> dict:
        fin = (lambda x: float(x) if x is not None and np.isfinite(x) else None)
        return {
            "preload": self.preload,
            "force_level": self.force_level,
            "force_level_unit": self.force_level_unit,
            "modal_force": self.modal_force,
            "extrapolated": self.extrapolated,
            "fitted_force_levels": list(self.fitted_levels),
            "peak_frequency_hz": fin(self.peak_frequency_hz),
            "peak_frequency_hz_stderr": fin(self.peak_frequency_hz_stderr),
            "peak_frequency_hz_ci95": self.ci95("peak_frequency_hz"),
            "peak_q_max": fin(self.peak_q_max),
            "peak_q_max_stderr": fin(self.peak_q_max_stderr),
            "peak_q_max_ci95": self.ci95("peak_q_max"),
            "peak_q_max_unit": "m (modal coordinate)",
            "amplitude_beyond_fitted": self.amplitude_beyond_fitted,
            "folds_hz": list(self.folds_hz),
            "frequency_range_hz": list(self.frequency_range_hz),
            "n_harmonics": self.n_harmonics,
            "curve": {"frequency_hz": self.frequency_hz.tolist(), "q_max": self.q_max.tolist(),
                      "stable": [bool(s) for s in self.stable]},
            "warnings": list(self.notes),
            "error": self.error,
            "time_integration_check": self.time_check,
            "joint_law": self.joint_law,
            "joint_law_model": self.joint_law_summary,
            "measured_dwells": None if self.measured is None else {
                "frequency_hz": [float(v) for v in self.measured[0]],
                "amplitude": [float(v) for v in self.measured[1]],
                "quantity": "fundamental of q at the dwell (|q''_1| / omega^2), modal"},
        }

    def report(self) -> str:
        from ..rounding import format_estimate, format_value

        head = (f"preload {format_value(self.preload)}, F = {_with_unit(self.force_level, self.force_level_unit)} "
                f"(Q = {format_value(self.modal_force)})")
        if self.joint_law != "polynomial":
            head += f" [{self.joint_law} joint law]"
        if self.error:
            return f"{head}: FAILED: {self.error}"
        if not self.has_peak:
            text = (f"{head}: no peak in {format_value(self.frequency_range_hz[0], 6)}-"
                    f"{format_value(self.frequency_range_hz[1], 6)} Hz (the response still grows at its edge)")
        else:
            def est(v, se, unit, digits):  # without a standard error: the digits the peak location supports
                return format_estimate(v, se, unit) if np.isfinite(se) else f"{format_value(v, digits)} {unit}"

            text = (f"{head}: peak {est(self.peak_frequency_hz, self.peak_frequency_hz_stderr, 'Hz', 7)}; "
                    f"q_max {est(self.peak_q_max, self.peak_q_max_stderr, 'm', 6)}")
        if self.folds_hz:
            text += f"; folds at {', '.join(format_value(f, 7) for f in self.folds_hz)} Hz"
        if self.extrapolated:
            text += "; EXTRAPOLATED (force level outside the fitted levels " + _levels_text(self.fitted_levels) + ")"
        for n in self.notes:
            if not n.startswith("extrapolat"):
                text += f"\n    warning: {n}"
        return text

    def _repr_html_(self) -> str:
        return f"<pre>{html.escape(self.report())}</pre>"

    def plot(self, ax=None, **kwargs):
        """The curve with its peak (:func:`jointid.report.predict_plots.plot_predictions`)."""
        from ..report.predict_plots import plot_predictions

        return plot_predictions([self], ax=ax, **kwargs)


def _with_unit(level, unit) -> str:
    from ..rounding import format_value

    return format_value(level) + (f" {unit}" if unit else "")


def _levels_text(levels) -> str:
    from ..rounding import format_value

    if not levels:
        return "(none numeric)"
    return f"{format_value(min(levels))}-{format_value(max(levels))}" if len(levels) > 1 else format_value(levels[0])


def _peak_near(model, Q, states, n_harmonics):
    """The peak of ``model`` from its steady states at the frequencies of ``states`` (the nominal
    curve's points about its peak, each the Newton guess of its own point), or ``None`` when a
    point leaves its branch (a fold moved past it) or the largest point is no longer inside."""
    from ..errors import ConvergenceError
    from ..simulate.hbm import steady_state

    w, q = [], []
    for st in states:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", JointidWarning)
                new = steady_state(model, st.omega, Q, n_harmonics, guess=st, stability=False)
        except (ConvergenceError, FloatingPointError, np.linalg.LinAlgError):
            return None
        if not abs(new.q_max / st.q_max - 1.0) < 0.05:  # another branch
            return None
        w.append(st.omega)
        q.append(new.q_max)
    k = int(np.argmax(q))
    if k in (0, len(q) - 1):
        return None
    return _located_peak(np.asarray(w), np.asarray(q))


def _peak_stderr(entry, Q, span, n_harmonics, response, peak):
    """Standard errors of the peak frequency and amplitude from the model's covariance, or
    ``(nan, nan, note)``.

    Central differences over one standard error of each parameter; the perturbed models are
    solved at the nominal curve's frequencies about its peak (Newton from the nominal points:
    the same points for every model, so the located peaks differ smoothly), and by a whole
    continuation where a point leaves its branch.
    """
    cov = entry.get("covariance")
    if cov is None:
        return float("nan"), float("nan"), "no covariance in the results: no standard error"
    C = np.array([[np.nan if x is None else x for x in row] for row in cov], float)
    theta = np.asarray(entry["parameters"], float)
    if C.shape != (theta.size, theta.size) or not np.all(np.isfinite(C)):
        return float("nan"), float("nan"), "the covariance holds undefined entries: no standard error"
    se = np.sqrt(np.clip(np.diag(C), 0.0, None))
    i = peak[2]
    states = [response.state(j) for j in range(max(i - 3, 0), min(i + 4, len(response)))]
    base = _peak_near(model_of_entry(entry), Q, states, n_harmonics)  # the nominal peak on these points
    J = np.zeros((2, theta.size))
    for k in range(theta.size):
        if not se[k] > 0:
            continue
        vals = []
        for sign in (1.0, -1.0):
            t = theta.copy()
            t[k] += sign * se[k]
            model = model_of_entry(entry, t)
            pk = None if base is None else _peak_near(model, Q, states, n_harmonics)
            if pk is None:
                _, pk, _ = predict_peak(model, Q, span, n_harmonics, widen=False)
                pk = None if pk is None else (pk[0], pk[1], None)
                ref = peak
            else:
                ref = base
            if pk is None:
                return float("nan"), float("nan"), (f"the peak leaves the band when {entry['parameter_names'][k]} "
                                                    "moves by one standard error: no standard error")
            vals.append(np.asarray(pk[:2]) - np.asarray(ref[:2]))  # the change of the peak
        J[:, k] = (vals[0] - vals[1]) / (2 * se[k])
    V = J @ C @ J.T
    return float(np.sqrt(max(V[0, 0], 0.0))), float(np.sqrt(max(V[1, 1], 0.0))), None


#: Relative difference of q_max between harmonic balance and time integration above which the
#: harmonics are too few.
TIME_CHECK_RTOL = 1e-3


def _time_check(model, Q, state) -> dict:
    """The curve point at the peak solved again by shooting on a time integration
    (:func:`jointid.simulate.timeint.periodic_orbit`, started from the point): its ``q_max``
    against the harmonic balance's."""
    from ..simulate.timeint import periodic_orbit

    out = {"frequency_hz": float(state.omega / (2 * np.pi)), "q_max_harmonic_balance": float(state.q_max)}
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", JointidWarning)
            orbit = periodic_orbit(model, state.omega, Q, guess=state)
    except (JointidError, ValueError, FloatingPointError, np.linalg.LinAlgError) as exc:
        return {**out, "q_max_time_integration": None, "relative_difference": None, "error": str(exc)}
    return {**out, "q_max_time_integration": float(orbit.q_max),
            "relative_difference": float(orbit.q_max / state.q_max - 1.0), "error": None}


def _negative_damping(model, lib, state) -> list:
    """A note per damping term with an amplitude law that feeds energy in at this steady state
    (its coefficient is negative there and its work per cycle is more than 0.1 % of the
    dissipated energy): the law, extrapolated, is not physical there."""
    t = np.linspace(0.0, state.period, 512, endpoint=False)
    q, v = state.q(t), state.velocity(t)
    theta = np.asarray(state.theta, float)
    total = float(np.mean(lib.restoring_force(q, v, theta) * v))
    notes = []
    for j, term in enumerate(lib):
        if term.kind != "damping" or term.coefficient not in model.amplitude_laws or theta[j] >= 0:
            continue
        unit = np.zeros(theta.size)
        unit[j] = theta[j]
        work = float(np.mean(lib.restoring_force(q, v, unit) * v))
        if work < -1e-3 * abs(total):
            notes.append(f"damping coefficient {term.coefficient} = {theta[j]:.4g} < 0 at q_max = {state.q_max:.4g}: "
                         f"its term feeds in {100 * -work / abs(total):.2g} % of the energy dissipated per cycle; "
                         "the damping law is not physical there")
    return notes


def _level_setup(entry, force_level, scale, fitted_levels, frequency_range, n_harmonics, f1):
    """``(Q, span, widen, notes, base)`` of one prediction: the modal force, the band, the extrapolation
    note and the fields every :class:`Prediction` of it has."""
    F = float(force_level)
    Q = float(scale) * F
    levels = tuple(float(v) for v in fitted_levels)
    tol = 1e-9
    extrapolated = bool(levels) and not (min(levels) * (1 - tol) <= F <= max(levels) * (1 + tol))
    notes = []
    if extrapolated:
        notes.append(f"extrapolated: force level {F:g} outside the fitted levels {_levels_text(levels)}")
    elif not levels:
        notes.append("the fitted force levels are not numbers: whether this level is extrapolated is not known")
    if frequency_range is not None:
        span, widen = tuple(float(v) for v in frequency_range), False
    else:
        rng = entry.get("frequency_hz_range")
        if isinstance(rng, list) and len(rng) == 2 and all(_numeric(v) for v in rng) and rng[1] > rng[0] > 0:
            span = (float(rng[0]), float(rng[1]))
        else:
            span = (0.9 * f1, 1.1 * f1)
        widen = True
    base = {"preload": entry.get("preload"), "force_level": F, "modal_force": Q, "fitted_levels": levels,
            "extrapolated": extrapolated, "n_harmonics": int(n_harmonics)}
    return Q, span, widen, notes, base


def _beyond_fitted(entry, pq, what):
    """``(beyond, note or None)``: the peak amplitude outside the model's fitted ``q_max_range``."""
    rng = entry.get("q_max_range")
    if not (isinstance(rng, list) and len(rng) == 2 and all(_numeric(v) for v in rng)):
        return False, None
    if rng[0] * (1 - 1e-9) <= pq <= rng[1] * (1 + 1e-9):
        return False, None
    pct = 100 * (pq / rng[1] - 1)
    where = (f"{pct:.0f} % above" if pct >= 10 else f"{pct:.2g} % above")  # not "1.6e+02 %"
    where = (f"{where} the largest fitted q_max {rng[1]:.4g}" if pq > rng[1]
             else f"below the smallest fitted q_max {rng[0]:.4g}")
    return True, f"peak amplitude {pq:.4g} {where}: {what}"


def _predict_hysteretic_level(entry, model, force_level, scale, fitted_levels, frequency_range, n_harmonics,
                              uncertainty) -> Prediction:
    """:func:`predict_level` with a selected hysteretic joint law (:mod:`jointid.app.predict_hysteretic`)."""
    from .predict_hysteretic import hysteretic_response

    Q, span, widen, notes, base = _level_setup(entry, force_level, scale, fitted_levels, frequency_range,
                                               n_harmonics, model.f1_hz)
    base.update(joint_law=model.law_name, joint_law_summary=model.summary(n_harmonics))
    try:
        out = hysteretic_response(model, Q, span, n_harmonics, widen=widen, uncertainty=uncertainty)
    except (JointidError, ValueError, FloatingPointError, np.linalg.LinAlgError) as exc:
        return Prediction(frequency_hz=[], q_max=[], stable=[], frequency_range_hz=tuple(span),
                          notes=tuple(notes), error=f"no steady state: {exc}", **base)
    beyond = False
    if out["peak"] is not None:
        beyond, note = _beyond_fitted(entry, out["peak"][1], "beyond the amplitudes the joint law was fitted on")
        notes += [note] if note else []
    pf, pq = out["peak"] if out["peak"] is not None else (float("nan"), float("nan"))
    return Prediction(frequency_hz=out["frequency_hz"], q_max=out["q_max"], stable=out["stable"],
                      folds_hz=out["folds_hz"], peak_frequency_hz=pf, peak_q_max=pq,
                      peak_frequency_hz_stderr=out["stderr"][0], peak_q_max_stderr=out["stderr"][1],
                      amplitude_beyond_fitted=beyond, frequency_range_hz=out["span"], time_check=out["time_check"],
                      notes=tuple(notes + out["notes"]), **base)


def predict_level(entry, force_level, *, scale=1.0, fitted_levels=(), frequency_range=None, n_harmonics=5,
                  uncertainty=True, hysteretic=None) -> Prediction:
    """Predict one preload's response (``models`` entry ``entry``) at one force level.

    ``frequency_range`` (Hz) fixes the band; by default the model's measured band
    (``frequency_hz_range``), widened where the peak lies beyond it.  With ``hysteretic`` (a
    :class:`~jointid.app.predict_hysteretic.HystereticModel`: the preload's selected joint law)
    that law is solved instead of the entry's polynomial terms, the entry giving the band and
    the fitted amplitudes.
    """
    from ..identify.terms import library

    if hysteretic is not None:
        return _predict_hysteretic_level(entry, hysteretic, force_level, scale, fitted_levels, frequency_range,
                                         n_harmonics, uncertainty)
    f1 = float(entry.get("f1_hz") or np.sqrt(max(entry["parameters"][0], 0.0)) / (2 * np.pi))
    Q, span, widen, notes, base = _level_setup(entry, force_level, scale, fitted_levels, frequency_range,
                                               n_harmonics, f1)
    try:
        model = model_of_entry(entry)
        r, peak, span = predict_peak(model, Q, span, n_harmonics, widen=widen, stability=True)
    except (JointidError, ValueError, FloatingPointError, np.linalg.LinAlgError) as exc:
        return Prediction(frequency_hz=[], q_max=[], stable=[], frequency_range_hz=tuple(span),
                          notes=tuple(notes), error=f"no steady state: {exc}", **base)
    f_hz = r.omega / (2 * np.pi)
    stable = np.ones(len(r), bool) if r.stable is None else np.asarray(r.stable, bool)
    folds = tuple(float(f_hz[i]) for i in r.folds)
    pf = pq = sf = sq = float("nan")
    beyond = False
    if peak is None:
        notes.append(f"no peak in {span[0]:.6g}-{span[1]:.6g} Hz: the response still grows at the edge of the band")
        if len(r):
            q_end = float(np.max(r.q_max))
            for t, c in zip(library(entry["terms"]), model.coefficients_at(q_end)):
                if t.kind == "damping" and c <= 0 and t.coefficient in model.amplitude_laws:
                    notes.append(f"damping coefficient {t.coefficient} = {c:.4g} <= 0 at q_max = {q_end:.4g} on the "
                                 "curve: the damping law, extrapolated, removes no energy there")
    else:
        pf, pq, _ = peak
        beyond, note = _beyond_fitted(entry, pq, "the amplitude laws are extrapolated" if model.amplitude_laws
                                      else "beyond the amplitudes the model was fitted on")
        notes += [note] if note else []
        notes += _negative_damping(model, library(entry["terms"]), r.state(peak[2]))
        check = _time_check(model, Q, r.state(peak[2]))
        if check["error"]:
            notes.append(f"time integration finds no periodic orbit at the peak ({check['error']}): the harmonic "
                         f"balance with {n_harmonics} harmonics may be truncated (--harmonics)")
        elif abs(check["relative_difference"]) > TIME_CHECK_RTOL:
            notes.append(f"at the peak, time integration gives q_max {100 * check['relative_difference']:+.2g} % "
                         f"from the harmonic balance with {n_harmonics} harmonics: give more (--harmonics)")
        if uncertainty:
            try:
                sf, sq, why = _peak_stderr(entry, Q, span, n_harmonics, r, peak)
            except (JointidError, ValueError, FloatingPointError, np.linalg.LinAlgError) as exc:
                sf, sq, why = float("nan"), float("nan"), f"standard error not computed: {exc}"
            if why:
                notes.append(why)
    return Prediction(frequency_hz=f_hz, q_max=np.asarray(r.q_max, float), stable=stable, folds_hz=folds,
                      time_check=None if peak is None else check,
                      peak_frequency_hz=pf, peak_q_max=pq, peak_frequency_hz_stderr=sf, peak_q_max_stderr=sq,
                      amplitude_beyond_fitted=beyond, frequency_range_hz=tuple(float(v) for v in span),
                      notes=tuple(notes), model=model, **base)


# --- a whole results.json ---------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class PredictResult:
    """Predictions of every usable preload model of a results.json at the requested force levels."""

    source: str
    force_levels: tuple
    predictions: tuple
    scaling: dict
    skipped: dict
    settings: dict
    models: tuple = ()
    source_run_id: str | None = None
    force_level_unit: str | None = None  # of the force levels, from the identification (None: not known)

    @property
    def failed(self) -> list:
        return [p for p in self.predictions if p.error or not p.has_peak]

    @property
    def extrapolated(self) -> list:
        return [p for p in self.predictions if p.extrapolated]

    def summary(self) -> dict:
        from .. import __version__

        return {
            "jointid_version": __version__,
            "kind": "predict",
            "source": self.source,
            "source_run_id": self.source_run_id,
            "settings": dict(self.settings),
            "force_levels": list(self.force_levels),
            "force_level_unit": self.force_level_unit,
            "force_scaling": [{"preload": p, **s} for p, s in self.scaling.items()],
            "models": list(self.models),
            "skipped_preloads": [{"preload": p, "reason": r} for p, r in self.skipped.items()],
            "predictions": [p.summary() for p in self.predictions],
            "n_failed": len(self.failed),
            "n_extrapolated": len(self.extrapolated),
        }

    def lines(self) -> list:
        from ..rounding import format_value

        out = [f"predictions from {self.source} at force levels {', '.join(format_value(f) for f in self.force_levels)}"
               + (f" {self.force_level_unit}" if self.force_level_unit else "")]
        for p, s in self.scaling.items():
            spread = "" if s["spread"] is None else f", spread {100 * s['spread']:.2g} % over {s['n_levels']} levels"
            out.append(f"preload {format_value(p)}: modal force {format_value(s['modal_force_per_unit'])} per unit of "
                       f"force level ({s['source']}{spread})")
        for p, why in self.skipped.items():
            out.append(f"preload {format_value(p)}: no prediction: {why}")
        out += [p.report() for p in self.predictions]
        if self.extrapolated:
            out.append(f"{len(self.extrapolated)} prediction(s) EXTRAPOLATED beyond the fitted force levels: "
                       "the model was not tested there")
        if self.failed:
            out.append(f"{len(self.failed)} prediction(s) without a peak (failed or no peak in the band)")
        return out

    def report(self) -> str:
        return "\n".join(self.lines())

    def _repr_html_(self) -> str:
        return f"<pre>{html.escape(self.report())}</pre>"


def predict_from_results(results, force_levels, *, frequency_range=None, n_harmonics=5, uncertainty=True,
                         progress=None) -> PredictResult:
    """Predict every usable preload model of a ``results.json`` at ``force_levels``.

    Parameters
    ----------
    results : path or dict
        The results folder of ``jointid identify``, its ``results.json``, or the parsed dict.
    force_levels : str or sequence of float
        In the campaign's force-level units (``"1.5,3,6"``).
    frequency_range : (float, float), optional
        Band of the curves [Hz]; default each model's measured band, widened to the peak.
    n_harmonics : int
    uncertainty : bool
        Propagate the covariance to the peak (2 continuations per parameter).
    progress : callable, optional
        Called with one line per prediction.

    Raises
    ------
    JointidError
        A bad file, bad force levels or no usable model (before any work).
    """
    if isinstance(results, dict):
        from .backbones import check_results_for_backbones

        source = "results"
        if "models" not in results:
            results = _identifications(results)
        check_results_for_backbones(results, source)
    else:
        results, file = load_results(results)
        source = str(file)
    levels = parse_force_levels(force_levels, f"{source}: --force-levels")
    if frequency_range is not None:
        lo, hi = (float(v) for v in frequency_range)
        if not (math.isfinite(lo) and math.isfinite(hi) and 0 < lo < hi):
            raise ManifestError(f"{source}: --frequency-range: expected 0 < LO < HI in Hz, got {lo:g}, {hi:g}")
        frequency_range = (lo, hi)
    usable, skipped = usable_models(results, source)
    if not usable:
        why = "; ".join(f"preload {p}: {r}" for p, r in skipped.items()) or "the results hold no model"
        raise RecordError(f"{source}: no usable model to predict with ({why})")
    from .predict_hysteretic import hysteretic_models

    hyst = hysteretic_models(results, source)  # preloads whose selection picked a hysteretic law: solved with it
    unit = force_level_unit(results)
    preds, scaling = [], {}
    for entry in usable:
        p = entry.get("preload")
        scaling[p] = force_scaling(results, p)
        fitted = fitted_force_levels(results, p)
        for F in levels:
            pred = predict_level(entry, F, scale=scaling[p]["modal_force_per_unit"], fitted_levels=fitted,
                                 frequency_range=frequency_range, n_harmonics=n_harmonics, uncertainty=uncertainty,
                                 hysteretic=hyst.get(p))
            pred = replace(pred, force_level_unit=unit, measured=measured_dwells(results, p, F))
            preds.append(pred)
            if progress is not None:
                progress(pred.report().splitlines()[0])
    settings = {"frequency_range_hz": None if frequency_range is None else list(frequency_range),
                "n_harmonics": int(n_harmonics), "uncertainty": bool(uncertainty), "ds_max": DS_MAX}
    keep = ("preload", "terms", "amplitude_laws", "parameter_names", "parameters", "stderr", "q_max_range",
            "frequency_hz_range")
    models = tuple({**{k: e.get(k) for k in keep},
                    "joint_law": hyst[e.get("preload")].law_name if e.get("preload") in hyst else "polynomial",
                    "joint_law_model": hyst[e.get("preload")].summary() if e.get("preload") in hyst else None}
                   for e in usable)
    return PredictResult(source, levels, tuple(preds), scaling, skipped, settings, models, results.get("run_id"),
                         unit)


def write_predictions(result: PredictResult, out, inputs=()) -> dict:
    """Write ``results.json``, ``report.txt``, ``report.html`` and one figure per preload into
    ``out`` as one output set (kind ``predict``); returns the written paths (in ``out``)."""
    from ..io.outputset import new_run_id, output_set
    from ..io.results import atomic_write, write_json
    from ..report.formatting import slug
    from ..report.html import Section, figure_to_png, page_meta, write_html
    from ..report.predict_plots import plot_predictions, prediction_rows

    final = Path(out)
    run_id = new_run_id()
    summary = result.summary()
    summary["run_id"] = run_id
    preloads = list(dict.fromkeys(p.preload for p in result.predictions))
    with output_set(final, run_id, kind="predict", inputs=inputs) as tmp:
        paths = {"results": write_json(tmp / "results.json", summary),
                 "report": atomic_write(tmp / "report.txt", result.report() + f"\n\nrun id {run_id}\n")}
        figs = []
        for p in preloads:
            preds = [x for x in result.predictions if x.preload == p and not x.error]
            if not preds:
                continue
            ax = plot_predictions(preds, title=f"preload {p}: predicted response")
            png = figure_to_png(ax.figure, dpi=120)  # a Figure outside pyplot: nothing to close
            name = f"predict_{slug(p)}.png"
            figs.append((p, name, png))
            atomic_write(tmp / "figures" / name, png)
        paths["figures"] = [tmp / "figures" / n for _, n, _ in figs]
        sections = [Section("Predictions", paragraphs=[
            (f"Source: {result.source}. Each preload's identified model solved by harmonic balance with continuation "
             "through the folds at the requested force levels; q_max in the modal coordinate; standard errors "
             "propagated from the model's covariance; 95 % intervals value ± 1.96 se.")],
            tables=[("Peaks", prediction_rows(result.predictions), None)])]
        warn = [ln for ln in result.lines() if "EXTRAPOLATED" in ln or "warning" in ln or "FAILED" in ln
                or "no prediction" in ln or "no peak" in ln]
        if warn:  # a prediction's warnings on lines of their own (HTML joins a paragraph's lines)
            sections.append(Section("Warnings", paragraphs=[seg.strip() for ln in warn for seg in ln.split("\n")]))
        for p, name, png in figs:
            caption = (f"predicted q_max against frequency, preload {p} (dashed: unstable; crosses: peaks with "
                       "95 % intervals; circles: measured dwells of a fitted level, fundamental amplitude)")
            sections.append(Section(f"Preload {p}", figures=[(caption, png)]))
        sections.append(Section("Force scaling", paragraphs=[ln for ln in result.lines()[1:]
                                                              if "per unit of force level" in ln]))
        write_html(tmp / "report.html", "jointid: predicted responses", sections,
                   intro=f"{len(result.predictions)} predictions, {len(result.failed)} without a peak, "
                         f"{len(result.extrapolated)} extrapolated beyond the fitted force levels.",
                   meta=page_meta(run_id))
        paths["html"] = tmp / "report.html"
    rel = (lambda v: final / Path(v).relative_to(tmp))
    return {k: ([rel(x) for x in v] if isinstance(v, list) else rel(v)) for k, v in paths.items()}
