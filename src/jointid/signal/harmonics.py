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

import functools
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
    return _time_step(t, channel, rtol)[0]


def _time_step(t, channel="time", rtol=1e-2):
    """:func:`check_time_base` and :func:`_uniform_step` in one blocked pass: ``(dt, dt or None)``."""
    t = np.asarray(t, dtype=float)
    if t.ndim != 1 or t.size < 3:
        raise RecordError(f"channel {channel!r}: expected a 1-D time vector of at least 3 samples, got shape {t.shape}")
    if not np.isfinite(t).all():
        i = int(np.flatnonzero(~np.isfinite(t))[0])
        raise RecordError(f"channel {channel!r}: non-finite time value {t[i]!r} at sample {i}")
    n = t.size
    t0 = float(t[0])
    dt = (float(t[-1]) - t0) / (n - 1)
    uniform = n >= 2 * TABLE_ROWS
    tol = 8.0 * np.finfo(float).eps * max(abs(t0), abs(float(t[-1])))
    rows = min(BLOCK, n - 1)
    grid = dt * np.arange(rows)
    d = np.empty(rows)
    w = np.empty(rows)
    worst, i_worst = -1.0, 0
    for sl in _blocks(n - 1, rows):
        m = sl.stop - sl.start
        ds = d[:m]
        np.subtract(t[sl.start + 1 : sl.stop + 1], t[sl], out=ds)
        if (ds <= 0).any():
            i = sl.start + int(np.flatnonzero(ds <= 0)[0])
            raise RecordError(
                f"channel {channel!r}: time must increase strictly; sample {i + 1} ({t[i + 1]!r} s) "
                f"does not follow sample {i} ({t[i]!r} s)"
            )
        ds -= dt
        j = int(np.argmax(np.abs(ds, out=ds)))
        if ds[j] > worst:
            worst, i_worst = float(ds[j]), sl.start + j
        if uniform:
            ws = w[:m]
            np.subtract(t[sl], t0 + dt * sl.start, out=ws)
            ws -= grid[:m]
            uniform = bool(np.abs(ws, out=ws).max() <= tol)
    if worst > rtol * dt:
        i = i_worst
        raise RecordError(
            f"channel {channel!r}: uneven sampling; expected a uniform step of {dt:.6g} s, "
            f"step {i} (after {t[i]!r} s) is {t[i + 1] - t[i]:.6g} s"
        )
    return float(dt), (float(dt) if uniform else None)


def check_signal(x, name, n=None) -> np.ndarray:
    """A 1-D finite float signal of ``n`` samples (when given), or a :class:`RecordError` naming the channel."""
    x = np.asarray(x, dtype=float)
    if x.ndim != 1:
        raise RecordError(f"channel {name!r}: expected a 1-D signal, got shape {x.shape}")
    if n is not None and x.size != n:
        raise RecordError(f"channel {name!r}: has {x.size} samples but the time column has {n}")
    for sl in _blocks(x.size):  # block by block: no mask as long as the record
        if not np.isfinite(x[sl]).all():
            bad = ~np.isfinite(x)
            i = int(np.flatnonzero(bad)[0])
            raise RecordError(f"channel {name!r}: non-finite value {x[i]!r} at sample {i} ({int(bad.sum())} in all)")
    return x


def _varies(x) -> bool:
    """Whether ``x`` differs from its mean anywhere (``np.any(x - x.mean())``, block by block)."""
    mean = x.mean()
    return any(bool((x[sl] != mean).any()) for sl in _blocks(x.size))


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
    if t0 is None or float(t0) == float(t[0]):
        dt = _uniform_step(t)
        if dt is not None:  # the series starts at the first sample: tau = n dt
            return _streaming_fit(None, x, omega, n_harmonics, float(t[0]), channel, dt)
    t0 = float(t[0]) if t0 is None else float(t0)
    return _streaming_fit(t, x, omega, n_harmonics, t0, channel, origin=t0)


#: Samples per block when streaming through long records (keeps the work in cache).
BLOCK = 32768


def _blocks(n, size=None):
    size = BLOCK if size is None else size  # read at the call: a test may shrink the blocks
    for start in range(0, n, size):
        yield slice(start, min(n, start + size))


# ----------------------------------------------------------------------------------------
# Uniformly sampled records: sinusoids by rotation of one table
# ----------------------------------------------------------------------------------------
#
# On a uniform grid ``t_n = t_0 + n dt`` the basis row of sample ``s + j`` is the row of
# sample ``j`` rotated by the phase ``k omega dt s`` of each harmonic ``k``.  One table of
# ``TABLE_ROWS`` rows therefore serves every block of a record: its sums against the data
# are one matrix product over all blocks, and per block only a ``(2H+1)``-square rotation
# is applied.  The table and the rotations are evaluated directly (no recurrence), so
# every basis value is exact to a few units of rounding.

#: Rows of the sinusoid table used to stream a uniformly sampled record.
TABLE_ROWS = 4096


def _uniform_step(t):
    """Step ``dt`` when ``t`` equals ``t[0] + n dt`` to within its own rounding, else ``None``.

    Time stamps produced as ``t0 + n dt`` (or ``n / fs``) pass; stamps rounded to fewer
    digits than a double holds do not, and their records take the general path, which
    uses every time stamp as it is.  Records shorter than two tables also take it (it
    costs well under a millisecond there, and on few samples the rounding of the time
    stamps does not average out).
    """
    n = t.size
    if n < 2 * TABLE_ROWS:
        return None
    t0 = float(t[0])
    dt = (float(t[-1]) - t0) / (n - 1)
    tol = 8.0 * np.finfo(float).eps * max(abs(t0), abs(float(t[-1])))
    rows = min(BLOCK, n)
    grid = dt * np.arange(rows)
    work = np.empty(rows)
    for sl in _blocks(n, rows):
        w = work[: sl.stop - sl.start]
        np.subtract(t[sl], t0 + dt * sl.start, out=w)
        w -= grid[: w.size]
        if np.abs(w, out=w).max() > tol:
            return None
    return dt


@functools.lru_cache(maxsize=6)
def _sinusoids(omega_dt, n_harmonics, rows):
    """Read-only basis rows ``[1, cos, sin, ...]`` at phases ``omega_dt * j`` (``j < rows``)."""
    j = np.arange(rows, dtype=float)
    T = np.empty((rows, n_coefficients(n_harmonics)))
    T[:, 0] = 1.0
    kt = np.multiply.outer(omega_dt * j, np.arange(1, n_harmonics + 1))
    T[:, 1::2] = np.cos(kt)
    T[:, 2::2] = np.sin(kt)
    T.flags.writeable = False
    return T


@functools.lru_cache(maxsize=6)
def _table(omega_dt, n_harmonics, rows, weighted):
    """Basis rows at phases ``omega_dt * j`` (``j < rows``) and their Gram matrix.

    With ``weighted`` the table is ``[T, j T]`` (the sample index times the basis, for
    derivatives with respect to the frequency).  Returns read-only ``(W, W.T @ W)``.
    """
    T = _sinusoids(omega_dt, n_harmonics, rows)
    W = np.hstack([T, np.arange(rows, dtype=float)[:, None] * T]) if weighted else T
    gram = W.T @ W
    W.flags.writeable = False
    gram.flags.writeable = False
    return W, gram


def _rotations(phase, n_harmonics):
    """``(len(phase), m, m)`` matrices ``M`` with ``basis(phase + theta) = basis(theta) @ M``."""
    m = n_coefficients(n_harmonics)
    k = np.arange(1, n_harmonics + 1)
    kp = np.multiply.outer(np.asarray(phase, float), k)
    c, s = np.cos(kp), np.sin(kp)
    M = np.zeros((kp.shape[0], m, m))
    M[:, 0, 0] = 1.0
    ic, is_ = 2 * k - 1, 2 * k
    M[:, ic, ic] = c  # cos(a + b) = cos a cos b - sin a sin b
    M[:, is_, ic] = -s
    M[:, is_, is_] = c  # sin(a + b) = sin a cos b + cos a sin b
    M[:, ic, is_] = s
    return M


def _uniform_moments(x, omega_dt, n_harmonics, weighted=False, rows=TABLE_ROWS):
    """Sums of a uniformly sampled ``x`` against the basis, in one pass over ``x``.

    With ``A`` the basis at phases ``omega_dt * n`` and ``N = diag(n)`` (sample index):
    returns ``(A.T A, A.T x)`` and, with ``weighted``, also ``A.T N A``,
    ``A.T N^2 A`` and ``A.T N x``.
    """
    n = x.size
    m = n_coefficients(n_harmonics)
    rows = min(rows, n)
    W, gram = _table(float(omega_dt), n_harmonics, rows, bool(weighted))
    nb, r = divmod(n, rows)
    parts = [(np.arange(nb) * float(rows), x[: nb * rows].reshape(nb, rows) @ W, gram)]
    if r:
        Wr = W[:r]
        parts.append((np.array([float(nb * rows)]), (x[nb * rows :] @ Wr)[None, :], Wr.T @ Wr))
    G = np.zeros((m, m))
    b = np.zeros(m)
    G1 = np.zeros((m, m))
    G2 = np.zeros((m, m))
    b1 = np.zeros(m)
    for starts, U, Gw in parts:
        M = _rotations(omega_dt * starts, n_harmonics)
        Mt = M.transpose(0, 2, 1)
        G0 = Gw[:m, :m]
        G += (Mt @ G0 @ M).sum(axis=0)
        b += np.einsum("bij,bi->j", M, U[:, :m])
        if weighted:
            Gj, Gjj = Gw[:m, m:], Gw[m:, m:]
            s = starts[:, None, None]
            G1 += (Mt @ (s * G0 + Gj) @ M).sum(axis=0)
            G2 += (Mt @ ((s * s) * G0 + 2.0 * s * Gj + Gjj) @ M).sum(axis=0)
            b1 += np.einsum("bij,bi->j", M, starts[:, None] * U[:, :m] + U[:, m:])
    if weighted:
        return G, b, G1, G2, b1
    return G, b


def _uniform_gn(x, omega, dt, n_harmonics, rows=TABLE_ROWS):
    """One Gauss-Newton step on the fundamental of a uniformly sampled periodic signal.

    The same model and variable projection as :func:`_gn_pass`, with the Jacobian taken
    at the coefficients of ``omega`` itself, all from one pass over ``x``.

    Returns ``(step, standard error of omega, coefficients, explained fraction)``.
    """
    G, b, G1, G2, b1 = _uniform_moments(x, omega * dt, n_harmonics, weighted=True, rows=rows)
    coef = linalg.solve(G, b, assume_a="pos")
    n = x.size
    xx = float(x @ x)
    sx = b[0]  # the constant column sums x
    var = max(xx - sx * sx / n, np.finfo(float).tiny)
    rss = max(xx - float(b @ coef), 0.0)
    fraction = 1.0 - rss / var
    k = np.arange(1, n_harmonics + 1)
    d = np.zeros_like(coef)  # J = tau A d: d/d omega of the series
    d[1::2] = k * coef[2::2]
    d[2::2] = -k * coef[1::2]
    GJ = dt * (G1 @ d)
    den = dt * dt * float(d @ G2 @ d) - float(GJ @ linalg.solve(G, GJ, assume_a="pos"))
    if not den > 0:
        return 0.0, np.inf, coef, fraction
    step = (dt * float(d @ b1) - float(GJ @ coef)) / den
    stderr = float(np.sqrt(rss / max(n - coef.size - 1, 1) / den))
    return step, stderr, coef, fraction


def _streaming_fit(tau, x, omega, n_harmonics, t0, channel, dt=None, origin=None):
    """Harmonic least squares accumulated block by block (normal equations).

    The columns are nearly orthogonal sinusoids, so the Gram matrix is well conditioned
    for any record of two periods or more.  With ``dt`` (a uniform grid, ``tau = n dt``)
    the sums come from one matrix product against a rotated table
    (:func:`_uniform_moments`); otherwise the basis is evaluated at every ``tau``, or at
    ``tau - origin`` block by block when ``origin`` is given (``tau`` then holds the time
    stamps themselves: no shifted copy of a long record).
    """
    if dt is not None:
        G, r = _uniform_moments(x, omega * dt, n_harmonics)
        xx = float(x @ x)
    else:
        m = n_coefficients(n_harmonics)
        G = np.zeros((m, m))
        r = np.zeros(m)
        xx = 0.0
        for sl in _blocks(tau.size):
            A = _basis(tau[sl] if origin is None else tau[sl] - origin, omega, n_harmonics)
            G += A.T @ A
            r += A.T @ x[sl]
            xx += float(x[sl] @ x[sl])
    try:
        coef = linalg.solve(G, r, assume_a="pos")
    except (linalg.LinAlgError, ValueError) as exc:
        raise RecordError(f"channel {channel!r}: harmonic fit failed ({exc})") from exc
    rss = max(xx - float(coef @ r), 0.0)
    return HarmonicSeries(float(omega), coef, t0), float(np.sqrt(rss / x.size))


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


def _refine_uniform(x, omega, dt, n_harmonics, first=32768, growth=8, tol=1e-8):
    """:func:`_refine_progressively` for a uniformly sampled record.

    Every pass is one Gauss-Newton step with the Jacobian at the current frequency
    (:func:`_uniform_gn`), so convergence is quadratic from the first pass and each
    stage runs until a step moves the phase at its end by less than ``tol``: the result
    is the fixed point to rounding, the same fixed point as the general path's.

    Returns ``(omega, explained fraction)``.
    """
    n = x.size
    m = min(n, first)
    passes = 10
    while True:
        span = (m - 1) * dt
        max_step = 0.5 * np.pi / span
        rows = min(TABLE_ROWS, max(512, m // 32))  # a short stage: a short table (built at every pass)
        for _ in range(passes):
            step, _, _, fraction = _uniform_gn(x[:m], omega, dt, n_harmonics, rows)
            omega += float(np.clip(step, -max_step, max_step))
            if abs(step) * span < tol:
                break
        if m == n:
            return float(omega), float(fraction)
        m = min(n, m * growth)
        passes = 4


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
    return _estimate_frequency(t, np.asarray(force, dtype=float), _uniform_step(t), channel, f_range, start_hz)


def _estimate_frequency(t, force, dt_uniform, channel, f_range=None, start_hz=None):
    """:func:`estimate_frequency` with the record's uniform step (see :func:`_uniform_step`) known."""
    x = force - force.mean()
    if not np.any(x):
        raise RecordError(f"channel {channel!r}: the force is zero; no excitation frequency can be found")
    n = x.size
    dt = (t[-1] - t[0]) / (n - 1)
    f0 = float(start_hz) if start_hz is not None else _spectral_peak(x, dt, f_range, channel)
    n_harm = int(max(1, min(FORCE_HARMONICS, np.floor(0.45 / (f0 * dt)))))
    if dt_uniform is not None:
        omega, fraction = _refine_uniform(x, 2 * np.pi * f0, dt_uniform, n_harm)
    else:
        omega, fraction = _refine_progressively(t - t[0], x, 2 * np.pi * f0, n_harm)
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

    def states(self, stop=None):
        """``(q, q', q''_filtered)`` at the sample times (the first ``stop`` samples when given)."""
        n = self.t.size if stop is None else int(min(max(stop, 0), self.t.size))
        out = np.empty((3, n))
        for sl, q, v, a in self.exact_blocks(stop=n):
            out[0, sl], out[1, sl], out[2, sl] = q, v, a
        return out[0], out[1], out[2]

    def exact_blocks(self, size=None, stop=None):
        """Iterate ``(slice, q, q', q''_filtered)`` like :meth:`blocks`, with every sinusoid
        evaluated at its sample (no rotation of a table): the values of one evaluation over
        the whole record, in blocks of ``size`` samples (memory of a block, not of the record)."""
        n = self.t.size if stop is None else int(min(max(stop, 0), self.t.size))
        size = BLOCK if size is None else int(size)
        C = self.series_coefficients()
        H = self.acceleration.n_harmonics
        if self._uniform_dt is None:
            for sl in _blocks(n, size):
                S = C.T @ _basis(self.t[sl] - self.acceleration.t0, self.omega, H).T
                yield sl, S[0], S[1], S[2]
            return
        omega_dt = self.omega * self._uniform_dt
        phase0 = self.omega * (float(self.t[0]) - self.acceleration.t0)
        CM = _rotations(np.array([phase0]), H)[0] @ C
        k = np.arange(1, H + 1)
        T = np.empty((min(size, n), n_coefficients(H)))
        for sl in _blocks(n, size):
            Tb = T[: sl.stop - sl.start]
            kt = np.multiply.outer(omega_dt * np.arange(sl.start, sl.stop, dtype=float), k)  # as in _sinusoids
            Tb[:, 0] = 1.0
            Tb[:, 1::2] = np.cos(kt)
            Tb[:, 2::2] = np.sin(kt)
            S = CM.T @ Tb.T
            yield sl, S[0], S[1], S[2]

    @functools.cached_property
    def _uniform_dt(self):
        """The time step when the record is uniformly sampled (see :func:`_uniform_step`), else None."""
        return _uniform_step(np.asarray(self.t, float))

    def _rotated_table(self, size):
        """``(T, M, rows)`` on a uniform grid: the sinusoid table of ``rows`` samples and the
        rotation of every block of ``rows`` samples (block ``b`` of the fit's design matrix is
        ``T @ M[b]``); ``None`` on a non-uniform grid."""
        if self._uniform_dt is None:
            return None
        H, n = self.acceleration.n_harmonics, self.t.size
        rows = min(int(size), n)
        omega_dt = self.omega * self._uniform_dt
        phase0 = self.omega * (float(self.t[0]) - self.acceleration.t0)
        return _sinusoids(omega_dt, H, rows), _rotations(phase0 + omega_dt * np.arange(0, n, rows), H), rows

    def basis_factors(self, size=BLOCK):
        """Iterate ``(slice, T, M)``: the fit's design matrix ``[1, cos, sin, ...]`` of a block
        is ``T @ M``.

        On a uniform grid ``T`` is the rows of one sinusoid table and ``M`` the block's
        ``(2H + 1)``-square rotation, so sums against the data (``X^T T``) are taken on the
        table and rotated afterwards; otherwise ``T`` is the design matrix itself and ``M``
        is ``None``.
        """
        table = self._rotated_table(size)
        if table is None:
            for sl in _blocks(self.t.size, size):
                yield sl, _basis(self.t[sl] - self.acceleration.t0, self.omega, self.acceleration.n_harmonics), None
            return
        T, M, rows = table
        for b, sl in enumerate(_blocks(self.t.size, rows)):
            yield sl, T[: sl.stop - sl.start], M[b]

    def series_coefficients(self) -> np.ndarray:
        """``(2H + 1, 3)``: the coefficients of ``q``, ``q'`` and the filtered ``q''``."""
        return np.column_stack(
            [self.displacement.coefficients, self.velocity.coefficients, self.acceleration.coefficients]
        )

    def blocks(self, size=BLOCK):
        """Iterate ``(slice, q, q', q''_filtered)`` over blocks of the record.

        On a uniform grid every block is one product of the fit's sinusoid table, rotated
        to the block's start, with the three series' coefficients.
        """
        C = self.series_coefficients()
        for sl, T, M in self.basis_factors(size):
            S = (C if M is None else M @ C).T @ T.T  # one contiguous row per state
            yield sl, S[0], S[1], S[2]

    def basis_blocks(self, size=BLOCK):
        """Iterate ``(slice, A)``: the fit's design matrix ``[1, cos, sin, ...]`` block by block.

        ``A`` is ``(block, 2H + 1)`` at the sample times (origin ``acceleration.t0``), the
        same rows :meth:`blocks` combines; on a uniform grid it is the rotated table, not
        a new evaluation of sines.
        """
        for sl, T, M in self.basis_factors(size):
            yield sl, (T if M is None else T @ M)

    def basis_gram(self, weighted=False):
        """``A^T A`` of the fit's design matrix over the record (``A`` as in :meth:`basis_blocks`).

        With ``weighted`` also ``A^T diag(tau) A`` and ``A^T diag(tau^2) A``, ``tau`` the
        time from the fit's origin (the information of the frequency).  On a uniform grid
        the sums come from the Gram matrices of one table of ``TABLE_ROWS`` samples,
        rotated to every block, without a pass over the samples.
        """
        H, n = self.acceleration.n_harmonics, self.t.size
        m = n_coefficients(H)
        G, G1, G2 = np.zeros((m, m)), np.zeros((m, m)), np.zeros((m, m))
        table = self._rotated_table(TABLE_ROWS)
        if table is None:
            for sl in _blocks(n):
                tau = self.t[sl] - self.acceleration.t0
                A = _basis(tau, self.omega, H)
                G += A.T @ A
                if weighted:
                    At = A * tau[:, None]
                    G1 += At.T @ A
                    G2 += At.T @ At
            return (G, G1, G2) if weighted else G
        _, M, rows = table
        dt = self._uniform_dt
        W, gram = _table(self.omega * dt, H, rows, bool(weighted))
        nb, r = divmod(n, rows)
        tau0 = float(self.t[0]) - self.acceleration.t0
        parts = [(slice(0, nb), gram)] if nb else []
        if r:
            Wr = W[:r]
            parts.append((slice(nb, nb + 1), Wr.T @ Wr))
        for sel, Gw in parts:
            Mb = M[sel]
            Mt = Mb.transpose(0, 2, 1)
            G0 = Gw[:m, :m]
            G += (Mt @ G0 @ Mb).sum(axis=0)
            if weighted:  # tau = tau_b + j dt over block b
                Gj, Gjj = dt * Gw[:m, m:], (dt * dt) * Gw[m:, m:]
                s = (tau0 + dt * rows * np.arange(sel.start, sel.stop, dtype=float))[:, None, None]
                G1 += (Mt @ (s * G0 + Gj) @ Mb).sum(axis=0)
                G2 += (Mt @ ((s * s) * G0 + 2.0 * s * Gj + Gjj) @ Mb).sum(axis=0)
        return (G, G1, G2) if weighted else G

    def q_max(self) -> float:
        """Steady-state amplitude ``max |q(t)|`` of the reconstructed displacement."""
        return self.displacement.max_abs()


#: Phase drift over a record [rad] above which a given frequency is reported as inaccurate.
DRIFT_TOL = 0.01


def _refine_given(t, force, f_given, channel, dt_uniform=None) -> float:
    """The force's own frequency near ``f_given``; warns when they differ noticeably.

    On a uniform grid one pass decides: a Gauss-Newton step from ``f_given``
    (:func:`_uniform_gn`) estimates the force's frequency to second order in the
    difference, so a step that drifts the phase by at most ``DRIFT_TOL`` over the record
    confirms the given value.  Anything else (a larger drift, a force that is not a
    clear sinusoid at ``f_given``) goes to the full refinement, which decides and warns.
    """
    if dt_uniform is not None:
        n_harm = int(max(1, min(FORCE_HARMONICS, np.floor(0.45 / (f_given * dt_uniform)))))
        step, _, _, fraction = _uniform_gn(force, 2 * np.pi * f_given, dt_uniform, n_harm)
        if fraction >= MIN_SINE_FRACTION and abs(step) * (t[-1] - t[0]) <= DRIFT_TOL:
            return f_given  # the force confirms it
    try:
        f = _estimate_frequency(t, force, dt_uniform, channel, start_hz=f_given)
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
    _, dt_uniform = _time_step(t, tname)
    force = check_signal(force, fname, t.size)
    accel = check_signal(accel, aname, t.size)
    if not _varies(force):
        raise RecordError(f"channel {fname!r}: the force is zero (or constant); the record carries no excitation")
    given = frequency_hz is not None
    dt = (t[-1] - t[0]) / (t.size - 1)
    if given:
        frequency_hz = float(frequency_hz)
        if not np.isfinite(frequency_hz) or frequency_hz <= 0:
            raise RecordError(f"frequency_hz must be a positive number, got {frequency_hz!r}")
        if refine_frequency:
            frequency_hz = _refine_given(t, force, frequency_hz, fname, dt_uniform)
    else:
        frequency_hz = _estimate_frequency(t, force, dt_uniform, fname)
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
    tau, origin = (None, None) if dt_uniform is not None else (t, float(t[0]))
    series, resid = _streaming_fit(tau, accel, omega, n_harmonics, float(t[0]), aname, dt_uniform, origin=origin)
    out = StateSignals(t, force, accel, series, frequency_hz, given, resid)
    out.__dict__["_uniform_dt"] = dt_uniform  # seeds the cached property (already computed)
    return out
