"""Peaks of sampled curves: a parabola through the top three samples, and refinement by halving.

Used for resonance peaks of frequency responses (the rig's measured and re-predicted
curves) but general: any sampled ``y(x)`` with one peak inside the samples.
"""

from __future__ import annotations

import numpy as np

__all__ = ["parabolic_peak", "refine_peak"]


def parabolic_peak(x, y) -> tuple[float, float]:
    """Peak of sampled ``y(x)`` refined by a parabola through the largest sample and its neighbours."""
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    i = int(np.argmax(y))
    if i == 0 or i == y.size - 1:
        return float(x[i]), float(y[i])
    xs = x[i - 1 : i + 2] - x[i]  # centred for conditioning
    a, b, c = np.polyfit(xs, y[i - 1 : i + 2], 2)
    if a >= 0:
        return float(x[i]), float(y[i])
    xp = -b / (2 * a)
    return float(x[i] + xp), float(np.polyval([a, b, c], xp))


def refine_peak(fun, x, y, xtol, max_iter: int = 60) -> tuple[np.ndarray, np.ndarray]:
    """Samples of a peak refined by halving the two intervals beside the largest sample.

    A parabola through three samples ``h`` apart misplaces an asymmetric peak (a softening
    or hardening resonance) by an amount that falls as ``h^2``; halving the intervals
    beside the largest sample until both are at most ``xtol`` makes that error negligible
    against ``xtol``.  The largest sample always stays bracketed by its neighbours, so a
    single peak inside the samples is not lost.

    Parameters
    ----------
    fun : callable
        ``fun(x_new) -> y_new``: the sampled function at an array of new abscissae.
    x, y : array_like
        The samples so far (any order).
    xtol : float
        Largest interval left beside the largest sample.
    max_iter : int
        Most halvings.

    Returns
    -------
    x, y : ndarray
        All samples, sorted by ``x``; :func:`parabolic_peak` of them is the refined peak.
        A largest sample at either end is left as it is (no peak is bracketed).

    Examples
    --------
    >>> f = lambda x: 1.0 / ((1.0 - x**2) ** 2 + (0.02 * x) ** 2)
    >>> x0 = np.linspace(0.9, 1.1, 5)
    >>> xs, ys = refine_peak(f, x0, f(x0), 1e-6)
    >>> round(parabolic_peak(xs, ys)[0], 6)
    0.9999
    """
    x = np.asarray(x, float).ravel()
    y = np.asarray(y, float).ravel()
    for _ in range(int(max_iter)):
        o = np.argsort(x, kind="stable")
        x, y = x[o], y[o]
        i = int(np.argmax(y))
        if i == 0 or i == x.size - 1:
            break
        new = [0.5 * (x[j] + x[j + 1]) for j in (i - 1, i) if x[j + 1] - x[j] > xtol]
        if not new:
            break
        x = np.concatenate([x, new])
        y = np.concatenate([y, np.asarray(fun(np.asarray(new)), float).ravel()])
    o = np.argsort(x, kind="stable")
    return x[o], y[o]
