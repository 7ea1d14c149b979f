"""Re-prediction of the measured nonlinear FRFs with the identified model (seed Fig 10).

For each (preload, force level) group the identified single-mode model

``q'' + c(q_max) q' + omega1^2 q - k3 q^3 = Q sin(omega t)``

(shared ``omega1`` and ``k3`` of the group's pooled fit, the preload's damping law
``c(q_max)``) is solved by harmonic balance with pseudo-arclength continuation over the
group's frequency band (:func:`jointid.simulate.hbm.frequency_response`, through any
folds), at the group's modal forcing amplitude ``Q`` (the mean fundamental of the
records' modal force; with an unknown force gain, the excitation times the identified
gain).  The curve is the fundamental of the modal acceleration over the forcing,
``omega^2 A / Q``, drawn over the measured points ``|q''_1| / |Q_1|`` of the dwells.

Errors reported
    * peak frequency and peak amplitude of the re-predicted curve against a reference
      peak: the measured dwells' (a parabola through the three largest points), or an
      exact reference curve when one is known (the virtual rig).  A measured peak is
      quoted only where the dwells resolve it: the largest dwell is interior with a lower
      dwell on each side (the dwells bracket the peak) and the dwells about it are at most
      half the predicted -3 dB width apart.  Otherwise the report says so and gives no
      peak error (``peak_resolved`` false, the errors ``None`` in ``summary()``);
    * the rms relative difference between each measured point and the model solved at
      that record's own frequency and forcing.

:func:`campaign_loops` forms, once per identification, the measured and identified
hysteresis loops (seed Figs 17-19) of each group's largest-amplitude record
(:class:`GroupLoops`, carried in the campaign result as ``hysteresis_loops``; the report
only draws them), and :func:`loop_errors` gives their rms differences and areas for
``results.json``.  :func:`dwell_loops` forms the loops of the seed's Figs 17-19 (dwells
about the resonance of the top force level, with the damping law's ``c(q_max)``).
"""

from __future__ import annotations

import html
import warnings
from dataclasses import dataclass, replace

import numpy as np

from ..errors import JointidError, JointidWarning
from ..numerics.peaks import parabolic_peak, refine_peak
from ..signal.harmonics import fit_harmonics
from ..rounding import format_percent, format_value

__all__ = ["Reprediction", "identified_model", "repredict_group", "repredict_campaign", "with_repredictions",
           "GroupLoops", "group_loops", "campaign_loops", "loop_errors", "DwellLoops", "dwell_loops"]

#: Largest interval beside a computed peak, relative to its frequency: a re-predicted or exact
#: peak is sampled this finely before the parabola through its three largest samples.  The
#: parabola's error on an asymmetric (softening) peak falls as the square of the interval:
#: at 5e-5 (1.3 mHz at 26 Hz) it is about 1e-5 % of the frequency.  Much closer samples would
#: not help: the virtual rig's Iwan joint (discrete slip elements) makes its exact FRF smooth
#: only to about 1e-5 of its magnitude, and a parabola through samples a few micro-hertz
#: apart turns that into peak shifts of 1e-3 %.
PEAK_RTOL = 5e-5


@dataclass(frozen=True, eq=False)
class Reprediction:
    """A group's identified model solved by harmonic balance beside its measured FRF.

    Attributes
    ----------
    force_level : float
    model : SingleModeModel
        The identified model.
    frequency_hz, predicted : ndarray
        Re-predicted FRF magnitude (continuation order; not monotonic past a fold).
    measured_frequency_hz, measured : ndarray
        The measured points (fundamental of the response over that of the force), by frequency.
    peak_predicted : (float, float)
        ``(frequency [Hz], magnitude)`` of the re-predicted peak.
    peak_reference : (float, float)
        The peak it is compared with (measured dwells, or ``exact``).
    exact : object, optional
        An exact reference FRF (``frequency_hz``, ``H``), e.g. the virtual rig's.
    preload : object
    forcing : float
        Modal forcing amplitude ``Q`` of the curve.
    quantity : str
        What the magnitude is (e.g. ``"modal acceleration / modal force"``).
    point_errors : ndarray
        Relative difference of the model solved at each measured point's frequency and
        forcing against the measured point.
    folds_hz : tuple of float
        Frequencies of the folds (turning points) of the re-predicted curve.
    stable : ndarray of bool, optional
        Stability of each curve point.
    peak_resolved : bool
        Whether the measured dwells resolve the peak: they bracket it (``peak_bracketed``)
        and their spacing about the largest dwell is at most half the predicted -3 dB
        width.  If not, the reference peak is the largest dwell itself and no peak error
        is quoted (the properties are ``nan``, ``summary()`` gives ``None``).
    peak_bracketed : bool
        Whether the largest measured dwell has a lower dwell on each side (a peak inside
        the measured band); always true against an exact reference.
    bandwidth_hz : float
        Predicted -3 dB width of the peak [Hz].
    dwell_spacing_hz : float
        Largest spacing of the measured points about the largest one [Hz].
    """

    force_level: float
    model: object
    frequency_hz: np.ndarray
    predicted: np.ndarray
    measured_frequency_hz: np.ndarray
    measured: np.ndarray
    peak_predicted: tuple
    peak_reference: tuple
    exact: object = None
    preload: object = None
    forcing: float = float("nan")
    quantity: str = "modal acceleration / modal force"
    point_errors: np.ndarray | None = None
    folds_hz: tuple = ()
    stable: np.ndarray | None = None
    peak_resolved: bool = True
    bandwidth_hz: float = float("nan")
    dwell_spacing_hz: float = float("nan")
    peak_bracketed: bool = True

    def __post_init__(self):
        for name in ("frequency_hz", "predicted", "measured_frequency_hz", "measured", "point_errors", "stable"):
            v = getattr(self, name)
            if v is not None:
                a = np.array(v)
                a.setflags(write=False)
                object.__setattr__(self, name, a)

    @property
    def reference_kind(self) -> str:
        return "exact" if self.exact is not None else "measured dwells"

    @property
    def peak_exact(self):
        """The reference peak (the name the demo's results use)."""
        return self.peak_reference

    @property
    def peak_frequency_error_percent(self) -> float:
        """Re-predicted against reference peak frequency [%]; ``nan`` where the dwells do not resolve the peak."""
        if not self.peak_resolved:
            return float("nan")
        return 100.0 * (self.peak_predicted[0] / self.peak_reference[0] - 1.0)

    @property
    def peak_amplitude_error_percent(self) -> float:
        """Re-predicted against reference peak magnitude [%]; ``nan`` where the dwells do not resolve the peak."""
        if not self.peak_resolved:
            return float("nan")
        return 100.0 * (self.peak_predicted[1] / self.peak_reference[1] - 1.0)

    @property
    def peak_status(self) -> str:
        """Why a peak error is, or is not, quoted (one phrase)."""
        if self.exact is not None:
            return "against the exact reference"
        if not self.peak_bracketed:
            return ("the dwells do not bracket the peak (the largest dwell, "
                    f"{self.peak_reference[0]:.4g} Hz, has no lower dwell on one side)")
        if not self.peak_resolved:
            return (f"the dwells do not resolve the peak (spacing {self.dwell_spacing_hz:.3g} Hz about the largest "
                    f"dwell, predicted -3 dB width {self.bandwidth_hz:.3g} Hz)")
        return "resolved by the dwells"

    @property
    def point_rms_error_percent(self) -> float | None:
        if self.point_errors is None or self.point_errors.size == 0:
            return None
        return 100.0 * float(np.sqrt(np.mean(self.point_errors**2)))

    def summary(self) -> dict:
        d = {
            "preload": self.preload,
            "force_level": self.force_level,
            "model": self.model.summary(),
            "forcing": self.forcing,
            "quantity": self.quantity,
            "reference": self.reference_kind,
            "peak_resolved": self.peak_resolved,
            "peak_bracketed": self.peak_bracketed,
            "peak_status": self.peak_status,
            "bandwidth_hz": self.bandwidth_hz,
            "dwell_spacing_hz": self.dwell_spacing_hz,
            "peak_predicted": {"frequency_hz": self.peak_predicted[0], "magnitude": self.peak_predicted[1]},
            "peak_reference": {"frequency_hz": self.peak_reference[0], "magnitude": self.peak_reference[1]},
            "peak_frequency_error_percent": _finite(self.peak_frequency_error_percent),
            "peak_amplitude_error_percent": _finite(self.peak_amplitude_error_percent),
            "point_rms_error_percent": self.point_rms_error_percent,
            "point_errors": None if self.point_errors is None else self.point_errors.tolist(),
            "folds_hz": list(self.folds_hz),
            "frequency_hz": self.frequency_hz.tolist(),
            "predicted": self.predicted.tolist(),
            "measured_frequency_hz": self.measured_frequency_hz.tolist(),
            "measured": self.measured.tolist(),
        }
        if self.exact is not None:
            d["peak_exact"] = dict(d["peak_reference"])
        return d

    def report(self) -> str:
        pts = self.point_rms_error_percent
        rms = f"; measured points rms {format_percent(pts)}" if pts is not None else ""
        head = f"preload {format_value(self.preload)}, F = {format_value(self.force_level)}"
        if not np.isfinite(self.peak_predicted[0]):
            return f"{head}: no re-predicted peak inside the band{rms}"
        if self.peak_resolved:
            peak = (f"peak {format_value(self.peak_predicted[0], 7)} Hz "
                    f"({format_percent(self.peak_frequency_error_percent, sign=True)}), magnitude "
                    f"{format_value(self.peak_predicted[1])} ({format_percent(self.peak_amplitude_error_percent, sign=True)})"
                    f" vs {self.reference_kind}")
        else:
            peak = (f"predicted peak {format_value(self.peak_predicted[0], 7)} Hz, magnitude "
                    f"{format_value(self.peak_predicted[1])}; {self.peak_status}: no peak error")
        folds = f"; folds at {', '.join(format_value(f, 7) for f in self.folds_hz)} Hz" if self.folds_hz else ""
        return f"{head}: {peak}{rms}{folds}"

    def _repr_html_(self) -> str:
        return f"<pre>{html.escape(self.report())}</pre>"

    def plot(self, ax=None, **kwargs):
        """Measured points and re-predicted curve (:func:`jointid.report.reprediction_plots.plot_reprediction`)."""
        from ..report.reprediction_plots import plot_reprediction

        return plot_reprediction([self], ax=ax, **kwargs)


def _finite(x):
    return float(x) if x is not None and np.isfinite(x) else None


def identified_model(result, group):
    """The group's identified single-mode model.

    With the terms chosen by the data (``terms="auto"``) the model selected for the group's
    preload: its terms and amplitude laws, fitted over all records of the preload
    (results.json ``selection``).  Otherwise the group's pooled ``omega1``, ``k3`` with the
    preload's ``c(q_max)``.  Returns ``None`` when the group has no pooled fit or its
    preload no damping law.
    """
    from ..simulate.model import SingleModeModel

    selection = (getattr(result, "selections", None) or {}).get(group.preload)
    if selection is not None and selection.model is not None:
        from .heldout_scoring import single_mode_model
        from ..identify.terms import library

        m = selection.model
        return single_mode_model(library(list(m.terms)), m.law_orders, m.parameters)
    law = result.damping_laws.get(group.preload)
    if group.pooled is None or law is None or not np.isfinite(group.pooled.omega1):
        return None
    k3 = group.pooled.k3 if "k3" in group.pooled.shared_names else None
    return SingleModeModel("q + -q^3 + q'", (group.pooled.omega1**2, k3 or 0.0, 0.0),
                           {"q'": tuple(float(c) for c in law.coefficients)})


def _fundamental(series) -> float:
    c = np.asarray(series.coefficients)
    return float(np.hypot(c[1], c[2]))


def _group_members(result, group):
    """The records of the group's pooled fit, in its row order (flagged records are not among them)."""
    indices = set(group.record_indices)
    return [o for o in result.records if o.spec.index in indices]


def _gain(group) -> float:
    if group.gain is None:
        return 1.0
    return float(group.gain.derived()["gain"][0])


class _NoFold(Exception):
    """The sweeps show no fold: the continuation is not needed."""


def _solve(model, forcing, omegas, n_harmonics):
    from ..simulate.hbm import frequency_response

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", JointidWarning)
        return frequency_response(model, forcing, omegas, n_harmonics=n_harmonics, stability=False)


def repredict_group(result, group, *, n_points: int = 61, n_harmonics: int = 5, forcing=None, scale: float = 1.0,
                    measured=None, exact=None, quantity=None, span=None, model=None) -> Reprediction | None:
    """Re-predict one group's nonlinear FRF with its identified model.

    Parameters
    ----------
    result : CampaignResult
    group : GroupResult
    n_points : int
        Continuation is started on a grid of this many points over the band (for the curve);
        the peak is refined by a sweep on a fine grid around the largest response.
    n_harmonics : int
        Harmonics of the harmonic balance.
    forcing : float, optional
        Modal forcing amplitude ``Q``; default the mean fundamental of the records' modal
        force (times the identified gain when the force gain is unknown).
    scale : float
        Factor from modal acceleration to the plotted response per unit of the measured
        force (e.g. ``|phi_sensor| / |phi_force|`` for a sensor FRF per newton).
    measured : (frequency_hz, magnitude), optional
        The measured points; default the records' ``|q''_1| / |Q_1|`` (times ``scale``).
    exact : object with ``frequency_hz``, ``H`` and ``peak()``, optional
        An exact reference FRF; its peak is the reference instead of the measured one.
    quantity : str, optional
        Label of the magnitude.
    span : (f_lo, f_hi), optional
        Frequency band of the curve [Hz]; default the measured (or exact) points' span.
    model : SingleModeModel, optional
        The model to solve instead of :func:`identified_model` (e.g. a selected model fitted
        without this group's records, :mod:`jointid.identify.selection`).

    Returns
    -------
    Reprediction or None
        ``None`` when the group has no identified model.
    """
    model = identified_model(result, group) if model is None else model
    members = _group_members(result, group)
    if model is None or not members:
        return None
    gain = _gain(group)
    f_rec = np.array([o.signals.frequency_hz for o in members])
    Q_rec = []
    for o in members:
        fser, _ = fit_harmonics(o.signals.t, o.signals.force, o.signals.omega, 1, channel="force")
        Q_rec.append(_fundamental(fser) * gain)
    Q_rec = np.asarray(Q_rec)
    if measured is None:
        m_rec = np.array([_fundamental(o.signals.acceleration) for o in members]) / Q_rec * scale
        order = np.argsort(f_rec)
        measured = (f_rec[order], m_rec[order])
    fm, Hm = (np.asarray(v, float) for v in measured)
    Q = float(np.mean(Q_rec)) if forcing is None else float(forcing)
    if span is None:
        ref_f = fm if exact is None else np.asarray(exact.frequency_hz, float)
        span = (float(np.min(ref_f)), float(np.max(ref_f)))
    lo, hi = span
    grid = np.linspace(lo, hi, int(n_points))
    r = _solve(model, Q, 2 * np.pi * grid, n_harmonics)
    mag = scale * r.omega**2 * r.amplitude / Q
    # peak: a fine sweep about the largest point of the curve (both ways across a fold)
    k = int(np.argmax(mag))
    step = (hi - lo) / max(int(n_points) - 1, 1)
    if exact is not None:
        f_ref, _ = exact.peak()
        centre, half = f_ref, 0.04
    else:
        centre, half = float(grid[k]), step
    fine = centre + np.linspace(-half, half, 17)
    rf = _solve(model, Q, 2 * np.pi * fine, n_harmonics)
    mag_f = scale * rf.omega**2 * rf.amplitude / Q
    f_all = np.concatenate([grid, fine])
    m_all = np.concatenate([mag, mag_f])
    o = np.argsort(f_all, kind="stable")
    f_all, m_all = f_all[o], m_all[o]
    keep = np.concatenate([[True], np.diff(f_all) > 1e-12 * hi])
    f_all, m_all = f_all[keep], m_all[keep]
    folds = ()
    stable = None
    # folds show as a disagreement of the sweeps up and down: two stable branches
    down = _solve(model, Q, 2 * np.pi * grid[::-1], n_harmonics).amplitude[::-1]
    may_fold = np.max(np.abs(down / r.amplitude - 1.0)) > 1e-4
    try:  # the curve through the folds, if any, by continuation
        from ..simulate.hbm import frequency_response

        if not may_fold:
            raise _NoFold
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", JointidWarning)
            rc = frequency_response(model, Q, omega_range=(2 * np.pi * lo, 2 * np.pi * hi), n_harmonics=n_harmonics,
                                    stability=False, max_steps=2000)
        if rc.folds:
            folds = tuple(float(rc.omega[i] / (2 * np.pi)) for i in rc.folds)
            f_all = rc.omega / (2 * np.pi)
            m_all = scale * rc.omega**2 * rc.amplitude / Q
            peak_pred = (float(f_all[np.argmax(m_all)]), float(np.max(m_all)))
    except (JointidError, _NoFold):
        pass
    if not folds:  # one branch: the intervals beside the largest point halved before the parabola
        def magnitude(f_new):
            rn = _solve(model, Q, 2 * np.pi * np.asarray(f_new), n_harmonics)
            return scale * rn.omega**2 * rn.amplitude / Q

        f_all, m_all = refine_peak(magnitude, f_all, m_all, PEAK_RTOL * float(f_all[int(np.argmax(m_all))]))
        peak_pred = parabolic_peak(f_all, m_all)
    k_max = int(np.argmax(m_all))
    if k_max in (0, m_all.size - 1):  # the response still grows at the end of the band: no peak in it
        peak_pred = (float("nan"), float("nan"))
    # the measured peak: a parabola through the three largest dwells when they resolve the
    # predicted -3 dB band, else the largest dwell itself (a resolution-limited reference)
    above = f_all[m_all >= peak_pred[1] / np.sqrt(2.0)]
    width = float(above.max() - above.min()) if above.size > 1 else 0.0
    km = int(np.argmax(Hm))
    spacing = float(np.max(np.diff(fm[max(km - 1, 0): km + 2]))) if fm.size > 1 else np.inf
    # a measured peak needs a lower dwell on each side of the largest one, and dwells close enough
    bracketed = exact is not None or bool(0 < km < fm.size - 1 and Hm[km - 1] < Hm[km] > Hm[km + 1])
    resolved = exact is not None or (bracketed and spacing <= 0.5 * width)
    if exact is not None:
        peak_ref = exact.peak()
    elif resolved:
        peak_ref = parabolic_peak(fm, Hm)
    else:
        peak_ref = (float(fm[km]), float(Hm[km]))
    # the model at each measured point's own frequency and forcing
    errs = []
    if measured is not None and len(fm) == len(members):
        for o_, fq, Qq, Hq in zip(sorted(members, key=lambda x: x.signals.frequency_hz), fm, Q_rec[np.argsort(f_rec)],
                                  Hm):
            rp = _solve(model, Qq, [2 * np.pi * fq], n_harmonics)
            errs.append(scale * rp.omega[0] ** 2 * rp.amplitude[0] / Qq / Hq - 1.0)
    qty = quantity or ("modal acceleration / modal force" if scale == 1.0 else "response / force")
    return Reprediction(float(group.force_level), model, f_all, m_all, fm, Hm, peak_pred, tuple(peak_ref), exact,
                        group.preload, Q, qty, np.asarray(errs) if errs else None, folds, stable, bool(resolved),
                        width, spacing, bool(bracketed))


def repredict_campaign(result, **kw) -> tuple:
    """:func:`repredict_group` for every group of a campaign result that has a model.

    A group whose re-prediction fails (no convergence) is skipped with a warning: one
    group never loses the others.
    """
    out = []
    for g in result.groups:
        try:
            r = repredict_group(result, g, **kw)
        except (JointidError, ValueError, FloatingPointError, np.linalg.LinAlgError) as exc:
            warnings.warn(f"re-prediction of preload {g.preload}, force level {g.force_level} failed: {exc}",
                          JointidWarning, stacklevel=2)
            continue
        if r is not None:
            out.append(r)
    return tuple(out)


def with_repredictions(result):
    """``result`` with every group's FRF re-predicted (:func:`repredict_campaign`) and its
    loops compared (:func:`loop_errors`, of the loops ``result`` carries), with the models
    ``result`` holds now."""
    return replace(result, repredictions=repredict_campaign(result), loops=tuple(loop_errors(result)))


@dataclass(frozen=True, eq=False)
class GroupLoops:
    """Measured and identified hysteresis loops of one group's largest-amplitude record.

    Attributes
    ----------
    preload, force_level : object
        The group.
    record : RecordOutcome
        The group's record of largest ``q_max`` (among the records of its pooled fit).
    filtered, unfiltered : HysteresisLoop or str
        The loop from the filtered signals (first period of the harmonic fit) and from the
        unfiltered ones (synchronous average), or the reason it could not be formed.
    gain_free : bool
        The force gain was identified: the force is in gain-free units (times the gain).
    """

    preload: object
    force_level: object
    record: object
    filtered: object
    unfiltered: object
    gain_free: bool = False

    @property
    def loops(self) -> dict:
        """``{"filtered": ..., "unfiltered": ...}`` (a loop, or the reason it is missing)."""
        return {"filtered": self.filtered, "unfiltered": self.unfiltered}

    def summary(self) -> dict:
        """One row of ``results.json`` ``reprediction.loops``: the record, and for each loop its
        relative rms difference and areas (or an ``error``)."""
        row = {"preload": self.preload, "force_level": self.force_level, "file": self.record.spec.file,
               "frequency_hz": float(self.record.signals.frequency_hz), "q_max": float(self.record.fit.q_max)}
        for key, loop in self.loops.items():
            row[key] = {"error": loop} if isinstance(loop, str) else loop.summary()
        return row


def group_loops(result, group):
    """Measured and identified hysteresis loops of a group's largest-amplitude record.

    The identified model is the group's shared ``omega1^2`` and ``k3`` with the record's
    own pooled damping; with an unknown force gain the force is put in gain-free units
    (times the identified gain) first, so that every campaign has its loops.

    Returns
    -------
    (RecordOutcome, {"filtered": HysteresisLoop or str, "unfiltered": ...}) or None
        A loop that cannot be formed is replaced by the reason.
    """
    from ..identify.hysteresis import hysteresis_loop

    members = _group_members(result, group)
    if group.pooled is None or not members:
        return None
    j = int(np.argmax([o.fit.q_max for o in members]))
    best = members[j]
    theta = []
    for n in best.fit.coefficient_names:
        if n in group.pooled.shared_names:
            theta.append(group.pooled.get(n))
        elif n in group.pooled.own_names:
            theta.append(group.pooled.get(n)[j])
        else:
            theta.append(0.0)
    signals = best.signals
    gain = _gain(group)
    if gain != 1.0:
        signals = replace(signals, force=np.asarray(signals.force) * gain)
    loops = {}
    for filt in (True, False):
        try:
            loops["filtered" if filt else "unfiltered"] = hysteresis_loop(signals, best.fit.terms,
                                                                          np.asarray(theta, float), filtered=filt)
        except (JointidError, ValueError) as exc:
            loops["filtered" if filt else "unfiltered"] = str(exc)
    return best, loops


def campaign_loops(result) -> tuple:
    """:class:`GroupLoops` of every group with a pooled fit and records (:func:`group_loops`),
    in the order of ``result.groups``: formed once where the campaign result is built and
    carried in it (``hysteresis_loops``)."""
    out = []
    for g in result.groups:
        found = group_loops(result, g)
        if found is None:
            continue
        best, loops = found
        out.append(GroupLoops(g.preload, g.force_level, best, loops["filtered"], loops["unfiltered"],
                              g.gain is not None))
    return tuple(out)


def loop_errors(source) -> list:
    """Measured vs identified hysteresis loops of every group, as numbers.

    ``source`` is a sequence of :class:`GroupLoops`, or a campaign result (the loops it
    carries in ``hysteresis_loops``, formed by :func:`campaign_loops` when it carries none).

    Returns one dict per group: ``file``, ``frequency_hz``, ``q_max``, and for the
    ``filtered`` and ``unfiltered`` loops the relative rms difference
    ``rms_difference`` and the enclosed areas (or an ``error``).
    """
    if hasattr(source, "groups"):
        source = getattr(source, "hysteresis_loops", None) or campaign_loops(source)
    return [gl.summary() for gl in source]


@dataclass(frozen=True, eq=False)
class DwellLoops:
    """The loops of the seed's Figs 17-19 for one preload, at its top force level.

    The identified model of each loop is the record's own fit with the group's shared
    ``omega1^2`` and ``k3`` and the damping law's ``c(q_max)`` at the record's amplitude.

    Attributes
    ----------
    preload, force_level : object
    records : tuple of RecordOutcome
        The resonant dwell (largest ``q_max``) and the dwells three below and three above it
        in frequency (fewer at the ends of the band), by frequency.
    filtered : tuple of HysteresisLoop
        Their loops from the filtered signals.
    largest : RecordOutcome
        The dwell of largest ``q_max``.
    largest_filtered, largest_unfiltered : HysteresisLoop
        Its loops from the filtered and from the unfiltered signals (seed Fig 19).
    """

    preload: object
    force_level: object
    records: tuple
    filtered: tuple
    largest: object
    largest_filtered: object
    largest_unfiltered: object


def _law_theta(o, group, law):
    """A record's coefficients with the group's shared ``omega1^2`` and ``k3`` and the law's ``c(q_max)``."""
    theta = np.array(o.fit.coefficients, float)
    names = o.fit.coefficient_names
    theta[names.index("omega1^2")] = group.pooled.get("omega1^2")
    if "k3" in names and group.pooled.k3 is not None:
        theta[names.index("k3")] = group.pooled.k3
    if "c" in names and law is not None:
        theta[names.index("c")] = float(law(o.fit.q_max))
    return theta


def dwell_loops(result, preload, around: int = 3) -> DwellLoops | None:
    """The hysteresis loops of the seed's Figs 17-19 (:class:`DwellLoops`) of ``preload`` at its
    top force level; ``None`` when that group has no pooled fit or fewer than three identified
    records.  ``around`` is the distance (in dwells) of the neighbours of the resonant dwell."""
    from ..identify.hysteresis import hysteresis_loop

    levels = [g.force_level for g in result.groups if g.preload == preload]
    if not levels:
        return None
    top = max(levels)
    g = result.group(preload, top)
    recs = sorted([o for o in result.records if o.ok and o.spec.group == (preload, top)],
                  key=lambda o: o.signals.frequency_hz)
    if len(recs) < 3 or g.pooled is None:
        return None
    law = result.damping_laws.get(preload)
    i_pk = int(np.argmax([o.fit.q_max for o in recs]))
    pick = sorted({max(i_pk - around, 0), i_pk, min(i_pk + around, len(recs) - 1)})
    chosen = tuple(recs[i] for i in pick)
    filtered = tuple(hysteresis_loop(o.signals, o.fit.terms, _law_theta(o, g, law), filtered=True) for o in chosen)
    o = max(recs, key=lambda o: o.fit.q_max)
    theta = _law_theta(o, g, law)
    both = {filt: hysteresis_loop(o.signals, o.fit.terms, theta, filtered=filt) for filt in (True, False)}
    return DwellLoops(preload, top, chosen, filtered, o, both[True], both[False])
