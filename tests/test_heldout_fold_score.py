"""Held-out scoring: when the dwells resolve a level's peak, every model is scored on that peak, also a model with
a fold among the three dwells about it (compared on the dwells' own branch); it was let off to the rms of the
dwell errors, a milder score of another kind, which chose a spurious fold over better models (issue 22, rig at
120 N)."""

import math

import numpy as np

from jointid.identify.heldout import PolynomialFirstHarmonic, level_errors
from jointid.identify.terms import library

K = (2 * np.pi * 30.0) ** 2
C = 2 * 0.015 * math.sqrt(K)


def test_a_fold_at_the_peak_is_scored_on_the_peak():
    w0, Q = math.sqrt(K), 1.0
    a_lin = Q / (C * w0)
    fh = PolynomialFirstHarmonic(library("q + -q^3 + q'"), (0, 0, 0), [K, 0.08 * K / (0.75 * a_lin**2), C])
    wp, ap = fh.peak(Q, w0)
    w = wp * (1 + np.linspace(0.0, 0.004, 5))  # three steady states at each: the upper branch measured
    upper = np.array([fh.response(Q, x, a_hint=ap).max() for x in w])
    same = level_errors(fh, Q, w, upper)
    assert np.all(same.n_branches == 3) and same.score < 1e-6
    bump = upper * np.array([1.0, 1.03, 1.0, 1.0, 1.0])  # the data's peak 3 % above the model's
    lp = level_errors(fh, Q, w, bump)
    rms_dwells = float(np.sqrt(np.mean((lp.dwell_errors_percent / 100) ** 2)))
    assert not lp.peak_resolved  # a fold among the three dwells: not quoted as a resolved peak ...
    assert lp.score > 0.02 and lp.score > 1.5 * rms_dwells  # ... but scored on it, not on the milder rms
