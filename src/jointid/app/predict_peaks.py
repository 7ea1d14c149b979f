"""The response curve of a single-mode model and its peak, located between the continued points.

Shared by :mod:`jointid.app.predict` (the polynomial models) and
:mod:`jointid.app.predict_hysteretic` (the hysteretic joint laws); see :mod:`jointid.app.predict`
for how the peak is defined.
"""

from __future__ import annotations

import warnings

import numpy as np

from ..errors import JointidWarning

__all__ = ["DS_MAX", "MAX_WIDEN", "WIDEST", "predict_peak"]

#: Largest continuation step (scaled space of :func:`jointid.simulate.hbm.frequency_response`):
#: small enough that the chord-length parabola places the peak to about 1e-6 of its value.
DS_MAX = 0.005
#: Times the default band is widened on one side to bring a peak at its edge inside.
MAX_WIDEN = 6
#: The widest default band, as fractions of the model's linear natural frequency.
WIDEST = (0.5, 2.0)


# --- the harmonic balance and the peak -------------------------------------------------------------

def _curve(model, Q, span_hz, n_harmonics, stability):
    from ..simulate.hbm import frequency_response

    lo, hi = span_hz
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", JointidWarning)
        with np.errstate(all="ignore"):
            return frequency_response(model, Q, omega_range=(2 * np.pi * lo, 2 * np.pi * hi), n_harmonics=n_harmonics,
                                      stability=stability, ds_max=DS_MAX, max_steps=200_000)


def _located_peak(omega, q_max):
    """``(frequency_hz, q_max, index)`` of the largest ``q_max`` along the curve, between the
    points (parabolas in chord length through the largest point and its neighbours); ``None``
    when the largest point is an end of the curve (no peak inside the band)."""
    w = np.asarray(omega, float)
    q = np.asarray(q_max, float)
    i = int(np.argmax(q))
    if i == 0 or i == q.size - 1:
        return None
    sw = max(float(np.ptp(w)), 1e-300)
    sq = max(float(np.max(q)), 1e-300)
    ds = np.hypot(np.diff(w[i - 1:i + 2]) / sw, np.diff(q[i - 1:i + 2]) / sq)
    s = np.array([-ds[0], 0.0, ds[1]])
    if not (ds[0] > 0 and ds[1] > 0):
        return float(w[i] / (2 * np.pi)), float(q[i]), i
    h = s / max(ds)  # scaled for conditioning
    V = np.vander(h, 3)
    aq = np.linalg.solve(V, q[i - 1:i + 2])
    aw = np.linalg.solve(V, w[i - 1:i + 2])
    if not aq[0] < 0:
        return float(w[i] / (2 * np.pi)), float(q[i]), i
    hp = float(np.clip(-aq[1] / (2 * aq[0]), h[0], h[2]))
    return float(np.polyval(aw, hp) / (2 * np.pi)), float(np.polyval(aq, hp)), i


def predict_peak(model, Q, span_hz, n_harmonics=5, *, widen=True, stability=False, curve=None, f1_hz=None):
    """Continue the model's response from ``span_hz[0]`` to ``span_hz[1]`` and locate its peak.

    Returns ``(response, peak, span_hz)``: the :class:`~jointid.simulate.hbm.FrequencyResponse`,
    ``(frequency_hz, q_max, index)`` or ``None``, and the band finally used (widened on the side of
    a peak at its edge when ``widen``).  ``curve(lo_hz, hi_hz)``, with ``f1_hz``, replaces the
    harmonic balance of ``model`` (any response with ``omega`` and ``q_max`` along the curve).
    """
    lo, hi = (float(v) for v in span_hz)
    # a single-mode model says nothing far from its mode: the band is widened to at most half
    # and twice its linear natural frequency
    f1 = model.omega1 / (2 * np.pi) if f1_hz is None else float(f1_hz)
    lo_min, hi_max = min(lo, WIDEST[0] * f1), max(hi, WIDEST[1] * f1)
    for _ in range(MAX_WIDEN + 1):
        r = _curve(model, Q, (lo, hi), n_harmonics, stability) if curve is None else curve(lo, hi)
        peak = _located_peak(r.omega, r.q_max)
        if peak is not None or not widen or len(r) < 2:
            return r, peak, (lo, hi)
        width = hi - lo
        f_top = float(r.omega[int(np.argmax(r.q_max))]) / (2 * np.pi)
        if f_top - lo < hi - f_top:  # the curve leaves the band at its low edge still growing
            if lo <= lo_min:
                break
            lo = max(lo - width, lo_min)
        else:
            if hi >= hi_max:
                break
            hi = min(hi + width, hi_max)
    return r, peak, (lo, hi)
