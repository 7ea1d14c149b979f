"""Free decay (ring-down) records: state reconstruction and the amplitude-dependent backbone.

After the shaker is released the modal coordinate decays freely, ``q'' + h(q, q') = 0``.
The decay is not periodic, so the harmonic fit of a steady state does not apply.  Here
the record is cut into short overlapping windows of ``n_cycles`` periods and in each
window the signal is fitted by one damped oscillation

``x(tau) = Re(C exp(lambda tau)) + x0``,   ``lambda = -sigma + i omega_d``,   ``tau = t - t_c``

(nonlinear least squares in ``omega_d`` and ``sigma``, linear in ``C`` and ``x0``, each
window started from the previous one).  Within a window the frequency and the decay
rate are taken as constant, which the nonlinearity only makes approximately true: the
amplitude changes by ``exp(-sigma T)`` over a window, a few per cent for a lightly
damped joint, and the fitted values are those of the window's centre to first order.
The second-order error is the average over the window: about ``(sigma T)^2 / 6`` of the
amplitude-dependent part of ``omega^2`` (halve the window, quarter the bias).

From each window:

* the natural frequency ``omega_n = |lambda|`` and damping ratio ``zeta = sigma / |lambda|``
  (exact for a linear mode; the backbone of a weakly nonlinear one).  The decay rate of
  an acceleration record's envelope is that of the displacement less ``2 (dw/dt) / w``
  (the frequency drifts as the amplitude falls); the drift is taken from the
  neighbouring windows and the displacement's rate restored;
* the displacement and velocity in closed form, ``q = Re(C / lambda^2 e^{lambda tau})``,
  ``q' = Re(C / lambda e^{lambda tau})`` for an acceleration record: the states of the
  force-state mapping on the free decay (restoring force ``-q''``; fitted on the identify
  floor by :func:`jointid.identify.ringdown.ringdown_force_state_mapping`).  Their error is stated per window as the RMS of the fit residual
  relative to the window's amplitude (``state_error``); it holds the measurement noise,
  the other modes and the distortion of the decay inside the window;
* the amplitude ``a = |C| / |lambda|^2`` of the displacement at the window's centre.

Bias at low amplitude (noise floor)
    The fitted amplitude is biased upwards by noise: ``E|C_hat|^2 = |C|^2 + 2 s_C^2`` with
    ``s_C`` its standard error, a relative bias of about ``(s_C / |C|)^2``; the frequency
    is unbiased to first order and the decay rate's error grows as ``s_C / |C|``.
    Windows whose amplitude is below ``snr_min`` standard errors (default 30: amplitude
    bias below 0.1 %) are flagged ``below_noise_floor`` and left out of the backbone.

Band-limited decays without a force (:func:`band_limit`, :func:`modal_ringdown`)
    An impact excites every mode and its force is often not recorded.  One mode is kept by a
    zero-phase band-pass (Butterworth, forward and backward: no phase shift, so no shift of
    the frequency or the amplitude in time; the squared magnitude response).  Inside the
    pass band the filter leaves the decay of a mode as it is; its own start-up transient
    (a few over the bandwidth, ``~ 1 / B`` seconds) is skipped, and so is the impact itself.
    The noise that remains is that of the band, correlated over about ``1 / B``: a window of
    a few periods holds only ``~ 2 B T`` independent noise samples, and the fitted oscillation
    takes up four of them.  The windows' covariances are therefore those of least squares
    under the band-limited noise's autocorrelation (white noise through the filter; the
    sandwich ``(J'J)^-1 J' S J (J'J)^-1``), and its level is the record's pooled residual over
    ``tr((I - P) S)``, not each window's residual over ``N - 5`` (which, for a +-15 % band and
    8-period windows, underestimated the standard errors about twice).  Overlapping windows
    (``hop_cycles < n_cycles``) have correlated errors.  The backbone can be given against the amplitude of the
    recorded signal itself (``measure="signal"``: for an accelerometer the first-harmonic
    acceleration amplitude, the quantity a stepped-sine controller holds at that point)
    or against the displacement amplitude.
"""

from __future__ import annotations

import html
import warnings
from dataclasses import dataclass, field

import numpy as np
from scipy import optimize

from ..errors import JointidWarning, RecordError
from .backbone import Backbone
from .harmonics import check_signal, check_time_base

__all__ = ["DecayFit", "fit_decay", "dominant_frequency", "band_limit",
           "modal_ringdown", "monotone_check"]


def _readonly(a):
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


def dominant_frequency(t, x, f_range=None) -> float:
    """Frequency [Hz] of the largest spectral peak of ``x`` (Hann window, parabolic refinement)."""
    t = np.asarray(t, float)
    x = np.asarray(x, float) - np.mean(x)
    dt = (t[-1] - t[0]) / (t.size - 1)
    n = 1 << int(np.ceil(np.log2(4 * t.size)))
    X = np.abs(np.fft.rfft(x * np.hanning(x.size), n))
    f = np.fft.rfftfreq(n, dt)
    sel = np.ones(f.size, bool) if f_range is None else (f >= f_range[0]) & (f <= f_range[1])
    sel[0] = False
    if not np.any(sel):
        raise RecordError(f"no spectral line in the range {f_range} Hz")
    i = int(np.flatnonzero(sel)[np.argmax(X[sel])])
    if 0 < i < f.size - 1:
        y0, y1, y2 = np.log(X[i - 1:i + 2] + 1e-300)
        d = 0.5 * (y0 - y2) / (y0 - 2 * y1 + y2) if (y0 - 2 * y1 + y2) != 0 else 0.0
        return float(f[i] + d * (f[1] - f[0]))
    return float(f[i])


@dataclass(frozen=True, eq=False)
class DecayFit:
    """Windowed damped-oscillation fit of one free decay.

    Attributes
    ----------
    t_centre : ndarray
        Centre of each window [s].
    amplitude, amplitude_stderr : ndarray
        Displacement amplitude ``a`` at the centre (in the units of the record integrated
        twice for an acceleration record).
    omega_n, omega_stderr : ndarray
        Natural frequency ``|lambda|`` [rad/s].
    zeta, zeta_stderr : ndarray
    state_error : ndarray
        RMS residual of the window's fit relative to its amplitude (the error of the
        reconstructed states).
    below_noise_floor : ndarray of bool
        ``amplitude < snr_min * amplitude_stderr``.
    coefficients : ndarray, shape (n, 4)
        ``[Re C, Im C, sigma, omega_d]`` of each window (signal units).
    window : tuple of (int, int)
        Sample range of each window.
    kind : {"acceleration", "velocity", "displacement"}
    n_cycles, snr_min : float
    misfit : ndarray of bool
        The window's residual exceeds the record's noise beyond chance (its 99 % point):
        the oscillation drifts inside the window or another mode is in it.  With
        ``noise_acf`` (:func:`modal_ringdown`) the other windows' standard errors are those
        of the record's noise; a misfit window's are from its own residual (conservative:
        the drift's error is in its values, and the residual overstates it).
    """

    t_centre: np.ndarray
    amplitude: np.ndarray
    amplitude_stderr: np.ndarray
    omega_n: np.ndarray
    omega_stderr: np.ndarray
    zeta: np.ndarray
    zeta_stderr: np.ndarray
    state_error: np.ndarray
    below_noise_floor: np.ndarray
    coefficients: np.ndarray = field(repr=False)
    window: tuple = field(repr=False)
    kind: str = "acceleration"
    n_cycles: float = 24.0
    snr_min: float = 30.0
    signal_amplitude: np.ndarray | None = None  # |C|: amplitude of the recorded signal at the window's centre
    signal_amplitude_stderr: np.ndarray | None = None
    misfit: np.ndarray | None = None

    def __len__(self):
        return int(self.t_centre.size)

    def backbone(self, label="", include_floor=False, measure="displacement", amplitude_unit=None):
        """The windows above the noise floor as a :class:`~jointid.signal.backbone.Backbone` (``"ringdown"``).

        ``measure="signal"`` gives the amplitude of the recorded signal (an accelerometer's
        first-harmonic acceleration amplitude) instead of the displacement's.
        """
        if measure not in ("displacement", "signal"):
            raise RecordError(f"measure must be 'displacement' or 'signal', got {measure!r}")
        keep = np.ones(len(self), bool) if include_floor else ~self.below_noise_floor
        if measure == "signal":
            a, ase = self.signal_amplitude, self.signal_amplitude_stderr
        else:
            a, ase = self.amplitude, self.amplitude_stderr
        meta = {"t_centre": self.t_centre[keep].tolist(), "state_error": self.state_error[keep].tolist(),
                "measure": measure}
        if self.misfit is not None:
            meta["misfit"] = self.misfit[keep].tolist()
        if amplitude_unit:
            meta["amplitude_unit"] = amplitude_unit
        return Backbone(a[keep], self.omega_n[keep], self.zeta[keep], self.omega_stderr[keep],
                        self.zeta_stderr[keep], "ringdown", ase[keep], label, meta)

    def states(self, t, x=None):
        """Reconstructed ``(q, q', q'')`` at the samples of every window above the noise floor.

        Parameters
        ----------
        t : array
            The record's time base.
        x : array, optional
            The record; when given, the measured ``q''`` replaces the fitted one (an
            acceleration record).

        Returns
        -------
        list of (slice, q, v, acc)
        """
        t = np.asarray(t, float)
        out = []
        for i, (i0, i1) in enumerate(self.window):
            if self.below_noise_floor[i]:
                continue
            cr, ci, sigma, wd = self.coefficients[i]
            lam = complex(-sigma, wd)
            C = complex(cr, ci)
            p = {"acceleration": 2, "velocity": 1, "displacement": 0}[self.kind]
            Cq = C / lam**p
            e = np.exp(lam * (t[i0:i1] - self.t_centre[i]))
            q, v, acc = (Cq * e).real, (Cq * lam * e).real, (Cq * lam**2 * e).real
            if x is not None and self.kind == "acceleration":
                acc = np.asarray(x[i0:i1], float)
            out.append((slice(i0, i1), q, v, acc))
        return out

    def summary(self) -> dict:
        n_ok = int(np.count_nonzero(~self.below_noise_floor))
        return {
            "kind": self.kind,
            "n_windows": len(self),
            "n_above_noise_floor": n_ok,
            "n_cycles": self.n_cycles,
            "snr_min": self.snr_min,
            "state_error_median": float(np.median(self.state_error)) if len(self) else None,
            "n_misfit": int(np.count_nonzero(self.misfit)) if self.misfit is not None else None,
            "amplitude_range": [float(self.amplitude[~self.below_noise_floor].min()),
                                float(self.amplitude[~self.below_noise_floor].max())] if n_ok else None,
        }

    def report(self) -> str:
        s = self.summary()
        rng = s["amplitude_range"]
        head = (f"DecayFit ({self.kind}): {s['n_windows']} windows of {self.n_cycles:g} cycles, "
                f"{s['n_above_noise_floor']} above the noise floor")
        if rng:
            head += f"; amplitude {rng[0]:.4g} .. {rng[1]:.4g}"
        return head + f"; median state error {100 * (s['state_error_median'] or 0):.3g} %"

    def _repr_html_(self) -> str:
        return f"<pre>{html.escape(self.report())}</pre>"


def _fit_window(tau, x, sigma0, wd0, acf=None):
    """Damped-oscillation fit of one window.

    Returns ``(coef [Re C, Im C, sigma, wd, x0], cov1, rss, trace, nu)``: ``cov1`` is the
    covariance of ``coef`` per unit noise variance, ``rss`` the residual sum of squares and
    ``trace`` its expectation per unit noise variance (``E rss = s^2 trace``), ``nu`` the
    residual's effective degrees of freedom.  White noise without ``acf``; with ``acf`` (the
    noise's autocorrelation at lags ``0, 1, ...`` samples, ``acf[0] = 1``) the sandwich
    ``(J'J)^-1 J' S J (J'J)^-1`` of least squares under correlated noise, and
    ``trace = tr((I - P) S)``, ``nu = trace^2 / tr(((I - P) S)^2)`` (Satterthwaite).
    """

    def design(sigma, wd):
        e = np.exp(-sigma * tau)
        return np.column_stack([e * np.cos(wd * tau), -e * np.sin(wd * tau), np.ones_like(tau)])

    def resid(p):
        A = design(*p)
        c, *_ = np.linalg.lstsq(A, x, rcond=None)
        return A @ c - x

    span = tau[-1] - tau[0]
    sol = optimize.least_squares(resid, [sigma0, wd0], x_scale=[1.0 / span, 1.0 / span], method="lm",
                                 xtol=1e-13, ftol=1e-13)
    sigma, wd = sol.x
    A = design(sigma, wd)
    c, *_ = np.linalg.lstsq(A, x, rcond=None)
    r = A @ c - x
    rss = float(r @ r)
    # full Jacobian in (Re C, Im C, sigma, wd, x0)
    e = np.exp(-sigma * tau)
    co, si = np.cos(wd * tau), np.sin(wd * tau)
    model = e * (c[0] * co - c[1] * si)
    dsig = -tau * model
    dwd = e * (-c[0] * tau * si - c[1] * tau * co)
    J = np.column_stack([A[:, 0], A[:, 1], dsig, dwd, A[:, 2]])
    coef = np.array([c[0], c[1], sigma, wd, c[2]])
    inv = np.linalg.pinv(J.T @ J)
    n = x.size
    if acf is None:
        dof = float(max(n - 5, 1))
        return coef, inv, rss, dof, dof
    from scipy.linalg import matmul_toeplitz

    a = np.zeros(n)
    m = min(n, len(acf))
    a[:m] = acf[:m]
    Q, _ = np.linalg.qr(J)
    SQ = matmul_toeplitz(a, Q)
    QSQ = Q.T @ SQ
    SJ = matmul_toeplitz(a, J)
    cov1 = inv @ (J.T @ SJ) @ inv
    trace = n * a[0] - float(np.trace(QSQ))
    tr_s2 = n * a[0] ** 2 + 2.0 * float(np.sum((n - np.arange(1, n)) * a[1:] ** 2))
    tr_w2 = tr_s2 - 2.0 * float(np.sum(SQ * SQ)) + float(np.sum(QSQ * QSQ))
    trace = max(trace, 1e-12 * n)
    return coef, 0.5 * (cov1 + cov1.T), rss, trace, trace**2 / max(tr_w2, 1e-300)


def _noise_scale(rss, trace, nu, pooled):
    """Noise variance of each window and whether its residual exceeds the noise beyond chance.

    ``own = rss / trace`` is a window's own estimate (``s^2 chi2_nu / nu``).  The record's level
    is first the median of ``own`` over that of ``chi2_nu / nu`` (robust to windows with model
    error): windows whose ``own`` is above its 99 % point are the misfits (drift within the
    window, another mode).  The level is then the pooled ``sum(rss) / sum(trace)`` of the later
    half of the other windows: the decay's smaller amplitudes, where the residual of a drift
    that falls with the amplitude is least (windows of a softening decay below the misfit
    threshold still raised the level of the whole record by about a tenth).
    With ``pooled`` (stationary noise, the usual case of a ring-down whose noise floor does not
    decay with the signal) the windows take the record's level: needed where a window holds
    few independent noise samples (a narrow band and a short window: ``nu`` of a few).  A
    misfit keeps its own, larger level: its values carry the drift's error, which the residual
    shows but the noise does not (a Jenkins joint's slip windows, residuals 30-130 times the
    noise; with the noise level alone a law fitted through them missed ``Fs`` by 3.7 standard
    errors).  Without ``pooled``, each window its own ``own``.
    """
    from scipy import stats

    own = rss / trace
    if rss.size < 2:
        return own, np.zeros(rss.size, bool)
    nu_m = float(np.median(nu))
    s2 = float(np.median(own)) / (stats.chi2.median(nu_m) / nu_m)
    misfit = own > s2 * stats.chi2.ppf(0.99, nu) / nu
    late = (np.arange(rss.size) >= rss.size // 2) & ~misfit
    late = late if late.any() else ~misfit
    s2 = float(np.sum(rss[late]) / np.sum(trace[late]))
    return (np.where(misfit, np.maximum(own, s2), s2) if pooled else own), misfit


def fit_decay(t, x, *, kind="acceleration", frequency_hz=None, n_cycles=24.0, hop_cycles=6.0, snr_min=30.0,
              start=None, channel="accel", noise_acf=None) -> DecayFit:
    """Windowed damped-oscillation fit of a free decay (module docstring).

    Parameters
    ----------
    t, x : array
        Time [s] and the free decay of one modal coordinate (or one sensor).
    kind : {"acceleration", "velocity", "displacement"}
        What ``x`` is; amplitudes and states are given for the displacement.
    frequency_hz : float, optional
        Starting frequency; the largest spectral peak by default.
    n_cycles, hop_cycles : float
        Window length and step in periods of the starting frequency.  The decay rate's
        error falls as the window's decay ``sigma T`` grows and the averaging bias rises as
        its square: 24 periods suit damping ratios near 0.2 % (``sigma T`` about 0.3);
        scale the window inversely with the damping.
    snr_min : float
        Windows with ``amplitude < snr_min * amplitude_stderr`` are flagged.
    start : float, optional
        Time [s] from which to analyse (default: the largest envelope sample, i.e. the
        release).
    channel : str
        Name used in messages.
    noise_acf : array, optional
        Autocorrelation of the noise at lags ``0, 1, ...`` samples (any scale), for a record
        whose noise is not white (a band-limited one, :func:`modal_ringdown`).  The windows'
        covariances are then those of least squares under that correlation (sandwich), with
        the noise level pooled over the record (stationary noise; windows whose residual
        exceeds it beyond chance keep their own level and are flagged ``misfit``).  Default:
        white noise, each window's own residual.

    Returns
    -------
    DecayFit
        Windows overlap when ``hop_cycles < n_cycles``: their errors are then correlated
        (by about the overlapping fraction), and a fit through the points of a backbone must
        not count them as independent (use ``hop_cycles = n_cycles`` for that).

    Raises
    ------
    RecordError
        Bad time base or values, or a record shorter than one window.
    """
    if kind not in ("acceleration", "velocity", "displacement"):
        raise RecordError(f"kind must be 'acceleration', 'velocity' or 'displacement', got {kind!r}")
    t = check_signal(t, "time")
    check_time_base(t)
    x = check_signal(x, channel, t.size)
    if not np.any(x - x.mean()):
        raise RecordError(f"channel {channel!r}: the signal is constant; no decay to analyse")
    dt = (t[-1] - t[0]) / (t.size - 1)
    f0 = float(frequency_hz) if frequency_hz is not None else dominant_frequency(t, x)
    if not (np.isfinite(f0) and 0 < f0 < 0.5 / dt):
        raise RecordError(f"channel {channel!r}: starting frequency {f0!r} Hz is not between 0 and Nyquist")
    n_win = int(round(n_cycles / (f0 * dt)))
    hop = max(1, int(round(hop_cycles / (f0 * dt))))
    i_start = 0
    if start is not None:
        i_start = int(np.searchsorted(t, float(start)))
    if t.size - i_start < n_win or n_win < 8:
        raise RecordError(
            f"channel {channel!r}: the decay spans {(t.size - i_start) * dt * f0:.3g} periods of {f0:.4g} Hz; "
            f"a window of {n_cycles:g} periods (at least 8 samples) is needed")
    p = {"acceleration": 2, "velocity": 1, "displacement": 0}[kind]
    acf = None
    if noise_acf is not None:
        acf = np.asarray(noise_acf, float).ravel()
        if not (acf.size and np.isfinite(acf).all() and acf[0] > 0):
            raise RecordError(f"channel {channel!r}: noise_acf must be finite with a positive lag-0 value")
        acf = acf / acf[0]
    rows, covs, windows, errs, fits = [], [], [], [], []
    sigma, wd = 0.0, 2 * np.pi * f0
    for i0 in range(i_start, t.size - n_win + 1, hop):
        i1 = i0 + n_win
        tc = 0.5 * (t[i0] + t[i1 - 1])
        coef, cov1, rss, trace, nu = _fit_window(t[i0:i1] - tc, x[i0:i1], sigma, wd, acf)
        if not (np.isfinite(coef).all() and coef[3] > 0):
            break
        sigma, wd = coef[2], coef[3]
        rows.append(np.append(coef, tc))
        covs.append(cov1)
        fits.append((rss, trace, nu))
        windows.append((i0, i1))
        errs.append(np.sqrt(rss / max(i1 - i0 - 5, 1)) / max(np.hypot(coef[0], coef[1]), 1e-300))
    if not fits:
        raise RecordError(f"channel {channel!r}: not a usable free decay: the first window of {n_cycles:g} periods "
                          f"of {f0:.4g} Hz fits no decaying oscillation")
    rss, trace, nu = (np.array(v) for v in zip(*fits))
    s2, misfit = _noise_scale(rss, trace, nu, acf is not None)
    covs = [c * v for c, v in zip(covs, s2)]
    R = np.array(rows)
    C = R[:, 0] + 1j * R[:, 1]
    sigma, wd = R[:, 2].copy(), R[:, 3]
    if p and len(rows) >= 3:
        # the envelope of q^(p) = (i w)^p q decays slower than q's while w drifts:
        # sigma_q = sigma_x + p (dw/dt) / w, dw/dt from the neighbouring windows
        sigma += p * np.gradient(wd, R[:, 5]) / wd
    lam = -sigma + 1j * wd
    wn = np.abs(lam)
    amp = np.abs(C) / wn**p
    zeta = sigma / wn
    # linear propagation of the window covariance (C, sigma, wd) to (a, wn, zeta)
    a_se, w_se, z_se = (np.empty(len(rows)) for _ in range(3))
    for i, cov in enumerate(covs):
        cr, ci, s, w = R[i, 0], R[i, 1], sigma[i], wd[i]
        Cm, L = np.hypot(cr, ci), wn[i]
        g_w = np.array([0, 0, s / L, w / L, 0])
        g_a = np.array([cr / Cm, ci / Cm, 0, 0, 0]) / L**p - p * Cm / L ** (p + 1) * g_w
        g_z = np.array([0, 0, 1 / L, 0, 0]) - s / L**2 * g_w
        a_se[i], w_se[i], z_se[i] = (np.sqrt(max(g @ cov @ g, 0.0)) for g in (g_a, g_w, g_z))
    floor = amp < snr_min * a_se
    if np.all(floor):
        warnings.warn(f"channel {channel!r}: every window of the decay is below the noise floor "
                      f"(amplitude < {snr_min:g} standard errors)", JointidWarning, stacklevel=2)
    coefs = np.column_stack([R[:, 0], R[:, 1], R[:, 2], wd])  # the fitted oscillation of each window
    c_abs = np.abs(C)
    c_se = np.array([np.sqrt(max(np.array([R[i, 0], R[i, 1]]) @ cov[:2, :2] @ np.array([R[i, 0], R[i, 1]]), 0.0))
                     / max(c_abs[i], 1e-300) for i, cov in enumerate(covs)])
    return DecayFit(_readonly(R[:, 5]), _readonly(amp), _readonly(a_se), _readonly(wn), _readonly(w_se),
                    _readonly(zeta), _readonly(z_se), _readonly(errs), np.array(floor), _readonly(coefs),
                    tuple(windows), kind, float(n_cycles), float(snr_min), _readonly(c_abs), _readonly(c_se),
                    np.array(misfit, bool))


def band_limit(t, x, band, order=4, channel="accel") -> np.ndarray:
    """Zero-phase Butterworth band-pass of ``x`` (forward and backward; module docstring).

    Parameters
    ----------
    t, x : array
        Uniform time base [s] and signal.
    band : (float, float)
        Pass band [Hz], ``0 < low < high <`` Nyquist.
    order : int
        Order of the Butterworth prototype (the forward-backward response is its square).

    Raises
    ------
    RecordError
        A band outside ``(0, Nyquist)`` or a record too short for the filter.
    """
    from scipy import signal as _signal

    t = check_signal(t, "time")
    check_time_base(t)
    x = check_signal(x, channel, t.size)
    fs = (t.size - 1) / (t[-1] - t[0])
    lo, hi = (float(v) for v in band)
    if not (0 < lo < hi < 0.5 * fs):
        raise RecordError(f"channel {channel!r}: band {[lo, hi]} Hz must satisfy 0 < low < high < Nyquist "
                          f"({0.5 * fs:.6g} Hz)")
    sos = _signal.butter(int(order), [lo, hi], btype="bandpass", fs=fs, output="sos")
    pad = 3 * (2 * sos.shape[0] + 1)
    if x.size <= pad:
        raise RecordError(f"channel {channel!r}: {x.size} samples are too few for the band-pass filter")
    return _signal.sosfiltfilt(sos, x)


def modal_ringdown(t, x, *, frequency_hz=None, band=None, half_width=None, order=4, settle_cycles=None,
                   n_cycles=24.0, hop_cycles=6.0, snr_min=30.0, kind="acceleration", channel="accel",
                   f_range=None) -> DecayFit:
    """Backbone of one mode of a free decay without a force: band-limit, skip the impact, windowed fits.

    Parameters
    ----------
    t, x : array
        The whole record (the impact may be inside it).
    frequency_hz : float, optional
        The mode's frequency; the largest spectral peak in ``f_range`` by default.
    band : (float, float), optional
        Pass band [Hz]; default ``frequency_hz +- half_width``.
    half_width : float, optional
        Default: 15 % of ``frequency_hz`` (keep the neighbouring modes outside).
    settle_cycles : float, optional
        Periods skipped after the largest sample of the band-limited signal (the impact)
        and before the end of the record, default ``max(8, 3 f / B)`` with ``B`` the band
        width (the start-up of the forward and of the backward pass).
    n_cycles, hop_cycles, snr_min, kind
        As :func:`fit_decay`.

    Returns
    -------
    DecayFit
        With ``signal_amplitude``: the first-harmonic amplitude of the band-limited signal.
        The standard errors are calibrated to the band's noise (module docstring; ``misfit``
        windows are conservative).  With ``hop_cycles < n_cycles`` (the default) neighbouring
        windows share samples and their errors are correlated: a downstream fit that counts the
        backbone's points as independent (``jointid.app.update_backbone``) needs
        ``hop_cycles = n_cycles``.
    """
    t = check_signal(t, "time")
    check_time_base(t)
    x = check_signal(x, channel, t.size)
    f0 = float(frequency_hz) if frequency_hz is not None else dominant_frequency(t, x, f_range)
    if band is None:
        hw = 0.15 * f0 if half_width is None else float(half_width)
        band = (f0 - hw, f0 + hw)
    y = band_limit(t, x, band, order=order, channel=channel)
    width = float(band[1] - band[0])
    settle = float(settle_cycles) if settle_cycles is not None else max(8.0, 3.0 * f0 / width)
    i_peak = int(np.argmax(np.abs(y)))
    start = t[i_peak] + settle / f0
    # the backward pass starts up at the end of the record as the forward pass does at its start
    keep = t <= t[-1] - settle / f0
    n_win = int(round(n_cycles * (t.size - 1) / ((t[-1] - t[0]) * f0)))
    # the band-limited noise is correlated over ~1 / B: the windows' covariances take its
    # autocorrelation (that of white noise through the forward-backward filter)
    return fit_decay(t[keep], y[keep], kind=kind, frequency_hz=f0, n_cycles=n_cycles, hop_cycles=hop_cycles,
                     snr_min=snr_min, start=start, channel=channel,
                     noise_acf=_noise_acf(t, band, order, max(n_win, 8)))


def _noise_acf(t, band, order, n) -> np.ndarray:
    """Autocorrelation (lags ``0 .. n-1`` samples, lag 0 = 1) of white noise after :func:`band_limit`."""
    from scipy import signal as _signal

    fs = (t.size - 1) / (t[-1] - t[0])
    sos = _signal.butter(int(order), [float(band[0]), float(band[1])], btype="bandpass", fs=fs, output="sos")
    # power response |H|^4 (forward and backward) on a grid fine enough that the circular
    # autocorrelation has decayed long before it wraps (at least 8 windows, 64 / B)
    m = 1 << (int(max(8 * n, 64 * fs / (float(band[1]) - float(band[0])), 1 << 12)) - 1).bit_length()
    _, h = _signal.sosfreqz(sos, worN=np.linspace(0.0, np.pi, m // 2 + 1))  # the rfft grid of m samples
    acf = np.fft.irfft(np.abs(h) ** 4, m)[:n]
    return acf / acf[0]


def monotone_check(amplitude, omega, omega_stderr, n_sigma=2.0) -> dict:
    """Is ``omega`` monotone in ``amplitude``?  Steps against the overall trend beyond ``n_sigma`` are counted.

    The trend is the sign of the rank correlation; a step between neighbouring points (in
    amplitude order) against it counts when it exceeds ``n_sigma`` times the standard error
    of the difference.
    """
    from scipy import stats

    a = np.asarray(amplitude, float)
    w = np.asarray(omega, float)
    se = np.asarray(omega_stderr, float)
    order = np.argsort(a)
    a, w, se = a[order], w[order], se[order]
    if a.size < 3:
        return {"monotone": None, "trend": None, "n_against": 0, "n_points": int(a.size)}
    rho = float(stats.spearmanr(a, w)[0])
    trend = 1.0 if rho > 0 else -1.0
    d = np.diff(w) * trend
    sd = np.hypot(se[1:], se[:-1])
    against = d < -n_sigma * np.where(np.isfinite(sd), sd, 0.0)
    return {"monotone": bool(not against.any()), "trend": "increasing" if trend > 0 else "decreasing",
            "spearman": rho, "n_against": int(against.sum()), "n_points": int(a.size), "n_sigma": n_sigma,
            "amplitude_range": [float(a.min()), float(a.max())]}
