"""Single-frequency steady-state records: frequency, harmonic fit and analytic integration.

Implements seed Eq 16-18.  A record ``(t, force, accel)`` of a steady state under a
single-frequency force is reduced to

* the excitation frequency, estimated from the force when it is not given;
* a least-squares fit of ``n`` harmonics (plus a constant) to the acceleration, valid for
  any record length (non-integer number of periods), any start time and any sampling
  rate above twice the highest fitted harmonic;
* velocity and displacement by analytic integration of the fitted series, with the
  integration constants set so that both have zero mean (``C1 = C2 = 0``).

The harmonic coefficient convention is the one of :mod:`jointid.conventions`, with the
time origin ``t0`` of the fit (the record's first time stamp) so that large absolute
times lose no precision.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
from scipy import linalg

from .._blas import single_threaded
from ..conventions import harmonic_index, n_coefficients
from ..errors import JointidWarning, RecordError

__all__ = [
    "HarmonicSeries",
    "StateSignals",
    "check_signal",
    "check_time_base",
    "estimate_frequency",
    "fit_harmonics",
    "steady_state_signals",
    "series_max_abs",
]

#: Minimum number of excitation periods in a record.
MIN_PERIODS = 2.0
#: Fewest harmonics a steady-state record must resolve (the cubic term shows at the third).
MIN_HARMONICS = 3
#: Harmonics of the force fitted together with its fundamental when estimating the frequency.
FORCE_HARMONICS = 5
#: Fraction of the force variance a sinusoid must explain to count as a single-frequency excitation.
MIN_SINE_FRACTION = 0.5


def check_time_base(t, *, channel="time", rtol=1e-2) -> float:
    """Check that ``t`` is finite, strictly increasing and uniform; return the step ``dt``.

    A step may deviate from the mean step by ``rtol`` of it (rounding of written time
    stamps); a dropped or repeated sample is far outside that.

    Raises
    ------
    RecordError
        Naming the channel and the first offending sample.
    """
    t = np.asarray(t, dtype=float)
    if t.ndim != 1 or t.size < 3:
        raise RecordError(f"channel {channel!r}: expected a 1-D time vector of at least 3 samples, got shape {t.shape}")
    bad = ~np.isfinite(t)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise RecordError(f"channel {channel!r}: non-finite time value {t[i]!r} at sample {i}")
    d = np.diff(t)
    if (d <= 0).any():
        i = int(np.flatnonzero(d <= 0)[0])
        raise RecordError(
            f"channel {channel!r}: time must increase strictly; sample {i + 1} ({t[i + 1]!r} s) "
            f"does not follow sample {i} ({t[i]!r} s)"
        )
    dt = (t[-1] - t[0]) / (t.size - 1)
    dev = np.abs(d - dt)
    i = int(np.argmax(dev))
    if dev[i] > rtol * dt:
        raise RecordError(
            f"channel {channel!r}: uneven sampling; expected a uniform step of {dt:.6g} s, "
            f"step {i} (after {t[i]!r} s) is {d[i]:.6g} s"
        )
    return float(dt)


def check_signal(x, name, n=None) -> np.ndarray:
    """A 1-D finite float signal of ``n`` samples (when given), or a :class:`RecordError` naming the channel."""
    x = np.asarray(x, dtype=float)
    if x.ndim != 1:
        raise RecordError(f"channel {name!r}: expected a 1-D signal, got shape {x.shape}")
    if n is not None and x.size != n:
        raise RecordError(f"channel {name!r}: has {x.size} samples but the time column has {n}")
    bad = ~np.isfinite(x)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise RecordError(f"channel {name!r}: non-finite value {x[i]!r} at sample {i} ({int(bad.sum())} in all)")
    return x


def _basis(tau, omega, n_harmonics):
    """Real design matrix ``(n, 2H+1)``: [1, cos wt, sin wt, cos 2wt, ...].

    Harmonics come from the angle-addition recurrence, refreshed with exact values every
    8 harmonics, which keeps the error at the rounding level and costs a few array
    multiplications per harmonic instead of a trigonometric call.
    """
    out = np.empty((tau.size, n_coefficients(n_harmonics)), order="F")  # contiguous columns
    out[:, 0] = 1.0
    phase = omega * tau
    c1, s1 = np.cos(phase), np.sin(phase)
    out[:, 1], out[:, 2] = c1, s1
    for k in range(2, n_harmonics + 1):
        if k % 8 == 0:
            out[:, 2 * k - 1] = np.cos(k * phase)
            out[:, 2 * k] = np.sin(k * phase)
        else:
            cp, sp = out[:, 2 * k - 3], out[:, 2 * k - 2]
            out[:, 2 * k - 1] = cp * c1 - sp * s1
            out[:, 2 * k] = sp * c1 + cp * s1
    return out


@dataclass(frozen=True)
class HarmonicSeries:
    """A truncated Fourier series ``x(t) = a0 + sum a_k cos(k w (t-t0)) + b_k sin(k w (t-t0))``."""

    omega: float
    coefficients: np.ndarray
    t0: float = 0.0

    @property
    def n_harmonics(self) -> int:
        return (len(self.coefficients) - 1) // 2

    @property
    def period(self) -> float:
        return 2 * np.pi / self.omega

    def __call__(self, t) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        return (_basis(np.ravel(t) - self.t0, self.omega, self.n_harmonics) @ self.coefficients).reshape(t.shape)

    def derivative(self) -> "HarmonicSeries":
        """The time derivative (its constant is zero)."""
        c = self.coefficients
        k = harmonic_index(self.n_harmonics)[1::2] * self.omega
        d = np.zeros_like(c)
        d[1::2] = k * c[2::2]
        d[2::2] = -k * c[1::2]
        return HarmonicSeries(self.omega, d, self.t0)

    def integral(self) -> "HarmonicSeries":
        """The zero-mean antiderivative (the constant term is dropped: seed Eq 17-18, C = 0)."""
        c = self.coefficients
        k = harmonic_index(self.n_harmonics)[1::2] * self.omega
        d = np.zeros_like(c)
        d[1::2] = -c[2::2] / k
        d[2::2] = c[1::2] / k
        return HarmonicSeries(self.omega, d, self.t0)

    def amplitudes(self) -> np.ndarray:
        """Amplitude of each harmonic ``1..H``."""
        c = self.coefficients
        return np.hypot(c[1::2], c[2::2])

    def max_abs(self) -> float:
        """``max_t |x(t)|`` over one period, to machine precision (see :func:`series_max_abs`)."""
        return series_max_abs(self.coefficients, self.omega)


def series_max_abs(coefficients, omega=1.0) -> float:
    """Largest ``|x(t)|`` of a harmonic series over one period.

    A dense grid of ``64 (H + 1)`` points per period locates the extremum and Newton's
    method on ``x'(t) = 0`` refines it, so the result does not depend on any sampling.
    """
    c = np.asarray(coefficients, dtype=float)
    H = (c.size - 1) // 2
    s = HarmonicSeries(1.0, c)
    n = 64 * (H + 1)
    tau = np.arange(n) * (2 * np.pi / n)
    x = s(tau)
    i = int(np.argmax(np.abs(x)))
    tt = tau[i]
    d1 = s.derivative()
    d2 = d1.derivative()
    for _ in range(20):
        g = float(d1(tt))
        h = float(d2(tt))
        if h == 0.0:
            break
        step = g / h
        if abs(step) > 2 * np.pi / n:  # stay in the bracket found on the grid
            break
        tt -= step
        if abs(step) < 1e-15:
            break
    return float(max(abs(float(s(tt))), abs(x[i])))


@single_threaded
def fit_harmonics(t, x, omega, n_harmonics, *, channel="accel", t0=None) -> tuple[HarmonicSeries, float]:
    """Least-squares fit of ``n_harmonics`` harmonics plus a constant (seed Eq 16).

    Parameters
    ----------
    t, x : array
        Uniformly sampled time [s] and signal.
    omega : float
        Fundamental angular frequency [rad/s].
    n_harmonics : int
        Number of harmonics ``n``.
    channel : str
        Name used in error messages.
    t0 : float, optional
        Time origin of the series; the first time stamp by default.

    Returns
    -------
    series : HarmonicSeries
    residual_rms : float
        RMS of ``x`` minus the fitted series (from the one-pass sums, so exact to about
        ``1e-8`` of the RMS of ``x``).

    Examples
    --------
    >>> t = np.arange(1000) / 1000.0 + 3.21
    >>> s, r = fit_harmonics(t, 2 * np.sin(30 * t) + 0.1 * np.cos(90 * t), 30.0, 3)
    >>> bool(np.allclose(s(t), 2 * np.sin(30 * t) + 0.1 * np.cos(90 * t)))
    True
    """
    t = np.asarray(t, dtype=float)
    x = np.asarray(x, dtype=float)
    n_harmonics = int(n_harmonics)
    if n_harmonics < 1:
        raise ValueError(f"n_harmonics must be >= 1, got {n_harmonics}")
    dt = (t[-1] - t[0]) / (t.size - 1)
    fs = 1.0 / dt
    f_top = n_harmonics * omega / (2 * np.pi)
    if f_top >= fs / 2:
        raise RecordError(
            f"channel {channel!r}: harmonic {n_harmonics} of {omega / (2 * np.pi):.6g} Hz is at {f_top:.6g} Hz, "
            f"not below the Nyquist frequency {fs / 2:.6g} Hz; sample faster or fit fewer harmonics"
        )
    t0 = float(t[0]) if t0 is None else float(t0)
    return _streaming_fit(t - t0, x, omega, n_harmonics, t0, channel)


#: Samples per block when streaming through long records (keeps the work in cache).
BLOCK = 32768


def _blocks(n, size=BLOCK):
    for start in range(0, n, size):
        yield slice(start, min(n, start + size))


def _streaming_fit(tau, x, omega, n_harmonics, t0, channel):
    """Harmonic least squares accumulated block by block (normal equations).

    The columns are nearly orthogonal sinusoids, so the Gram matrix is well conditioned
    for any record of two periods or more.
    """
    m = n_coefficients(n_harmonics)
    G = np.zeros((m, m))
    r = np.zeros(m)
    xx = 0.0
    for sl in _blocks(tau.size):
        A = _basis(tau[sl], omega, n_harmonics)
        G += A.T @ A
        r += A.T @ x[sl]
        xx += float(x[sl] @ x[sl])
    try:
        coef = linalg.solve(G, r, assume_a="pos")
    except (linalg.LinAlgError, ValueError) as exc:
        raise RecordError(f"channel {channel!r}: harmonic fit failed ({exc})") from exc
    rss = max(xx - float(coef @ r), 0.0)
    return HarmonicSeries(float(omega), coef, t0), float(np.sqrt(rss / tau.size))


def _gn_pass(tau, x, omega, n_harmonics, coef_prev):
    """One streamed pass of Gauss-Newton on the fundamental of a periodic signal.

    The model is a constant plus ``n_harmonics`` harmonics of ``omega``; fitting the
    harmonics together with the fundamental keeps a distorted force (a shaker's
    harmonics) from biasing the frequency.  The linear coefficients are projected out
    (variable projection) and the Jacobian uses the coefficients of the previous pass,
    so every pass reads the record once, block by block.

    Returns ``(step, coefficients, explained fraction)``.
    """
    m = n_coefficients(n_harmonics)
    k = np.arange(1, n_harmonics + 1)
    G, b, GJ = np.zeros((m, m)), np.zeros(m), np.zeros(m)
    JJ = Jx = xx = sx = 0.0
    for sl in _blocks(tau.size):
        A = _basis(tau[sl], omega, n_harmonics)
        xs = x[sl]
        G += A.T @ A
        b += A.T @ xs
        xx += float(xs @ xs)
        sx += float(xs.sum())
        if coef_prev is not None:
            # d/d omega of sum a_k cos(k w t) + b_k sin(k w t)
            J = tau[sl] * (A[:, 2::2] @ (-k * coef_prev[1::2]) + A[:, 1::2] @ (k * coef_prev[2::2]))
            GJ += A.T @ J
            JJ += float(J @ J)
            Jx += float(J @ xs)
    coef = linalg.solve(G, b, assume_a="pos")
    var = max(xx - sx * sx / tau.size, np.finfo(float).tiny)
    fraction = 1.0 - max(xx - float(b @ coef), 0.0) / var
    if coef_prev is None:
        return 0.0, coef, fraction
    den = JJ - float(GJ @ linalg.solve(G, GJ, assume_a="pos"))  # |J projected out of span(A)|^2
    step = (Jx - float(GJ @ coef)) / den if den > 0 else 0.0  # J . residual
    return step, coef, fraction


def _refine_progressively(tau, x, omega, n_harmonics, first=32768, growth=8):
    """Refine on a growing prefix of the record so that each stage starts well inside
    the convergence region of the next, longer one; Gauss-Newton converges
    quadratically, so a longer stage needs one or two passes.

    Returns ``(omega, explained fraction)``.
    """
    n = tau.size
    m = min(n, first)
    coef, passes, tol = None, 10, 1e-6
    while True:
        max_step = 0.5 * np.pi / tau[m - 1]
        for _ in range(passes):
            step, coef, fraction = _gn_pass(tau[:m], x[:m], omega, n_harmonics, coef)
            omega += float(np.clip(step, -max_step, max_step))
            if step != 0.0 and abs(step) * tau[m - 1] < tol:
                break
        if m == n:
            return float(omega), float(fraction)
        m = min(n, m * growth)
        # a longer stage starts from a converged shorter one: a step that moves the phase at
        # its end by less than 1e-3 rad leaves an error of the order of its square
        passes, tol = 2, 1e-3


def _spectral_peak(x, dt, f_range, channel) -> float:
    """Frequency of the largest peak of the (Hann, zero-padded) spectrum of a prefix of ``x``."""
    m = min(x.size, 32768)  # the spectrum of a prefix is enough to start the refinement
    nfft = 1 << int(np.ceil(np.log2(4 * m)))
    spec = np.abs(np.fft.rfft(x[:m] * np.hanning(m), nfft))
    freqs = np.fft.rfftfreq(nfft, dt)
    spec[0] = 0.0
    if f_range is not None:
        spec[(freqs < f_range[0]) | (freqs > f_range[1])] = 0.0
    k = int(np.argmax(spec))
    delta = 0.0
    if 0 < k < spec.size - 1:
        y0, y1, y2 = np.log(spec[k - 1 : k + 2] + np.finfo(float).tiny)
        den = y0 - 2 * y1 + y2
        delta = 0.5 * (y0 - y2) / den if den != 0 else 0.0
    f0 = (k + float(np.clip(delta, -0.5, 0.5))) / (nfft * dt)
    if f0 <= 0:
        raise RecordError(f"channel {channel!r}: no excitation frequency found (spectrum peak at 0 Hz)")
    return f0


@single_threaded
def estimate_frequency(t, force, *, channel="force", f_range=None, start_hz=None) -> float:
    """Excitation frequency [Hz] of a single-frequency force record.

    The largest peak of the zero-padded spectrum (or ``start_hz`` when given, e.g. a
    nominal frequency logged by the test controller) is refined by Gauss-Newton on a
    constant plus the fundamental and its first harmonics fitted to all samples
    (maximum likelihood for white noise; harmonics of a distorted force do not bias it).

    Raises
    ------
    RecordError
        If the force is identically zero, or no sinusoid explains at least half of its
        variance (not a single-frequency excitation).
    """
    t = np.asarray(t, dtype=float)
    x = np.asarray(force, dtype=float)
    x = x - x.mean()
    if not np.any(x):
        raise RecordError(f"channel {channel!r}: the force is zero; no excitation frequency can be found")
    n = x.size
    dt = (t[-1] - t[0]) / (n - 1)
    f0 = float(start_hz) if start_hz is not None else _spectral_peak(x, dt, f_range, channel)
    tau = t - t[0]
    n_harm = int(max(1, min(FORCE_HARMONICS, np.floor(0.45 / (f0 * dt)))))
    omega, fraction = _refine_progressively(tau, x, 2 * np.pi * f0, n_harm)
    if fraction < MIN_SINE_FRACTION or not np.isfinite(omega) or omega <= 0:
        raise RecordError(
            f"channel {channel!r}: no excitation frequency found; the best periodic fit ({f0:.6g} Hz) explains only "
            f"{100 * fraction:.1f} % of the force variance (expected a single-frequency force, at least "
            f"{100 * MIN_SINE_FRACTION:.0f} %)"
        )
    return omega / (2 * np.pi)


@dataclass(frozen=True)
class StateSignals:
    """A steady-state record reduced to its state signals (modal coordinates).

    Attributes
    ----------
    t : array
        Sample times [s].
    force : array
        Measured (modal) force ``Q(t)``.
    accel_measured : array
        Measured (modal) acceleration ``q''(t)``.
    acceleration : HarmonicSeries
        The harmonic fit of the acceleration (the "filtered" acceleration).
    frequency_hz : float
        Excitation frequency.
    frequency_given : bool
        Whether the frequency came with the record (else estimated from the force).
    accel_residual_rms : float
        RMS of the acceleration left outside the fitted harmonics.
    """

    t: np.ndarray = field(repr=False)
    force: np.ndarray = field(repr=False)
    accel_measured: np.ndarray = field(repr=False)
    acceleration: HarmonicSeries
    frequency_hz: float
    frequency_given: bool
    accel_residual_rms: float

    @property
    def omega(self) -> float:
        return 2 * np.pi * self.frequency_hz

    @property
    def velocity(self) -> HarmonicSeries:
        return self.acceleration.integral()

    @property
    def displacement(self) -> HarmonicSeries:
        return self.velocity.integral()

    @property
    def n_periods(self) -> float:
        return (self.t[-1] - self.t[0] + (self.t[1] - self.t[0])) * self.frequency_hz

    def states(self):
        """``(q, q', q''_filtered)`` at the sample times."""
        parts = list(self.blocks(size=self.t.size))
        return parts[0][1:]

    def blocks(self, size=BLOCK):
        """Iterate ``(slice, q, q', q''_filtered)`` over blocks of the record."""
        C = np.column_stack(
            [self.displacement.coefficients, self.velocity.coefficients, self.acceleration.coefficients]
        )
        H = self.acceleration.n_harmonics
        for sl in _blocks(self.t.size, size):
            S = _basis(self.t[sl] - self.acceleration.t0, self.omega, H) @ C
            yield sl, S[:, 0], S[:, 1], S[:, 2]

    def q_max(self) -> float:
        """Steady-state amplitude ``max |q(t)|`` of the reconstructed displacement."""
        return self.displacement.max_abs()


#: Phase drift over a record [rad] above which a given frequency is reported as inaccurate.
DRIFT_TOL = 0.01


def _refine_given(t, force, f_given, channel) -> float:
    """The force's own frequency near ``f_given``; warns when they differ noticeably."""
    try:
        f = estimate_frequency(t, force, channel=channel, start_hz=f_given)
    except RecordError as exc:
        warnings.warn(f"channel {channel!r}: the given frequency {f_given:.9g} Hz is used as it is; it could "
                      f"not be refined on the force ({exc})", JointidWarning, stacklevel=4)
        return f_given
    drift = 2 * np.pi * abs(f - f_given) * (t[-1] - t[0])
    if drift <= DRIFT_TOL:
        return f_given  # the force confirms it
    warnings.warn(
        f"channel {channel!r}: the given frequency {f_given:.9g} Hz differs from the force's {f:.9g} Hz "
        f"(phase drift {drift:.3g} rad over the record); the force's frequency is used",
        JointidWarning,
        stacklevel=4,
    )
    return f


@single_threaded
def steady_state_signals(t, force, accel, *, frequency_hz=None, n_harmonics=5, channels=("time", "force", "accel"),
                         refine_frequency=True):
    """Validate a steady-state record and reduce it to :class:`StateSignals`.

    Parameters
    ----------
    t, force, accel : array
        Time [s], (modal) force and (modal) acceleration, equal lengths.
    frequency_hz : float, optional
        Excitation frequency; estimated from the force when ``None``.
    n_harmonics : int
        Harmonics fitted to the acceleration (the seed uses 4).  When the sampling rate
        does not allow so many, the harmonics below Nyquist are fitted and a
        :class:`~jointid.errors.JointidWarning` says so (fewer than ``MIN_HARMONICS`` is
        an error).
    channels : tuple of str
        Column names used in error messages.
    refine_frequency : bool
        Check a given frequency on the force record (Gauss-Newton started from it).  A
        logged frequency is often rounded (26.48 Hz), and over a long record the phase
        drift of a 0.005 Hz error spoils the damping estimate.  When the given value
        would drift by more than ``DRIFT_TOL`` (0.01 rad) over the record, the force's
        frequency is used instead, with a warning; otherwise the given value is kept.

    Raises
    ------
    RecordError
        Non-finite values, different lengths, bad time base, zero force, no excitation
        frequency found, fewer than two periods, or fewer than ``MIN_HARMONICS``
        harmonics below Nyquist.
    """
    tname, fname, aname = channels
    t = check_signal(t, tname)
    check_time_base(t, channel=tname)
    force = check_signal(force, fname, t.size)
    accel = check_signal(accel, aname, t.size)
    if not np.any(force - force.mean()):
        raise RecordError(f"channel {fname!r}: the force is zero (or constant); the record carries no excitation")
    given = frequency_hz is not None
    dt = (t[-1] - t[0]) / (t.size - 1)
    if given:
        frequency_hz = float(frequency_hz)
        if not np.isfinite(frequency_hz) or frequency_hz <= 0:
            raise RecordError(f"frequency_hz must be a positive number, got {frequency_hz!r}")
        if refine_frequency:
            frequency_hz = _refine_given(t, force, frequency_hz, fname)
    else:
        frequency_hz = estimate_frequency(t, force, channel=fname)
    periods = (t[-1] - t[0] + dt) * frequency_hz
    if periods < MIN_PERIODS:
        raise RecordError(
            f"channel {tname!r}: the record spans {periods:.3g} periods of {frequency_hz:.6g} Hz; "
            f"at least {MIN_PERIODS:g} are needed"
        )
    omega = 2 * np.pi * frequency_hz
    n_harmonics = int(n_harmonics)
    below = int(np.ceil(0.5 / (dt * frequency_hz)) - 1)  # harmonics strictly below Nyquist
    if n_harmonics > below:
        if below < MIN_HARMONICS:
            raise RecordError(
                f"channel {aname!r}: only {max(below, 0)} harmonic(s) of {frequency_hz:.6g} Hz lie below the "
                f"Nyquist frequency {0.5 / dt:.6g} Hz; at least {MIN_HARMONICS} are needed (sample faster)"
            )
        warnings.warn(
            f"channel {aname!r}: fitting {below} harmonics instead of {n_harmonics}: harmonic {below + 1} of "
            f"{frequency_hz:.6g} Hz is not below the Nyquist frequency {0.5 / dt:.6g} Hz",
            JointidWarning,
            stacklevel=3,
        )
        n_harmonics = below
    series, resid = _streaming_fit(t - t[0], accel, omega, n_harmonics, float(t[0]), aname)
    return StateSignals(t, force, accel, series, frequency_hz, given, resid)
