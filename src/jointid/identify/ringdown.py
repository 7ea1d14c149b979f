"""Force-state mapping on a free decay (ring-down).

The signal floor (:mod:`jointid.signal.ringdown`) cuts an acceleration record into windows,
fits one damped oscillation in each and reconstructs the states ``(q, q', q'')`` there.
Here ``-q''`` is regressed on the restoring-force terms window by window, which gives, for
``"q + q'"``, the equivalent stiffness and damping of each window against its amplitude.
"""

from __future__ import annotations

import numpy as np

from ..errors import RecordError
from ..signal.ringdown import DecayFit
from .terms import library

__all__ = ["ringdown_force_state_mapping"]


def ringdown_force_state_mapping(decay: DecayFit, t, accel, terms="q + q'"):
    """Force-state mapping on a free decay: ``-q''`` regressed on the terms, window by window.

    Parameters
    ----------
    decay : DecayFit
        From :func:`jointid.signal.ringdown.fit_decay` of the same acceleration record (its states are used).
    t, accel : array
        The record (measured ``q''``).
    terms : str or TermLibrary
        Restoring-force terms; ``"q + q'"`` gives the equivalent stiffness and damping of
        each window.

    Returns
    -------
    coefficients, stderr : ndarray, shape (n_windows_used, n_terms)
    amplitude : ndarray
        Window amplitudes (``decay.amplitude`` above the noise floor).
    """
    if decay.kind != "acceleration":
        raise RecordError(f"the free-decay force-state mapping needs an acceleration record, got {decay.kind!r}")
    lib = library(terms)
    coef, se = [], []
    for _, q, v, acc in decay.states(t, accel):
        X = lib.evaluate(q, v)
        y = -acc
        scale = np.max(np.abs(X), axis=0)
        scale[scale == 0] = 1.0
        c, *_ = np.linalg.lstsq(X / scale, y, rcond=None)
        r = y - (X / scale) @ c
        s2 = float(r @ r) / max(y.size - len(lib), 1)
        cov = np.linalg.pinv((X / scale).T @ (X / scale)) * s2
        coef.append(c / scale)
        se.append(np.sqrt(np.clip(np.diag(cov), 0, None)) / scale)
    return np.array(coef), np.array(se), decay.amplitude[~decay.below_noise_floor]
