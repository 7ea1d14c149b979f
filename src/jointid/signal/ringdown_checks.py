"""Plausibility checks of a ring-down's decay fit: named flags with the numbers that triggered them.

A ring-down record is a free decay: its amplitude falls, its damping ratio is positive and
its windows hold an oscillation well above the noise.  :func:`ringdown_flags` looks at the
windowed fit of :func:`jointid.signal.ringdown.fit_decay` and returns a
:class:`~jointid.signal.checks.Flag` for each way the record fails that:

``ringdown_noise``
    Most windows are below the noise floor, or the fitted oscillation leaves a residual as
    large as itself (median relative residual above :data:`MAX_STATE_ERROR`): noise, not a
    decay.
``ringdown_growing``
    The damping ratio is negative beyond its noise (``Z`` standard errors): the amplitude
    grows -- a driven or unstable response, not a free decay of a passive joint.
``ringdown_no_decay``
    The damping ratio is not resolved from zero (within ``Z`` standard errors): a steady
    sine, or a record too short for its damping.
``ringdown_short``
    Fewer than :data:`MIN_WINDOWS` windows: too few amplitudes for a backbone.
"""

from __future__ import annotations

import numpy as np

from .checks import Flag

__all__ = ["ringdown_flags", "MAX_STATE_ERROR", "MIN_WINDOWS", "ZETA_Z"]

#: Median relative residual of the windows' oscillation fits above which the record is noise.
MAX_STATE_ERROR = 0.5
#: Fewest windows of a usable decay.
MIN_WINDOWS = 3
#: Standard errors by which the damping ratio must differ from zero.
ZETA_Z = 3.0


def ringdown_flags(decay, channel: str = "accel") -> list:
    """Flags of a :class:`~jointid.signal.ringdown.DecayFit` (empty for a plausible free decay)."""
    zeta = np.asarray(decay.zeta, float)
    se = np.asarray(decay.zeta_stderr, float)
    n = zeta.size
    floor = np.asarray(decay.below_noise_floor, bool)
    err = np.asarray(decay.state_error, float)
    med_err = float(np.median(err)) if n else float("nan")
    if n == 0 or 2 * int(floor.sum()) > n or not med_err <= MAX_STATE_ERROR:
        return [Flag("ringdown_noise", f"channel {channel!r}: {int(floor.sum())} of {n} windows below the noise "
                                       f"floor, median residual {med_err:.3g} of the fitted oscillation (at most "
                                       f"{MAX_STATE_ERROR:g}): noise, not a free decay",
                     {"windows": n, "below_noise_floor": int(floor.sum()), "median_state_error": med_err})]
    flags = []
    if n < MIN_WINDOWS:
        flags.append(Flag("ringdown_short", f"channel {channel!r}: the decay gives {n} window(s) of "
                                            f"{decay.n_cycles:g} periods (at least {MIN_WINDOWS} for a backbone)",
                          {"windows": n, "window_periods": float(decay.n_cycles)}))
    good = ~floor & np.isfinite(zeta) & np.isfinite(se) & (se > 0)
    if not np.any(good):
        return flags
    w = 1.0 / se[good] ** 2
    z_mean = float(np.sum(w * zeta[good]) / np.sum(w))
    z_se = float(np.median(se[good]))  # the windows overlap: no averaging down of their errors
    amp = np.asarray(decay.amplitude, float)
    ratio = float(amp[-1] / amp[0]) if amp[0] > 0 else float("nan")
    values = {"zeta": z_mean, "zeta_stderr": z_se, "last_over_first_amplitude": ratio, "windows": n}
    if z_mean < -ZETA_Z * z_se:
        flags.append(Flag("ringdown_growing", f"channel {channel!r}: damping ratio {z_mean:.3g} ± {z_se:.2g} is "
                                              f"negative, the amplitude grows by {ratio:.4g} over the record: not a "
                                              "free decay of a passive joint", values))
    elif abs(z_mean) <= ZETA_Z * z_se:
        flags.append(Flag("ringdown_no_decay", f"channel {channel!r}: damping ratio {z_mean:.3g} ± {z_se:.2g} is not "
                                               f"resolved from zero (last/first amplitude {ratio:.4g}): a steady "
                                               "oscillation, or a record too short for its damping", values))
    return flags
