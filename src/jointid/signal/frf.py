"""Linear frequency response functions: H1 estimate, coherence, modal fit, simulation.

* :func:`h1_estimate` -- ``H1 = S_fx / S_ff`` and the coherence from random-excitation
  records (Welch averaging with :func:`scipy.signal.csd` / :func:`scipy.signal.welch`).
* :func:`fit_modes` -- natural frequencies and damping ratios by a least-squares SDOF
  fit around each resonance peak: in a band about the peak the FRF, converted to
  receptance, is modelled as

  ``H(w) = A / (w_r^2 - w^2 + 2 i zeta w_r w) + R_0 + R_2 / w^2``

  with complex modal constant ``A`` and complex residual terms for the modes above
  (``R_0``, residual flexibility) and below (``R_2 / w^2``, residual mass).  The
  coefficients enter linearly and are eliminated (variable projection); only
  ``(w_r, zeta)`` are found by :func:`scipy.optimize.least_squares`, from a peak-pick /
  half-power start.  Points are weighted by the coherence.  Every candidate peak is first
  checked by a stabilisation test: a common-denominator rational fraction
  ``B(u) / A(u)`` (``u`` the band-normalised ``i w``) is fitted in its band at model
  orders 1 to ``max_order``; a resonance gives the same pole at every order, a noise
  spike or an anti-resonance ripple does not.  Only peaks whose pole is stable, whose
  band is coherent and whose SDOF fit is physical are trusted; the lowest trusted peaks
  are the modes.
* :func:`modal_frf` -- the closed-form FRF of a modal model (for tests and plots).
* :func:`simulate_modal_response` -- the response of a linear, modally damped structure
  to a sampled force by modal superposition, each mode discretised *exactly* for a
  force that is linear between samples (first-order hold) and run with
  :func:`scipy.signal.lfilter`.

Frequencies ``*_hz`` are in hertz, ``omega`` in rad/s; time is the last axis.
"""

from __future__ import annotations

import html
from dataclasses import dataclass

import numpy as np
import scipy.optimize
import scipy.signal

from ..errors import IdentificationError, RecordError
from ..numerics.receptance import modal_denominator

__all__ = [
    "FRFEstimate",
    "ModalFit",
    "ModalResponse",
    "h1_estimate",
    "fit_modes",
    "modal_frf",
    "simulate_modal_response",
]

_OUTPUT_POWER = {"displacement": 0, "velocity": 1, "acceleration": 2}


def _check_output(output: str) -> int:
    if output not in _OUTPUT_POWER:
        raise ValueError(f"output must be one of {sorted(_OUTPUT_POWER)}, got {output!r}")
    return _OUTPUT_POWER[output]


# ----------------------------------------------------------------------------------
# H1 estimate
# ----------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class FRFEstimate:
    """An FRF estimate with its coherence.

    Attributes
    ----------
    frequency_hz : ndarray, shape (n_f,)
    H : ndarray, complex, shape (n_out, n_f) or (n_f,)
        Response per unit force (units of the response signal per newton).
    coherence : ndarray, same shape as ``H``
        Ordinary coherence between force and response.
    fs : float
        Sample rate [Hz].
    nperseg : int
        Segment length of the Welch averages.
    n_averages : int
        Number of segments averaged.
    output : str
        Response quantity: "acceleration", "velocity" or "displacement".
    force_psd : ndarray, shape (n_f,), optional
        Auto-spectrum of the force [N^2/Hz]; :func:`fit_modes` searches peaks only where
        the force excites the structure.
    """

    frequency_hz: np.ndarray
    H: np.ndarray
    coherence: np.ndarray
    fs: float
    nperseg: int
    n_averages: int
    output: str = "acceleration"
    force_psd: np.ndarray | None = None

    def excited_range(self, level: float = 1e-2) -> tuple | None:
        """``(f_lo, f_hi)`` [Hz] where the force spectrum is within ``level`` of its median.

        ``None`` when the force spectrum is unknown.
        """
        if self.force_psd is None:
            return None
        f, S = self.frequency_hz, self.force_psd
        pos = f > 0
        ok = pos & (S >= level * np.median(S[pos]))
        if not np.any(ok):
            return None
        return float(f[ok][0]), float(f[ok][-1])

    def __post_init__(self):
        for name in ("frequency_hz", "H", "coherence", "force_psd"):
            if getattr(self, name) is None:
                continue
            a = np.array(getattr(self, name))
            a.setflags(write=False)
            object.__setattr__(self, name, a)

    def summary(self) -> dict:
        return {
            "fs": float(self.fs),
            "nperseg": int(self.nperseg),
            "n_averages": int(self.n_averages),
            "resolution_hz": float(self.fs / self.nperseg),
            "output": self.output,
            "mean_coherence": float(np.mean(self.coherence)),
        }

    def report(self) -> str:
        s = self.summary()
        return (
            f"H1 estimate ({s['output']} / force): {s['n_averages']} averages of {s['nperseg']} samples, "
            f"resolution {s['resolution_hz']:.4g} Hz, mean coherence {s['mean_coherence']:.3f}"
        )

    def _repr_html_(self) -> str:
        return f"<pre>{html.escape(self.report())}</pre>"

    def plot(self, ax=None, **kwargs):
        """Plot magnitude, phase and coherence (:func:`jointid.report.modal_plots.plot_frf`)."""
        from .. import plotting  # drawing lives in report, reached by name

        return plotting.draw("modal_plots.plot_frf", self, ax=ax, **kwargs)


def h1_estimate(
    force,
    response,
    fs: float,
    *,
    nperseg: int | None = None,
    noverlap: int | None = None,
    window: str = "hann",
    detrend="constant",
    output: str = "acceleration",
) -> FRFEstimate:
    """H1 estimate ``S_fx / S_ff`` and coherence from random-excitation records.

    Parameters
    ----------
    force : array_like, shape (n_t,)
        Force [N].
    response : array_like, shape (n_t,) or (n_out, n_t)
        Response signal(s) sampled with the force.
    fs : float
        Sample rate [Hz].
    nperseg : int, optional
        Welch segment length; default ``n_t // 8`` (about 15 averages with 50 % overlap).
    noverlap : int, optional
        Default ``nperseg // 2``.
    window, detrend
        As in :func:`scipy.signal.csd`.
    output : {"acceleration", "velocity", "displacement"}
        The response quantity (used by :func:`fit_modes`).

    Returns
    -------
    FRFEstimate
    """
    _check_output(output)
    f = np.asarray(force, dtype=float)
    x = np.asarray(response, dtype=float)
    if f.ndim != 1:
        raise RecordError(f"force: expected a 1-D signal, got shape {f.shape}")
    if x.shape[-1] != f.size:
        raise RecordError(f"response has {x.shape[-1]} samples, force has {f.size}")
    if not (np.all(np.isfinite(f)) and np.all(np.isfinite(x))):
        raise RecordError("force and response must be finite")
    if nperseg is None:
        nperseg = max(f.size // 8, 16)
    nperseg = int(min(nperseg, f.size))
    if noverlap is None:
        noverlap = nperseg // 2
    kw = dict(fs=fs, window=window, nperseg=nperseg, noverlap=noverlap, detrend=detrend, axis=-1)
    freq, Sff = scipy.signal.welch(f, **kw)
    _, Sxx = scipy.signal.welch(x, **kw)
    _, Sfx = scipy.signal.csd(f, x, **kw)
    tiny = np.finfo(float).tiny
    H = Sfx / np.maximum(Sff, tiny)
    coh = np.abs(Sfx) ** 2 / np.maximum(Sff * Sxx, tiny)
    step = nperseg - noverlap
    n_avg = 1 + (f.size - nperseg) // step
    return FRFEstimate(freq, H, np.clip(coh, 0.0, 1.0), float(fs), nperseg, int(n_avg), output, Sff)


# ----------------------------------------------------------------------------------
# modal FRF (closed form)
# ----------------------------------------------------------------------------------
def modal_frf(frequency_hz, omega, damping_ratio, phi_force, phi_out, output: str = "acceleration") -> np.ndarray:
    """Closed-form FRF of a modally damped structure with mass-normalised modes.

    ``H_k(w) = (i w)^p sum_r phi_r(x_k) phi_r(x_f) / (w_r^2 - w^2 + 2 i zeta_r w_r w)``
    with ``p = 0, 1, 2`` for displacement, velocity, acceleration.

    Parameters
    ----------
    frequency_hz : array_like, shape (n_f,)
    omega : array_like, shape (n_modes,)
        Natural frequencies [rad/s].
    damping_ratio : float or array_like, shape (n_modes,)
    phi_force : array_like, shape (n_modes,)
        Mode shapes at the force point.
    phi_out : array_like, shape (n_out, n_modes) or (n_modes,)
        Mode shapes at the outputs.
    output : {"acceleration", "velocity", "displacement"}

    Returns
    -------
    ndarray, complex, shape (n_out, n_f) or (n_f,)
    """
    p = _check_output(output)
    w = 2 * np.pi * np.asarray(frequency_hz, dtype=float)
    wr = np.atleast_1d(np.asarray(omega, dtype=float))
    z = np.broadcast_to(np.asarray(damping_ratio, dtype=float), wr.shape)
    pf = np.atleast_1d(np.asarray(phi_force, dtype=float))
    po = np.asarray(phi_out, dtype=float)
    single = po.ndim == 1
    po = np.atleast_2d(po)
    den = modal_denominator(wr[:, None], z[:, None], w[None, :])
    H = (po * pf[None, :]) @ (1.0 / den) * (1j * w) ** p
    return H[0] if single else H


# ----------------------------------------------------------------------------------
# modal fit around the peaks
# ----------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class ModalFit:
    """Natural frequencies and damping ratios fitted to an FRF.

    Attributes
    ----------
    frequencies_hz : ndarray, shape (n_modes,)
    damping_ratios : ndarray, shape (n_modes,)
    modal_constants : ndarray, complex, shape (n_modes,)
        ``A_r`` of the receptance form (``phi_r(x_out) phi_r(x_f)`` for mass-normalised
        modes and noise-free data).
    bands_hz : ndarray, shape (n_modes, 2)
        Frequency band of each fit.
    fit_errors : ndarray, shape (n_modes,)
        Relative rms misfit in each band (``||H - H_fit|| / ||H||``, weighted).
    output : str
        Response quantity of the FRF that was fitted.
    trusted : ndarray of bool, shape (n_modes,)
        Whether each mode passed the stabilisation, coherence and fit checks (explicit
        bands are fitted whatever the checks say; the flag tells the result).
    stable_orders : ndarray of int, shape (n_modes,)
        Model orders (of ``max_order``) at which the mode's pole was stable.
    max_order : int
        Highest model order of the stabilisation check.
    candidates : tuple of dict
        Every peak examined by the automatic picking: ``frequency_hz``, ``coherence``
        (band median), ``stable_orders``, ``trusted`` and the ``reason`` it was not.
    """

    frequencies_hz: np.ndarray
    damping_ratios: np.ndarray
    modal_constants: np.ndarray
    bands_hz: np.ndarray
    fit_errors: np.ndarray
    output: str = "acceleration"
    trusted: np.ndarray | None = None
    stable_orders: np.ndarray | None = None
    max_order: int = 0
    candidates: tuple = ()

    def __post_init__(self):
        n = np.size(self.frequencies_hz)
        if self.trusted is None:
            object.__setattr__(self, "trusted", np.ones(n, dtype=bool))
        if self.stable_orders is None:
            object.__setattr__(self, "stable_orders", np.zeros(n, dtype=int))
        for name in ("frequencies_hz", "damping_ratios", "modal_constants", "bands_hz", "fit_errors", "trusted",
                     "stable_orders"):
            a = np.array(getattr(self, name))
            a.setflags(write=False)
            object.__setattr__(self, name, a)
        object.__setattr__(self, "candidates", tuple(dict(c) for c in self.candidates))

    def synthesize(self, frequency_hz) -> np.ndarray:
        """FRF of the fitted modes alone (no residual terms), in the fitted output."""
        p = _check_output(self.output)
        w = 2 * np.pi * np.asarray(frequency_hz, dtype=float)
        wr = 2 * np.pi * self.frequencies_hz
        den = wr[:, None] ** 2 - w[None, :] ** 2 + 2j * self.damping_ratios[:, None] * wr[:, None] * w[None, :]
        return (self.modal_constants[:, None] / den).sum(axis=0) * (1j * w) ** p

    def summary(self) -> dict:
        return {
            "frequencies_hz": [float(v) for v in self.frequencies_hz],
            "damping_ratios": [float(v) for v in self.damping_ratios],
            "bands_hz": [[float(a), float(b)] for a, b in self.bands_hz],
            "fit_errors": [float(v) for v in self.fit_errors],
            "output": self.output,
            "trusted": [bool(v) for v in self.trusted],
            "stable_orders": [int(v) for v in self.stable_orders],
            "max_order": int(self.max_order),
            "candidates": [dict(c) for c in self.candidates],
        }

    def report(self) -> str:
        lines = ["mode  f [Hz]     zeta [%]  band [Hz]           misfit    stable  trusted"]
        for i, (f, z, (a, b), e, s, t) in enumerate(
            zip(self.frequencies_hz, self.damping_ratios, self.bands_hz, self.fit_errors, self.stable_orders,
                self.trusted)
        ):
            stable = f"{s}/{self.max_order}" if self.max_order else "-"
            lines.append(f"{i + 1:4d}  {f:9.3f}  {100 * z:8.3f}  {a:8.2f}-{b:8.2f}  {e:8.2e}  {stable:>6}  "
                         f"{'yes' if t else 'NO'}")
        rejected = sorted((c for c in self.candidates if not c["trusted"]), key=lambda c: -c.get("prominence", 0))
        if rejected:
            lines.append("most prominent peaks not trusted: "
                         + "; ".join(f"{c['frequency_hz']:.2f} Hz ({c['reason']})" for c in rejected[:5])
                         + (f"; {len(rejected) - 5} more" if len(rejected) > 5 else ""))
        return "\n".join(lines)

    def _repr_html_(self) -> str:
        return f"<pre>{html.escape(self.report())}</pre>"


def _half_power_zeta(f, mag, k):
    """Damping ratio from the half-power width around bin ``k`` (linear interpolation)."""
    level = mag[k] / np.sqrt(2.0)
    i = k
    while i > 0 and mag[i] > level:
        i -= 1
    j = k
    while j < mag.size - 1 and mag[j] > level:
        j += 1
    if i == k or j == k or mag[i] > level or mag[j] > level:
        return None
    fl = f[i] + (level - mag[i]) * (f[i + 1] - f[i]) / (mag[i + 1] - mag[i])
    fh = f[j - 1] + (level - mag[j - 1]) * (f[j] - f[j - 1]) / (mag[j] - mag[j - 1])
    z = (fh - fl) / (2 * f[k])
    return z if z > 0 else None


def _fit_band(f, Hd, weight, f0, z0):
    """Variable-projection SDOF fit in one band; returns (f_r, zeta, A, misfit)."""
    w = 2 * np.pi * f
    scale = np.max(np.abs(Hd))
    y = Hd / scale
    sw = np.sqrt(weight)

    def basis(x):
        wr, z = np.exp(x)
        return np.column_stack([1.0 / modal_denominator(wr, z, w), np.ones_like(w), 1.0 / w**2])

    def solve(x):
        B = basis(x) * sw[:, None]
        coef, *_ = np.linalg.lstsq(B, y * sw, rcond=None)
        return coef, y * sw - B @ coef

    def resid(x):
        r = solve(x)[1]
        return np.concatenate([r.real, r.imag])

    x0 = np.log([2 * np.pi * f0, z0])
    lo = np.log([2 * np.pi * f[0], 1e-6])
    hi = np.log([2 * np.pi * f[-1], 0.5])
    x0 = np.clip(x0, lo + 1e-9, hi - 1e-9)
    sol = scipy.optimize.least_squares(
        resid, x0, bounds=(lo, hi), x_scale=np.array([0.01, 1.0]), xtol=1e-12, ftol=1e-12
    )
    coef, r = solve(sol.x)
    wr, z = np.exp(sol.x)
    misfit = float(np.linalg.norm(r) / max(np.linalg.norm(y * sw), 1e-300))
    return wr / (2 * np.pi), z, coef[0] * scale, misfit


def _band_poles(f, Hd, weight, order: int) -> np.ndarray:
    """Poles [rad/s] of a common-denominator rational fraction of ``order`` fitted in a band.

    ``H(u) = B(u) / A(u)`` with ``u = i (w - w_c) / w_h`` (the band mapped onto ``[-i, i]``
    for conditioning), ``A`` monic of degree ``order`` and ``B`` of degree ``order``; the
    linearised least-squares problem ``B(u_k) - H_k A(u_k) = 0`` is solved directly
    (complex coefficients: the band need not be symmetric about zero frequency).  A pole
    ``r`` of ``A`` in ``u`` is ``s = i w_c + w_h r`` in the Laplace variable.
    """
    om = 2 * np.pi * np.asarray(f, dtype=float)
    wc, wh = 0.5 * (om[0] + om[-1]), 0.5 * (om[-1] - om[0])
    u = 1j * (om - wc) / wh
    V = u[:, None] ** np.arange(order + 1)
    y = Hd / np.max(np.abs(Hd))
    sw = np.sqrt(weight)[:, None]
    M = np.hstack([V, -y[:, None] * V[:, :order]]) * sw
    theta, *_ = np.linalg.lstsq(M, (y * u**order) * sw[:, 0], rcond=None)
    a = np.concatenate([theta[order + 1:], [1.0]])
    if not np.all(np.isfinite(a)):
        return np.empty(0, dtype=complex)
    return 1j * wc + wh * np.roots(a[::-1])


def _stable_orders(f, Hd, weight, f_ref, z_ref, max_order, freq_tol, damping_tol) -> int:
    """Number of model orders ``1..max_order`` that hold a pole matching ``(f_ref, z_ref)``.

    At each order the poles of :func:`_band_poles` are computed; the order counts when
    one of them is physical (``zeta > 0``) and within ``freq_tol`` (relative) of
    ``f_ref`` [Hz] and ``damping_tol`` (relative) of the damping ratio ``z_ref``.  A
    resonance is found at (nearly) every order; the extra poles a higher order adds to
    fit noise wander from order to order and match nothing.
    """
    n_ok = 0
    for n in range(1, int(max_order) + 1):
        p = _band_poles(f, Hd, weight, n)
        if p.size == 0:
            continue
        wn = np.abs(p)
        z = -p.real / np.maximum(wn, np.finfo(float).tiny)
        match = (z > 0) & (np.abs(wn / (2 * np.pi * f_ref) - 1) <= freq_tol) & (np.abs(z / z_ref - 1) <= damping_tol)
        n_ok += bool(np.any(match))
    return n_ok


def _auto_bands(f, peaks_hz, band_fraction):
    """Fit band of each peak: +-band_fraction, cut halfway (geometrically) to its neighbours."""
    bands = []
    for i, fk in enumerate(peaks_hz):
        lo, hi = fk * (1 - band_fraction), fk * (1 + band_fraction)
        if i > 0:
            lo = max(lo, np.sqrt(peaks_hz[i - 1] * fk))
        if i < len(peaks_hz) - 1:
            hi = min(hi, np.sqrt(peaks_hz[i + 1] * fk))
        bands.append((lo, hi))
    return bands


def _receptance_band(f, H, weight, lo, hi, p, min_points=8):
    sel = (f >= lo) & (f <= hi) & (f > 0)
    n = int(np.count_nonzero(sel))
    if n < min_points:
        return None
    fb = f[sel]
    return fb, H[sel] / (1j * 2 * np.pi * fb) ** p, weight[sel], sel


def fit_modes(
    frf,
    n_modes: int | None = None,
    *,
    bands=None,
    f_range=None,
    band_fraction: float = 0.1,
    output: str | None = None,
    channel: int = 0,
    use_coherence: bool = True,
    min_coherence: float = 0.8,
    max_order: int = 8,
    min_stable: float = 0.75,
    freq_tol: float = 2e-3,
    damping_tol: float = 0.5,
    max_candidates: int = 40,
) -> ModalFit:
    """Fit natural frequencies and damping ratios around the peaks of an FRF.

    Automatic picking (no ``bands``) examines the most prominent peaks of ``|H|`` in the
    search range and trusts a peak when

    * its band is coherent: the median coherence over the band is at least
      ``min_coherence`` (the coherence *at* a lightly damped resonance dips by leakage,
      so the band median is used, not the peak value);
    * its pole is stable: rational fractions of orders ``1..max_order`` fitted in the
      band put a physical pole within ``freq_tol`` in frequency and ``damping_tol`` in
      damping of their median at ``min_stable`` of the orders or more;
    * its SDOF fit is physical: damping ratio below 0.2, resonance inside the band.

    The ``n_modes`` lowest trusted peaks are the modes (the first modes of the
    structure, not the loudest).  The examined peaks and the reason each untrusted one
    was refused are in :attr:`ModalFit.candidates`.

    Parameters
    ----------
    frf : FRFEstimate or tuple (frequency_hz, H[, coherence])
        The FRF.  For a multi-output estimate ``channel`` selects the row.
    n_modes : int, optional
        Number of modes to fit.  Required unless ``bands`` is given.
    bands : sequence of (f_lo, f_hi), optional
        Explicit fit bands [Hz], one per mode (fitted whatever the checks say;
        :attr:`ModalFit.trusted` tells the result).
    f_range : (f_lo, f_hi), optional
        Search peaks only in this range [Hz]; default where the force spectrum of an
        :class:`FRFEstimate` is within 20 dB of its median (the whole axis otherwise).
    band_fraction : float
        Half-width of an automatic band relative to the peak frequency; bands are also
        cut halfway (geometrically) to the neighbouring trusted peaks.
    output : str, optional
        Response quantity; default the estimate's ``output`` ("acceleration" for a tuple).
    channel : int
        Output row of a multi-output FRF.
    use_coherence : bool
        Weight points by the coherence.
    min_coherence : float
        Lowest median coherence of a trusted peak's band; 0 disables the check.
    max_order : int
        Highest model order of the stabilisation check (0 disables it).
    min_stable : float
        Fraction of the orders at which a trusted pole must be stable.
    freq_tol, damping_tol : float
        Relative stability tolerances on the pole's frequency and damping ratio.
    max_candidates : int
        Most prominent peaks examined.

    Returns
    -------
    ModalFit

    Raises
    ------
    IdentificationError
        Fewer trusted peaks than asked for, or too few points in a band.

    Examples
    --------
    >>> f = np.linspace(1.0, 300.0, 6000)
    >>> H = modal_frf(f, 2 * np.pi * np.array([30.0, 150.0]), 0.002, [0.2, 0.4], [1.0, -0.8])
    >>> fit = fit_modes((f, H), 2)
    >>> np.round(fit.frequencies_hz, 3), bool(fit.trusted.all())
    (array([ 30., 150.]), True)
    """
    if isinstance(frf, FRFEstimate):
        f, H, coh = frf.frequency_hz, frf.H, frf.coherence
        output = frf.output if output is None else output
        if f_range is None and bands is None:
            f_range = frf.excited_range()
    else:
        f, H, *rest = frf
        coh = rest[0] if rest else None
        output = "acceleration" if output is None else output
    p = _check_output(output)
    f = np.asarray(f, dtype=float)
    H = np.asarray(H)
    if H.ndim == 2:
        H = H[channel]
        coh = None if coh is None else np.asarray(coh)[channel]
    if H.shape != f.shape:
        raise IdentificationError(f"FRF has {H.shape[-1]} points, frequency axis {f.size}")
    if not np.all(np.isfinite(H)):
        raise IdentificationError("FRF has non-finite values")
    coh = None if coh is None else np.asarray(coh, dtype=float)
    weight = np.ones_like(f) if (coh is None or not use_coherence) else np.clip(coh, 1e-3, 1.0)
    usable = f > 0
    if f_range is not None:
        usable &= (f >= f_range[0]) & (f <= f_range[1])
    n_ord = max(int(max_order), 0)

    def fit_and_check(lo, hi):
        """SDOF fit of a band and its checks: (fit, trusted, reason, coherence, stable orders)."""
        band = _receptance_band(f, H, weight, lo, hi, p)
        if band is None:
            return None, False, "too few points in band", float("nan"), 0
        fb, Hd, wb, sel = band
        k = int(np.argmax(np.abs(Hd)))
        fit = _fit_band(fb, Hd, wb, fb[k], _half_power_zeta(fb, np.abs(Hd), k) or 0.01)
        fr, z = fit[0], fit[1]
        c_med = float(np.median(coh[sel])) if coh is not None else 1.0
        if coh is not None and min_coherence > 0 and c_med < min_coherence:
            return fit, False, f"band coherence {c_med:.2f} < {min_coherence:g}", c_med, 0
        if not (z < 0.2 and fb[0] < fr < fb[-1]):
            return fit, False, f"SDOF fit not physical (zeta {z:.3g}, f {fr:.5g} Hz)", c_med, 0
        n_stable = 0
        if n_ord:
            n_stable = _stable_orders(fb, Hd, wb, fr, z, n_ord, freq_tol, damping_tol)
            if n_stable < min_stable * n_ord:
                return fit, False, f"pole stable at {n_stable}/{n_ord} orders", c_med, n_stable
        return fit, True, "", c_med, n_stable

    candidates = []
    if bands is None:
        if n_modes is None:
            raise ValueError("give n_modes or bands")
        idx = np.flatnonzero(usable)
        logm = np.log(np.maximum(np.abs(H[idx]), np.finfo(float).tiny))
        peaks, props = scipy.signal.find_peaks(logm, prominence=0.5)
        keep = np.sort(np.argsort(props["prominences"])[::-1][:max(int(max_candidates), int(n_modes))])
        pk_hz = f[idx[peaks[keep]]]
        prominence = props["prominences"][keep]
        trusted_hz = []
        for lo_hi, fk, pr in zip(_auto_bands(f, pk_hz, band_fraction), pk_hz, prominence):
            _, ok, reason, c_med, n_stable = fit_and_check(*lo_hi)
            candidates.append({"frequency_hz": float(fk), "prominence": float(pr), "coherence": c_med,
                               "stable_orders": int(n_stable), "trusted": bool(ok), "reason": reason})
            if ok:
                trusted_hz.append(float(fk))
        if len(trusted_hz) < n_modes:
            refused = sorted((c for c in candidates if not c["trusted"]), key=lambda c: -c["prominence"])
            shown = "; ".join(f"{c['frequency_hz']:.2f} Hz: {c['reason']}" for c in refused[:5])
            raise IdentificationError(
                f"found {len(trusted_hz)} trusted resonance peaks"
                + (f" ({', '.join(f'{v:.2f}' for v in trusted_hz)} Hz)" if trusted_hz else "")
                + f", {n_modes} were asked for"
                + (f"; most prominent refused: {shown}" if shown else "")
                + "; give the bands explicitly, narrow f_range or lower min_coherence"
            )
        bands = _auto_bands(f, trusted_hz, band_fraction)[: int(n_modes)]
    bands = np.asarray(bands, dtype=float).reshape(-1, 2)

    freqs, zetas, consts, errs, trusted, stable = [], [], [], [], [], []
    for lo, hi in bands:
        fit, ok, _, _, n_stable = fit_and_check(lo, hi)
        if fit is None:
            raise IdentificationError(
                f"band {lo:.3g}-{hi:.3g} Hz has {np.count_nonzero((f >= lo) & (f <= hi) & (f > 0))} FRF points, "
                "at least 8 are needed; use a finer resolution (longer nperseg) or a wider band"
            )
        fr, z, A, e = fit
        freqs.append(fr)
        zetas.append(z)
        consts.append(A)
        errs.append(e)
        trusted.append(ok)
        stable.append(n_stable)
    return ModalFit(np.array(freqs), np.array(zetas), np.array(consts), bands, np.array(errs), output,
                    np.array(trusted, dtype=bool), np.array(stable, dtype=int), n_ord, tuple(candidates))

# ----------------------------------------------------------------------------------
# simulation by modal superposition
# ----------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class ModalResponse:
    """Simulated response of a modally damped structure.

    Attributes
    ----------
    t : ndarray, shape (n_t,)
        Time [s], starting at zero (structure at rest).
    q, qd, qdd : ndarray, shape (n_modes, n_t)
        Modal coordinates and their derivatives (mass-normalised modes).
    response : ndarray, shape (n_out, n_t)
        The requested physical output at the output points.
    output : str
    """

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    response: np.ndarray
    output: str

    def __post_init__(self):
        for name in ("t", "q", "qd", "qdd", "response"):
            a = np.array(getattr(self, name))
            a.setflags(write=False)
            object.__setattr__(self, name, a)


def _sdof_filters(wr: float, zeta: float, dt: float):
    """Exact FOH discretisation of ``q'' + 2 zeta wr q' + wr^2 q = u``; (b, a) per output."""
    A = np.array([[0.0, 1.0], [-(wr**2), -2 * zeta * wr]])
    B = np.array([[0.0], [1.0]])
    C = np.array([[1.0, 0.0], [0.0, 1.0], [-(wr**2), -2 * zeta * wr]])
    D = np.array([[0.0], [0.0], [1.0]])
    Ad, Bd, Cd, Dd, _ = scipy.signal.cont2discrete((A, B, C, D), dt, method="foh")
    out = []
    for i in range(3):
        b, a = scipy.signal.ss2tf(Ad, Bd, Cd[i : i + 1], Dd[i : i + 1])
        out.append((np.atleast_1d(b.ravel()), a))
    return out


def simulate_modal_response(
    omega,
    damping_ratio,
    phi_force,
    phi_out,
    force,
    fs: float,
    *,
    output: str = "acceleration",
    method: str = "foh",
) -> ModalResponse:
    """Response of a linear, modally damped structure to a point force.

    Each mode obeys ``q_r'' + 2 zeta_r w_r q_r' + w_r^2 q_r = phi_r(x_f) F(t)``; the
    physical output at point ``k`` is ``sum_r phi_r(x_k) q_r`` (or its derivatives).

    ``method="foh"`` (default) discretises each mode exactly for a force linear between
    samples (first-order hold) and runs it with :func:`scipy.signal.lfilter`, from rest:
    a causal response with transients, as a test rig would see it.  The hold acts as a
    mild low-pass on a sampled random force (about ``sinc^2(f / fs)``, 1 % at
    ``f = fs / 18``).

    ``method="fft"`` treats the force as one period of a band-limited periodic signal
    and returns the periodic steady state, ``q_r = IFFT(H_r(w) FFT(phi_r(x_f) F))``:
    exact at every frequency bin, no transient; good for FRF checks.

    Parameters
    ----------
    omega : array_like, shape (n_modes,)
        Natural frequencies [rad/s].  All must be below the Nyquist frequency.
    damping_ratio : float or array_like, shape (n_modes,)
        Modal damping ratios.
    phi_force : array_like, shape (n_modes,)
        Mass-normalised mode shapes at the force point.
    phi_out : array_like, shape (n_out, n_modes)
        Mass-normalised mode shapes at the output points.
    force : array_like, shape (n_t,)
        Force samples [N].
    fs : float
        Sample rate [Hz].
    output : {"acceleration", "velocity", "displacement"}
    method : {"foh", "fft"}
        Time-stepping from rest, or periodic steady state (see above).

    Returns
    -------
    ModalResponse

    Examples
    --------
    >>> fs, w = 1000.0, 2 * np.pi * 20.0
    >>> t = np.arange(20000) / fs
    >>> r = simulate_modal_response([w], 0.05, [1.0], [[1.0]], np.sin(w * t), fs, output="displacement")
    >>> amplitude = float(np.max(np.abs(r.response[0, -2000:])))
    >>> round(amplitude * 2 * 0.05 * w**2, 2)   # resonance amplitude 1 / (2 zeta w^2)
    1.0
    """
    p = _check_output(output)
    wr = np.atleast_1d(np.asarray(omega, dtype=float))
    z = np.broadcast_to(np.asarray(damping_ratio, dtype=float), wr.shape)
    pf = np.atleast_1d(np.asarray(phi_force, dtype=float))
    po = np.atleast_2d(np.asarray(phi_out, dtype=float))
    F = np.asarray(force, dtype=float)
    if F.ndim != 1 or not np.all(np.isfinite(F)):
        raise RecordError(f"force: expected a finite 1-D signal, got shape {F.shape}")
    if pf.shape != wr.shape or po.shape[1] != wr.size:
        raise ValueError(
            f"{wr.size} modes: phi_force must have shape ({wr.size},), phi_out (n_out, {wr.size}); "
            f"got {pf.shape} and {po.shape}"
        )
    if np.any(wr <= 0) or np.any(wr >= np.pi * fs):
        raise ValueError(f"natural frequencies must lie in (0, fs/2) = (0, {fs / 2:g}) Hz")
    if np.any(z < 0) or np.any(z >= 1):
        raise ValueError("damping ratios must lie in [0, 1)")
    if method not in ("foh", "fft"):
        raise ValueError(f"method must be 'foh' or 'fft', got {method!r}")
    dt = 1.0 / fs
    n = F.size
    q = np.empty((wr.size, n))
    qd = np.empty_like(q)
    qdd = np.empty_like(q)
    if method == "fft":
        w = 2 * np.pi * np.fft.rfftfreq(n, dt)
        U = np.fft.rfft(F)
        for r in range(wr.size):
            X = pf[r] * U / modal_denominator(wr[r], z[r], w)
            q[r] = np.fft.irfft(X, n)
            qd[r] = np.fft.irfft(1j * w * X, n)
            qdd[r] = np.fft.irfft(-(w**2) * X, n)
        modal = (q, qd, qdd)[p]
        return ModalResponse(np.arange(n) * dt, q, qd, qdd, po @ modal, output)
    for r in range(wr.size):
        u = pf[r] * F
        (b0, a0), (b1, a1), (b2, a2) = _sdof_filters(wr[r], z[r], dt)
        q[r] = scipy.signal.lfilter(b0, a0, u)
        qd[r] = scipy.signal.lfilter(b1, a1, u)
        qdd[r] = scipy.signal.lfilter(b2, a2, u)
    modal = (q, qd, qdd)[p]
    return ModalResponse(np.arange(n) * dt, q, qd, qdd, po @ modal, output)
