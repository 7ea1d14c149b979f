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
  half-power start.  Points are weighted by the coherence.
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
    """

    frequency_hz: np.ndarray
    H: np.ndarray
    coherence: np.ndarray
    fs: float
    nperseg: int
    n_averages: int
    output: str = "acceleration"

    def __post_init__(self):
        for name in ("frequency_hz", "H", "coherence"):
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
        from ..report.modal_plots import plot_frf  # plotting lives in report

        return plot_frf(self, ax=ax, **kwargs)


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
    return FRFEstimate(freq, H, np.clip(coh, 0.0, 1.0), float(fs), nperseg, int(n_avg), output)


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
    den = wr[:, None] ** 2 - w[None, :] ** 2 + 2j * z[:, None] * wr[:, None] * w[None, :]
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
    """

    frequencies_hz: np.ndarray
    damping_ratios: np.ndarray
    modal_constants: np.ndarray
    bands_hz: np.ndarray
    fit_errors: np.ndarray
    output: str = "acceleration"

    def __post_init__(self):
        for name in ("frequencies_hz", "damping_ratios", "modal_constants", "bands_hz", "fit_errors"):
            a = np.array(getattr(self, name))
            a.setflags(write=False)
            object.__setattr__(self, name, a)

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
        }

    def report(self) -> str:
        lines = ["mode  f [Hz]     zeta [%]  band [Hz]           misfit"]
        for i, (f, z, (a, b), e) in enumerate(
            zip(self.frequencies_hz, self.damping_ratios, self.bands_hz, self.fit_errors)
        ):
            lines.append(f"{i + 1:4d}  {f:9.3f}  {100 * z:8.3f}  {a:8.2f}-{b:8.2f}  {e:8.2e}")
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
        return np.column_stack([1.0 / (wr**2 - w**2 + 2j * z * wr * w), np.ones_like(w), 1.0 / w**2])

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
) -> ModalFit:
    """Fit natural frequencies and damping ratios around the peaks of an FRF.

    Parameters
    ----------
    frf : FRFEstimate or tuple (frequency_hz, H[, coherence])
        The FRF.  For a multi-output estimate ``channel`` selects the row.
    n_modes : int, optional
        Number of peaks to fit (the most prominent, in frequency order).  Required
        unless ``bands`` is given.
    bands : sequence of (f_lo, f_hi), optional
        Explicit fit bands [Hz], one per mode.
    f_range : (f_lo, f_hi), optional
        Search peaks only in this range [Hz].
    band_fraction : float
        Half-width of an automatic band relative to the peak frequency; bands are also
        cut halfway (geometrically) to the neighbouring peaks.
    output : str, optional
        Response quantity; default the estimate's ``output`` ("acceleration" for a tuple).
    channel : int
        Output row of a multi-output FRF.
    use_coherence : bool
        Weight points by the coherence.
    min_coherence : float
        Automatic peak picking ignores peaks whose coherence is below this (noise
        spikes at anti-resonances); 0 disables the check.

    Returns
    -------
    ModalFit

    Raises
    ------
    IdentificationError
        Fewer peaks than asked for, or too few points in a band.
    """
    if isinstance(frf, FRFEstimate):
        f, H, coh = frf.frequency_hz, frf.H, frf.coherence
        output = frf.output if output is None else output
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
    weight = np.ones_like(f) if (coh is None or not use_coherence) else np.clip(np.asarray(coh, float), 1e-3, 1.0)
    usable = f > 0
    if f_range is not None:
        usable &= (f >= f_range[0]) & (f <= f_range[1])
    mag = np.abs(H)

    if bands is None:
        if n_modes is None:
            raise ValueError("give n_modes or bands")
        idx = np.flatnonzero(usable)
        logm = np.log(np.maximum(mag[idx], np.finfo(float).tiny))
        peaks, props = scipy.signal.find_peaks(logm, prominence=0.5)
        if coh is not None and min_coherence > 0:
            ok = np.asarray(coh, float)[idx[peaks]] >= min_coherence
            peaks, props = peaks[ok], {k: v[ok] for k, v in props.items()}
        if peaks.size < n_modes:
            raise IdentificationError(
                f"found {peaks.size} resonance peaks (coherence >= {min_coherence}), {n_modes} were asked for; "
                "give the bands explicitly or narrow f_range"
            )
        best = np.sort(peaks[np.argsort(props["prominences"])[::-1][:n_modes]])
        pk = idx[best]
        bands = []
        for i, k in enumerate(pk):
            lo, hi = f[k] * (1 - band_fraction), f[k] * (1 + band_fraction)
            if i > 0:
                lo = max(lo, np.sqrt(f[pk[i - 1]] * f[k]))
            if i < pk.size - 1:
                hi = min(hi, np.sqrt(f[pk[i + 1]] * f[k]))
            bands.append((lo, hi))
    bands = np.asarray(bands, dtype=float).reshape(-1, 2)

    freqs, zetas, consts, errs = [], [], [], []
    for lo, hi in bands:
        sel = (f >= lo) & (f <= hi) & (f > 0)
        if np.count_nonzero(sel) < 8:
            raise IdentificationError(
                f"band {lo:.3g}-{hi:.3g} Hz has {np.count_nonzero(sel)} FRF points, at least 8 are needed; "
                "use a finer resolution (longer nperseg) or a wider band"
            )
        fb = f[sel]
        Hd = H[sel] / (1j * 2 * np.pi * fb) ** p  # to receptance
        k = int(np.argmax(np.abs(Hd)))
        z0 = _half_power_zeta(fb, np.abs(Hd), k) or 0.01
        fr, z, A, e = _fit_band(fb, Hd, weight[sel], fb[k], z0)
        freqs.append(fr)
        zetas.append(z)
        consts.append(A)
        errs.append(e)
    return ModalFit(np.array(freqs), np.array(zetas), np.array(consts), bands, np.array(errs), output)


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
            X = pf[r] * U / (wr[r] ** 2 - w**2 + 2j * z[r] * wr[r] * w)
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
