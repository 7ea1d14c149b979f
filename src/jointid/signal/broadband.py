"""Broadband records: periodic multisines and random excitation reduced to state signals.

Force-state mapping needs the displacement, velocity and acceleration of the response
coordinate at every sample.  A test measures only one of them (an accelerometer, a laser
vibrometer, or a displacement-like quantity such as the output voltage of the Silverbox
circuit); the other two are derived here in the frequency domain, where integration and
differentiation are exact multiplications by ``(i omega)^-1`` and ``i omega``.

Two paths, chosen by what the excitation allows:

**Periodic (multisine) records** -- :func:`average_periods` averages whole periods (after
dropping transient ones), estimates the noise of each frequency line from the spread
between periods, and finds the excited lines of the input.  :func:`periodic_states`
(or :meth:`PeriodAverage.states`) then differentiates/integrates one averaged period by
its DFT.  The period is exactly periodic, so the DFT has no leakage and the derived
signals are exact *within the chosen band*; lines outside the band and the DC line are
set to zero (an integration constant is unknowable; a differentiation outside the band
would only amplify noise).  The default band runs from the lowest to the highest excited
line; widen it (``band=``) when the response carries significant nonlinear distortion
above the excitation and the noise there is low.

**Random (non-periodic) records** -- :func:`random_states` has two documented methods:

``"window"`` (default)
    Remove the mean, taper both ends with a Tukey window (``taper`` is the tapered
    fraction of the record), zero-pad to at least twice the length (no circular
    wrap-around), multiply the spectrum by ``(i omega)^k`` inside the band and by a
    raised-cosine roll-off of width ``edge_hz`` at the band edges (a brick-wall band
    would ring for the whole record), and transform back.  The low band edge is what
    prevents drift: integration never sees the lines below it.  The tapered ends and a
    further margin of ``2 / f_low`` seconds are marked invalid (``BroadbandStates.valid``)
    and must not be used in a regression.
``"highpass"``
    Zero-phase Butterworth filters (``scipy.signal.sosfiltfilt``, order 4): band-pass the
    measured signal, integrate by the trapezoidal rule and high-pass again after each
    integration (removing the drift each integration creates), differentiate by central
    differences and low-pass.  Simpler and local in time, but the filters' phase is only
    zero for the two-pass combination and the trapezoidal rule loses accuracy near the
    Nyquist frequency; use it when the record is too long for one FFT.

In both paths the force is band-limited with the *same* band (:func:`band_filter`), so
that a regression of the filtered force on filtered regressors is consistent
(:mod:`jointid.identify.broadband` filters every regressor column with it too).

Examples
--------
>>> fs, N = 256.0, 1024
>>> t = np.arange(N) / fs
>>> q = np.cos(2 * np.pi * 5.0 * t)              # 5 Hz is line 20 of the period
>>> s = periodic_states(np.sin(2 * np.pi * 5.0 * t), q, fs, measured="displacement")
>>> bool(np.allclose(s.acceleration, -(2 * np.pi * 5.0) ** 2 * q))
True
"""

from __future__ import annotations

import html
from dataclasses import dataclass, field

import numpy as np
from scipy import fft as sfft
from scipy import signal as ssignal

from ..errors import RecordError
from .harmonics import check_signal

__all__ = [
    "MEASURED_KINDS",
    "PeriodAverage",
    "BroadbandStates",
    "detect_period",
    "find_periodic_segments",
    "average_periods",
    "multisine_transient_flags",
    "excited_lines",
    "band_lines",
    "band_weights",
    "band_filter",
    "spectral_derivative",
    "periodic_states",
    "random_states",
]

#: What a response channel measures, and its derivative order relative to displacement.
MEASURED_KINDS = {"displacement": 0, "velocity": 1, "acceleration": 2}

#: Default relative threshold (of the largest line) above which an input line is "excited".
EXCITED_REL = 1e-2


# ----------------------------------------------------------------------------- helpers
def _check_fs(fs) -> float:
    fs = float(fs)
    if not np.isfinite(fs) or fs <= 0:
        raise RecordError(f"sampling rate must be a positive number, got {fs!r}")
    return fs


def _order(measured: str) -> int:
    if measured not in MEASURED_KINDS:
        raise RecordError(f"measured must be one of {sorted(MEASURED_KINDS)}, got {measured!r}")
    return MEASURED_KINDS[measured]


def spectral_derivative(X, freqs, order) -> np.ndarray:
    """Multiply a one-sided spectrum by ``(i 2 pi f)^order`` (negative order integrates).

    The DC line of an integral is set to zero (the integration constant is unknown).

    Parameters
    ----------
    X : complex array
        Spectrum (``numpy.fft.rfft`` convention), frequency on the last axis.
    freqs : array
        Frequency of each line [Hz].
    order : int
        ``1`` differentiates once, ``-2`` integrates twice.
    """
    X = np.asarray(X)
    if order == 0:
        return X.copy()
    jw = 2j * np.pi * np.asarray(freqs, float)
    if order > 0:
        return X * jw**order
    with np.errstate(divide="ignore", invalid="ignore"):
        out = X / jw ** (-order)
    out[..., np.asarray(freqs) == 0] = 0.0
    return out


def band_lines(freqs, band) -> np.ndarray:
    """Indices of the lines with ``band[0] <= f <= band[1]`` and ``f > 0``."""
    f = np.asarray(freqs, float)
    lo, hi = band
    return np.flatnonzero((f >= lo) & (f <= hi) & (f > 0))


def band_weights(freqs, band, edge_hz=0.0) -> np.ndarray:
    """Band-pass gain of every line: 1 inside ``band``, raised-cosine roll-off of width ``edge_hz``.

    The roll-off lies outside the band (the band itself is passed with unit gain) and the
    DC line is always zero.
    """
    f = np.asarray(freqs, float)
    lo, hi = float(band[0]), float(band[1])
    w = ((f >= lo) & (f <= hi)).astype(float)
    if edge_hz > 0:
        below = (f < lo) & (f > lo - edge_hz)
        w[below] = 0.5 * (1 + np.cos(np.pi * (lo - f[below]) / edge_hz))
        above = (f > hi) & (f < hi + edge_hz)
        w[above] = 0.5 * (1 + np.cos(np.pi * (f[above] - hi) / edge_hz))
    w[f <= 0] = 0.0
    return w


def _padded_length(n) -> int:
    return int(sfft.next_fast_len(2 * int(n), real=True))


def band_filter(x, fs, band, *, edge_hz=0.0, order=0, axis=-1) -> np.ndarray:
    """Zero-phase band-limiting (and optional differentiation/integration) of a non-periodic signal.

    The signal is zero-padded to at least twice its length, multiplied in the frequency
    domain by :func:`band_weights` and ``(i omega)^order``, and cut back to its length.

    Parameters
    ----------
    x : array
        Signal(s), time on ``axis``.
    fs : float
        Sampling rate [Hz].
    band : (float, float)
        Pass band [Hz].
    edge_hz : float
        Width of the raised-cosine roll-off outside the band.
    order : int
        Derivative order (negative integrates).
    """
    x = np.asarray(x, dtype=float)
    n = x.shape[axis]
    nfft = _padded_length(n)
    X = np.fft.rfft(x, nfft, axis=axis)
    f = np.fft.rfftfreq(nfft, 1.0 / fs)
    shape = [1] * X.ndim
    shape[axis] = f.size
    H = band_weights(f, band, edge_hz).reshape(shape)
    Y = spectral_derivative(np.moveaxis(X, axis, -1), f, order)
    Y = np.moveaxis(Y, -1, axis) * H
    y = np.fft.irfft(Y, nfft, axis=axis)
    return np.take(y, np.arange(n), axis=axis)


# ----------------------------------------------------------------------------- periods
def detect_period(x, *, min_period=8, max_period=None, threshold=0.9, channel="input") -> int:
    """Period (in samples) of a periodic record, from its normalised autocorrelation.

    The smallest lag ``>= min_period`` at which the normalised autocorrelation is a local
    maximum above ``threshold`` is returned.  The autocorrelation is normalised over the
    overlapping part only, so the record may hold any number (>= 2) of periods.

    Raises
    ------
    RecordError
        If no lag reaches the threshold (not a periodic record, or fewer than 2 periods).
    """
    x = check_signal(x, channel)
    x = x - x.mean()
    n = x.size
    if not np.any(x):
        raise RecordError(f"channel {channel!r}: the signal is constant; no period can be detected")
    max_period = n // 2 if max_period is None else min(int(max_period), n // 2)
    nfft = _padded_length(n)
    X = np.fft.rfft(x, nfft)
    acf = np.fft.irfft(np.abs(X) ** 2, nfft)[: max_period + 2]
    c = np.concatenate([[0.0], np.cumsum(x * x)])
    k = np.arange(acf.size)
    head = c[n - k]  # sum of x[i]^2 for i < n - k
    tail = c[n] - c[k]  # sum of x[i]^2 for i >= k
    with np.errstate(divide="ignore", invalid="ignore"):
        r = acf / np.sqrt(head * tail)
    r[~np.isfinite(r)] = 0.0
    for lag in range(max(int(min_period), 1), max_period + 1):
        if r[lag] >= threshold and r[lag] >= r[lag - 1] and r[lag] >= r[lag + 1]:
            return int(lag)
    best = int(np.argmax(r[max(int(min_period), 1) : max_period + 1]) + max(int(min_period), 1))
    raise RecordError(
        f"channel {channel!r}: no period found between {min_period} and {max_period} samples; the best "
        f"normalised autocorrelation is {r[best]:.3f} at lag {best} (expected at least {threshold:g} for a "
        f"periodic record with 2 or more periods)"
    )


def find_periodic_segments(x, period, *, rtol=0.05, min_length=None, channel="input") -> list[slice]:
    """Stretches of a record that repeat with ``period`` samples.

    A sample ``i`` is periodic when ``|x[i] - x[i + period]| <= rtol * rms(x)``; every run
    of such samples ``[a, b)`` means that ``x[a : b + period]`` is one periodic stretch.
    Records made of several multisine realisations separated by transients or gaps give
    one slice per realisation; the steady-state period of a realisation is its last
    ``period`` samples.

    Parameters
    ----------
    x : array
        The (input) signal.
    period : int
        Period in samples.
    rtol : float
        Tolerance relative to the RMS of ``x``.
    min_length : int, optional
        Shortest stretch returned (default ``period + max(16, period // 64)``).

    Returns
    -------
    list of slice
        Periodic stretches, in order.
    """
    x = check_signal(x, channel)
    period = int(period)
    if period < 1 or period >= x.size:
        raise RecordError(f"channel {channel!r}: period must be between 1 and {x.size - 1} samples, got {period}")
    xc = x - x.mean()
    rms = float(np.sqrt(np.mean(xc**2)))
    tol = rtol * rms
    ok = (np.abs(xc[period:] - xc[:-period]) <= tol).astype(np.int8)
    ok = ssignal.medfilt(ok, 9).astype(bool)  # isolated noisy samples do not cut a stretch
    d = np.diff(np.concatenate([[0], ok.astype(np.int8), [0]]))
    starts, stops = np.flatnonzero(d == 1), np.flatnonzero(d == -1)
    min_length = period + max(16, period // 64) if min_length is None else int(min_length)
    out = []
    for a, b in zip(starts, stops):
        seg = slice(int(a), int(b) + period)
        # a constant stretch (a gap in the excitation) repeats trivially: not a periodic excitation
        if seg.stop - seg.start >= min_length and np.sqrt(np.mean(xc[seg] ** 2)) > 10 * tol:
            out.append(seg)
    return out


def excited_lines(U, *, rel=EXCITED_REL, noise_var=None, snr=10.0) -> np.ndarray:
    """Lines (DC excluded) of an input spectrum above ``rel`` times its largest line.

    With ``noise_var`` (the variance of each line, e.g. from :func:`average_periods`) a
    line must also exceed the noise power ``snr`` times.
    """
    a = np.abs(np.asarray(U)).copy()
    a[0] = 0.0
    top = a.max()
    if top == 0:
        return np.zeros(0, dtype=int)
    ok = a > rel * top
    if noise_var is not None:
        nv = np.asarray(noise_var, float)
        ok &= ~(a**2 <= snr * np.where(np.isfinite(nv), nv, 0.0))
    return np.flatnonzero(ok)


@dataclass(frozen=True)
class PeriodAverage:
    """Period-averaged channels of a periodic (multisine) record.

    Attributes
    ----------
    fs : float
        Sampling rate [Hz].
    samples_per_period : int
    n_periods : int
        Periods averaged (after the dropped transient periods).
    skipped_periods : int
    mean : dict of str to array
        One averaged period per channel.
    spectra : dict of str to complex array
        ``numpy.fft.rfft`` of each averaged period.
    noise_var : dict of str to array
        Variance of each line of the *averaged* spectrum, from the spread between periods
        (``var over periods / n_periods``); ``nan`` with a single period.
    excited : array of int
        Excited lines of the input channel.
    input : str or None
        Name of the input channel.
    """

    fs: float
    samples_per_period: int
    n_periods: int
    skipped_periods: int
    mean: dict = field(repr=False)
    spectra: dict = field(repr=False)
    noise_var: dict = field(repr=False)
    excited: np.ndarray = field(repr=False)
    input: str | None = None

    @property
    def channels(self) -> tuple[str, ...]:
        return tuple(self.mean)

    @property
    def frequencies(self) -> np.ndarray:
        """Frequency of each line [Hz]."""
        return np.fft.rfftfreq(self.samples_per_period, 1.0 / self.fs)

    @property
    def excited_band(self) -> tuple[float, float]:
        """Lowest and highest excited frequency [Hz]."""
        f = self.frequencies[self.excited]
        return (float(f.min()), float(f.max())) if f.size else (float("nan"), float("nan"))

    def snr_db(self, channel) -> np.ndarray:
        """Signal-to-noise ratio of every line of ``channel`` [dB] (averaged spectrum)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return 10 * np.log10(np.abs(self.spectra[channel]) ** 2 / self.noise_var[channel])

    def noise_rms(self, channel) -> float:
        """Time-domain RMS of the noise left in the averaged period of ``channel``."""
        v = np.asarray(self.noise_var[channel], float)
        n = self.samples_per_period
        w = np.full(v.size, 2.0)
        w[0] = 1.0
        if n % 2 == 0:
            w[-1] = 1.0
        return float(np.sqrt(np.nansum(w * v)) / n)

    def states(self, force, response, *, measured="displacement", band=None, fit_band=None, keep_mean=False):
        """:func:`periodic_states` of two of the averaged channels, carrying their noise estimates."""
        for c in (force, response):
            if c not in self.mean:
                raise RecordError(f"channel {c!r} is not in the averaged record (channels: {self.channels})")
        if band is None and self.excited.size:
            band = self.excited_band
        return periodic_states(
            self.mean[force],
            self.mean[response],
            self.fs,
            measured=measured,
            band=band,
            fit_band=fit_band,
            keep_mean=keep_mean,
            force_noise_var=self.noise_var[force],
            response_noise_var=self.noise_var[response],
            channels=(force, response),
        )

    def summary(self) -> dict:
        return {
            "fs": self.fs,
            "samples_per_period": self.samples_per_period,
            "n_periods": self.n_periods,
            "skipped_periods": self.skipped_periods,
            "input": self.input,
            "n_excited_lines": int(self.excited.size),
            "excited_band_hz": list(self.excited_band),
            "noise_rms": {c: self.noise_rms(c) for c in self.channels},
        }

    def report(self) -> str:
        lo, hi = self.excited_band
        lines = [
            f"periodic record: {self.n_periods} periods of {self.samples_per_period} samples at {self.fs:.6g} Hz "
            f"({self.skipped_periods} transient periods dropped)",
            f"  {self.excited.size} excited lines of {self.input!r}, {lo:.4g} .. {hi:.4g} Hz",
        ]
        for c in self.channels:
            lines.append(f"  noise RMS of the averaged {c!r}: {self.noise_rms(c):.3g}")
        return "\n".join(lines)

    def _repr_html_(self):
        return "<pre>" + html.escape(self.report()) + "</pre>"


def average_periods(channels, fs, *, period=None, skip_periods=0, n_periods=None, input=None,
                    excited_rel=EXCITED_REL) -> PeriodAverage:
    """Average the whole periods of a periodic record and estimate the noise per line.

    Parameters
    ----------
    channels : mapping of str to array
        Equal-length signals (e.g. ``{"u": u, "y": y}``); a :class:`~jointid.io.channels.Channels`
        works too.
    fs : float
        Sampling rate [Hz].
    period : int, optional
        Samples per period; detected from the input channel when ``None``
        (:func:`detect_period`).
    skip_periods : int
        Leading periods dropped as transient.
    n_periods : int, optional
        Number of periods to average (default: all whole periods after the skipped ones).
    input : str, optional
        Input channel, used for the period detection and the excited lines (default: the
        first channel).
    excited_rel : float
        Threshold of :func:`excited_lines`.

    Raises
    ------
    RecordError
        Unequal lengths, non-finite values, or fewer samples than ``skip_periods + 1`` periods.
    """
    fs = _check_fs(fs)
    names = list(channels)
    if not names:
        raise RecordError("average_periods needs at least one channel")
    input = names[0] if input is None else input
    if input not in names:
        raise RecordError(f"input channel {input!r} is not among the channels {names}")
    n = None
    data = {}
    for c in names:
        data[c] = check_signal(channels[c], c, n)
        n = data[c].size
    if period is None:
        period = detect_period(data[input], channel=input)
    period = int(period)
    if period < 2:
        raise RecordError(f"period must be at least 2 samples, got {period}")
    whole = n // period
    skip = int(skip_periods)
    avail = whole - skip
    if avail < 1:
        raise RecordError(
            f"channel {input!r}: {n} samples hold {whole} whole periods of {period}; cannot drop {skip} "
            f"transient periods and keep one"
        )
    P = avail if n_periods is None else int(n_periods)
    if P < 1 or P > avail:
        raise RecordError(f"n_periods must be between 1 and {avail}, got {n_periods!r}")
    start = skip * period
    mean, spectra, noise = {}, {}, {}
    for c in names:
        blocks = data[c][start : start + P * period].reshape(P, period)
        mean[c] = blocks.mean(axis=0)
        spectra[c] = np.fft.rfft(mean[c])
        if P > 1:
            B = np.fft.rfft(blocks, axis=1)
            noise[c] = np.sum(np.abs(B - spectra[c]) ** 2, axis=0) / (P - 1) / P
        else:
            noise[c] = np.full(period // 2 + 1, np.nan)
    exc = excited_lines(spectra[input], rel=excited_rel, noise_var=noise[input] if P > 1 else None)
    return PeriodAverage(fs, period, P, skip, mean, spectra, noise, exc, input)


# ----------------------------------------------------------------------------- states
@dataclass(frozen=True)
class BroadbandStates:
    """Force and response state signals of a broadband record.

    Attributes
    ----------
    t : array
        Sample times [s] (from zero).
    force : array
        The excitation (force, or a voltage proportional to it).
    displacement, velocity, acceleration : array
        Response states derived within ``band``.
    fs : float
    measured : str
        Which state was measured (``"displacement"``, ``"velocity"``, ``"acceleration"``).
    band : (float, float)
        Band [Hz] of the derived states.
    fit_band : (float, float)
        Band [Hz] in which a regression should use the equation of motion.
    periodic : bool
        True for one averaged period (exact DFT processing), False for a random record.
    valid : slice
        Samples usable in a time-domain regression (all for periodic records).
    edge_hz : float
        Roll-off width used by the random path (0 for periodic records).
    response_mean : float
        Mean of the measured response removed from the states (DC is never integrated; a
        measured displacement keeps it with ``keep_mean``, and this is then 0).
    force_noise_var, response_noise_var : array or None
        Noise variance of each line of the force and measured-response spectra, when known
        (periodic records averaged over several periods).
    channels : (str, str)
        Names of the force and response channels (for messages).
    """

    t: np.ndarray = field(repr=False)
    force: np.ndarray = field(repr=False)
    displacement: np.ndarray = field(repr=False)
    velocity: np.ndarray = field(repr=False)
    acceleration: np.ndarray = field(repr=False)
    fs: float
    measured: str
    band: tuple
    fit_band: tuple
    periodic: bool
    valid: slice
    edge_hz: float = 0.0
    response_mean: float = 0.0
    force_noise_var: np.ndarray | None = field(default=None, repr=False)
    response_noise_var: np.ndarray | None = field(default=None, repr=False)
    channels: tuple = ("force", "response")

    @property
    def n_samples(self) -> int:
        return int(self.t.size)

    @property
    def frequencies(self) -> np.ndarray:
        """Line frequencies of the record's DFT [Hz] (periodic records)."""
        return np.fft.rfftfreq(self.n_samples, 1.0 / self.fs)

    def fit_lines(self) -> np.ndarray:
        """DFT lines of a periodic record inside ``fit_band`` (DC excluded)."""
        return band_lines(self.frequencies, self.fit_band)

    def q_max(self) -> float:
        """Largest ``|q|`` over the valid samples."""
        return float(np.max(np.abs(self.displacement[self.valid])))

    def filter(self, x, axis=0) -> np.ndarray:
        """Band-limit ``x`` (time on ``axis``) to ``fit_band`` the way the states were processed."""
        x = np.asarray(x, float)
        if self.periodic:
            X = np.fft.rfft(x, axis=axis)
            shape = [1] * X.ndim
            shape[axis] = X.shape[axis]
            w = np.zeros(self.n_samples // 2 + 1)
            w[self.fit_lines()] = 1.0
            return np.fft.irfft(X * w.reshape(shape), self.n_samples, axis=axis)
        return band_filter(x, self.fs, self.fit_band, edge_hz=self.edge_hz, axis=axis)


def _derive(X, f, order_measured, weights):
    """Displacement, velocity, acceleration spectra from the measured one, within ``weights``."""
    return [spectral_derivative(X, f, k - order_measured) * weights for k in (0, 1, 2)]


def periodic_states(force, response, fs, *, measured="displacement", band=None, fit_band=None, keep_mean=False,
                    force_noise_var=None, response_noise_var=None, channels=("force", "response")) -> BroadbandStates:
    """State signals of one period of a periodic record, by exact DFT integration/differentiation.

    Parameters
    ----------
    force, response : array
        One (averaged) period of the excitation and of the measured response.
    fs : float
        Sampling rate [Hz].
    measured : {"displacement", "velocity", "acceleration"}
        What ``response`` is.
    band : (float, float), optional
        Band [Hz] of the derived states; lines outside it and DC are zero.  Default: the
        excited band of ``force`` (lowest to highest line above 1 % of the largest).
    fit_band : (float, float), optional
        Band for the regression; default ``band``.
    keep_mean : bool
        Only for a measured displacement: keep its mean in the displacement state.  Use it
        when the mean is a true static displacement of the coordinate on which the
        nonlinearity acts (a full multisine on a cubic system creates a small static
        displacement through its intermodulation ``f_a + f_b - f_c = 0``; removing it biases
        the cubic coefficient, or shows up as a spurious ``q^2`` term).  By default the mean
        is removed (and stored in ``response_mean``).
    force_noise_var, response_noise_var : array, optional
        Noise variance per line (from :func:`average_periods`).
    channels : (str, str)
        Names used in messages.

    Raises
    ------
    RecordError
        Unequal lengths, non-finite values, a zero force, or an empty band.
    """
    fs = _check_fs(fs)
    fname, rname = channels
    force = check_signal(force, fname)
    response = check_signal(response, rname, force.size)
    k = _order(measured)
    n = force.size
    if n < 4:
        raise RecordError(f"channel {fname!r}: a period needs at least 4 samples, got {n}")
    F = np.fft.rfft(force)
    f = np.fft.rfftfreq(n, 1.0 / fs)
    if band is None:
        exc = excited_lines(F)
        if exc.size == 0:
            raise RecordError(f"channel {fname!r}: the force has no excited line (it is constant)")
        band = (float(f[exc.min()]), float(f[exc.max()]))
    band = (float(band[0]), float(band[1]))
    lines = band_lines(f, band)
    if lines.size == 0:
        raise RecordError(
            f"channel {rname!r}: no frequency line of the {n}-sample period (resolution {fs / n:.4g} Hz) lies in "
            f"the band {band} Hz"
        )
    fit_band = band if fit_band is None else (float(fit_band[0]), float(fit_band[1]))
    w = np.zeros(f.size)
    w[lines] = 1.0
    Q, V, A = _derive(np.fft.rfft(response), f, k, w)
    t = np.arange(n) / fs
    mean = float(response.mean())
    if keep_mean:
        if k != 0:
            raise RecordError(f"channel {rname!r}: keep_mean applies to a measured displacement, not a {measured}")
        Q[0] = n * mean
        mean = 0.0
    return BroadbandStates(
        t, force, np.fft.irfft(Q, n), np.fft.irfft(V, n), np.fft.irfft(A, n), fs, measured, band, fit_band, True,
        slice(0, n), 0.0, mean,
        None if force_noise_var is None else np.asarray(force_noise_var, float),
        None if response_noise_var is None else np.asarray(response_noise_var, float),
        (fname, rname),
    )


def random_states(t, force, response, *, measured="acceleration", band, method="window", taper=0.1,
                  edge_hz=None, fit_band=None, channels=("force", "response")) -> BroadbandStates:
    """State signals of a non-periodic (random, swept, transient) record, band-limited.

    See the module notes for the two methods.  The returned ``valid`` slice excludes the
    samples spoiled by the taper and by the filters' settling.

    Parameters
    ----------
    t : array
        Uniform time vector [s].
    force, response : array
        Excitation and measured response.
    measured : {"displacement", "velocity", "acceleration"}
    band : (float, float)
        Band [Hz] of the derived states.  Its lower edge is what prevents drift: choose
        it below the lowest frequency of interest but well above zero.
    method : {"window", "highpass"}
    taper : float
        Tukey-window fraction (``"window"`` only), between 0 and 1.
    edge_hz : float, optional
        Raised-cosine roll-off width (``"window"`` only); default ``band[0] / 2``.
    fit_band : (float, float), optional
        Band for the regression; default ``band``.
    channels : (str, str)
        Names used in messages.

    Raises
    ------
    RecordError
        Bad time base or values, a band outside ``(0, fs/2)``, or a record too short for
        the band (no valid samples left).
    """
    fname, rname = channels
    t = check_signal(t, "time")
    force = check_signal(force, fname, t.size)
    response = check_signal(response, rname, t.size)
    k = _order(measured)
    n = t.size
    dt = (t[-1] - t[0]) / (n - 1)
    if not np.allclose(np.diff(t), dt, rtol=1e-6, atol=0):
        raise RecordError("channel 'time': expected a uniform time vector")
    fs = 1.0 / dt
    lo, hi = float(band[0]), float(band[1])
    if not (0 < lo < hi < fs / 2):
        raise RecordError(f"band must satisfy 0 < low < high < fs/2 = {fs / 2:.6g} Hz, got {band!r}")
    fit_band = (lo, hi) if fit_band is None else (float(fit_band[0]), float(fit_band[1]))
    settle = int(np.ceil(2.0 * fs / lo))
    r0 = response - response.mean()
    f0 = force - force.mean()
    if method == "window":
        if not 0 <= taper <= 1:
            raise RecordError(f"taper must be between 0 and 1, got {taper!r}")
        edge = 0.5 * lo if edge_hz is None else float(edge_hz)
        win = ssignal.windows.tukey(n, taper) if taper > 0 else np.ones(n)
        nfft = _padded_length(n)
        f = np.fft.rfftfreq(nfft, dt)
        H = band_weights(f, (lo, hi), edge)
        R = np.fft.rfft(r0 * win, nfft)
        Q, V, A = (np.fft.irfft(X, nfft)[:n] for X in _derive(R, f, k, H))
        F = np.fft.irfft(np.fft.rfft(f0 * win, nfft) * H, nfft)[:n]
        flat = np.flatnonzero(win >= 1.0 - 1e-12)
        a, b = (int(flat[0]), int(flat[-1]) + 1) if flat.size else (n // 2, n // 2)
        valid = slice(a + settle, b - settle)
    elif method == "highpass":
        edge = 0.0
        sos_hp = ssignal.butter(4, lo, btype="highpass", fs=fs, output="sos")
        sos_bp = ssignal.butter(4, (lo, hi), btype="bandpass", fs=fs, output="sos")
        sos_lp = ssignal.butter(4, hi, btype="lowpass", fs=fs, output="sos")
        x = ssignal.sosfiltfilt(sos_bp, r0)
        states = {k: x}
        cur = x
        for j in range(k - 1, -1, -1):  # integrate down to displacement
            cur = ssignal.sosfiltfilt(sos_hp, _cumtrapz(cur, dt))
            states[j] = cur
        cur = x
        for j in range(k + 1, 3):  # differentiate up to acceleration
            cur = ssignal.sosfiltfilt(sos_lp, np.gradient(cur, dt))
            states[j] = cur
        Q, V, A = states[0], states[1], states[2]
        F = ssignal.sosfiltfilt(sos_bp, f0)
        valid = slice(3 * settle // 2, n - 3 * settle // 2)
    else:
        raise RecordError(f"method must be 'window' or 'highpass', got {method!r}")
    if valid.stop - valid.start < 16:
        raise RecordError(
            f"channel {rname!r}: the record ({n} samples, {n * dt:.4g} s) is too short for a low band edge of "
            f"{lo:.4g} Hz: no valid samples remain after the taper and {settle} settling samples at each end"
        )
    return BroadbandStates(
        t - t[0], F, Q, V, A, fs, measured, (lo, hi), fit_band, False, valid, edge, float(response.mean()),
        None, None, (fname, rname),
    )


def _cumtrapz(x, dt):
    out = np.empty_like(x)
    out[0] = 0.0
    np.cumsum(0.5 * (x[1:] + x[:-1]) * dt, out=out[1:])
    return out - out.mean()


# ------------------------------------------------------------------ plausibility of broadband records
#: Share of a multisine record's force power off the lines of its period above which the record is
#: not periodic with the period given (a wrong ``period_s``): noise at -10 dB of the force, far more
#: than any usable test.
NON_PERIODIC_LIMIT = 0.1
#: Fewest excited lines a multisine must have to be identified over a band.
MIN_LINES = 3
#: Mean force-response coherence over the excitation band below which a random record's response
#: is not driven by its force (unrelated noise, a wrong channel).
MIN_COHERENCE = 0.5


def multisine_flags(u, n_period: int, channel: str = "force") -> list:
    """Plausibility flags of a multisine excitation ``u`` with ``n_period`` samples per period.

    ``multisine_period``: more than :data:`NON_PERIODIC_LIMIT` of the force power (mean
    removed) is not periodic with the period given -- over two or more whole periods after
    the first, the power off the harmonics of the period; in a record of one whole period
    and a part of the next, the difference between that part and the start of the period --
    the period given is not the excitation's; ``multisine_lines``: fewer than
    :data:`MIN_LINES` excited lines in a period (a plain sine is not a multisine).  A record
    of exactly one period cannot be checked for periodicity (it is taken as steady).
    """
    from .checks import Flag

    u = np.asarray(u, float)
    n_per = int(n_period)
    whole = u.size // n_per if n_per > 0 else 0
    if whole < 1:
        return []
    use = max(whole - 1, 1)
    seg = u[u.size - use * n_per:]
    share = None
    if use >= 2:
        P = np.abs(np.fft.rfft(seg - seg.mean())) ** 2
        P[0] = 0.0
        total = float(P.sum())
        share = 1.0 - float(P[::use].sum()) / total if total > 0 else 0.0
        how = f"off the lines of a {n_per}-sample period over {use} periods"
    elif u.size - n_per >= max(8, n_per // 10):  # one period and a part of the next: they must repeat
        r = u.size - n_per
        a, b = u[:r] - u.mean(), u[n_per:] - u.mean()
        total = float(a @ a + b @ b)
        share = float((a - b) @ (a - b)) / total if total > 0 else 0.0
        how = f"in the {r} samples after a {n_per}-sample period that differ from its start"
    flags = []
    if share is not None and share > NON_PERIODIC_LIMIT:
        flags.append(Flag("multisine_period", f"{100 * share:.3g} % of the {channel} power lies {how} (at most "
                                              f"{100 * NON_PERIODIC_LIMIT:g} % for a periodic excitation): "
                                              "period_s is not the excitation's period",
                          {"non_periodic_share": share, "samples_per_period": n_per, "whole_periods": whole}))
    avg = seg.reshape(use, n_per).mean(axis=0)
    lines = excited_lines(np.fft.rfft(avg - avg.mean()))
    if lines.size < MIN_LINES:
        flags.append(Flag("multisine_lines", f"the {channel} excites {lines.size} line(s) of the period (at least "
                                             f"{MIN_LINES} for a broadband fit): a plain sine, not a multisine",
                          {"excited_lines": int(lines.size)}))
    return flags


#: A multisine response whose first kept period differs from the last by more than this many times the
#: last two periods' difference is still settling (noise alone gives about 1).
TRANSIENT_RATIO = 2.0
#: ... and by more than this share of the response power (a settling too small to bias the fit is let be).
TRANSIENT_SHARE = 1e-3


def multisine_transient_flags(y, n_period: int, channel: str = "response") -> list:
    """``multisine_transient``: the response of a multisine record still changes from period to period over
    the whole periods after the first (a start-up transient of a lightly damped mode outlasting the dropped
    period): the first of them differs from the last by more than :data:`TRANSIENT_RATIO` times the last two's
    difference and by more than :data:`TRANSIENT_SHARE` of the response power.  Needs three such periods."""
    from .checks import Flag

    y = np.asarray(y, float)
    n_per = int(n_period)
    use = (y.size // n_per - 1) if n_per > 0 else 0
    if use < 3:
        return []
    seg = y[y.size - use * n_per:].reshape(use, n_per)
    first, last = seg[0] - seg[-1], seg[-2] - seg[-1]
    power = float(np.sum((seg - seg.mean()) ** 2)) / use
    ratio = float(np.linalg.norm(first) / max(np.linalg.norm(last), np.finfo(float).tiny))
    share = float(first @ first) / power if power > 0 else 0.0
    if ratio > TRANSIENT_RATIO and share > TRANSIENT_SHARE:
        return [Flag("multisine_transient", f"the {channel} still settles over the {use} periods used: the first "
                                            f"differs from the last by {ratio:.3g} times the last two's difference "
                                            f"({100 * share:.3g} % of its power): a start-up transient; record more "
                                            "periods before the ones kept",
                     {"ratio": ratio, "share": share, "periods": use})]
    return []


def random_flags(u, y, fs, band, channels=("force", "response")) -> list:
    """Plausibility flags of a random record: ``random_coherence`` when the mean magnitude-squared
    coherence of force and response over ``band`` is below :data:`MIN_COHERENCE` (the response is
    not driven by this force: unrelated noise or a wrong channel)."""
    from .checks import Flag

    u = np.asarray(u, float)
    y = np.asarray(y, float)
    nper = int(min(max(64, u.size // 16), u.size))
    f, coh = ssignal.coherence(u - u.mean(), y - y.mean(), fs=fs, nperseg=nper)
    sel = (f >= band[0]) & (f <= band[1])
    if not np.any(sel):
        return []
    mean = float(np.mean(coh[sel]))
    if mean < MIN_COHERENCE:
        return [Flag("random_coherence", f"mean coherence of {channels[0]!r} and {channels[1]!r} over "
                                         f"{band[0]:.4g}-{band[1]:.4g} Hz is {mean:.3g} (at least {MIN_COHERENCE:g}): "
                                         "the response is not driven by this excitation",
                     {"mean_coherence": mean, "band_hz": [float(band[0]), float(band[1])],
                      "segments": int(u.size // nper)})]
    return []
