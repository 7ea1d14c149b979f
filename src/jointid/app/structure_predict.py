"""Nonlinear frequency responses of a structure model file (``MODEL.toml``).

:func:`predict_structure` reads the model (:mod:`jointid.io.structure_model`), computes at
each force level the frequency response over the band by the multi-mode harmonic balance
condensed on the joint DOFs, continued through folds
(:mod:`jointid.simulate.structure_hb`), and reports per level the peak of the first-harmonic
amplitude at every response DOF (located between the continued points), the folds, the
Newton iterations, the largest relative residual and the cost per point.  For every elastic
mode in the band (else the one nearest to it) it computes the damped nonlinear mode by the
extended periodic motion concept (:mod:`jointid.simulate.nlmodes`): backbone frequency and
damping ratio against the modal amplitude, from 1/1000 of the largest amplitude the
responses reach up to 1.5 times it.  A curve whose largest amplitude is at an end (no peak in
the band), a continuation stopped before the end of the band, a time check that failed or
could not be done and a model implausible at rest (statically unstable, negative or no
damping: :func:`_model_warnings`) are flagged: :attr:`StructurePrediction.failed`.  The stability of
the points is not reported: Hill's method with the periodic-map Jacobian of slider laws
(:meth:`jointid.simulate.structure_hb.CondensedHB.growth_rate`) is not yet checked for them.
:func:`write_structure_predictions` writes ``results.json``, ``report.txt`` and a figure as
one output set.
"""

from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import ConvergenceError, ConvergenceWarning, ManifestError
from ..io.structure_model import read_structure_model, stuck_stiffness
from ..simulate.structure import structure_from_spec
from ..simulate.nlmodes import epmc_backbone
from ..simulate.structure_hb import default_n_time, to_complex
from ..simulate.structure_timeint import TooStiffError, integrate_structure

__all__ = ["StructurePrediction", "predict_structure", "write_structure_predictions", "located_peak"]


def located_peak(frequency_hz, amplitude):
    """Peak of a continued curve located between its points: ``(frequency_hz, amplitude)``.

    The largest point and its two neighbours on the curve are joined by a quadratic in the
    chord length (frequency and amplitude each normalised by their range), whose maximum of
    the amplitude gives the peak; at an end of the curve the point itself.
    """
    f = np.asarray(frequency_hz, float)
    a = np.asarray(amplitude, float)
    i = int(np.argmax(a))
    if i == 0 or i == a.size - 1:
        return float(f[i]), float(a[i])
    sf = max(float(np.ptp(f)), 1e-300)
    sa = max(float(np.ptp(a)), 1e-300)
    idx = [i - 1, i, i + 1]
    s = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(f[idx]) / sf, np.diff(a[idx]) / sa))])
    ca = np.polyfit(s, a[idx], 2)
    if ca[0] >= 0:
        return float(f[i]), float(a[i])
    s_star = float(np.clip(-ca[1] / (2 * ca[0]), s[0], s[-1]))
    cf = np.polyfit(s, f[idx], 2)
    return float(np.polyval(cf, s_star)), float(np.polyval(ca, s_star))


@dataclass
class LevelPrediction:
    force_level: float
    frequency_hz: list = field(default_factory=list)
    amplitude: dict = field(default_factory=dict)  # DOF -> first-harmonic amplitudes along the curve
    peaks: dict = field(default_factory=dict)  # DOF -> {"peak_frequency_hz", "peak_amplitude"}
    folds_hz: list = field(default_factory=list)
    n_points: int = 0
    newton_iterations_mean: float = float("nan")
    max_residual: float = float("nan")
    seconds_per_point: float = float("nan")
    error: str = ""
    warnings: list = field(default_factory=list)  # what makes the curve unsure (a continuation stopped early)
    modal_max: object = None  # largest first-harmonic amplitude of each modal coordinate on the curve
    peak_point: object = None  # the curve's point of largest first-harmonic amplitude at the first response DOF

    def summary(self) -> dict:
        out = {
            "force_level": self.force_level,
            "force_level_unit": "N",  # the amplitude of the model's force (N m on a rotation DOF)
            "peaks": self.peaks,
            "folds_hz": self.folds_hz,
            "n_points": self.n_points,
            "newton_iterations_mean": _finite_or_none(self.newton_iterations_mean),
            "max_residual": _finite_or_none(self.max_residual),
            "curve": {"frequency_hz": self.frequency_hz, "amplitude": self.amplitude},
            "timing": {"seconds_per_point": _finite_or_none(self.seconds_per_point)},
            "error": self.error,
            "warnings": list(self.warnings),
        }
        return out

    @property
    def no_peak(self) -> list:
        """Response DOFs whose largest amplitude is at an end of the curve (no peak in the band)."""
        return [d for d, p in self.peaks.items() if p.get("located") == "no peak"]

    @property
    def flagged(self) -> bool:
        """Failed, or a curve without a peak at some response DOF, or one with warnings."""
        return bool(self.error or self.warnings or self.no_peak)


@dataclass
class ModeBackbone:
    """The backbone of one mode (``mode`` counted from 1 in the model's mode order)."""

    mode: int
    linear_frequency_hz: float
    linear_damping_ratio: float
    amplitude: list = field(default_factory=list)
    frequency_hz: list = field(default_factory=list)
    damping_ratio: list = field(default_factory=list)
    joint_amplitude: dict = field(default_factory=dict)  # joint name -> first-harmonic amplitude
    response_amplitude: dict = field(default_factory=dict)  # response DOF -> first-harmonic amplitude
    newton_iterations_mean: float = float("nan")
    max_residual: float = float("nan")
    seconds_per_point: float = float("nan")
    error: str = ""

    def summary(self) -> dict:
        return {
            "mode": self.mode,
            "linear_frequency_hz": self.linear_frequency_hz,
            "linear_damping_ratio": self.linear_damping_ratio,
            "amplitude": self.amplitude,
            "amplitude_definition": "first-harmonic amplitude of the mass-normalised modal coordinate",
            "frequency_hz": self.frequency_hz,
            "damping_ratio": self.damping_ratio,
            "joint_amplitude": self.joint_amplitude,
            "response_amplitude": self.response_amplitude,
            "n_points": len(self.amplitude),
            "newton_iterations_mean": _finite_or_none(self.newton_iterations_mean),
            "max_residual": _finite_or_none(self.max_residual),
            "timing": {"seconds_per_point": _finite_or_none(self.seconds_per_point)},
            "error": self.error,
        }


def _finite_or_none(x):
    return float(x) if x is not None and math.isfinite(x) else None


@dataclass
class StructurePrediction:
    source: str
    model: dict
    settings: dict
    levels: list
    backbones: list = field(default_factory=list)
    time_checks: list = field(default_factory=list)
    warnings: list = field(default_factory=list)  # the model's implausible features (static instability, ...)

    @property
    def failed(self) -> list:
        """What makes the prediction unsure (the command then exits 1): failed or flagged levels (no peak in the
        band, a partial curve), failed backbones, time checks that failed or could not be done, and the
        model's :attr:`warnings`."""
        return ([lv for lv in self.levels if lv.flagged] + [b for b in self.backbones if b.error]
                + [c for c in self.time_checks if c["error"]] + list(self.warnings))

    def summary(self) -> dict:
        return {"kind": "structure prediction", "source": self.source, "model": self.model,
                "settings": self.settings, "force_level_unit": "N", "predictions": [lv.summary() for lv in self.levels],
                "backbones": [b.summary() for b in self.backbones], "time_checks": self.time_checks,
                "warnings": list(self.warnings)}

    def unit(self, dof) -> str:
        """Unit of a response DOF's motion (``[response] units`` of the model file; m unless declared)."""
        return (self.model.get("response_units") or {}).get(dof, "m")

    def lines(self) -> list:
        out = [f"structure model {self.model['name']} ({self.source}): {self.model['n_modes']} modes, "
               f"{len(self.model['joints'])} joint element(s); harmonics 0..{self.settings['n_harmonics']}, "
               f"{self.settings['n_time']} time samples"]
        for lv in self.levels:
            if lv.error:
                out.append(f"F = {lv.force_level:g} N: FAILED: {lv.error}")
                continue
            pk = "; ".join(self._peak_text(d, p) for d, p in lv.peaks.items())
            folds = f"folds at {', '.join(f'{f:.6g}' for f in lv.folds_hz)} Hz" if lv.folds_hz else "no fold"
            out.append(f"F = {lv.force_level:g} N: {pk}; {folds}; {lv.n_points} points, "
                       f"{lv.newton_iterations_mean:.2g} Newton iterations per point, residual <= "
                       f"{lv.max_residual:.1e}, {1e3 * lv.seconds_per_point:.3g} ms per point")
            out.extend(f"F = {lv.force_level:g} N: WARNING: {w}" for w in lv.warnings)
        skipped = self.settings.get("backbone_modes_not_excited")
        if skipped:
            out.append(f"nonlinear modes {', '.join(map(str, skipped))} in the band: not excited by the force, "
                       "no backbone computed")
        for b in self.backbones:
            head = (f"nonlinear mode {b.mode} (linear {b.linear_frequency_hz:.6g} Hz, damping ratio "
                    f"{b.linear_damping_ratio:.3g}): ")
            if b.amplitude:
                i = int(np.argmax(b.damping_ratio))
                out.append(head + f"{b.frequency_hz[0]:.6g} Hz at modal amplitude {b.amplitude[0]:.3g} to "
                           f"{b.frequency_hz[-1]:.6g} Hz at {b.amplitude[-1]:.3g}; damping ratio "
                           f"{b.damping_ratio[0]:.3g} to {b.damping_ratio[-1]:.3g} (largest {b.damping_ratio[i]:.3g} "
                           f"at {b.amplitude[i]:.3g}); {len(b.amplitude)} points, residual <= {b.max_residual:.1e}, "
                           f"{1e3 * b.seconds_per_point:.3g} ms per point")
            if b.error:
                out.append(head + f"FAILED: {b.error}")
        if self.time_checks:
            done = [c for c in self.time_checks if c["relative_difference"] is not None]
            txt = ", ".join(f"{c['relative_difference']:.1e} (F = {c['force_level']:g} N at {c['frequency_hz']:.6g} Hz)"
                            for c in done)
            out.append(f"time integration from the peaks ({self.time_checks[0]['periods']} periods, DOP853): "
                       f"fundamental at the response DOFs differs from the harmonic balance by {txt or 'none'}"
                       + "".join(f"; F = {c['force_level']:g} N: FAILED: {c['error']}" for c in self.time_checks
                                 if c["error"])
                       + "".join(f"; F = {c['force_level']:g} N: not done: {c['not_done']}"
                                 for c in self.time_checks if c.get("not_done"))
                       + f"; {sum(c['cost_s'] for c in self.time_checks):.3g} s")
        out.extend(f"WARNING: {w}" for w in self.warnings)
        return out

    def _peak_text(self, d, p) -> str:
        if p.get("located") == "no peak":
            band = self.settings.get("frequency_range_hz") or [float("nan")] * 2
            return (f"{d} no peak in {band[0]:.6g}-{band[1]:.6g} Hz (largest {p['largest_amplitude']:.4g} "
                    f"{self.unit(d)} at {p['largest_at_hz']:.6g} Hz, an end of the curve: the response still grows "
                    "there)")
        return f"{d} peak {p['peak_amplitude']:.4g} {self.unit(d)} at {p['peak_frequency_hz']:.6g} Hz"

    def report(self) -> str:
        return "\n".join(self.lines())


def _refined_peak(st, pts, folds, amp, dof, F, H, N):
    """The peak of ``dof`` on the curve by fixed-frequency solutions between the neighbours of
    the largest point (bounded Brent search on the first-harmonic amplitude, each solution
    started from the curve interpolated at its frequency); None next to a fold or an end."""
    from scipy.optimize import minimize_scalar

    i = int(np.argmax(amp))
    if i == 0 or i == len(pts) - 1 or any(abs(i - k) <= 1 for k in folds):
        return None
    a, b = pts[i - 1], pts[i + 1]
    if not a.omega < pts[i].omega < b.omega:
        return None

    def neg_amp(w):
        j0, j1 = (a, pts[i]) if w <= pts[i].omega else (pts[i], b)
        s = (w - j0.omega) / (j1.omega - j0.omega)
        p = st.engine.solve(w, [0.0, 0.0, F], H, n_time=N, guess=(1 - s) * j0.joint + s * j1.joint)
        return -float(abs(to_complex(st.response(p, [dof])[dof])[1]))

    try:
        r = minimize_scalar(neg_amp, bounds=(a.omega, b.omega), method="bounded",
                            options={"xatol": 1e-7 * pts[i].omega})
    except ConvergenceError:
        return None
    if not r.success or -r.fun < amp[i]:
        return None
    return float(r.x / (2 * np.pi)), float(-r.fun)


#: Periods of each time-integration check (started on the harmonic-balance orbit; :func:`_time_checks`).
TIME_CHECK_PERIODS = 10


def _time_checks(st, levels, response, n_points, periods=TIME_CHECK_PERIODS) -> list:
    """The peak point of the ``n_points`` largest force levels integrated in time
    (:func:`jointid.simulate.structure_timeint.integrate_structure`, from the orbit, ``periods`` periods):
    the relative difference of the fundamental at the response DOFs, the periods and the cost."""
    out = []
    picks = sorted((lv for lv in levels if lv.peak_point is not None), key=lambda lv: -lv.force_level)
    for lv in picks[:max(int(n_points), 0)]:
        p = lv.peak_point
        row = {"frequency_hz": float(p.frequency_hz), "force_level": lv.force_level, "relative_difference": None,
               "periods": int(periods), "n_steps": None, "cost_s": 0.0, "error": "", "not_done": ""}
        t0 = time.process_time()
        try:
            r = integrate_structure(st, p, dofs=response, n_periods=periods, rtol=1e-7,
                                    atol=1e-10 * max(float(np.abs(p.modal).max()), 1e-300))
            row.update(relative_difference=r.relative_difference, n_steps=r.n_steps)
            if not math.isfinite(r.relative_difference):
                row.update(relative_difference=None, error="the fundamental of the time integration or of the "
                                                           "harmonic balance is not a finite number")
        except TooStiffError as exc:  # not done: a note, not a failure of the prediction
            row["not_done"] = (f"{exc}; keep the modes the band needs ([model] n_modes) or give --time-check 0")
        except ConvergenceError as exc:
            row["error"] = str(exc)
        row["cost_s"] = time.process_time() - t0
        out.append(row)
    return out


def predict_structure(model_toml, *, force_levels=None, frequency_range=None, n_harmonics=None, n_time=None,
                      progress=None, time_check=None) -> StructurePrediction:
    """Frequency responses of the structure in ``model_toml`` at each force level.

    Arguments left at None come from the file's ``[predict]`` table (the band and the force
    levels are then required there; harmonics default 5).  ``time_check``: the number of force
    levels (the largest first) whose peak point is checked by a time integration (default: up to 3;
    0: none).
    """
    spec = read_structure_model(model_toml)
    pred = spec.predict
    levels = list(force_levels) if force_levels is not None else pred.get("force_levels")
    band = tuple(frequency_range) if frequency_range is not None else pred.get("frequency_range_hz")
    if not levels:
        raise ManifestError(f"{spec.path}: predict.force_levels: missing (give them in [predict] or with --force-levels)")
    if band is None:
        raise ManifestError(f"{spec.path}: predict.frequency_range_hz: missing (give it in [predict] or with "
                            "--frequency-range LO HI)")
    if not (0 < band[0] < band[1]):
        raise ManifestError(f"{spec.path}: frequency range {band}: expected 0 < low < high")
    H = int(n_harmonics if n_harmonics is not None else pred.get("n_harmonics", 5))
    N = int(n_time if n_time is not None else pred.get("n_time", default_n_time(H)))
    if N <= 2 * H:
        src = "predict.n_time" if n_time is None else "n_time"
        raise ManifestError(f"{spec.path}: {src}: {N} time samples per period must exceed 2 n_harmonics = {2 * H} "
                            f"(n_harmonics {H}{' from --harmonics' if n_harmonics is not None else ''})")
    st, response = structure_from_spec(spec)
    model = {"name": spec.name, "path": spec.path, "n_modes": st.modal.n_modes,
             "frequencies_hz": [float(x) for x in st.modal.frequencies_hz],
             "damping_ratios": [float(x) for x in st.modal.zeta],
             "joints": [{"name": j.name, "dofs": [j.dof_a, j.dof_b], "k_model": j.k_model, "law": j.law.summary(),
                         "motion": j.motion, "units": j.units} for j in spec.joints],
             "force": dict(spec.force), "response": list(response),
             "response_units": {d: spec.response_units.get(d, "m") for d in response}}
    settings = {"frequency_range_hz": [float(band[0]), float(band[1])], "n_harmonics": H, "n_time": N,
                "force_levels": [float(x) for x in levels]}
    out = []
    for F in levels:
        lv = LevelPrediction(float(F))
        t0 = time.process_time()
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always", ConvergenceWarning)
                curve = st.frequency_response(band[0], band[1], float(F), H, N)
            for w in caught:  # a continuation stopped early: the level's warning; any other warning as it came
                if issubclass(w.category, ConvergenceWarning):
                    msg = str(w.message).replace("; returning the partial curve", "")
                    lv.warnings.append(f"{msg}: the curve is partial, its peak unsure")
                else:
                    warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
        except ConvergenceError as exc:
            lv.error = str(exc)
            out.append(lv)
            if progress:
                progress(f"F = {F:g}: {exc}")
            continue
        cost = time.process_time() - t0
        pts = curve.points
        lv.frequency_hz = [float(p.frequency_hz) for p in pts]
        end_hz = pts[-1].frequency_hz
        if not lv.warnings and not any(math.isclose(end_hz, b, rel_tol=1e-9) for b in band):
            lv.warnings.append(f"the curve ends at {end_hz:.6g} Hz, inside the band: it is partial, its peak unsure")
        for d in response:
            amp = [float(abs(to_complex(st.response(p, [d])[d])[1])) for p in pts]
            lv.amplitude[d] = amp
            top = int(np.argmax(amp))
            if top == 0 or top == len(amp) - 1:  # the largest amplitude at an end of the curve: no peak in the band
                lv.peaks[d] = {"peak_frequency_hz": None, "peak_amplitude": None, "located": "no peak",
                               "largest_amplitude": amp[top], "largest_at_hz": lv.frequency_hz[top]}
                continue
            fpk, apk = located_peak(lv.frequency_hz, amp)
            refined = _refined_peak(st, pts, curve.folds, amp, d, float(F), H, N)
            located = "refined" if refined is not None else "between points"
            if refined is not None:
                fpk, apk = refined
            lv.peaks[d] = {"peak_frequency_hz": fpk, "peak_amplitude": apk, "located": located}
        lv.peak_point = pts[int(np.argmax(lv.amplitude[response[0]]))] if response else None
        lv.modal_max = np.abs(to_complex(np.array([p.modal for p in pts]))[..., 1]).max(axis=0)
        lv.folds_hz = [float(pts[i].frequency_hz) for i in curve.folds]
        lv.n_points = len(pts)
        lv.newton_iterations_mean = float(np.mean([p.iterations for p in pts]))
        lv.max_residual = float(max(p.residual_norm for p in pts))
        lv.seconds_per_point = cost / max(len(pts), 1)
        out.append(lv)
        if progress:
            progress(f"F = {F:g}: {len(pts)} points, {len(lv.folds_hz)} fold(s)"
                     + (f"; no peak in the band at {', '.join(lv.no_peak)}" if lv.no_peak else "")
                     + "".join(f"; {w}" for w in lv.warnings))
    plan = _backbone_plan(st, band, out)
    settings["backbone_modes"] = [r + 1 for r, top in plan if top > 0]
    settings["backbone_modes_not_excited"] = [r + 1 for r, top in plan if not top > 0]
    backbones = [_mode_backbone(st, spec, r, top, H, N, response) for r, top in plan if top > 0]
    if progress:
        for b in backbones:
            progress(f"nonlinear mode {b.mode}: {len(b.amplitude)} points" + (f"; {b.error}" if b.error else ""))
    n_checks = min(3, len(out)) if time_check is None else int(time_check)
    settings["time_check_points"] = n_checks
    checks = _time_checks(st, out, response, n_checks)
    if progress and checks:
        done = [c for c in checks if c["relative_difference"] is not None]
        bad = [c for c in checks if c["error"]]
        skipped = [c for c in checks if c["not_done"]]
        parts = ([f"fundamental within {max(c['relative_difference'] for c in done):.1e}"] if done else []) \
            + ([f"{len(bad)} FAILED ({bad[0]['error']})"] if bad else []) \
            + ([f"{len(skipped)} not done ({skipped[0]['not_done']})"] if skipped else [])
        progress(f"time integration from {len(checks)} peak(s): " + "; ".join(parts))
    flags = _model_warnings(st, spec, band) + _backbone_warnings(backbones)
    return StructurePrediction(spec.path, model, settings, out, backbones, checks, flags)


def _model_warnings(st, spec, band) -> list:
    """What makes the model implausible at rest: a negative stiffness (statically unstable: the joints' stiffness
    at rest less ``k_model`` makes the modal stiffness indefinite), a negative damping (modal damping with the
    joints' viscous terms), an elastic mode in the band without any damping at rest."""
    e = st.engine
    out = []
    psi, el = e.joint_shapes, ~e._rigid
    k_rest, c_rest = [], []
    for j in spec.joints:
        try:
            k_rest.append(stuck_stiffness(j.law) - j.k_model)
        except (AttributeError, TypeError):  # a law without a stiffness at rest known here
            k_rest.append(0.0)
        terms = dict(getattr(j.law, "terms", ()) or ())
        c_rest.append(float(terms.get("q'", 0.0)))
    K = np.diag(e.omega**2) + psi.T @ (np.array(k_rest)[:, None] * psi)
    C = np.diag(2 * e.zeta * e.omega) + psi.T @ (np.array(c_rest)[:, None] * psi)
    K, C = K[np.ix_(el, el)], C[np.ix_(el, el)]
    if K.size:
        lam = np.linalg.eigvalsh(K)
        if lam[0] < -1e-9 * max(float(np.abs(lam).max()), 1e-300):
            ks = ", ".join(f"{j.name!r} {k:.4g}" for j, k in zip(spec.joints, k_rest))
            out.append(f"statically unstable: with the joints' stiffness at rest less k_model ({ks}) the modal "
                       f"stiffness has a negative eigenvalue ({lam[0]:.4g} 1/s^2): the rest position is unstable "
                       "and the responses around it are no physical motion")
        mu = np.linalg.eigvalsh(C)
        if mu[0] < -1e-9 * max(float(np.abs(mu).max()), 1e-300):
            cs = ", ".join(f"{j.name!r} q' = {c:.4g}" for j, c in zip(spec.joints, c_rest) if c)
            out.append(f"negative damping at rest: the modal damping with the joints' viscous terms ({cs}) has a "
                       f"negative eigenvalue ({mu[0]:.4g} 1/s): the joints feed energy in")
        idx = np.flatnonzero(el)
        f = e.omega / (2 * np.pi)
        undamped = [int(r) + 1 for k, r in enumerate(idx)
                    if band[0] <= f[r] <= band[1] and abs(C[k, k]) <= 1e-12 * e.omega[r]]
        if undamped:
            out.append(f"mode(s) {', '.join(map(str, undamped))} in the band have no damping at rest (modal damping "
                       "ratio 0 and no viscous joint term): their resonance is bounded only by the joints' slip, if "
                       "at all")
    return out


def _backbone_warnings(backbones) -> list:
    """A nonlinear mode whose damping ratio turns negative: the model feeds energy in there."""
    out = []
    for b in backbones:
        z = np.asarray(b.damping_ratio, float)
        if z.size and float(z.min()) < -1e-6:
            i = int(np.argmin(z))
            out.append(f"nonlinear mode {b.mode}: negative damping ratio {z[i]:.3g} at modal amplitude "
                       f"{b.amplitude[i]:.3g}: the model feeds energy in there")
    return out


def _backbone_plan(st, band, levels):
    """``(mode index, largest modal amplitude)`` of the modes whose backbones are computed.

    The elastic modes with a natural frequency in the band, else the elastic mode nearest to
    it; amplitudes up to 1.5 times the largest first-harmonic modal amplitude on the computed
    curves (the linear resonance amplitude at the largest force where no curve was computed).
    A mode the force does not excite gets no amplitude scale (0): it is listed, not computed.
    """
    e = st.engine
    f = e.omega / (2 * np.pi)
    elastic = np.flatnonzero(~e._rigid)
    modes = [int(r) for r in elastic if band[0] <= f[r] <= band[1]]
    if not modes and elastic.size:
        modes = [int(elastic[np.argmin(np.minimum(abs(f[elastic] - band[0]), abs(f[elastic] - band[1])))])]
    plan = []
    every = max([float(lv.modal_max.max()) for lv in levels if lv.modal_max is not None] or [0.0])
    for r in modes:
        reached = [float(lv.modal_max[r]) for lv in levels if lv.modal_max is not None]
        if reached and max(reached) > 1e-9 * every:
            top = 1.5 * max(reached)
        elif reached:
            top = 0.0
        else:
            Fmax = max(lv.force_level for lv in levels)
            d = 2 * e.zeta[r] * e.omega[r] ** 2
            top = abs(e.force_shape[r]) * Fmax / d if d > 0 else 0.0
        plan.append((r, float(top)))
    return plan


def _mode_backbone(st, spec, r, top, H, N, response, n_points=20) -> ModeBackbone:
    e = st.engine
    b = ModeBackbone(r + 1, float(e.omega[r] / (2 * np.pi)), float(e.zeta[r]))
    t0 = time.process_time()
    bb = epmc_backbone(e, r, np.geomspace(1e-3 * top, top, n_points), H, n_time=N, partial=True)
    cost = time.process_time() - t0
    b.error = bb.error
    if not len(bb):
        return b
    b.amplitude = [float(x) for x in bb.amplitude]
    b.frequency_hz = [float(x) for x in bb.frequency_hz]
    b.damping_ratio = [float(x) for x in bb.damping_ratio]
    ja = bb.joint_amplitude
    b.joint_amplitude = {j.name: [float(x) for x in ja[:, i]] for i, j in enumerate(spec.joints)}
    for d in response:
        shape = st.modal.shape(d)
        b.response_amplitude[d] = [float(abs(to_complex(shape @ p.modal)[1])) for p in bb.points]
    b.newton_iterations_mean = float(np.mean([p.iterations for p in bb.points]))
    b.max_residual = float(max(p.residual_norm for p in bb.points))
    b.seconds_per_point = cost / len(bb)
    return b


def write_structure_predictions(result: StructurePrediction, out, inputs=()) -> dict:
    """``results.json``, ``report.txt``, ``figures/structure_frf.png`` (the backbones dashed) and
    ``figures/backbones.png`` in ``out`` as one output set."""
    from ..io.outputset import new_run_id, output_set
    from ..io.results import atomic_write, write_json
    from ..report.html import figure_to_png
    from ..report.structure_plots import plot_backbones, plot_structure_frf

    final = Path(out)
    run_id = new_run_id()
    summary = result.summary()
    summary["run_id"] = run_id
    with output_set(final, run_id, kind="predict", inputs=inputs) as tmp:
        paths = {"results": write_json(tmp / "results.json", summary),
                 "report": atomic_write(tmp / "report.txt", result.report() + f"\n\nrun id {run_id}\n")}
        fig = plot_structure_frf(result)
        atomic_write(tmp / "figures" / "structure_frf.png", figure_to_png(fig, dpi=110))
        paths["figures"] = [tmp / "figures" / "structure_frf.png"]
        fig = plot_backbones(result.backbones, result.model["name"])
        if fig is not None:
            atomic_write(tmp / "figures" / "backbones.png", figure_to_png(fig, dpi=110))
            paths["figures"].append(tmp / "figures" / "backbones.png")
    rel = (lambda v: final / Path(v).relative_to(tmp))
    return {k: ([rel(x) for x in v] if isinstance(v, list) else rel(v)) for k, v in paths.items()}
