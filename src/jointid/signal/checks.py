"""Plausibility checks of records: named flags with the numbers that triggered them.

A check never raises for data that are merely implausible: it returns a :class:`Flag`
(``transient: first/second-half fundamental differs by 31 % (z = 85)``) that is stored
on the record's result.  A flagged record is kept in the results but left out of the
pooled fits by default.  Only data that cannot be used at all (a channel that is
constant) raise a :class:`~jointid.errors.RecordError` (:func:`check_live`).

Thresholds come from the noise of the record itself, so that a clean record is never
flagged: a statistic is compared with its standard deviation under white noise
(estimated from the residual outside the fitted harmonics) and must also exceed a small
physical floor (a difference nobody would call a fault).

Record checks (:func:`record_flags`):

``clipping``
    Flat tops: many samples exactly at the extreme value of a channel, far more than at
    the next distinct value (the amplitude histogram of a sinusoid has no such spike).
``dead_channel``
    The fundamental of a channel is not above its noise (``z`` below 6), or the fitted
    harmonics explain less than half of its variance (noise: the robust scale of the
    residual, so that spikes are not taken for noise).
``spikes``
    Samples far off the fitted harmonics: more than 10 robust standard deviations of the
    residual (a Gaussian sample exceeds that with probability 1e-23) and more than 1e-6 of
    the channel's peak.
``transient``
    The fundamental fitted to the first and to the second half of the record differ by more
    than the noise allows (``z`` above 6) and by more than 2 %.
``negative_input_power`` / ``channel_swap``
    The mean power ``<Q q'>`` fed in by the force is negative beyond its noise (a passive
    joint dissipates): a flipped sign, a timing offset, or swapped channels (named
    ``channel_swap`` when the force is also the more distorted of the two channels).

Group checks (:func:`scale_outliers`, :func:`trend_outliers`): a record whose excitation
frequency or identified ``omega1`` is off from its group's median by a large factor (time in
ms instead of s, acceleration in g instead of m/s^2), or whose damping is off the group's
trend against the amplitude.  The damping compared is the record's equivalent viscous
damping ``c_eq = <Q q'> / <q'^2>`` (:func:`equivalent_damping`): the dissipation per cycle,
which the record resolves whatever damping terms the model has (the coefficient of ``q'``
alone is not resolved when ``|q'|q'`` or ``q'^3`` are fitted beside it), with its standard
error.  A unit error scales ``c_eq`` by 9.81 or 1000; a record is flagged only when its
``c_eq`` is off the trend by the factor *and* by many of its standard errors.
"""

from __future__ import annotations

import html
from dataclasses import dataclass, field

import numpy as np

from ..errors import RecordError
from .harmonics import _blocks, fit_harmonics

__all__ = ["Flag", "check_live", "clipping_flag", "record_flags", "scale_outliers", "trend_outliers", "monotone_outliers",
           "equivalent_damping", "Z_LIMIT"]

#: Noise z-score above which a statistic is called significant (white noise: P(|z| > 6) < 1e-8).
Z_LIMIT = 6.0
#: Smallest relative change of the fundamental between the two halves that counts as a transient.
TRANSIENT_FLOOR = 0.02
#: Smallest fraction of a channel's variance its fitted harmonics must explain.
MIN_EXPLAINED = 0.5
#: Residual z-score (robust) above which a sample is a spike.
SPIKE_Z = 10.0
#: Standard errors of the trend's slope allowed where :func:`trend_outliers` extrapolates it.
SLOPE_Z = 3.0
#: Clipping: share of samples at the extremes, and how many times the next level's count.
CLIP_FRACTION = 0.005
CLIP_RATIO = 4.0


@dataclass(frozen=True)
class Flag:
    """A named plausibility flag with the numbers that triggered it.

    Attributes
    ----------
    name : str
        Short name (``"transient"``, ``"clipping"``...).
    message : str
        One sentence with the numbers and the likely cause.
    values : dict
        The numbers (JSON-safe floats and strings).
    """

    name: str
    message: str
    values: dict = field(default_factory=dict)

    def summary(self) -> dict:
        return {"name": self.name, "message": self.message,
                "values": {k: (float(v) if isinstance(v, (int, float, np.floating, np.integer)) and
                               not isinstance(v, bool) else v) for k, v in self.values.items()}}

    def report(self) -> str:
        return f"{self.name}: {self.message}"

    def _repr_html_(self) -> str:
        return f"<b>{html.escape(self.name)}</b>: {html.escape(self.message)}"


#: Largest magnitude a sample may have: the regressions square and cube the signals.
MAX_ABS = 1e100


def check_live(x, channel: str) -> None:
    """Raise a :class:`RecordError` when a channel is constant (a stuck or dead sensor) or holds
    values so large (beyond ``MAX_ABS``) that the regressions would overflow.

    Examples
    --------
    >>> check_live(np.full(10, 9.81), "accel")
    Traceback (most recent call last):
    ...
    jointid.errors.RecordError: channel 'accel': constant (9.81 at every sample); a stuck or dead sensor
    """
    x = np.asarray(x, dtype=float)
    lo, hi = float(np.min(x)), float(np.max(x))
    if max(abs(lo), abs(hi)) > MAX_ABS:
        i = int(np.argmax(np.abs(x)))
        raise RecordError(f"channel {channel!r}: value {x[i]:.3g} at sample {i} is beyond the usable range "
                          f"(|x| <= {MAX_ABS:g}); a corrupted sample or a wrong unit")
    if hi - lo <= 1e-12 * max(abs(lo), abs(hi)):
        value = float(np.median(x))
        what = "zero at every sample" if value == 0 else f"constant ({value:.6g} at every sample)"
        raise RecordError(f"channel {channel!r}: {what}; a stuck or dead sensor")


def clipping_flag(x, channel: str) -> Flag | None:
    """``clipping`` when a channel sits at its extreme values far more than a sinusoid would.

    The samples equal to the maximum (and to the minimum) are counted and compared with the
    samples at the next distinct level; a clipped signal piles up at the limit, a sampled or
    quantised sinusoid does not.
    """
    x = np.asarray(x, dtype=float)
    n = x.size
    worst = None
    for side, sign in (("maximum", 1.0), ("minimum", -1.0)):
        top = sign * (x.max() if sign > 0 else x.min())  # max(-x) = -min(x)
        at_top, level, nxt = 0, None, 0
        for sl in _blocks(n):  # block by block: no copy of the record
            y = sign * x[sl]
            at_top += int(np.count_nonzero(y == top))
            below = y[y < top]
            if below.size:
                m = below.max()
                if level is None or m > level:
                    level, nxt = m, int(np.count_nonzero(below == m))
                elif m == level:
                    nxt += int(np.count_nonzero(below == m))
        frac = at_top / n
        if at_top >= 5 and frac >= CLIP_FRACTION and at_top >= CLIP_RATIO * max(nxt, 1):
            if worst is None or frac > worst[1]:
                worst = (side, frac, at_top, nxt, sign * top)
    if worst is None:
        return None
    side, frac, at_top, nxt, level = worst
    return Flag("clipping", f"channel {channel!r}: {at_top} samples ({100 * frac:.1f} %) sit exactly at the {side} "
                            f"{level:.6g} (next level: {nxt}); clipped or saturated",
                {"channel": channel, "fraction_at_limit": frac, "samples_at_limit": at_top,
                 "samples_at_next_level": nxt, "limit": level})


def _fundamental(series) -> complex:
    c = series.coefficients
    return complex(c[1], c[2])


def _robust_sigma(r) -> float:
    return 1.4826 * float(np.median(np.abs(r - np.median(r))))


def _dead_flag(series, sigma, x, n, channel) -> Flag | None:
    """``dead_channel`` from the fundamental's noise z-score and the variance explained
    (``sigma``: robust scale of the residual, so that a few spikes do not count as noise)."""
    X1 = abs(_fundamental(series))
    sigma = max(float(sigma), 1e-300)
    z = X1 / (sigma * np.sqrt(2.0 / n))
    var = float(np.var(x))
    explained = max(0.0, 1.0 - sigma**2 / var) if var > 0 else 0.0
    if z < Z_LIMIT or explained < MIN_EXPLAINED:
        return Flag("dead_channel", f"channel {channel!r}: the excitation frequency is not above the noise "
                                    f"(fundamental {X1:.3g}, noise z = {z:.2f}, harmonics explain "
                                    f"{100 * explained:.1f} % of the variance); a dead or disconnected sensor",
                    {"channel": channel, "fundamental": X1, "z": z, "explained": explained})
    return None


def _residual_blocks(t, x, series):
    """Iterate ``(slice, x - series(t))`` block by block (the residual of a long record is never
    held whole)."""
    for sl in _blocks(x.size):
        yield sl, x[sl] - series(t[sl])


def _residual_sigma(t, x, series, work) -> float:
    """:func:`_robust_sigma` of the residual ``x - series(t)``, in the buffer ``work`` (overwritten)."""
    r = work[: x.size]
    for sl, rb in _residual_blocks(t, x, series):
        r[sl] = rb
    med = np.median(r, overwrite_input=True)  # the same values as the whole residual's, reordered
    np.subtract(r, med, out=r)
    np.abs(r, out=r)
    return 1.4826 * float(np.median(r, overwrite_input=True))


def _spike_flag(t, x, series, scale, channel) -> Flag | None:
    """``spikes`` when samples lie far off the fitted harmonics (``scale``: robust scale of the
    residual ``x - series(t)``, which is formed again block by block)."""
    peak = max(float(np.max(x)), -float(np.min(x)))
    limit = max(SPIKE_Z * scale, 1e-6 * peak)
    count, i, worst, value = 0, -1, -1.0, 0.0
    for sl, r in _residual_blocks(t, x, series):
        a = np.abs(r)
        count += int(np.count_nonzero(a > limit))
        j = int(np.argmax(a))
        if a[j] > worst:
            i, worst, value = sl.start + j, float(a[j]), float(r[j])
    if not count:
        return None
    return Flag("spikes", f"channel {channel!r}: {count} sample(s) lie more than {SPIKE_Z:g} robust standard "
                          f"deviations off the fitted harmonics, the worst {value:.4g} at sample {i}; spikes or "
                          f"dropouts", {"channel": channel, "n_samples": count, "worst": value,
                                        "worst_sample": i, "robust_sigma": scale})


def _halves_flag(t, x, omega, H, t0, channel) -> tuple[float, float, float]:
    """Relative change and z-score of the fundamental between the two halves of a record."""
    n = t.size
    h = n // 2
    s1, r1 = fit_harmonics(t[:h], x[:h], omega, H, channel=channel, t0=t0)
    s2, r2 = fit_harmonics(t[h:], x[h:], omega, H, channel=channel, t0=t0)
    X1, X2 = _fundamental(s1), _fundamental(s2)
    # each cos/sin coefficient of a half has variance 2 sigma^2 / (n/2) under white noise
    sd = np.sqrt(2.0 * (r1**2 / h + r2**2 / (n - h)))
    d = abs(X2 - X1)
    ref = max(abs(X1), abs(X2), 1e-300)
    return d / ref, d / max(sd, 1e-300), abs(X2) / max(abs(X1), 1e-300)


def record_flags(signals, *, channels=("force", "accel"), n_harmonics=None) -> tuple:
    """Plausibility flags of one steady-state record.

    Parameters
    ----------
    signals : StateSignals
        The record reduced to its state signals (its force and measured acceleration are used).
    channels : (str, str)
        Names of the force and acceleration channels in the messages.
    n_harmonics : int, optional
        Harmonics fitted to the force (default: those of the acceleration fit).

    Returns
    -------
    tuple of Flag
        Empty for a plausible record.
    """
    t, Q, a = signals.t, signals.force, signals.accel_measured
    n = t.size
    acc = signals.acceleration
    H = n_harmonics or acc.n_harmonics
    omega = signals.omega
    fQ, rQ = fit_harmonics(t, Q, omega, H, channel=channels[0], t0=acc.t0)
    flags = []
    for ch, x in zip(channels, (Q, a)):
        f = clipping_flag(x, ch)
        if f is not None:
            flags.append(f)
    fitted = ((channels[0], fQ, Q), (channels[1], acc, a))
    work = np.empty(n)  # one residual at a time, the only array as long as the record
    sigma = {}
    for ch, series, x in fitted:
        sigma[ch] = _residual_sigma(t, x, series, work)
        f = _dead_flag(series, sigma[ch], x, n, ch)
        if f is not None:
            flags.append(f)
    del work
    if any(f.name == "dead_channel" for f in flags):
        return tuple(flags)  # the other checks compare signals that are not there
    for ch, series, x in fitted:
        f = _spike_flag(t, x, series, sigma[ch], ch)
        if f is not None:
            flags.append(f)

    # steady state: the fundamental of the first and second halves
    if n >= 8 * (2 * H + 1):
        worst = None
        for ch, x in zip(channels, (Q, a)):
            rel, z, ratio = _halves_flag(t, x, omega, H, acc.t0, ch)
            if z > Z_LIMIT and rel > TRANSIENT_FLOOR and (worst is None or rel > worst[1]):
                worst = (ch, rel, z, ratio)
        if worst is not None:
            ch, rel, z, ratio = worst
            flags.append(Flag("transient", f"channel {ch!r}: the fundamental of the second half differs from the "
                                           f"first half's by {100 * rel:.1f} % (amplitude ratio {ratio:.3f}, noise "
                                           f"z = {z:.1f}); not in steady state",
                              {"channel": ch, "relative_change": rel, "amplitude_ratio": ratio, "z": z}))

    # input power <Q q'> from the harmonic coefficients, and its noise
    V = signals.velocity.coefficients
    F = fQ.coefficients
    k = np.arange(1, H + 1)
    P = 0.5 * float(np.dot(F[1:], V[1:]))
    sa = signals.accel_residual_rms
    var = rQ**2 * float(np.dot(V[1:], V[1:])) / (2 * n)
    Fk2 = F[1::2] ** 2 + F[2::2] ** 2
    var += float(np.sum(Fk2 * sa**2 / (2 * n * (k * omega) ** 2)))
    se = np.sqrt(var)
    if P < -Z_LIMIT * se:
        thd = _distortion(F), _distortion(acc.coefficients)
        swapped = thd[0] > 2.0 * thd[1]
        name = "channel_swap" if swapped else "negative_input_power"
        cause = (f"the force is the more distorted channel (distortion {thd[0]:.3g} vs {thd[1]:.3g}): "
                 f"force and acceleration swapped?" if swapped else
                 "a flipped sign of the force or acceleration, or a timing offset between them")
        flags.append(Flag(name, f"mean input power <Q q'> = {P:.4g} is negative (noise z = {P / se:.1f}); a passive "
                                f"joint dissipates: {cause}",
                          {"input_power": P, "input_power_stderr": se, "force_distortion": thd[0],
                           "accel_distortion": thd[1]}))
    return tuple(flags)


def _distortion(coefficients) -> float:
    """Harmonics 2..H relative to the fundamental (total harmonic distortion)."""
    c = np.asarray(coefficients, float)
    amp = np.hypot(c[1::2], c[2::2])
    return float(np.sqrt(np.sum(amp[1:] ** 2)) / max(amp[0], 1e-300))


def equivalent_damping(force_coefficients, velocity_coefficients, omega, sigma_force, sigma_accel, n_samples):
    """Equivalent viscous damping ``c_eq = <Q q'> / <q'^2>`` of a steady-state record and its standard error.

    Over a period the inertia and every conservative force do no work, so the mean input
    power ``<Q q'>`` is the power the joint dissipates, and ``c_eq`` is the viscous damping
    that dissipates as much at the record's velocity.  It needs no model: the same number
    whatever damping terms (``q'``, ``|q'|q'``, ``q'^3``) share the dissipation in a fit.  A
    force or acceleration in the wrong unit scales it by the unit's factor.

    Parameters
    ----------
    force_coefficients, velocity_coefficients : array
        Harmonic coefficients ``[a0, a1, b1, a2, b2, ...]`` of the force and the velocity on
        the same basis.
    omega : float
        Excitation frequency [rad/s].
    sigma_force, sigma_accel : float
        White-noise standard deviations of the force and the acceleration.
    n_samples : int

    Returns
    -------
    (c_eq, stderr) : (float, float)
        First-order standard error from the noise of the harmonic coefficients (each cos/sin
        coefficient has variance ``2 sigma^2 / n``; a velocity coefficient of harmonic ``k`` is
        an acceleration coefficient divided by ``k omega``).

    Examples
    --------
    >>> w = 10.0
    >>> c, se = equivalent_damping([0, 3.0, 0.5], [0, 0.0, 0.1], w, 0.0, 0.0, 1000)
    >>> round(c, 12), se
    (5.0, 0.0)
    """
    F = np.asarray(force_coefficients, float)[1:]
    V = np.asarray(velocity_coefficients, float)[1:]
    m = min(F.size, V.size)
    F, V = F[:m], V[:m]
    vv = float(V @ V)
    if not vv > 0:
        return float("nan"), float("nan")
    c = float(F @ V) / vv
    k = np.repeat(np.arange(1, m // 2 + 1), 2)[:m]
    var = 2.0 * float(sigma_force) ** 2 / (n_samples * vv)
    var += float(np.sum((F - 2.0 * c * V) ** 2 * 2.0 * float(sigma_accel) ** 2 / (n_samples * (k * omega) ** 2))) / vv**2
    return c, float(np.sqrt(var))


def scale_outliers(values, *, factor: float, min_records: int = 3) -> dict:
    """Members of a group whose value is off from the group's median by a large factor.

    Parameters
    ----------
    values : mapping key -> float
        Positive values of one group (non-finite or non-positive values are ignored).
    factor : float
        Smallest ratio to the median that is flagged (also at least 6 robust standard
        deviations of the log values, so a group with a wide spread flags only real outliers).
    min_records : int
        Groups with fewer valid values are not checked.

    Returns
    -------
    dict key -> (ratio to the median, median)

    Examples
    --------
    >>> list(scale_outliers({0: 26.4, 1: 26.5, 2: 26.6, 3: 0.0265}, factor=3.0))
    [3]
    """
    keys = [k for k, v in values.items() if v is not None and np.isfinite(v) and v > 0]
    if len(keys) < min_records:
        return {}
    logs = np.log([values[k] for k in keys])
    med = float(np.median(logs))
    mad = 1.4826 * float(np.median(np.abs(logs - med)))
    limit = max(np.log(factor), Z_LIMIT * mad)
    median = float(np.exp(med))
    return {k: (float(values[k] / median), median)
            for k, lv in zip(keys, logs) if abs(lv - med) > limit}


def _theil_sen(lx, ly):
    """Median pairwise slope and median intercept of a line through ``(lx, ly)``."""
    i, j = np.triu_indices(lx.size, 1)
    dx = lx[j] - lx[i]
    ok = np.abs(dx) > 1e-12
    slope = float(np.median((ly[j] - ly[i])[ok] / dx[ok])) if ok.any() else 0.0
    return slope, float(np.median(ly - slope * lx))


def trend_outliers(x, y, *, factor, min_records: int = 5, max_pairs_n: int = 60, stderr=None, invariant=None,
                   _log_se=None) -> dict:
    """Members of a group far off the group's power-law trend ``y ~ x^p``.

    A straight line through ``(log x, log y)`` of the other members is fitted robustly
    (Theil-Sen: the median of the pairwise slopes, then the median intercept) and a member
    whose ``y`` is off that line by more than ``factor`` (and by more than 6 robust standard
    deviations of the others' residuals) is returned.  Beyond the others' range of ``x`` the
    line is an extrapolation: its uncertainty there, ``SLOPE_Z`` standard errors of the slope
    times the distance, is taken off the residual first (the resonant record of a group often
    has ten times the others' amplitude, and their slope is poorly known when they are few
    and noisy).  Used for the damping coefficient
    against the amplitude: ``c`` changes with ``q_max`` along the damping law, but a record
    in other units falls off that law.  Groups of more than ``max_pairs_n`` members use one
    line through all of them (one outlier cannot move it).

    With ``invariant``, the check asks the question a unit error poses: a factor ``s`` on one
    channel moves a member along a known direction, ``(log x, log y) + log s * (1, invariant)``
    (for ``c_eq`` against ``q_max`` a factor on the acceleration multiplies ``q_max`` by ``s`` and
    ``c_eq`` by ``1 / s``: ``invariant = -1``, the product ``c_eq q_max`` is unchanged).  The factor
    that takes the member back onto the line, ``s`` with ``log s = r / (invariant - p)`` for a
    residual ``r`` and slope ``p``, must then also exceed ``factor``, with the line's
    extrapolation uncertainty taken where the member would land.  On a flat trend that is the
    residual itself; where ``y`` grows steeply with ``x`` (the dissipation of a friction joint
    setting in as it starts to slip) a record of a sticking joint below the others' amplitudes
    lies below their line, yet no unit factor puts it on that line inside their range.

    Parameters
    ----------
    x, y : mapping key -> float
        Positive values (others are ignored); the keys of ``y`` are the members.
    factor : float or (float, float)
        Smallest ratio to the trend that is flagged, or ``(below, above)``: the factors for
        values below and above the trend (a damping law that grows faster than a power law
        puts its largest-amplitude record above the line of the others).
    stderr : mapping key -> float, optional
        Standard error of each ``y``: a member is then flagged only when it is also more than
        ``Z_LIMIT`` of its standard errors off the trend (a value the record does not
        resolve is no outlier), and members whose ``y`` is not resolved to better than a
        factor of 2 (``stderr > y / 2``) do not enter the trend of the others.
    invariant : float, optional
        Log-log slope along which a scale error moves a member (above); ``None``: the
        residual alone is judged.

    Returns
    -------
    dict key -> (ratio to the trend, trend value, scale factor)
        The scale factor is the factor along ``invariant`` that takes the member onto the
        trend (the ratio itself without ``invariant``).

    Examples
    --------
    >>> q = {i: 1e-3 * (i + 1) for i in range(8)}
    >>> c = {i: 0.1 + 50 * q[i] for i in range(8)}
    >>> c[3] *= 9.81
    >>> list(trend_outliers(q, c, factor=3.0))
    [3]
    """
    keys = [k for k in y if k in x and all(v is not None and np.isfinite(v) and v > 0 for v in (x[k], y[k]))]
    se = {k: float(stderr[k]) if stderr is not None and stderr.get(k) is not None and np.isfinite(stderr[k]) else 0.0
          for k in keys}
    if stderr is not None:  # the trend from the values the records resolve
        resolved = [k for k in keys if se[k] <= 0.5 * y[k]]
        out = {}
        if len(resolved) >= min_records:
            out = trend_outliers(x, {k: y[k] for k in resolved}, factor=factor, min_records=min_records,
                                 max_pairs_n=max_pairs_n, invariant=invariant,
                                 _log_se={k: se[k] / y[k] for k in resolved})
        return {k: v for k, v in out.items() if abs(y[k] - v[1]) > Z_LIMIT * se[k]}
    n = len(keys)
    if n < min_records:
        return {}
    lx = np.log([x[k] for k in keys])
    ly = np.log([y[k] for k in keys])
    lse = np.array([(_log_se or {}).get(k, 0.0) for k in keys])
    order = np.sort(lx)

    def beyond(m, slope, icpt, mad, ox, ose):
        """Residual of member ``m`` against the line, less the line's own uncertainty where it is
        extrapolated beyond the others' range of ``x`` (``SLOPE_Z`` standard errors of the slope,
        from the others' scatter about it or their own standard errors, whichever is larger); and
        the log of the scale factor along ``invariant`` that takes it onto the line, less the same
        uncertainty where it lands."""
        lo, hi = (order[1], order[-1]) if lx[m] == order[0] else (order[0], order[-2] if lx[m] == order[-1] else order[-1])
        r = ly[m] - slope * lx[m] - icpt
        sxx = float(np.sum((ox - ox.mean()) ** 2))
        scatter = max(mad, float(np.sqrt(np.mean(ose**2))) if ose.size else 0.0)
        s_slope = scatter / np.sqrt(sxx) if sxx > 0 else np.inf

        def band(at):  # the line's uncertainty at log x = at, beyond the others' range
            d = abs(at - min(max(at, lo), hi))
            return SLOPE_Z * s_slope * d if d > 0 else 0.0

        vertical = float(np.sign(r) * max(abs(r) - band(lx[m]), 0.0))
        if invariant is None:
            return vertical, r, mad, vertical, r
        gap = float(invariant) - slope  # the direction a scale error moves along, against the line's slope
        if abs(gap) < 1e-12:  # parallel: no scale factor takes the member onto the line
            return vertical, r, mad, 0.0, np.inf
        ls = r / gap  # log s: the member is at (true point) + ls * (1, invariant), the true point on the line
        return vertical, r, mad, float(np.sign(ls) * max(abs(ls) - band(lx[m] - ls) / abs(gap), 0.0)), ls

    if n > max_pairs_n:
        sub = np.linspace(0, n - 1, max_pairs_n).astype(int)  # the line from a spread subset
        slope, icpt = _theil_sen(lx[sub], ly[sub])
        r_all = ly - slope * lx - icpt
        mad = 1.4826 * float(np.median(np.abs(r_all)))
        fits = [beyond(m, slope, icpt, mad, lx, lse) for m in range(n)]
    else:
        fits = []
        for m in range(n):
            others = np.arange(n) != m
            slope, icpt = _theil_sen(lx[others], ly[others])
            r = ly[others] - slope * lx[others] - icpt
            fits.append(beyond(m, slope, icpt, 1.4826 * float(np.median(np.abs(r))), lx[others], lse[others]))
    below, above = (factor, factor) if np.isscalar(factor) else factor
    out = {}
    for k, (rk, r_line, mad, ls, ls_line) in zip(keys, fits):
        if abs(rk) > max(np.log(below if rk < 0 else above), Z_LIMIT * mad) and abs(ls) > np.log(below if r_line < 0
                                                                                                 else above):
            out[k] = (float(np.exp(r_line)), float(y[k] / np.exp(r_line)), float(np.exp(ls_line)))
    return out


def monotone_outliers(x, y, *, factor, stderr=None, min_records: int = 3, along: str = "y") -> dict:
    """Members of a group that break the rule "``y`` does not decrease as ``x`` grows" by a large factor.

    A pair of members breaks it when the one with the smaller ``x`` has the larger ``y``, by more
    than ``factor`` and by more than ``Z_LIMIT`` standard errors of the difference.  Members are
    taken out one at a time, first the one in the most such pairs (then the one with the largest
    factor), until no pair is left: one wrong member breaks the rule with many others, each of
    them only with it.  Used for the energy a joint dissipates per cycle over its amplitude,
    ``W / (pi q_max) = c_eq omega q_max``: for viscous, Coulomb, polynomial and Masing-type
    friction damping (Jenkins, Iwan) ``W`` is convex in the amplitude and zero at zero, so
    ``W / q_max`` does not decrease.  A force in other units multiplies it by the unit's factor at
    the same amplitude; an acceleration in other units leaves it unchanged and moves the
    amplitude: that break is measured along ``x`` (``along="x"``), as the factor by which the
    member's ``x`` would have to move for the pair to keep the rule.

    Parameters
    ----------
    x, y : mapping key -> float
        Positive values (others are ignored); the keys of ``y`` are the members.
    factor : float or (float, float)
        Smallest ratio that is flagged, or ``(below, above)``: for a member whose ``y`` is below
        that of a member with a smaller ``x``, and for one whose ``y`` is above that of a member
        with a larger ``x``.
    stderr : mapping key -> float, optional
        Standard error of each ``y``.
    along : {"y", "x"}
        The factor of a breaking pair: the ratio of its ``y`` (the larger over the smaller), or of
        its ``x`` (the larger over the smaller; the pair's ``y`` must still differ by ``Z_LIMIT``
        standard errors).  With ``"x"``, ``below`` applies to the member with the larger ``x``
        (its ``x`` too large) and ``above`` to the one with the smaller ``x``.

    Returns
    -------
    dict key -> factor
        The largest factor by which the member breaks the rule (> 1).

    Examples
    --------
    >>> q = {i: 1e-3 * (i + 1) for i in range(6)}
    >>> w = {i: 5.0 * q[i] + 0.01 for i in range(6)}
    >>> w[3] /= 9.81
    >>> {k: round(v, 3) for k, v in monotone_outliers(q, w, factor=3.0).items()}
    {3: 8.175}
    >>> w = {i: 5.0 * q[i] + 0.01 for i in range(6)}
    >>> q[5] /= 9.81
    >>> {k: round(v, 3) for k, v in monotone_outliers(q, w, factor=3.0, along="x").items()}
    {5: 8.175}
    """
    if along not in ("x", "y"):
        raise ValueError(f"along must be 'x' or 'y', not {along!r}")
    keys = [k for k in y if k in x and all(v is not None and np.isfinite(v) and v > 0 for v in (x[k], y[k]))]
    if len(keys) < min_records:
        return {}
    below, above = (factor, factor) if np.isscalar(factor) else factor
    se = {k: float(stderr[k]) if stderr is not None and stderr.get(k) is not None and np.isfinite(stderr[k]) else 0.0
          for k in keys}

    def breaks(a, b):  # x[a] < x[b] and y[a] > y[b] beyond the factor and the noise: (ratio, which side is odd)
        if not x[a] < x[b]:
            a, b = b, a
        if not x[a] < x[b] or y[a] <= y[b] + Z_LIMIT * float(np.hypot(se[a], se[b])):
            return None
        ratio = y[a] / y[b] if along == "y" else x[b] / x[a]
        return ratio if ratio > min(below, above) else None

    pairs = {}
    for i, a in enumerate(keys):
        for b in keys[i + 1:]:
            r = breaks(a, b)
            if r is not None:
                pairs[(a, b) if x[a] < x[b] else (b, a)] = r
    out = {}
    while pairs:
        count = {}
        for (lo, hi), r in pairs.items():
            for k, side in ((lo, above), (hi, below)):  # lo's y too high (above), hi's y too low (below)
                if r > side:
                    n, worst = count.get(k, (0, 1.0))
                    count[k] = (n + 1, max(worst, r))
        if not count:
            break
        k = max(count, key=lambda m: count[m])
        out[k] = float(count[k][1])
        pairs = {p: r for p, r in pairs.items() if k not in p}
    return out
