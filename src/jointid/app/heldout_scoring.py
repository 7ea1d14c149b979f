"""Held-out scoring that needs the multi-harmonic balance of ``jointid.simulate``.

The model selection (:func:`jointid.identify.selection.select_model`) predicts a held-out
force level by first-harmonic balance inside ``identify``, which must not depend on
``simulate``.  This module, one floor above both, turns a fitted polynomial preload model into
a :class:`~jointid.simulate.model.SingleModeModel` (:func:`single_mode_model`) and offers
:func:`harmonic_balance_predictor`, a ``predictor`` for ``select_model`` that solves the
held-out dwells by multi-harmonic balance instead, each on the branch nearest the measured
amplitude.
"""

from __future__ import annotations

import warnings

import numpy as np

from ..identify.model import law_size
from ..identify.powerlaw import PowerLaw, is_power

__all__ = ["single_mode_model", "harmonic_balance_predictor"]


def single_mode_model(lib, orders, theta):
    """The :class:`~jointid.simulate.model.SingleModeModel` of fitted preload-model parameters."""
    from ..simulate.model import SingleModeModel

    coefs, laws, k = [], {}, 0
    for t, L in zip(lib, orders):
        n = law_size(L)
        if n == 1:
            coefs.append(float(theta[k]))
        else:
            coefs.append(0.0)
            laws[t.coefficient] = (PowerLaw(*theta[k:k + 3]) if is_power(L)
                                   else tuple(float(x) for x in theta[k : k + L + 1]))
        k += n
    return SingleModeModel(lib, tuple(coefs), laws)


def harmonic_balance_predictor(n_harmonics=5):
    """A ``predictor`` for :func:`~jointid.identify.selection.select_model`: held-out dwells by harmonic balance.

    The model is continued over the held-out frequencies at the level's forcing; at a dwell
    where the continuation passes a fold, the solution nearest the measured amplitude is used.
    """
    from ..simulate.hbm import frequency_response

    def predict(candidate, fitted, forcing, omegas, a_measured):
        lib, orders, theta = fitted
        model = single_mode_model(lib, orders, theta)
        w = np.asarray(omegas, float)
        am = np.asarray(a_measured, float)
        lo, hi = float(w.min()), float(w.max())
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            frf = frequency_response(model, forcing, omega_range=(lo * 0.999, hi * 1.001), n_harmonics=n_harmonics,
                                     stability=False, max_steps=2000)
        fw = np.asarray(frf.omega, float)
        fa = np.asarray(frf.amplitude, float)
        out = np.full(w.size, np.inf)
        for i, (wi, ai) in enumerate(zip(w, am)):
            # every crossing of the continued curve with omega = wi (one, or three at a fold)
            cands = []
            for j in range(fw.size - 1):
                if (fw[j] - wi) * (fw[j + 1] - wi) <= 0 and fw[j] != fw[j + 1]:
                    s = (wi - fw[j]) / (fw[j + 1] - fw[j])
                    cands.append(fa[j] + s * (fa[j + 1] - fa[j]))
            if cands:
                out[i] = min(cands, key=lambda x: abs(np.log(x / ai)))
        return out

    return predict
