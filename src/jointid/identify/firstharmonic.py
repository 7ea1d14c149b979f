"""Single nonlinear mode from first-harmonic stepped-sine data (one line per frequency).

Data
    Each level (one record of a stepped-sine test: force-, response- or
    phase-resonance-controlled) gives per line the frequency ``w``, the force's first
    harmonic ``F e^{i phi_F}`` and the driving-point acceleration's ``X e^{i phi_X}``: the
    measured accelerance ``H = X / F e^{i (phi_X - phi_F)}``.

Amplitude measure
    ``a = X``, the first-harmonic acceleration amplitude at the driving point [m/s^2], as
    measured at each line: the quantity the tests control and the one an impact ring-down
    at the same point gives, so the backbones of both tests are drawn against the same
    ``a``.  It includes the small contribution of the other modes (the residual below).

Model
    ::

        H(w, a) = -w^2 m / (wn(a)^2 - w^2 + 2 i zeta(a) wn(a) w) + R

    with the modal constant ``m = phi_d^2`` (the mass-normalised mode shape at the
    driving point squared; the modal mass there is ``1 / |m|``; a negative ``m`` means the
    export's phase convention is inverted, which only flips the sign), the complex residual
    ``R`` of the other modes (constant over the narrow band of lines), and amplitude laws
    in ``s = a / a_ref`` (``a_ref`` the largest measured amplitude)::

        wn(a)   = 2 pi f0 (1 + w1 s + w2 s^2 + ...)          ("poly<p>")
                  2 pi f0 (1 + w1 s^g)                        ("power")
        zeta(a) = zeta0 + z1 s + z2 s^2 + ...                 ("poly<q>")
                  zeta0 + z1 s^g                              ("power")

    A polynomial frequency law of order 2 or more need not be monotone.

Fit
    Nonlinear least squares on the complex accelerance of all lines of all levels together
    (real and imaginary parts, each divided by ``|H|``: a relative noise model), with the
    measured ``a`` of each line.  Standard errors from the Jacobian and the residual scale,
    with the noise of the measured amplitude carried through (a sandwich covariance,
    :func:`_covariance`); 95 % intervals ``+-1.96 se`` (calibrated by the Monte Carlo of
    :func:`simulate_levels`).  The modal constant is also estimated from the lowest level
    alone (``low_level``) with its standard error, as a check of the joint value.

Re-prediction
    For each line the amplitude equation ``a = F |H(w, a)|`` is solved with the *measured*
    force ``F`` of that line (the force of a force-controlled test dips at resonance).
    All roots on the line are found (a log grid, then Brent); the lines are followed in
    their measurement order and each takes the root nearest (in ``log a``) to the previous
    line's, the first line its smallest: the branch a stepped sine follows.

Per-line points
    With ``m`` and ``R`` fitted, each line gives its own ``wn`` and ``zeta``:
    ``D = -w^2 m / (H - R) = wn^2 - w^2 + 2 i zeta wn w``.  Well determined near resonance
    only; points whose ``zeta`` has a relative standard error above ``max_rel_se`` are left
    out of the measured backbone.

Selection and adequacy
    :func:`select_laws` fits every candidate pair of laws and scores it by leave-one-level-
    out prediction (fit on the other levels, re-predict the level left out from its measured
    forces); :func:`adequacy` tests the residuals for whiteness along the frequency axis
    (lag-1 autocorrelation per level) and the levels' residual scales against the pooled one.
"""

from __future__ import annotations

import html
import warnings
from dataclasses import dataclass, field

import numpy as np
from scipy import optimize, stats

from ..errors import ConvergenceWarning, IdentificationError, JointidWarning
from .backbone import Z95, Backbone

__all__ = ["FirstHarmonicLevel", "AmplitudeLaw", "FirstHarmonicModel", "FirstHarmonicFit", "LevelPrediction",
           "fit_first_harmonic", "repredict_level", "leave_one_level_out", "select_laws", "adequacy",
           "simulate_levels", "AMPLITUDE_UNIT", "DEFAULT_CANDIDATES"]

#: What ``a`` is, in words (written beside every backbone drawn from first-harmonic data).
AMPLITUDE_UNIT = "m/s^2 (first-harmonic acceleration amplitude at the driving point)"
#: Candidate (frequency law, damping law) pairs of :func:`select_laws`.
DEFAULT_CANDIDATES = tuple((f"poly{p}", f"poly{q}") for p in range(1, 7) for q in range(1, 4)) + (
    ("power", "power"), ("power+quadratic", "poly2"))
_ZETA_FLOOR = 1e-7  # the damping law is clipped here when it is extrapolated below zero


def _ro(a, dtype=float):
    a = np.array(a, dtype=dtype)
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class FirstHarmonicLevel:
    """The lines of one level: frequency [Hz], force and acceleration first harmonics."""

    frequency_hz: np.ndarray
    force: np.ndarray
    force_phase: np.ndarray
    accel: np.ndarray
    accel_phase: np.ndarray
    label: str = ""
    control: str = "force"

    def __post_init__(self):
        n = np.size(self.frequency_hz)
        for k in ("frequency_hz", "force", "force_phase", "accel", "accel_phase"):
            v = np.broadcast_to(np.asarray(getattr(self, k), float), (n,))
            if not np.all(np.isfinite(v)):
                raise IdentificationError(f"level {self.label!r}: {k} holds values that are not finite")
            object.__setattr__(self, k, _ro(v))
        if np.any(self.frequency_hz <= 0) or np.any(self.force <= 0) or np.any(self.accel <= 0):
            raise IdentificationError(f"level {self.label!r}: frequencies and amplitudes must be positive")

    def __len__(self):
        return int(self.frequency_hz.size)

    @property
    def omega(self) -> np.ndarray:
        return 2 * np.pi * self.frequency_hz

    @property
    def frf(self) -> np.ndarray:
        """Measured accelerance (phase relative to the force)."""
        return self.accel / self.force * np.exp(1j * (self.accel_phase - self.force_phase))

    @classmethod
    def from_record(cls, rec, label="") -> "FirstHarmonicLevel":
        """From any object with the record's columns (e.g. :class:`jointid.io.firsth.FirstHarmonicRecord`)."""
        return cls(rec.frequency_hz, rec.force, rec.force_phase, rec.accel, rec.accel_phase, label,
                   getattr(rec, "control", "force"))


@dataclass(frozen=True)
class AmplitudeLaw:
    """A law ``g(s)`` of the normalised amplitude ``s``: ``"poly<p>"`` or ``"power"``."""

    kind: str

    def __post_init__(self):
        if not (self.kind in ("power", "power+quadratic")
                or (self.kind.startswith("poly") and self.kind[4:].isdigit())):
            raise IdentificationError(f"amplitude law must be 'poly<order>' (e.g. 'poly2'), 'power' or "
                                      f"'power+quadratic', got {self.kind!r}")

    @property
    def n(self) -> int:
        """Parameters beyond the constant."""
        return {"power": 2, "power+quadratic": 3}.get(self.kind) or int(self.kind[4:])

    def names(self, prefix) -> list:
        if self.kind == "power":
            return [f"{prefix}1", f"{prefix}_exponent"]
        if self.kind == "power+quadratic":
            return [f"{prefix}1", f"{prefix}_exponent", f"{prefix}2"]
        return [f"{prefix}{j}" for j in range(1, self.n + 1)]

    def start(self) -> list:
        return {"power": [0.0, 1.0], "power+quadratic": [0.0, 1.0, 0.0]}.get(self.kind) or [0.0] * self.n

    def bounds(self):
        if self.kind == "power":
            return [-np.inf, 0.05], [np.inf, 6.0]
        if self.kind == "power+quadratic":
            return [-np.inf, 0.05, -np.inf], [np.inf, 6.0, np.inf]
        return [-np.inf] * self.n, [np.inf] * self.n

    def __call__(self, s, p) -> np.ndarray:
        s = np.asarray(s, float)
        if self.kind == "power":
            return p[0] * np.power(np.maximum(s, 0.0), p[1])
        if self.kind == "power+quadratic":
            return p[0] * np.power(np.maximum(s, 0.0), p[1]) + p[2] * s**2
        out = np.zeros_like(s)
        for j in range(self.n, 0, -1):
            out = (out + p[j - 1]) * s
        return out


@dataclass(frozen=True, eq=False)
class FirstHarmonicModel:
    """``H(w, a)`` of the module docstring with given parameters."""

    frequency_law: AmplitudeLaw
    damping_law: AmplitudeLaw
    a_ref: float
    params: np.ndarray

    @property
    def names(self) -> list:
        return (["modal_constant", "residual_re", "residual_im", "f0_hz"] + self.frequency_law.names("w")
                + ["zeta0"] + self.damping_law.names("z"))

    def split(self, p=None):
        p = self.params if p is None else p
        nf = self.frequency_law.n
        m, rr, ri, f0 = p[:4]
        wp = p[4:4 + nf]
        z0 = p[4 + nf]
        zp = p[5 + nf:]
        return m, complex(rr, ri), f0, wp, z0, zp

    def omega_n(self, a, p=None) -> np.ndarray:
        m, R, f0, wp, z0, zp = self.split(p)
        return 2 * np.pi * f0 * (1 + self.frequency_law(np.asarray(a, float) / self.a_ref, wp))

    def zeta(self, a, p=None) -> np.ndarray:
        m, R, f0, wp, z0, zp = self.split(p)
        return z0 + self.damping_law(np.asarray(a, float) / self.a_ref, zp)

    def frf(self, omega, a, p=None) -> np.ndarray:
        """Accelerance at ``omega`` [rad/s] and amplitude ``a``."""
        m, R, f0, wp, z0, zp = self.split(p)
        wn = self.omega_n(a, p)
        z = np.maximum(self.zeta(a, p), _ZETA_FLOOR)
        w = np.asarray(omega, float)
        return -w**2 * m / (wn**2 - w**2 + 2j * z * wn * w) + R

    def with_params(self, p) -> "FirstHarmonicModel":
        return FirstHarmonicModel(self.frequency_law, self.damping_law, self.a_ref, _ro(p))


@dataclass(frozen=True, eq=False)
class LevelPrediction:
    """Re-prediction of one level from its measured forces."""

    label: str
    frequency_hz: np.ndarray
    accel_measured: np.ndarray
    phase_measured: np.ndarray  # accelerance phase [rad]
    accel_predicted: np.ndarray
    phase_predicted: np.ndarray
    n_roots: np.ndarray  # roots of the amplitude equation at each line

    @property
    def amplitude_rms_rel(self) -> float:
        return float(np.sqrt(np.nanmean((self.accel_predicted / self.accel_measured - 1) ** 2)))

    @property
    def phase_rms_deg(self) -> float:
        d = np.angle(np.exp(1j * (self.phase_predicted - self.phase_measured)))
        return float(np.degrees(np.sqrt(np.nanmean(d**2))))

    @property
    def complex_rms_rel(self) -> float:
        zp = self.accel_predicted * np.exp(1j * self.phase_predicted)
        zm = self.accel_measured * np.exp(1j * self.phase_measured)
        return float(np.sqrt(np.nanmean(np.abs(zp / zm - 1) ** 2)))

    @staticmethod
    def _peak(f, a):
        order = np.argsort(f)
        f, a = f[order], a[order]
        ok = np.isfinite(a)
        if not ok.any():
            return np.nan, np.nan
        k = int(np.nanargmax(np.where(ok, a, -np.inf)))
        if 0 < k < f.size - 1 and np.all(np.isfinite(a[k - 1:k + 2])):
            y0, y1, y2 = a[k - 1:k + 2]
            den = y0 - 2 * y1 + y2
            d = 0.5 * (y0 - y2) / den if den < 0 else 0.0
            d = float(np.clip(d, -1, 1))
            h = 0.5 * (f[k + 1] - f[k - 1])
            return float(f[k] + d * h), float(y1 - 0.25 * (y0 - y2) * d)
        return float(f[k]), float(a[k])

    def peaks(self) -> dict:
        """Peak frequency and amplitude (three-line parabola at the largest line), measured and predicted."""
        fm, am = self._peak(self.frequency_hz, self.accel_measured)
        fp, ap = self._peak(self.frequency_hz, self.accel_predicted)
        return {"measured_hz": fm, "measured_amplitude": am, "predicted_hz": fp, "predicted_amplitude": ap,
                "frequency_error_rel": (fp - fm) / fm, "amplitude_error_rel": ap / am - 1}

    def summary(self) -> dict:
        def lst(x):
            return [None if not np.isfinite(v) else float(v) for v in x]

        return {"label": self.label, "frequency_hz": lst(self.frequency_hz),
                "accel_measured": lst(self.accel_measured), "accel_predicted": lst(self.accel_predicted),
                "phase_measured_deg": lst(np.degrees(self.phase_measured)),
                "phase_predicted_deg": lst(np.degrees(self.phase_predicted)),
                "n_roots": [int(x) for x in self.n_roots],
                "amplitude_rms_rel": self.amplitude_rms_rel, "phase_rms_deg": self.phase_rms_deg,
                "complex_rms_rel": self.complex_rms_rel, "peak": self.peaks()}


def repredict_level(model: FirstHarmonicModel, level: FirstHarmonicLevel, n_grid=600) -> LevelPrediction:
    """Solve ``a = F |H(w, a)|`` at every line with the measured force (module docstring)."""
    w, F = level.omega, level.force
    a_meas = level.accel
    lo = max(1e-4 * float(np.min(a_meas)), 1e-12)
    hi0 = 20.0 * float(np.max(a_meas))
    a_pred = np.full(len(level), np.nan)
    ph = np.full(len(level), np.nan)
    nroots = np.zeros(len(level), int)
    prev = None
    for k in range(len(level)):
        def g(a):
            return F[k] * np.abs(model.frf(w[k], a)) - a

        hi = hi0
        for _ in range(8):  # the grid reaches beyond the largest root: F |H| < a at its top
            if g(hi) < 0:
                break
            hi *= 10.0
        grid = np.geomspace(lo, hi, n_grid)
        gv = g(grid)
        sgn = np.sign(gv)
        idx = np.nonzero(sgn[:-1] * sgn[1:] < 0)[0]
        roots = []
        for i in idx:
            try:
                roots.append(optimize.brentq(g, grid[i], grid[i + 1], xtol=1e-14 * grid[i + 1], rtol=1e-12))
            except (ValueError, RuntimeError):
                continue
        nroots[k] = len(roots)
        if not roots:
            continue
        roots = np.array(roots)
        r = roots[0] if prev is None else roots[np.argmin(np.abs(np.log(roots / prev)))]
        prev = r
        a_pred[k] = r
        ph[k] = np.angle(model.frf(w[k], r))
    return LevelPrediction(level.label, level.frequency_hz, a_meas, np.angle(level.frf), _ro(a_pred), _ro(ph),
                           np.array(nroots))


@dataclass(frozen=True, eq=False)
class FirstHarmonicFit:
    """The fitted single-nonlinear-mode model, its uncertainty, re-predictions and backbones."""

    model: FirstHarmonicModel
    covariance: np.ndarray
    residual_scale: float  # relative noise of the accelerance (s)
    n_lines: int
    levels: tuple  # FirstHarmonicLevel
    predictions: tuple  # LevelPrediction per level
    low_level: dict = field(default_factory=dict)  # modal constant from the lowest level alone
    residuals: tuple = ()  # per level: complex normalised residual (H_model - H) / |H|
    warnings: tuple = ()
    cost_evaluations: int = 0

    @property
    def names(self) -> list:
        return self.model.names

    @property
    def params(self) -> np.ndarray:
        return self.model.params

    @property
    def stderr(self) -> np.ndarray:
        return np.sqrt(np.clip(np.diag(self.covariance), 0, None))

    def get(self, name) -> float:
        return float(self.params[self.names.index(name)])

    def get_stderr(self, name) -> float:
        return float(self.stderr[self.names.index(name)])

    @property
    def modal_mass(self) -> tuple:
        """``(1 / |m|, its standard error)`` [kg]: the modal mass at the driving point."""
        m, se = self.get("modal_constant"), self.get_stderr("modal_constant")
        return 1 / abs(m), se / m**2

    @property
    def amplitude_range(self) -> tuple:
        a = np.concatenate([lv.accel for lv in self.levels])
        return float(a.min()), float(a.max())

    def backbone(self, amplitudes=None, n_points=60, label="") -> Backbone:
        """The model's ``wn(a)``, ``zeta(a)`` with 95 % bands (delta method on the covariance)."""
        if amplitudes is None:
            lo, hi = self.amplitude_range
            amplitudes = np.geomspace(lo, hi, n_points)
        a = np.asarray(amplitudes, float)
        p = self.params
        wn, z = self.model.omega_n(a), self.model.zeta(a)
        Jw, Jz = np.empty((a.size, p.size)), np.empty((a.size, p.size))
        for j in range(p.size):
            h = 1e-6 * max(abs(p[j]), 1e-8)
            pp, pm = p.copy(), p.copy()
            pp[j] += h
            pm[j] -= h
            Jw[:, j] = (self.model.omega_n(a, pp) - self.model.omega_n(a, pm)) / (2 * h)
            Jz[:, j] = (self.model.zeta(a, pp) - self.model.zeta(a, pm)) / (2 * h)
        C = self.covariance
        sw = np.sqrt(np.clip(np.einsum("ij,jk,ik->i", Jw, C, Jw), 0, None))
        sz = np.sqrt(np.clip(np.einsum("ij,jk,ik->i", Jz, C, Jz), 0, None))
        return Backbone(a, wn, z, sw, sz, "model", np.zeros_like(a), label or "first-harmonic model",
                        {"amplitude_unit": AMPLITUDE_UNIT, "frequency_law": self.model.frequency_law.kind,
                         "damping_law": self.model.damping_law.kind})

    def line_points(self, max_rel_se=0.25, label="") -> Backbone:
        """Per-line ``wn``, ``zeta`` from the measured accelerance (module docstring), well-determined lines only."""
        amps, wns, zs, swn, sz, lab, fr = [], [], [], [], [], [], []
        m, R = self.get("modal_constant"), complex(self.get("residual_re"), self.get("residual_im"))
        Cm = self.covariance[:3, :3]
        s = self.residual_scale
        for lv in self.levels:
            H, w = lv.frf, lv.omega

            def point(Hr, Hi, mm, rr, ri):
                D = -w**2 * mm / ((Hr + 1j * Hi) - (rr + 1j * ri))
                wn = np.sqrt(np.maximum(D.real + w**2, 0.0))
                return wn, D.imag / (2 * wn * w)

            base = [H.real, H.imag, np.full_like(w, m), np.full_like(w, R.real), np.full_like(w, R.imag)]
            wn, z = point(*base)
            grads = []
            for j in range(5):
                h = 1e-7 * (np.abs(H) if j < 2 else max(abs([m, R.real, R.imag][j - 2]), 1e-9))
                bp = [b.copy() for b in base]
                bp[j] = bp[j] + h
                wp_, zp_ = point(*bp)
                grads.append(((wp_ - wn) / h, (zp_ - z) / h))
            var_w = (grads[0][0]**2 + grads[1][0]**2) * (s * np.abs(H))**2
            var_z = (grads[0][1]**2 + grads[1][1]**2) * (s * np.abs(H))**2
            gw = np.column_stack([g[0] for g in grads[2:]])
            gz = np.column_stack([g[1] for g in grads[2:]])
            var_w += np.einsum("ij,jk,ik->i", gw, Cm, gw)
            var_z += np.einsum("ij,jk,ik->i", gz, Cm, gz)
            amps.append(lv.accel)
            wns.append(wn)
            zs.append(z)
            swn.append(np.sqrt(var_w))
            sz.append(np.sqrt(var_z))
            lab += [lv.label] * len(lv)
            fr.append(lv.frequency_hz)
        a, wn, z, swn, sz, fr = (np.concatenate(x) for x in (amps, wns, zs, swn, sz, fr))
        keep = np.isfinite(z) & (z > 0) & (sz < max_rel_se * np.abs(z)) & (wn > 0)
        b = Backbone(a, wn, z, swn, sz, "stepped-sine", np.zeros_like(a), label or "first-harmonic lines",
                     {"amplitude_unit": AMPLITUDE_UNIT, "level": lab, "line_frequency_hz": fr.tolist()})
        return b.select(keep).sorted()

    def summary(self) -> dict:
        p, se = self.params, self.stderr
        mm, mse = self.modal_mass
        return {
            "model": "single nonlinear mode, first harmonics: H(w,a) = -w^2 m / (wn(a)^2 - w^2 + 2i zeta(a) wn(a) w) + R",
            "amplitude": "a", "amplitude_unit": AMPLITUDE_UNIT, "a_ref": self.model.a_ref,
            "frequency_law": self.model.frequency_law.kind, "damping_law": self.model.damping_law.kind,
            "parameter_names": self.names, "parameters": p.tolist(), "stderr": se.tolist(),
            "ci95": [[float(v - Z95 * s), float(v + Z95 * s)] for v, s in zip(p, se)],
            "covariance": self.covariance.tolist(),
            "modal_mass_kg": mm, "modal_mass_kg_stderr": mse,
            "modal_mass_kg_ci95": [mm - Z95 * mse, mm + Z95 * mse],
            "low_level": dict(self.low_level),
            "residual_scale": self.residual_scale, "n_lines": self.n_lines, "n_parameters": int(p.size),
            "levels": [lv.label for lv in self.levels],
            "reprediction": [pr.summary() for pr in self.predictions],
            "warnings": list(self.warnings),
        }

    def report(self) -> str:
        lines = [f"Single nonlinear mode from first harmonics: {self.n_lines} lines, {len(self.levels)} levels, "
                 f"laws wn: {self.model.frequency_law.kind}, zeta: {self.model.damping_law.kind}, "
                 f"a = {AMPLITUDE_UNIT}, a_ref = {self.model.a_ref:.4g}",
                 f"  {'parameter':<16} {'value':>14} {'stderr':>12} {'95 % interval':>30}"]
        for n, v, s in zip(self.names, self.params, self.stderr):
            lines.append(f"  {n:<16} {v:14.6g} {s:12.3g}   [{v - Z95 * s:.6g}, {v + Z95 * s:.6g}]")
        mm, mse = self.modal_mass
        lines.append(f"  modal mass at the driving point 1/|m| = {mm:.4g} +- {Z95 * mse:.2g} kg (95 %)")
        if self.low_level:
            ll = self.low_level
            lines.append(f"  lowest level alone: m = {ll['modal_constant']:.5g} +- {Z95 * ll['stderr']:.2g}, "
                         f"modal mass {ll['modal_mass_kg']:.4g} kg")
        lines.append(f"  relative residual scale s = {self.residual_scale:.3g}")
        lines.append(f"  {'level':<12} {'amp rms %':>10} {'phase rms deg':>14} {'peak Hz meas/pred':>22} "
                     f"{'peak a meas/pred':>20}")
        for pr in self.predictions:
            pk = pr.peaks()
            lines.append(f"  {pr.label:<12} {100 * pr.amplitude_rms_rel:10.2f} {pr.phase_rms_deg:14.2f} "
                         f"{pk['measured_hz']:10.4f}/{pk['predicted_hz']:<10.4f} "
                         f"{pk['measured_amplitude']:9.3f}/{pk['predicted_amplitude']:<9.3f}")
        lines += [f"  warning: {w}" for w in self.warnings]
        return "\n".join(lines)

    def _repr_html_(self) -> str:
        return f"<pre>{html.escape(self.report())}</pre>"


def _law(x) -> AmplitudeLaw:
    return x if isinstance(x, AmplitudeLaw) else AmplitudeLaw(str(x))


def _stack(levels):
    w = np.concatenate([lv.omega for lv in levels])
    a = np.concatenate([lv.accel for lv in levels])
    H = np.concatenate([lv.frf for lv in levels])
    return w, a, H


def _start(levels, fl, dl, a_ref):
    """Starting values from the lowest level: peak of |H|, its half-power width, the quadrature value."""
    low = min(levels, key=lambda lv: float(np.max(lv.accel)))
    H, f = low.frf, low.frequency_hz
    k = int(np.argmax(np.abs(H)))
    f0 = float(f[k])
    half = np.abs(H) >= np.abs(H[k]) / np.sqrt(2)
    width = float(f[half].max() - f[half].min()) if half.sum() > 1 else float(np.median(np.diff(np.sort(f))))
    zeta0 = float(np.clip(0.5 * max(width, 1e-3 * f0) / f0, 1e-5, 0.2))
    m0 = 2 * zeta0 * float(H[k].imag)  # at resonance the mode term is i m / (2 zeta)
    return np.array([m0, 0.0, 0.0, f0] + fl.start() + [zeta0] + dl.start(), float), a_ref


NFEV_PER_PARAMETER = 50  # evaluations of the residuals a fit may take, per parameter


def _solve(levels, fl, dl, a_ref, x0, max_nfev=None):
    """One bounded least-squares fit; ``max_nfev`` defaults to :data:`NFEV_PER_PARAMETER` x the parameters.

    The fits of a measured campaign converge in a few times the number of parameters (the
    Brake-Reuss beam's 20 candidate laws in at most 18 x); one that has not converged at the
    bound is reported unconverged (``sol.status == 0``, :func:`_unconverged`) instead of running on.
    """
    if max_nfev is None:
        max_nfev = NFEV_PER_PARAMETER * len(x0)
    w, a, H = _stack(levels)
    model = FirstHarmonicModel(fl, dl, a_ref, x0)
    scale = np.abs(H)

    def resid(p):
        r = (model.frf(w, a, p) - H) / scale
        return np.concatenate([r.real, r.imag])

    lo = [-np.inf, -np.inf, -np.inf, 0.0] + fl.bounds()[0] + [0.0] + dl.bounds()[0]
    hi = [np.inf, np.inf, np.inf, np.inf] + fl.bounds()[1] + [np.inf] + dl.bounds()[1]
    x0 = np.clip(x0, np.array(lo) + 1e-12, np.array(hi) - 1e-12)
    try:
        sol = optimize.least_squares(resid, x0, bounds=(lo, hi), x_scale="jac", xtol=1e-12, ftol=1e-12,
                                     gtol=1e-12, max_nfev=max_nfev, method="trf")
    except ValueError as exc:  # residuals not finite at the start (a degenerate level)
        raise IdentificationError(f"the first-harmonic fit cannot start: {exc}") from None
    return sol, model.with_params(sol.x), resid


def _unconverged(sol, what="the first-harmonic fit"):
    """The IdentificationError of a fit that did not converge (the evaluation bound reached or another reason)."""
    if sol.status == 0:
        return IdentificationError(f"{what} did not converge within {sol.nfev} evaluations of the residuals "
                                   f"({NFEV_PER_PARAMETER} per parameter, {sol.x.size} parameters; a fit the "
                                   f"levels support converges in a few per parameter): check each level's force and "
                                   f"acceleration units and phases, or use simpler laws")
    return IdentificationError(f"{what} did not converge: {sol.message}")


def _covariance(sol, model, levels):
    """Covariance of the parameters, with the amplitude's own noise (errors in variables), and the noise scale.

    The law's amplitude ``a = F |H|`` is measured with the accelerance it explains, so the
    noise ``e`` of a line's (normalised) accelerance enters its residual twice:
    ``r = (F dH/da h^T - I) e = M e`` with ``h = H / |H|``.  With ``cov(e) = s^2 I`` the
    residuals have covariance ``s^2 M M^T`` per line; the parameters' covariance is the
    sandwich ``(J^T J)^-1 J^T M M^T J (J^T J)^-1 s^2`` and ``s^2`` follows from
    ``E[RSS] = s^2 (sum tr(M M^T)) (1 - p / 2n)``.  Without the amplitude's noise (``M = -I``)
    this is the usual ``s^2 (J^T J)^-1``.
    """
    J = sol.jac
    n2, p = J.shape
    n = n2 // 2
    w, a, H = _stack(levels)
    F = np.concatenate([lv.force for lv in levels])
    h = 1e-6 * a
    dH = (model.frf(w, a + h) - model.frf(w, a - h)) / (2 * h)  # r's noise: F dH/da (h . e) - e, e = delta H / |H|
    hh = H / np.abs(H)
    M00 = F * dH.real * hh.real - 1
    M01 = F * dH.real * hh.imag
    M10 = F * dH.imag * hh.real
    M11 = F * dH.imag * hh.imag - 1
    trace = float(np.sum(M00**2 + M01**2 + M10**2 + M11**2))
    dof_factor = max(1.0 - p / n2, 1.0 / n2)
    s2 = float(sol.fun @ sol.fun) / (trace * dof_factor)
    Jr, Ji = J[:n], J[n:]
    B = np.concatenate([Jr.T * M00 + Ji.T * M10, Jr.T * M01 + Ji.T * M11], axis=1)  # J^T M
    U, sv, Vt = np.linalg.svd(J, full_matrices=False)
    cond = sv[0] / sv[-1] if sv[-1] > 0 else np.inf
    inv = (Vt.T / np.where(sv > sv[0] * 1e-13, sv, np.inf) ** 2) @ Vt
    cov = inv @ (B @ B.T) @ inv * s2
    return 0.5 * (cov + cov.T), np.sqrt(s2), cond


def _fit_core(levels, fl, dl, a_ref):
    """Fit in stages (constant laws, then the full laws) from the lowest level's start."""
    x0, _ = _start(levels, AmplitudeLaw("poly0"), AmplitudeLaw("poly0"), a_ref)
    sol0, m0, _ = _solve(levels, AmplitudeLaw("poly0"), AmplitudeLaw("poly0"), a_ref, x0)
    base = list(sol0.x[:4])
    best = None
    starts = [fl.start()]
    if fl.kind == "power+quadratic":  # softening at low amplitude, hardening above
        starts = [[-1e-2, 1.0, 1e-2], [-1e-2, 2.0, 1e-2]]
    elif fl.kind != "power":  # a second start: a slight softening slope
        starts.append([-1e-3] + [0.0] * (fl.n - 1))
    for fs in starts:
        x = np.array(base + fs + [sol0.x[4]] + dl.start(), float)
        sol, model, resid = _solve(levels, fl, dl, a_ref, x)
        # a converged start beats one stopped at the evaluation cap, whatever their costs
        if best is None or (sol.success, -sol.cost) > (best[0].success, -best[0].cost):
            best = (sol, model, resid)
    return best


def fit_first_harmonic(levels, frequency_law="poly2", damping_law="poly1", *, a_ref=None, repredict=True,
                       low_level=True) -> FirstHarmonicFit:
    """Fit the single-nonlinear-mode model to all lines of all levels (module docstring).

    Parameters
    ----------
    levels : sequence of FirstHarmonicLevel
    frequency_law, damping_law : str or AmplitudeLaw
        ``"poly<p>"`` or ``"power"``.
    a_ref : float, optional
        Amplitude normalisation (default: the largest measured amplitude).
    repredict : bool
        Re-predict every level from its measured forces.
    low_level : bool
        Also estimate the modal constant from the lowest level alone.

    Raises
    ------
    IdentificationError
        Fewer lines than parameters, or a fit that does not converge.
    """
    levels = tuple(levels)
    if not levels:
        raise IdentificationError("no first-harmonic levels to fit")
    fl, dl = _law(frequency_law), _law(damping_law)
    n_par = 5 + fl.n + dl.n
    n_lines = sum(len(lv) for lv in levels)
    if 2 * n_lines <= n_par:
        raise IdentificationError(f"{n_lines} lines give {2 * n_lines} real values for {n_par} parameters; "
                                  f"use simpler laws or more lines")
    a_ref = float(a_ref) if a_ref is not None else float(max(np.max(lv.accel) for lv in levels))
    notes = []
    sol, model, _ = _fit_core(levels, fl, dl, a_ref)
    if not sol.success:
        raise _unconverged(sol)
    cov, s, cond = _covariance(sol, model, levels)
    if cond > 1e12:
        notes.append(f"ill-conditioned fit (condition number {cond:.2g}): the laws are more flexible than the "
                     f"amplitude range supports")
    zs = model.zeta(np.concatenate([lv.accel for lv in levels]))
    if np.any(zs <= 0):
        notes.append("the damping law falls to zero or below inside the measured amplitude range")
    resid = []
    for lv in levels:
        resid.append(_ro((model.frf(lv.omega, lv.accel) - lv.frf) / np.abs(lv.frf), complex))
    ll = {}
    if low_level:
        low = min(levels, key=lambda lv: float(np.max(lv.accel)))
        try:
            lsol, lmodel, _ = _fit_core((low,), AmplitudeLaw("poly1"), AmplitudeLaw("poly1"), a_ref)
            if not lsol.success:
                raise _unconverged(lsol, "the fit of the lowest level alone")
            lcov, ls, _ = _covariance(lsol, lmodel, (low,))
            mc, mse = float(lsol.x[0]), float(np.sqrt(lcov[0, 0]))
            mj, mjse = float(sol.x[0]), float(np.sqrt(cov[0, 0]))
            ll = {"level": low.label, "modal_constant": mc, "stderr": mse, "modal_mass_kg": 1 / abs(mc),
                  "modal_mass_kg_stderr": mse / mc**2, "ci95": [mc - Z95 * mse, mc + Z95 * mse],
                  "laws": "poly1/poly1", "z_vs_joint": (mc - mj) / np.hypot(mse, mjse)}
        except (IdentificationError, np.linalg.LinAlgError, ValueError) as exc:
            ll = {"level": low.label, "error": str(exc)}
    preds = tuple(repredict_level(model, lv) for lv in levels) if repredict else ()
    for pr in preds:
        if np.any(pr.n_roots == 0):
            notes.append(f"level {pr.label}: the amplitude equation has no root at "
                         f"{int(np.sum(pr.n_roots == 0))} lines")
    return FirstHarmonicFit(model, _ro(cov), float(s), n_lines, levels, preds, ll, tuple(resid), tuple(notes),
                            int(sol.nfev))


def leave_one_level_out(levels, frequency_law="poly2", damping_law="poly1", a_ref=None, *,
                        stop_at_error=False) -> list:
    """Fit on all levels but one, re-predict that one from its measured forces; one entry per level.

    Each entry: ``label``, the :class:`LevelPrediction` (``prediction``) and its ``peaks()``,
    or ``error`` when the fit on the other levels fails.  With ``stop_at_error`` the levels after
    the first failure are not fitted (their ``error`` says so): a candidate that fails once
    scores ``inf`` in :func:`select_laws` whatever the others give.
    """
    levels = tuple(levels)
    if len(levels) < 2:
        raise IdentificationError("leave-one-level-out needs at least two levels")
    a_ref = float(a_ref) if a_ref is not None else float(max(np.max(lv.accel) for lv in levels))
    out = []
    failed = None
    for j, lv in enumerate(levels):
        if failed is not None:
            out.append({"label": lv.label, "error": f"not fitted: the fit leaving out level {failed} failed"})
            continue
        rest = levels[:j] + levels[j + 1:]
        try:
            fit = fit_first_harmonic(rest, frequency_law, damping_law, a_ref=a_ref, repredict=False, low_level=False)
            pr = repredict_level(fit.model, lv)
            out.append({"label": lv.label, "prediction": pr, "peaks": pr.peaks(),
                        "amplitude_rms_rel": pr.amplitude_rms_rel, "phase_rms_deg": pr.phase_rms_deg,
                        "complex_rms_rel": pr.complex_rms_rel})
        except (IdentificationError, np.linalg.LinAlgError) as exc:
            out.append({"label": lv.label, "error": str(exc)})
            if stop_at_error:
                failed = lv.label
    return out


def select_laws(levels, candidates=DEFAULT_CANDIDATES, a_ref=None) -> dict:
    """``--terms auto`` for first harmonics: the pair of laws with the smallest leave-one-level-out error.

    The score of a candidate is the RMS over the levels of each left-out level's complex
    relative prediction error (:attr:`LevelPrediction.complex_rms_rel`), with a standard
    error from the spread of the levels' errors.  The candidate chosen is the one with the
    fewest parameters whose score is within one standard error of the best score (the
    one-standard-error rule: among laws the levels cannot tell apart, the simplest).
    Returns ``{"selected": (fl, dl), "table": [...]}``; a candidate whose fit fails scores
    ``inf``.
    """
    levels = tuple(levels)
    table = []
    for fl, dl in candidates:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", (JointidWarning, RuntimeWarning))
            lolo = leave_one_level_out(levels, fl, dl, a_ref, stop_at_error=True)
        errs = [e.get("complex_rms_rel", np.inf) for e in lolo]
        score = float(np.sqrt(np.mean(np.square(errs)))) if np.all(np.isfinite(errs)) else np.inf
        # standard error of the RMS from that of the mean square (delta method)
        se = (float(np.std(np.square(errs), ddof=1) / np.sqrt(len(errs)) / (2 * score))
              if np.isfinite(score) and len(errs) > 1 and score > 0 else np.inf)
        table.append({"frequency_law": fl, "damping_law": dl, "lolo_complex_rms_rel": score,
                      "lolo_stderr": se,
                      "per_level": [None if not np.isfinite(e) else float(e) for e in errs],
                      "n_parameters": 5 + AmplitudeLaw(fl).n + AmplitudeLaw(dl).n})
    finite = [t for t in table if np.isfinite(t["lolo_complex_rms_rel"])]
    if not finite:
        raise IdentificationError("no candidate law could be fitted on the levels")
    best = min(finite, key=lambda t: (t["lolo_complex_rms_rel"], t["n_parameters"]))
    limit = best["lolo_complex_rms_rel"] + best["lolo_stderr"]
    chosen = min((t for t in finite if t["lolo_complex_rms_rel"] <= limit),
                 key=lambda t: (t["n_parameters"], t["lolo_complex_rms_rel"]))
    return {"selected": (chosen["frequency_law"], chosen["damping_law"]), "table": table,
            "best_score": (best["frequency_law"], best["damping_law"]),
            "criterion": "leave-one-level-out complex relative prediction error (RMS over levels); the fewest "
                         "parameters within one standard error of the best"}


def adequacy(fit: FirstHarmonicFit, alpha=0.01) -> dict:
    """Residual checks: whiteness along frequency per level, and each level's scale against the pooled one.

    ``lag1``: the lag-1 autocorrelation of the real and imaginary residuals of a level in
    frequency order; under white noise ``z = r1 sqrt(n)`` is about standard normal, and a
    missing or wrong law leaves smooth residuals (``z`` large and positive: one-sided test).
    ``scale_ratio``: the level's mean squared residual over the pooled one; under one noise
    scale ``n_j * ratio`` is about chi^2 with ``n_j`` degrees of freedom.  The family of tests
    (two parts and one scale per level) is held at ``alpha`` by Bonferroni; ``adequate`` when no
    level fails.
    """
    rows, ok = [], True
    n_tests = 3 * len(fit.levels)
    zc = stats.norm.ppf(1 - alpha / n_tests)
    s2 = float(np.mean(np.concatenate([np.abs(r) ** 2 for r in fit.residuals]))) / 2  # pooled, per part
    for lv, r in zip(fit.levels, fit.residuals):
        order = np.argsort(lv.frequency_hz)
        zs = []
        for part in (r.real[order], r.imag[order]):
            x = part - part.mean()
            r1 = float(np.sum(x[1:] * x[:-1]) / np.sum(x * x)) if np.sum(x * x) > 0 else 0.0
            zs.append(r1 * np.sqrt(x.size))
        n2 = 2 * r.size
        ratio = float(np.sum(np.abs(r) ** 2) / n2 / s2)
        lo = stats.chi2.ppf(alpha / (2 * n_tests), n2) / n2
        hi = stats.chi2.ppf(1 - alpha / (2 * n_tests), n2) / n2
        white = all(z < zc for z in zs)
        level_ok = white and lo <= ratio <= hi
        ok &= level_ok
        rows.append({"level": lv.label, "lag1_z_real": float(zs[0]), "lag1_z_imag": float(zs[1]),
                     "lag1_z_limit": float(zc), "white": bool(white), "scale_ratio": ratio,
                     "scale_range": [float(lo), float(hi)], "ok": bool(level_ok)})
    return {"adequate": bool(ok), "verdict": _adequacy_verdict(rows), "alpha": alpha, "levels": rows,
            "test": "lag-1 autocorrelation of the residuals along frequency (one-sided) and level scale vs pooled "
                    "(chi^2), Bonferroni over the levels"}


def _adequacy_verdict(rows) -> str:
    """The reason of the adequacy verdict in words, with the numbers (rows of :func:`adequacy`)."""
    if not rows:
        return "not assessed: no level"
    limit = rows[0]["lag1_z_limit"]
    worst = max(rows, key=lambda r: max(r["lag1_z_real"], r["lag1_z_imag"]))
    z_worst = max(worst["lag1_z_real"], worst["lag1_z_imag"])
    coloured = [r for r in rows if not r["white"]]
    scaled = [r for r in rows if not r["scale_range"][0] <= r["scale_ratio"] <= r["scale_range"][1]]
    if not coloured and not scaled:
        return (f"the residuals are white along frequency (largest lag-1 autocorrelation z {z_worst:.2f}, limit "
                f"{limit:.2f}) and of one scale over the {len(rows)} level(s)")
    why = []
    if coloured:
        why.append(f"the residuals are not white along frequency at {len(coloured)} of {len(rows)} level(s) "
                   f"(largest lag-1 autocorrelation z {z_worst:.2f} at level {worst['level']}, limit {limit:.2f}): "
                   "the model leaves a smooth misfit")
    if scaled:
        why.append("the residual scale differs from the pooled one at " + ", ".join(
            f"level {r['level']} (x{r['scale_ratio']:.3g}, expected {r['scale_range'][0]:.3g}.."
            f"{r['scale_range'][1]:.3g})" for r in scaled))
    return "; ".join(why)


def simulate_levels(fit: FirstHarmonicFit, rng, noise=None) -> tuple:
    """A synthetic campaign with the same lines and forces: the fitted model as the truth, plus noise.

    Each line's amplitude solves the amplitude equation with the measured force (the branch
    rule of :func:`repredict_level`); the accelerance gets complex relative noise of scale
    ``noise`` (default: the fit's residual scale) in each of its real and imaginary parts.
    Lines where the equation has no root keep the measured amplitude.
    """
    s = fit.residual_scale if noise is None else float(noise)
    out = []
    for lv, pr in zip(fit.levels, fit.predictions or [repredict_level(fit.model, lv) for lv in fit.levels]):
        a = np.where(np.isfinite(pr.accel_predicted), pr.accel_predicted, lv.accel)
        H = fit.model.frf(lv.omega, a)
        Hn = H + s * np.abs(H) * (rng.standard_normal(H.size) + 1j * rng.standard_normal(H.size))
        out.append(FirstHarmonicLevel(lv.frequency_hz, lv.force, lv.force_phase, np.abs(Hn) * lv.force,
                                      np.angle(Hn) + lv.force_phase, lv.label, lv.control))
    return tuple(out)
