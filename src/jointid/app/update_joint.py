"""Updating a joint law in a structure model to measured first harmonics (``jointid update``).

The structure model (``MODEL.toml``, docs/formats.md "Structure model") carries a joint
element whose law parameters are the starting values.  The measurements are first-harmonic
FRF points: per force level, the first harmonic of the displacement at a named DOF at each
dwell frequency (``MEASURED.csv``, docs/formats.md "Measured first harmonics for updating").

Besides the law's parameters, ``zeta_<r>`` fits the modal damping ratio of mode ``r`` (1-based)
of the linear model: a damping ratio estimated at a low level (a random test) holds the joint's
own micro-slip dissipation there, which the law then counts a second time.

The fitted parameters ``theta`` (log of each positive parameter, the others as they are)
minimise by :func:`scipy.optimize.least_squares`

``sum_i |X_model(f_i, F_i; theta) - X_i|^2 / se_i^2``

over the real and imaginary parts of every point, where ``X_model`` is the first harmonic of
the multi-harmonic balance of :mod:`jointid.simulate.structure_hb` at the measured frequency
and force (the dwells of a level solved in file order, each started from its predecessor:
the branch a stepped sweep follows).  The covariance is ``(J^T J)^-1`` of the weighted
residual Jacobian, multiplied by ``chi^2 / dof`` when that exceeds one (said in the result);
standard errors by the delta method, 95 % intervals ``theta +- 1.96 se`` mapped back (so
asymmetric for log parameters).

Leave-one-level-out: with at least two levels, each level in turn is left out, the law
refitted on the others, and the left-out level's frequency response predicted by
continuation over its measured band; its peak (located between the continued points) is
compared on the same branch: the model solved at the left-out dwells in their order, the
peak located by one estimator (quadratic through the largest dwell and its neighbours, only
where that dwell is inside the band) on the predicted and on the measured dwells, errors in
%, and the rms amplitude error over the dwells.  The model's own peak between continued
points is reported beside (``model_peak_*``): a quadratic through dwells is coarser than
the prediction and would blame it for the dwell spacing.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.optimize

from ..errors import (
    ConvergenceError,
    IdentificationError,
    ManifestError,
    StructureError,
)
from ..io.structure_model import read_structure_model
from ..numerics.intervals import Z95
from ..rounding import format_ci, format_pm, format_value
from ..simulate.structure import (
    JointElement,
    ModalModel,
    StructureModel,
    structure_from_spec,
)
from ..simulate.structure_hb import to_complex, warm_sweep
from .structure_predict import located_peak
from .update_backbone import (
    FRF_COLUMNS,
    MeasuredBackbone,
    backbone_curve,
    backbone_response,
    check_backbone,
    dof_cell,
    measured_kind,
    number_cell,
    read_measured_backbone,
    table_rows,
)

__all__ = ["JointUpdate", "MeasuredBackbone", "MeasuredFRF", "read_measured", "read_measured_backbone",
           "read_measured_frf", "update_joint", "update_structure_joint", "write_update"]

#: Weighted residual of every point where the model cannot be solved (steers the fit away from there).
_FAILED = 1e6
#: Above this chi2/dof the fit is flagged inadequate (results.json ``fit_adequate``; the command exits 1).
ADEQUATE_CHI2_PER_DOF = 4.0
#: A positive law parameter fitted further than this factor from its start is flagged (``far_from_start``; exit 1):
#: a unit slip in a measured file (amplitudes in mm for m scale a Jenkins joint's slip force by 1000 and fit
#: as well: the fit alone cannot tell) or a parameter running away where the data do not hold it.
FAR_FROM_START = 100.0


def _exp(t) -> float:
    """``exp(t)``, inf where that overflows (an unbounded interval, a step of the optimiser far out)."""
    try:
        return math.exp(t)
    except OverflowError:
        return math.inf


@dataclass(frozen=True, eq=False)
class MeasuredFRF:
    """First harmonics ``x = a1 cos + b1 sin`` at ``dof``; ``se`` the standard error of a1 and of b1."""

    path: str
    force_level: np.ndarray
    frequency_hz: np.ndarray
    dof: tuple
    X: np.ndarray  # complex a1 - i b1
    se: np.ndarray
    origin: tuple = ()  # per point (file, line) where read from a file, else empty

    def levels(self):
        return sorted(set(self.force_level.tolist()))

    def subset(self, mask):
        m = np.asarray(mask, bool)
        return MeasuredFRF(self.path, self.force_level[m], self.frequency_hz[m],
                           tuple(d for d, k in zip(self.dof, m) if k), self.X[m], self.se[m],
                           tuple(o for o, k in zip(self.origin, m) if k))

    def where(self, i) -> str:
        """``"file: line n"`` of point ``i`` (``"file"`` without line numbers)."""
        return f"{self.origin[i][0]}: line {self.origin[i][1]}" if self.origin else self.path


def _refuse_repeated_points(keys, origins, what):
    """:class:`ManifestError` at the second occurrence of a key (one measured point given twice)."""
    seen = {}
    for key, (f, ln) in zip(keys, origins):
        if key in seen:
            f0, ln0 = seen[key]
            first = f"line {ln0}" if f0 == f else f"{f0}: line {ln0}"
            raise ManifestError(f"{f}: line {ln} repeats the point of {first} ({what(key)}): each point once, "
                                "or it counts twice and its standard error shrinks by sqrt 2")
        seen[key] = (f, ln)


def read_measured_frf(path) -> MeasuredFRF:
    """Read a MEASURED.csv; bad input -> :class:`ManifestError` naming the file, row and column."""
    p = Path(path)
    vals = {c: [] for c in FRF_COLUMNS if c != "dof"}
    dofs, lines = [], []
    for i, r in table_rows(p, "measured first-harmonic file", FRF_COLUMNS):  # i: the line of the file
        for c, col in vals.items():
            v = number_cell(p, i, r, c)
            if c in ("force_level", "frequency_hz", "se") and v <= 0:
                raise ManifestError(f"{p}: line {i}, column {c}: must be > 0, got {v:g}")
            col.append(v)
        dofs.append(dof_cell(p, i, r))
        lines.append(i)
    a1, b1 = np.array(vals["a1"]), np.array(vals["b1"])
    origin = tuple((str(p), i) for i in lines)
    _refuse_repeated_points(zip(vals["force_level"], vals["frequency_hz"], dofs, vals["a1"], vals["b1"]), origin,
                            _frf_key)
    return MeasuredFRF(str(p), np.array(vals["force_level"]), np.array(vals["frequency_hz"]), tuple(dofs),
                       a1 - 1j * b1, np.array(vals["se"]), origin)


def _frf_key(key):
    """A measured first harmonic's identity: level, frequency, DOF and the measured a1, b1 (the same frequency
    measured again on another branch, a sweep up and down through a jump, is another point)."""
    return f"force_level {key[0]:g}, frequency_hz {key[1]:g}, dof {key[2]}, a1 {key[3]:g}, b1 {key[4]:g}"


def _with_law(model: StructureModel, j: int, law, zeta=None) -> StructureModel:
    """``model`` with joint ``j``'s law replaced and, given ``{mode index: ratio}``, modal damping ratios."""
    joints = list(model.joints)
    old = joints[j]
    joints[j] = JointElement(old.name, old.dof_a, old.dof_b, law, old.k_model)
    modal = model.modal
    if zeta:
        z = modal.zeta.copy()
        for r, v in zeta.items():
            z[r] = v
        modal = ModalModel(modal.omega, z, modal.dof_names, modal.shapes)
    return StructureModel(modal, joints, model.force)


def _zeta_mode(name):
    """``"zeta_2"`` -> 1 (the mode's index), other names -> None."""
    head, _, num = name.partition("_")
    return int(num) - 1 if head == "zeta" and num.isdigit() and int(num) >= 1 else None


class _Fitter:
    def __init__(self, model, joint, names, n_harmonics, n_time):
        self.model, self.j, self.names = model, joint, list(names)
        self.H, self.N = int(n_harmonics), n_time
        law = model.joints[joint].law
        p0 = {**law.parameters, **{k: float(model.modal.zeta[_zeta_mode(k)]) for k in self.names
                                   if _zeta_mode(k) is not None}}
        self.start = {k: p0[k] for k in self.names}
        self.log = [p0[k] > 0 for k in self.names]
        self.theta0 = np.array([math.log(p0[k]) if lg else p0[k] for k, lg in zip(self.names, self.log)])

    def _values(self, theta):
        return {k: (_exp(t) if lg else float(t)) for k, t, lg in zip(self.names, theta, self.log)}

    def law(self, theta):
        vals = {k: v for k, v in self._values(theta).items() if _zeta_mode(k) is None}
        return self.model.joints[self.j].law.replace(**vals)

    def structure(self, theta) -> StructureModel:
        """The structure model at ``theta`` (the joint's law and any fitted modal damping ratios)."""
        zeta = {_zeta_mode(k): v for k, v in self._values(theta).items() if _zeta_mode(k) is not None}
        return _with_law(self.model, self.j, self.law(theta), zeta)

    def responses(self, theta, meas: MeasuredFRF, m=None):
        """Model first harmonics at the measured points: per level, its dwells (runs of one frequency in
        file order: the sensors of one dwell share one solve) swept in order, each started from its
        predecessors (:func:`jointid.simulate.structure_hb.warm_sweep`).  ``m``: the structure at
        ``theta`` when the caller has it."""
        m = self.structure(theta) if m is None else m
        out = np.empty(meas.X.size, complex)
        for lv in meas.levels():
            idx = np.flatnonzero(meas.force_level == lv)
            f = meas.frequency_hz[idx]
            new = np.r_[True, f[1:] != f[:-1]]  # the first point of each dwell
            dwell = np.cumsum(new) - 1
            pts = warm_sweep(lambda fh, guess, lv=lv: m.solve(fh, lv, self.H, n_time=self.N, guess=guess), f[new],
                             frequency=lambda p: p.frequency_hz)
            for i, k in zip(idx, dwell):
                out[i] = to_complex(m.modal.shape(meas.dof[i]) @ pts[k].modal)[1]
        return out

    def backbones(self, theta, bbs, m=None):
        """Model ``(frequency [Hz], damping ratio)`` at the points of each measured backbone."""
        if not bbs:
            return []
        m = self.structure(theta) if m is None else m
        return [backbone_response(m, bb, self.H, self.N) for bb in bbs]

    def residual(self, theta, meas, bbs=()):
        """Weighted residuals: real and imaginary parts of the FRF points (``meas``, may be None), then per
        backbone the frequencies and the damping ratios over their standard errors."""
        n = (2 * meas.X.size if meas is not None else 0) + sum(2 * bb.n for bb in bbs)
        parts = []
        if not all(math.isfinite(v) and v != 0 for v, lg in zip(self._values(theta).values(), self.log) if lg) \
                or not np.all(np.isfinite(theta)):
            return np.full(n, _FAILED)  # a step of the optimiser out of range (a log parameter at 0 or inf)
        try:
            m = self.structure(theta)  # one structure for both kinds of points
            if meas is not None:
                d = (self.responses(theta, meas, m) - meas.X) / meas.se
                parts += [d.real, d.imag]
            for bb, (f, z) in zip(bbs, self.backbones(theta, bbs, m)):
                parts += list(bb.z_scores(f, z))
        except (ConvergenceError, StructureError):  # no steady state, or a step outside the law's bounds
            return np.full(n, _FAILED)
        return np.concatenate(parts)

    def fit(self, meas, theta0=None, bbs=()):
        th0 = self.theta0 if theta0 is None else theta0
        sol = scipy.optimize.least_squares(self.residual, th0, args=(meas, tuple(bbs)), method="lm", diff_step=1e-5,
                                           x_scale="jac", xtol=1e-10, ftol=1e-10, max_nfev=200)
        return sol


@dataclass
class JointUpdate:
    model_path: str
    measured_path: str
    joint: str
    law: str
    names: list
    units: dict
    start: dict
    estimate: dict
    stderr: dict
    ci95: dict
    log_parametrised: dict
    chi2: float
    dof: int
    covariance_scaled: bool
    correlation: list
    n_points: int
    n_harmonics: int
    nfev: int
    heldout: list = field(default_factory=list)
    warnings: list = field(default_factory=list)
    backbones: list = field(default_factory=list)  # per measured backbone: its points, measured and fitted
    heldout_backbone: dict = field(default_factory=dict)
    heldout_note: str = ""  # why ``heldout`` is empty (one level, not asked for, no first harmonics)
    far_from_start: dict = field(default_factory=dict)  # parameter -> estimate / start, beyond FAR_FROM_START
    fitted: dict = field(default_factory=dict)  # measured vs model first harmonics (for the figure), fitted model

    @property
    def chi2_per_dof(self) -> float:
        return self.chi2 / self.dof if self.dof > 0 else float("nan")

    @property
    def adequate(self) -> bool:
        """chi2/dof <= 4: the law fits the points to within twice their standard errors (rms)."""
        return bool(self.chi2_per_dof <= ADEQUATE_CHI2_PER_DOF)

    @property
    def flagged(self) -> bool:
        """Not adequate, or a positive law parameter ended more than :data:`FAR_FROM_START` times above or below
        its start (``far_from_start``): the command exits 1."""
        return not self.adequate or bool(self.far_from_start)

    def summary(self) -> dict:
        return {
            "kind": "joint_update", "model": self.model_path, "measured": self.measured_path,
            "joint": self.joint, "law": self.law, "units": self.units,
            "parameters": self.estimate, "start": self.start, "stderr": self.stderr, "ci95": self.ci95,
            "log_parametrised": self.log_parametrised, "correlation": self.correlation,
            "chi2": self.chi2, "dof": self.dof, "chi2_per_dof": self.chi2_per_dof, "fit_adequate": self.adequate,
            "covariance_scaled_by_chi2_per_dof": self.covariance_scaled,
            "n_points": self.n_points, "n_harmonics": self.n_harmonics, "function_evaluations": self.nfev,
            "heldout": self.heldout, "heldout_note": self.heldout_note, "far_from_start": self.far_from_start,
            "warnings": self.warnings,
            "n_backbone_points": sum(b["n_points"] for b in self.backbones), "backbones": self.backbones,
            "heldout_backbone": self.heldout_backbone,
        }

    def report(self) -> str:
        L = [f"joint update: {self.joint} ({self.law}) in {self.model_path}",
             (f"measured: {self.measured_path}, {self.n_points} first-harmonic points"
              + (f", {sum(b['n_points'] for b in self.backbones)} backbone points" if self.backbones else "")
              + f", harmonic balance H = {self.n_harmonics}"),
             f"chi2/dof = {self.chi2:.4g} / {self.dof} = {self.chi2_per_dof:.3f}"
             + (" (covariance scaled by it)" if self.covariance_scaled else " (covariance not scaled: <= 1)"),
             "", f"{'parameter':<10} {'start':>10} {'estimate ± standard error':>28} {'95 % interval':>24}  unit"]
        for k in self.names:
            lo, hi = self.ci95[k]
            if all(math.isfinite(x) for x in (lo, hi, self.stderr[k])):
                pm, ci = format_pm(self.estimate[k], self.stderr[k]), format_ci(self.ci95[k], self.stderr[k])
            else:  # not resolved: the estimate where the fit stopped, the interval as it is (inf, or none)
                pm = f"{format_value(self.estimate[k])} (not resolved)"
                ci = "–" if math.isnan(lo) or math.isnan(hi) else \
                    "[" + ", ".join(format_value(x) if math.isfinite(x) else f"{x:g}" for x in (lo, hi)) + "]"
            L.append(f"{k:<10} {self.start[k]:>10.6g} {pm:>28} {ci:>24}  {self.units.get(k, '')}")
        for b in self.backbones:
            L += ["", (f"backbone {b['file']} ({b['n_points']} points, chi2 {b['chi2']:.4g}): amplitude at dof, "
                       "frequency [Hz] and damping ratio [%], measured ± se and fitted"),
                  (f"{'dof':>8} {'mode':>4} {'amplitude':>11} {'f measured':>22} {'f model':>11} "
                   f"{'zeta measured %':>20} {'zeta model %':>12}")]
            for p in b["points"]:
                L.append(f"{p['dof']:>8} {p['mode']:>4} {p['amplitude']:>11.4e} "
                         f"{format_pm(p['frequency_hz'], p['se_frequency_hz']):>22} {p['model_frequency_hz']:>11.6g} "
                         f"{format_pm(100 * p['damping_ratio'], 100 * p['se_damping_ratio']):>20} "
                         f"{100 * p['model_damping_ratio']:>12.5g}")
        hb = self.heldout_backbone
        if hb:
            L += ["", f"backbone held out ({hb['how']}):"]
            if hb.get("note"):
                L.append(f"  {hb['note']}")
            if "n_points" in hb:
                L.append(f"  {hb['n_points']} points predicted: rms z frequency {hb['rms_z_frequency']:.3g}, "
                         f"damping {hb['rms_z_damping']:.3g}; max |error| frequency "
                         f"{hb['max_abs_frequency_error_pct']:.4g} %, damping ratio "
                         f"{hb['max_abs_damping_error_pct']:.4g} %")
        if self.heldout_note:
            L += ["", f"leave-one-level-out: none, {self.heldout_note}"]
        if self.heldout:
            L += ["", "leave-one-level-out (fitted without the level, its response predicted):",
                  f"{'level':>8} {'peak f err %':>13} {'peak A err %':>13} {'rms A err %':>12}  note"]
            for h in self.heldout:
                def fmt(x):
                    return f"{x:+.4f}" if x is not None else "-"
                L.append(f"{h['force_level']:>8g} {fmt(h['peak_frequency_error_pct']):>13} "
                         f"{fmt(h['peak_amplitude_error_pct']):>13} {fmt(h['rms_amplitude_error_pct']):>12}  "
                         f"{h['note']}")
        for w in self.warnings:
            L.append(f"WARNING: {w}")
        return "\n".join(L)


def _measured_peak(f, a):
    """Peak of the dwells where they resolve it (largest dwell not at an end), else None."""
    o = np.argsort(f)
    f, a = f[o], a[o]
    i = int(np.argmax(a))
    if i == 0 or i == a.size - 1:
        return None
    c = np.polyfit(f[i - 1:i + 2] - f[i], a[i - 1:i + 2], 2)
    if c[0] >= 0:
        return float(f[i]), float(a[i])
    df = float(np.clip(-c[1] / (2 * c[0]), f[i - 1] - f[i], f[i + 1] - f[i]))
    return float(f[i] + df), float(np.polyval(c, df))


def _heldout(fitter, meas, level, theta_all, n_harmonics, n_time, bbs=()):
    keep = meas.force_level != level
    out = meas.subset(~keep)
    dof = out.dof[0]
    row = {"force_level": level, "dof": dof, "parameters": None,
           "peak_frequency_error_pct": None, "peak_amplitude_error_pct": None, "rms_amplitude_error_pct": None,
           "note": ""}
    if 2 * int(keep.sum()) + 2 * sum(bb.n for bb in bbs) <= len(fitter.names):
        row["note"] = "too few points left without this level to fit the parameters"
        return row
    sol = fitter.fit(meas.subset(keep), theta0=theta_all, bbs=bbs)
    if np.all(sol.fun == _FAILED):
        row["note"] = "the fit without this level found no parameters where the model can be solved"
        return row
    row["parameters"] = {k: float(v) for k, v in fitter.law(sol.x).parameters.items()}
    sv = np.linalg.svd(sol.jac, compute_uv=False)
    weak = "the points kept do not determine every parameter (singular Jacobian): the prediction is weak; " \
        if not sv[-1] > 1e-8 * sv[0] else ""
    row["note"] = weak.rstrip("; ")
    try:
        pred = fitter.responses(sol.x, out)
    except (ConvergenceError, StructureError) as exc:
        row["note"] = f"{weak}dwell prediction failed: {exc}"
        return row
    row["rms_amplitude_error_pct"] = float(100 * np.sqrt(np.mean((np.abs(pred) / np.abs(out.X) - 1) ** 2)))
    mp = _measured_peak(out.frequency_hz, np.abs(out.X))
    pp = _measured_peak(out.frequency_hz, np.abs(pred))
    if mp is None or pp is None:
        row["note"] = f"{weak}peak not resolved by the dwells (largest dwell at an end of the band)"
        return row
    # like with like: the same estimator on the predicted and the measured dwells (same branch)
    row.update(measured_peak_frequency_hz=mp[0], measured_peak_amplitude=mp[1],
               predicted_peak_frequency_hz=pp[0], predicted_peak_amplitude=pp[1],
               peak_frequency_error_pct=100 * (pp[0] / mp[0] - 1), peak_amplitude_error_pct=100 * (pp[1] / mp[1] - 1))
    # the model's own peak between continued points (not limited by the dwell spacing)
    m = fitter.structure(sol.x)
    try:
        curve = m.frequency_response(float(out.frequency_hz.min()), float(out.frequency_hz.max()), level,
                                     n_harmonics, n_time=n_time)
        amp = np.array([abs(to_complex(m.modal.shape(dof) @ p.modal)[1]) for p in curve.points])
        cf, ca = located_peak(curve.frequency_hz, amp)
        row.update(model_peak_frequency_hz=cf, model_peak_amplitude=ca)
    except (ConvergenceError, StructureError) as exc:
        row["note"] = f"{weak}continuation of the predicted curve failed: {exc}"
    return row


def _backbone_points(bb, f, z):
    return [{"line": int(ln), "dof": d, "mode": int(r), "amplitude": float(a), "frequency_hz": float(fm),
             "se_frequency_hz": float(sf), "damping_ratio": float(zm), "se_damping_ratio": float(sz),
             "model_frequency_hz": float(fp), "model_damping_ratio": float(zp)}
            for ln, d, r, a, fm, sf, zm, sz, fp, zp in zip(bb.line, bb.dof, bb.mode, bb.amplitude, bb.frequency_hz,
                                                             bb.se_frequency_hz, bb.damping_ratio,
                                                             bb.se_damping_ratio, f, z)]


def _lower_half(bb):
    """Points of ``bb`` at or below the median amplitude of their own DOF and mode."""
    keys = list(zip(bb.dof, bb.mode.tolist()))
    med = {k: np.median([a for kk, a in zip(keys, bb.amplitude) if kk == k]) for k in set(keys)}
    return np.array([a <= med[k] for k, a in zip(keys, bb.amplitude)])


def _heldout_backbone(fitter, meas, bbs, n_par):
    """The backbones predicted by a fit that has not seen them (FRF points only), or, without FRF points,
    the upper half of each backbone's amplitudes predicted from the lower half."""
    if meas is not None:
        how, fit_bbs, test_bbs = "fitted to the FRF points only, the backbones predicted", (), list(bbs)
        if 2 * meas.X.size <= n_par:
            return {"how": how, "note": "too few FRF points to fit the parameters without the backbones"}
    else:
        how = "fitted to the lower half of each backbone's amplitudes, the upper half predicted"
        lows = [_lower_half(bb) for bb in bbs]
        fit_bbs = [bb.subset(lo) for bb, lo in zip(bbs, lows)]
        test_bbs = [bb.subset(~lo) for bb, lo in zip(bbs, lows)]
        fit_bbs = [b for b in fit_bbs if b.n]
        test_bbs = [b for b in test_bbs if b.n]
        if 2 * sum(b.n for b in fit_bbs) <= n_par or not test_bbs:
            return {"how": how, "note": "too few points in the lower half to fit the parameters"}
    out = {"how": how, "parameters": None, "note": ""}
    try:  # from the model file's start, not the full fit's estimate: what the points kept determine
        sol = fitter.fit(meas, bbs=fit_bbs)
        if np.all(sol.fun == _FAILED):
            out["note"] = "the fit without the held-out points found no parameters where the model can be solved"
            return out
        out["parameters"] = {k: float(v) for k, v in fitter._values(sol.x).items()}
        pred = fitter.backbones(sol.x, test_bbs)
    except (ConvergenceError, StructureError) as exc:
        out["note"] = f"prediction failed: {exc}"
        return out
    sv = np.linalg.svd(sol.jac, compute_uv=False)
    if sv[-1] <= 1e-8 * sv[0]:
        out["note"] = "the points kept do not determine every parameter (singular Jacobian): the prediction is weak"
    zf, zz = (np.concatenate(v) for v in zip(*(b.z_scores(f, z) for b, (f, z) in zip(test_bbs, pred))))
    ef = np.concatenate([100 * (f / b.frequency_hz - 1) for b, (f, _) in zip(test_bbs, pred)])
    ez = np.concatenate([100 * (z / b.damping_ratio - 1) for b, (_, z) in zip(test_bbs, pred)])
    out.update(n_points=int(zf.size), rms_z_frequency=float(np.sqrt(np.mean(zf ** 2))),
               rms_z_damping=float(np.sqrt(np.mean(zz ** 2))), max_abs_frequency_error_pct=float(np.abs(ef).max()),
               max_abs_damping_error_pct=float(np.abs(ez).max()),
               points=[p for b, (f, z) in zip(test_bbs, pred) for p in _backbone_points(b, f, z)])
    return out


def read_measured(paths):
    """``(MeasuredFRF or None, [MeasuredBackbone])`` from measured files, each recognised by its header
    (first harmonics: several files are joined; backbones: one target each)."""
    frfs, bbs, seen = [], [], {}
    for p in paths:
        kind = measured_kind(p)  # a missing file, a folder, an unknown header: said here
        real = os.path.realpath(p)
        if real in seen:
            again = "" if str(seen[real]) == str(p) else f" (also as {seen[real]})"
            raise ManifestError(f"{p}: measured file given twice{again}: its points would count twice and "
                                "their standard errors shrink by sqrt 2")
        seen[real] = p
        if kind == "frf":
            frfs.append(read_measured_frf(p))
        else:
            bbs.append(read_measured_backbone(p))
    # the same point in two files counts twice as surely as one file given twice
    _refuse_repeated_points([(d, int(r), a, f, z) for bb in bbs for d, r, a, f, z in
                             zip(bb.dof, bb.mode, bb.amplitude, bb.frequency_hz, bb.damping_ratio)],
                            [(bb.path, int(ln)) for bb in bbs for ln in bb.line],
                            lambda k: f"dof {k[0]}, mode {k[1]}, amplitude {k[2]:g}, frequency_hz {k[3]:g}, "
                                      f"damping_ratio {k[4]:g}")
    if not frfs:
        return None, bbs
    if len(frfs) == 1:
        return frfs[0], bbs
    joined = MeasuredFRF(", ".join(m.path for m in frfs), np.concatenate([m.force_level for m in frfs]),
                         np.concatenate([m.frequency_hz for m in frfs]), sum((m.dof for m in frfs), ()),
                         np.concatenate([m.X for m in frfs]), np.concatenate([m.se for m in frfs]),
                         sum((m.origin for m in frfs), ()))
    _refuse_repeated_points(zip(joined.force_level.tolist(), joined.frequency_hz.tolist(), joined.dof,
                                joined.X.real.tolist(), (-joined.X.imag).tolist()), joined.origin, _frf_key)
    return joined, bbs


def update_joint(model_path, measured, *, joint=None, parameters=None, n_harmonics=9, n_time=None,
                 heldout=True) -> JointUpdate:
    """Fit a joint law's parameters of ``model_path`` to measured first harmonics (see the module doc)."""
    spec = read_structure_model(model_path)
    model, _ = structure_from_spec(spec)
    items = measured if isinstance(measured, (list, tuple)) else [measured]
    meas, bbs = read_measured([m for m in items if not isinstance(m, (MeasuredFRF, MeasuredBackbone))])
    given = [m for m in items if isinstance(m, MeasuredFRF)]
    if given:
        if meas is not None or len(given) > 1:
            raise ManifestError("update: give the first harmonics as one MeasuredFRF or as files, not both")
        meas = given[0]
    bbs = [m for m in items if isinstance(m, MeasuredBackbone)] + bbs
    j = _joint_index(model, joint, spec.path)
    units = {k: spec.joints[j].units.get(k, "") for k in model.joints[j].law.parameters}
    return update_structure_joint(model, meas, joint=joint, parameters=parameters, n_harmonics=n_harmonics,
                                  n_time=n_time, heldout=heldout, source=str(spec.path), units=units,
                                  backbones=bbs)


def _joint_index(model, joint, source):
    names_j = [j.name for j in model.joints]
    if joint is None:
        return 0
    if joint in names_j:
        return names_j.index(joint)
    raise ManifestError(f"{source}: no joint named {joint!r} (joints: {', '.join(names_j)})")


def update_structure_joint(model: StructureModel, meas: MeasuredFRF | None, *, joint=None, parameters=None,
                           n_harmonics=9, n_time=None, heldout=True, source="<structure model>", units=None,
                           backbones=()) -> JointUpdate:
    """:func:`update_joint` on a structure model in memory (``source`` names it in messages and results;
    ``units`` per parameter, default the law's own; ``backbones`` measured backbones, with or without
    first harmonics ``meas``)."""
    j = _joint_index(model, joint, source)
    names_j = [jt.name for jt in model.joints]
    bbs = tuple(backbones)
    if meas is None and not bbs:
        raise ManifestError(f"{source}: nothing measured to update to (no first harmonics, no backbone)")
    for bb in bbs:
        check_backbone(bb, model, source)
    for i, d in enumerate(meas.dof if meas is not None else ()):
        if d not in model.modal.dof_names:
            col = ", column dof" if meas.origin else ""
            raise ManifestError(f"{meas.where(i)}{col}: dof {d!r} is not a DOF of the structure model {source} "
                                f"(its DOFs: {', '.join(model.modal.dof_names)})")
    law = model.joints[j].law
    units = {**(law.units if units is None else units), **{f"zeta_{r + 1}": "1" for r in range(model.modal.n_modes)}}
    avail = list(law.parameters) + [f"zeta_{r + 1}" for r in range(model.modal.n_modes)]
    names = list(law.parameters) if parameters is None else list(parameters)
    bad = [k for k in names if k not in avail]
    if bad or not names:
        raise ManifestError(f"{source}: joint {names_j[j]!r} ({law.name}) has no parameter(s) "
                            f"{', '.join(bad) or '(none given)'}; its parameters: {', '.join(avail)}")
    twice = sorted({k for k in names if names.count(k) > 1})
    if twice:
        raise ManifestError(f"{source}: parameters to fit ({', '.join(names)}): {', '.join(twice)} named more "
                            "than once; name each parameter once")
    n_par = len(names)
    n_frf = meas.X.size if meas is not None else 0
    n_bb = sum(bb.n for bb in bbs)
    paths = ([meas.path] if meas is not None else []) + [bb.path for bb in bbs]
    dof = 2 * n_frf + 2 * n_bb - n_par
    if dof < 1:
        raise IdentificationError(f"{', '.join(paths)}: {n_frf + n_bb} points cannot determine {n_par} parameters")
    fitter = _Fitter(model, j, names, n_harmonics, n_time)
    try:
        fitter.backbones(fitter.theta0, bbs)  # a point the model cannot reach: named by its file and line
    except ConvergenceError as exc:
        raise ManifestError(f"{exc} at the starting parameters of {source}") from None
    except Exception as exc:  # noqa: BLE001 - as below
        raise ManifestError(f"{source}: cannot evaluate the model at its starting parameters ({exc})") from None
    try:  # the first harmonics at the start (the backbones were just solved there)
        r0 = fitter.residual(fitter.theta0, meas) if meas is not None else None
    except Exception as exc:  # noqa: BLE001 - a law rejecting its own start is a bad model file
        raise ManifestError(f"{source}: cannot evaluate the model at its starting parameters ({exc})") from None
    if r0 is not None and np.all(r0 == _FAILED):
        raise IdentificationError(f"{', '.join(paths)}: the harmonic balance does not converge at the starting "
                                  "parameters")
    sol = fitter.fit(meas, bbs=bbs)
    warn = []
    if not sol.success:
        warn.append(f"least squares stopped: {sol.message}")
    chi2 = float(np.sum(sol.fun ** 2))
    if np.any(sol.fun == _FAILED):
        raise IdentificationError(f"{', '.join(paths)}: the harmonic balance failed at the fitted parameters")
    J = sol.jac
    try:
        cov = np.linalg.inv(J.T @ J)
    except np.linalg.LinAlgError:
        cov = np.full((n_par, n_par), np.nan)
        warn.append("the Jacobian is singular: some parameters are not determined by these data")
    scaled = chi2 / dof > 1
    if scaled:
        cov = cov * (chi2 / dof)
    var = np.diag(cov)
    with np.errstate(invalid="ignore"):  # a negative variance (round-off of a near-singular J^T J): not resolved
        se_t = np.where(var >= 0, np.sqrt(np.abs(var)), np.nan)
    est, se, ci, far = {}, {}, {}, {}
    for k, t, s, lg in zip(names, sol.x, se_t, fitter.log):
        v = _exp(t) if lg else float(t)
        est[k] = v
        se[k] = v * float(s) if lg else float(s)
        ci[k] = [_exp(t - Z95 * s), _exp(t + Z95 * s)] if lg else [t - Z95 * s, t + Z95 * s]
        if not np.isfinite(s):
            warn.append(f"{k} is not resolved by these data (no standard error)")
        elif not all(math.isfinite(x) for x in ci[k]):
            warn.append(f"{k} is not resolved by these data: its 95 % interval is unbounded")
        elif s > (1.0 if lg else max(abs(t), 1e-12)):
            warn.append(f"{k} is poorly determined (relative standard error > 100 %)")
        if lg and _zeta_mode(k) is None and math.isfinite(v) and v > 0 \
                and not 1 / FAR_FROM_START <= v / fitter.start[k] <= FAR_FROM_START:  # a law's parameter only: a
            # modal damping ratio may well drop far below a random test's (which held the joint's dissipation)
            far[k] = v / fitter.start[k]
    with np.errstate(invalid="ignore", divide="ignore"):
        d = np.sqrt(np.diag(cov))
        corr = (cov / np.outer(d, d)).tolist()
    if chi2 / dof > ADEQUATE_CHI2_PER_DOF:
        warn.append(f"chi2/dof = {chi2 / dof:.3g}: the model does not fit the points to their standard errors")
    for k, r in far.items():
        how = f"{r:.3g} times above" if r > 1 else f"{1 / r:.3g} times below"
        warn.append(f"{k} = {est[k]:.4g} ended {how} its start {fitter.start[k]:g} (more than {FAR_FROM_START:g}): "
                    "a unit slip (amplitudes in mm, not m?) or a parameter the data do not hold; not trusted")
    res = JointUpdate(str(source), ", ".join(paths), names_j[j], law.name, names,
                      {k: units.get(k, "") for k in names}, fitter.start, est, se, ci, dict(zip(names, fitter.log)),
                      chi2, dof, bool(scaled), corr, int(n_frf), int(n_harmonics), int(sol.nfev), warnings=warn,
                      far_from_start=far)
    res.fitted = {"measured": meas, "model": fitter.responses(sol.x, meas) if meas is not None else None,
                  "structure": fitter.structure(sol.x), "n_time": n_time}
    fb = fitter.backbones(sol.x, bbs)
    res.fitted["backbones"] = list(zip(bbs, fb))
    for bb, (f, z) in zip(bbs, fb):
        c2 = float(sum(np.sum(v**2) for v in bb.z_scores(f, z)))
        res.backbones.append({"file": bb.path, "n_points": bb.n, "chi2": c2, "points": _backbone_points(bb, f, z)})
    if not heldout:
        res.heldout_note = "not asked for (--no-heldout)"
    elif meas is None:
        res.heldout_note = "no first harmonics: no force level to leave out (the backbone's check: heldout_backbone)"
    elif len(meas.levels()) < 2:
        res.heldout_note = (f"one force level only ({meas.levels()[0]:g}): no level to leave out and predict; "
                            "the fit is not checked against data it has not seen")
    else:
        for lv in meas.levels():
            res.heldout.append(_heldout(fitter, meas, lv, sol.x, n_harmonics, n_time, bbs))
    if heldout and bbs:
        res.heldout_backbone = _heldout_backbone(fitter, meas, bbs, n_par)
    return res


def write_update(result: JointUpdate, out, inputs=()) -> dict:
    """``results.json``, ``report.txt`` and ``figures/update_fit.png`` in ``out`` as one output set."""
    from ..io.outputset import new_run_id, output_set
    from ..io.results import atomic_write, write_json
    from ..report.html import figure_to_png
    from ..report.structure_plots import plot_update_backbone, plot_update_fit

    run_id = new_run_id()
    summary = result.summary()
    summary["run_id"] = run_id
    with output_set(Path(out), run_id, kind="update", inputs=inputs) as tmp:
        paths = {"results": write_json(tmp / "results.json", summary),
                 "report": atomic_write(tmp / "report.txt", result.report() + f"\n\nrun id {run_id}\n")}
        meas, mod = result.fitted.get("measured"), result.fitted.get("model")
        if meas is not None:
            fig = plot_update_fit(meas, mod, joint=result.joint, law=result.law,
                                  response_units=read_structure_model(result.model_path).response_units)
            paths["figure"] = atomic_write(tmp / "figures" / "update_fit.png", figure_to_png(fig, dpi=110))
        if result.fitted.get("backbones"):
            fig = plot_update_backbone(result.fitted["backbones"], joint=result.joint, law=result.law,
                                       curves=[backbone_curve(result.fitted["structure"], bb, result.n_harmonics,
                                                              result.fitted.get("n_time"))
                                               for bb, _ in result.fitted["backbones"]],
                                       response_units=read_structure_model(result.model_path).response_units)
            paths["backbone_figure"] = atomic_write(tmp / "figures" / "update_backbone.png",
                                                    figure_to_png(fig, dpi=110))
    return paths
