"""The analytic frequency derivative of a record's regression (uncertainty.FrequencySums).

A record whose frequency is estimated carries the estimate's error into every
coefficient: the regression is redone at another frequency (harmonic fit of the
acceleration, integration, regression).  ``RecordScores.frequency_score`` gives
``M d theta / d omega`` from sums of the one streamed pass; here it is checked against
that refit done for real at ``omega +- h`` (central differences, Richardson-extrapolated).
"""

from dataclasses import replace

import numpy as np
import pytest

from jointid.identify.regression import lstsq_from_reduced
from jointid.identify.terms import library
from jointid.identify.uncertainty import record_pass
from jointid.signal.harmonics import fit_harmonics, steady_state_signals
from jointid.simulate.hbm import steady_state
from jointid.simulate.model import seed_model


def _refit(lib, sig, filtered, omega):
    """Coefficients of the record analysed at ``omega``: harmonic fit and regression redone."""
    series, rms = fit_harmonics(sig.t, sig.accel_measured, omega, sig.acceleration.n_harmonics,
                                t0=sig.acceleration.t0)
    s = replace(sig, acceleration=series, frequency_hz=omega / (2 * np.pi), accel_residual_rms=rms)
    R, _ = record_pass(lib, s, filtered)
    p = len(lib)
    return lstsq_from_reduced(R[:, :p], R[:, p], s.t.size).coefficients


def _numerical_score(lib, sig, filtered, R, rel_step):
    p = len(lib)
    M = R[:, :p].T @ R[:, :p]
    d = []
    for h in (rel_step * sig.omega, 0.5 * rel_step * sig.omega):
        d.append((_refit(lib, sig, filtered, sig.omega + h) - _refit(lib, sig, filtered, sig.omega - h)) / (2 * h))
    return M @ ((4 * d[1] - d[0]) / 3)


@pytest.mark.parametrize("terms", ["q + -q^3 + q'", "q + q^2 + |q|q + q^2 q' + q'^3"])
@pytest.mark.parametrize("filtered", [True, False])
@pytest.mark.parametrize("n, fs, jitter", [(60000, 20000.0, False), (5000, 4000.0, False), (20001, 3000.0, True)])
def test_frequency_score_is_the_derivative_of_the_refit(terms, filtered, n, fs, jitter):
    rng = np.random.default_rng(n)
    state = steady_state(seed_model(), 169.0, 1.0, n_harmonics=9)
    t = np.arange(n) / fs + 0.1
    if jitter:  # time stamps off the uniform grid: the general path (as for records under two tables)
        t = t + 1e-7 / fs * rng.standard_normal(n)
    Q, a = state.force(t), state.acceleration(t)
    Q = Q + 0.01 * Q.std() * rng.standard_normal(n)
    a = a + 0.01 * a.std() * rng.standard_normal(n)
    sig = steady_state_signals(t, Q, a, n_harmonics=5)
    assert not sig.frequency_given
    lib = library(terms)
    R, scores = record_pass(lib, sig, filtered)
    p = len(lib)
    theta = lstsq_from_reduced(R[:, :p], R[:, p], n).coefficients
    analytic = scores.frequency_score(theta)
    numerical = _numerical_score(lib, sig, filtered, R, 1e-4)
    assert np.abs(analytic - numerical).max() <= 2e-3 * np.abs(numerical).max()


def test_given_frequency_has_no_frequency_sums():
    t = np.arange(20000) / 4000.0
    sig = steady_state_signals(t, np.sin(30 * t), -np.sin(30 * t) / 900, frequency_hz=30 / (2 * np.pi))
    _, scores = record_pass(library("q + q'"), sig)
    assert scores.omega_sums is None and scores.omega_variance == 0.0


def test_declared_constant_derivatives_match_the_derivatives():
    """A term's ``dq_const``/``dv_const`` (used to skip sums) equal its derivative everywhere."""
    from jointid.identify.terms import STANDARD_TERMS

    rng = np.random.default_rng(0)
    q, v = rng.standard_normal(1000), rng.standard_normal(1000)
    declared = 0
    for t in STANDARD_TERMS.values():
        gq, gv = t.derivatives(q, v)
        for const, g in ((t.dq_const, gq), (t.dv_const, gv)):
            if const is not None:
                declared += 1
                assert np.all(g == const), t.name
    assert declared >= 10
