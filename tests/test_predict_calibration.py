"""Calibration of the standard errors of a hysteretic law's predicted peak (``jointid predict`` with a selected law).

Monte Carlo over noisy campaigns of the Jenkins and the discrete Iwan single-mode joints of
``test_hysteretic_fsm`` (time integration, 0.5 % noise; one clean campaign, the noise drawn anew each
time), fitted on the two lower force levels, predicting the top level and a level 1.75 x the top fitted
one.  Per campaign the prediction error is the delta method's linearisation ``J (theta_hat - theta)``
(``J``: the predictor's derivatives at the true parameters, the same band fit and time samples as
``predict``), its standard error ``sqrt(J C J^T)`` with the campaign's own covariance ``C``; to it is
added the predictor's own error at the true parameters: the peak of the true law by ``predict``'s
``hysteretic_response`` (512 samples) against the same law's peak at 1024 samples (the sampled slider
force's error falls as ``N^-2``).  A full ``predict`` per campaign (~30 s) would not fit in the test's time.
"""

import warnings

import numpy as np
import pytest
from test_hysteretic_fsm import campaign, noisy
from test_predict_hysteretic import CASES, true_model

from jointid.app.predict_hysteretic import (
    INDEPENDENT,
    _band_peak,
    hysteretic_response,
)
from jointid.identify.hysteretic import HystereticForceStateMapping

N_CAMPAIGNS = 30


@pytest.mark.slow
@pytest.mark.parametrize("name", list(CASES))
def test_peak_standard_errors_are_calibrated(name):
    law, levels, span = CASES[name]
    data = campaign(law, levels[:2], span)
    rng = np.random.default_rng(2024)
    names = INDEPENDENT[name]
    th, cv = [], []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for _ in range(N_CAMPAIGNS):
            res = HystereticForceStateMapping(name).fit(noisy(data, rng)).result_
            idx = [res.names.index(n) for n in names]
            th.append(res.values[idx])
            cv.append(res.covariance[np.ix_(idx, idx)])
    th, cv = np.array(th), np.array(cv)
    tm = true_model(law)
    idx = [tm.names.index(n) for n in names]
    theta = tm.values[idx]
    step = np.sqrt(np.diag(cv.mean(axis=0)))
    for Q in (levels[2], 1.75 * levels[1]):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            out = hysteretic_response(tm, Q, (28.0, 34.0), 5, uncertainty=False)  # what predict gives
            omegas, sol = out["peak_band"]
            base = (*out["peak"], sol)
            ref = _band_peak(tm.engine(), Q, omegas, sol, 5, n_time=1024)  # the reference: 1024 samples
            J = np.zeros((2, len(idx)))
            for j, k in enumerate(idx):
                vp, vm = tm.values.copy(), tm.values.copy()
                vp[k] += step[j]
                vm[k] -= step[j]
                if tm.names[k] == "beta":
                    vm[k] = max(vm[k], 0.0)  # the law's domain
                pp = _band_peak(tm.engine(vp), Q, omegas, base[2], 5)
                pm = _band_peak(tm.engine(vm), Q, omegas, base[2], 5)
                J[:, j] = (np.array(pp[:2]) - np.array(pm[:2])) / (vp[k] - vm[k])
        pred = np.array(base[:2]) + (th - theta) @ J.T
        se = np.sqrt(np.einsum("ij,njk,ik->ni", J, cv, J))
        z = (pred - np.array(ref[:2])) / se
        frac = np.mean(np.abs(z) < 1.96, axis=0)
        print(f"\n{name} Q = {Q:g}: predictor vs 1024 samples f {base[0] / ref[0] - 1:+.2e} "
              f"q {base[1] / ref[1] - 1:+.2e};"
              f" mean z {np.round(z.mean(axis=0), 2)}, sd {np.round(z.std(axis=0, ddof=1), 2)}, |z| < 1.96: {frac}")
        assert np.all((frac >= 0.85) & (frac <= 1.0)), frac
        # the mean within 4 standard errors of the mean of n calibrated z (0.73 for 30): the 7-point parabola's
        # bias at the true law was -65 se (Jenkins Q = 14, fallen back to 128 samples) and +3 se (Q = 17.5);
        # measured now +0.53 / +0.59 (seed 2024), +0.03 / +0.14 (another 30): a shift of about 0.3-0.6 se may
        # remain (open; suspected: the generator's RK4 holds the sliders over a step)
        assert np.all(np.abs(z.mean(axis=0)) < 4.0 / np.sqrt(len(z))), z.mean(axis=0)
