"""Nonlinear frequency responses of a structure model file (``MODEL.toml``).

:func:`predict_structure` reads the model (:mod:`jointid.io.structure_model`), computes at
each force level the frequency response over the band by the multi-mode harmonic balance
condensed on the joint DOFs, continued through folds
(:mod:`jointid.simulate.structure_hb`), and reports per level the peak of the first-harmonic
amplitude at every response DOF (located between the continued points), the folds, the
Newton iterations, the largest relative residual and the cost per point.  The stability of
the points is not reported: Hill's method with the periodic-map Jacobian of slider laws
(:meth:`jointid.simulate.structure_hb.CondensedHB.growth_rate`) is not yet checked for them.
:func:`write_structure_predictions` writes ``results.json``, ``report.txt`` and a figure as
one output set.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import ConvergenceError, ManifestError
from ..io.structure_model import read_structure_model
from ..simulate.structure import structure_from_spec
from ..simulate.structure_hb import default_n_time, to_complex

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

    def summary(self) -> dict:
        out = {
            "force_level": self.force_level,
            "peaks": self.peaks,
            "folds_hz": self.folds_hz,
            "n_points": self.n_points,
            "newton_iterations_mean": _finite_or_none(self.newton_iterations_mean),
            "max_residual": _finite_or_none(self.max_residual),
            "curve": {"frequency_hz": self.frequency_hz, "amplitude": self.amplitude},
            "timing": {"seconds_per_point": _finite_or_none(self.seconds_per_point)},
            "error": self.error,
        }
        return out


def _finite_or_none(x):
    return float(x) if x is not None and math.isfinite(x) else None


@dataclass
class StructurePrediction:
    source: str
    model: dict
    settings: dict
    levels: list

    @property
    def failed(self) -> list:
        return [lv for lv in self.levels if lv.error]

    def summary(self) -> dict:
        return {"kind": "structure prediction", "source": self.source, "model": self.model,
                "settings": self.settings, "predictions": [lv.summary() for lv in self.levels]}

    def lines(self) -> list:
        out = [f"structure model {self.model['name']} ({self.source}): {self.model['n_modes']} modes, "
               f"{len(self.model['joints'])} joint element(s); harmonics 0..{self.settings['n_harmonics']}, "
               f"{self.settings['n_time']} time samples"]
        for lv in self.levels:
            if lv.error:
                out.append(f"F = {lv.force_level:g}: FAILED: {lv.error}")
                continue
            pk = "; ".join(f"{d} peak {p['peak_amplitude']:.4g} m at {p['peak_frequency_hz']:.6g} Hz"
                           for d, p in lv.peaks.items())
            folds = ", ".join(f"{f:.6g}" for f in lv.folds_hz) or "none"
            out.append(f"F = {lv.force_level:g}: {pk}; folds at {folds} Hz; {lv.n_points} points, "
                       f"{lv.newton_iterations_mean:.2g} Newton iterations per point, residual <= "
                       f"{lv.max_residual:.1e}, {1e3 * lv.seconds_per_point:.3g} ms per point")
        return out

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


def predict_structure(model_toml, *, force_levels=None, frequency_range=None, n_harmonics=None, n_time=None,
                      progress=None) -> StructurePrediction:
    """Frequency responses of the structure in ``model_toml`` at each force level.

    Arguments left at None come from the file's ``[predict]`` table (the band and the force
    levels are then required there; harmonics default 5).
    """
    spec = read_structure_model(model_toml)
    pred = spec.predict
    levels = list(force_levels) if force_levels is not None else pred.get("force_levels")
    band = tuple(frequency_range) if frequency_range is not None else pred.get("frequency_range_hz")
    if not levels:
        raise ManifestError(f"{spec.path}: predict.force_levels: missing (or give the force levels)")
    if band is None:
        raise ManifestError(f"{spec.path}: predict.frequency_range_hz: missing (or give the frequency range)")
    if not (0 < band[0] < band[1]):
        raise ManifestError(f"{spec.path}: frequency range {band}: expected 0 < low < high")
    H = int(n_harmonics if n_harmonics is not None else pred.get("n_harmonics", 5))
    N = int(n_time if n_time is not None else pred.get("n_time", default_n_time(H)))
    st, response = structure_from_spec(spec)
    model = {"name": spec.name, "path": spec.path, "n_modes": st.modal.n_modes,
             "frequencies_hz": [float(x) for x in st.modal.frequencies_hz],
             "damping_ratios": [float(x) for x in st.modal.zeta],
             "joints": [{"name": j.name, "dofs": [j.dof_a, j.dof_b], "k_model": j.k_model, "law": j.law.summary()}
                        for j in spec.joints],
             "force": dict(spec.force), "response": list(response)}
    settings = {"frequency_range_hz": [float(band[0]), float(band[1])], "n_harmonics": H, "n_time": N,
                "force_levels": [float(x) for x in levels]}
    out = []
    for F in levels:
        lv = LevelPrediction(float(F))
        t0 = time.process_time()
        try:
            curve = st.frequency_response(band[0], band[1], float(F), H, N)
        except ConvergenceError as exc:
            lv.error = str(exc)
            out.append(lv)
            if progress:
                progress(f"F = {F:g}: {exc}")
            continue
        cost = time.process_time() - t0
        pts = curve.points
        lv.frequency_hz = [float(p.frequency_hz) for p in pts]
        for d in response:
            amp = [float(abs(to_complex(st.response(p, [d])[d])[1])) for p in pts]
            lv.amplitude[d] = amp
            fpk, apk = located_peak(lv.frequency_hz, amp)
            refined = _refined_peak(st, pts, curve.folds, amp, d, float(F), H, N)
            located = "refined" if refined is not None else "between points"
            if refined is not None:
                fpk, apk = refined
            lv.peaks[d] = {"peak_frequency_hz": fpk, "peak_amplitude": apk, "located": located}
        lv.folds_hz = [float(pts[i].frequency_hz) for i in curve.folds]
        lv.n_points = len(pts)
        lv.newton_iterations_mean = float(np.mean([p.iterations for p in pts]))
        lv.max_residual = float(max(p.residual_norm for p in pts))
        lv.seconds_per_point = cost / max(len(pts), 1)
        out.append(lv)
        if progress:
            progress(f"F = {F:g}: {len(pts)} points, {len(lv.folds_hz)} fold(s)")
    return StructurePrediction(spec.path, model, settings, out)


def write_structure_predictions(result: StructurePrediction, out, inputs=()) -> dict:
    """``results.json``, ``report.txt`` and ``figures/structure_frf.png`` in ``out`` as one output set."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..io.outputset import new_run_id, output_set
    from ..io.results import atomic_write, write_json
    from ..report.html import figure_to_png

    final = Path(out)
    run_id = new_run_id()
    summary = result.summary()
    summary["run_id"] = run_id
    with output_set(final, run_id, kind="predict", inputs=inputs) as tmp:
        paths = {"results": write_json(tmp / "results.json", summary),
                 "report": atomic_write(tmp / "report.txt", result.report() + f"\n\nrun id {run_id}\n")}
        resp = result.model["response"]
        fig, axes = plt.subplots(len(resp), 1, figsize=(7, 2.6 * len(resp) + 0.6), squeeze=False)
        for ax, d in zip(axes[:, 0], resp):
            for lv in result.levels:
                if lv.error:
                    continue
                line, = ax.plot(lv.frequency_hz, lv.amplitude[d], lw=1.2, label=f"F = {lv.force_level:g}")
                pk = lv.peaks[d]
                ax.plot(pk["peak_frequency_hz"], pk["peak_amplitude"], "o", color=line.get_color(), ms=4)
            ax.set_ylabel(f"|{d}| first harmonic")
            ax.grid(alpha=0.3)
        axes[-1, 0].set_xlabel("frequency [Hz]")
        axes[0, 0].legend(fontsize=8)
        axes[0, 0].set_title(f"{result.model['name']}: multi-harmonic balance with continuation (dots: peaks)")
        fig.tight_layout()
        atomic_write(tmp / "figures" / "structure_frf.png", figure_to_png(fig, dpi=110))
        plt.close(fig)
        paths["figures"] = [tmp / "figures" / "structure_frf.png"]
    rel = (lambda v: final / Path(v).relative_to(tmp))
    return {k: ([rel(x) for x in v] if isinstance(v, list) else rel(v)) for k, v in paths.items()}
