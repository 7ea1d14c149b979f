"""Backbone curves of identified models and of stepped-sine records (closed forms and simulated data)."""

import json

import numpy as np
import pytest
from scipy import optimize

from jointid.errors import IdentificationError
from jointid.identify.backbone import (
    Backbone,
    equivalent_linearisation,
    model_backbone,
    parameter_vector,
    phase_resonance_points,
)
from jointid.signal.harmonics import steady_state_signals
from jointid.simulate.hbm import steady_state
from jointid.simulate.model import seed_model
from jointid.simulate.synth import synthesize_record


def test_duffing_and_viscous_closed_form():
    w1, k3, c = 150.0, 4e6, 0.6
    a = np.geomspace(1e-4, 3e-2, 7)
    b = model_backbone("q + -q^3 + q'", [w1**2, k3, c], a)
    w = np.sqrt(w1**2 - 0.75 * k3 * a**2)
    np.testing.assert_allclose(b.omega, w, rtol=1e-13)
    np.testing.assert_allclose(b.zeta, c / (2 * w), rtol=1e-12)
    assert np.all(np.isnan(b.omega_stderr))


def test_coulomb_equivalent_damping():
    """Coulomb friction f_c sign(q'): c_eq = 4 f_c / (pi a w)."""
    w1, fc = 100.0, 0.02
    a = np.array([1e-3, 1e-2])
    b = model_backbone("q + sign(q')", [w1**2, fc], a, n_phase=4096)
    np.testing.assert_allclose(b.omega, w1, rtol=1e-12)
    np.testing.assert_allclose(b.zeta, 4 * fc / (np.pi * a * w1) / (2 * w1), rtol=1e-6)


def test_amplitude_law_and_parameter_order():
    m = seed_model()
    p, names = parameter_vector(m.terms, m.coefficients, m.amplitude_laws)
    assert names == ["omega1^2", "k3", "c[0]", "c[1]", "c[2]"]
    np.testing.assert_allclose(p, [170.0**2, 5e6, 0.08, 70.0, 1e4])
    a = np.array([0.002, 0.008])
    b = model_backbone(m.terms, m.coefficients, a, amplitude_laws=m.amplitude_laws)
    c = 0.08 + 70 * a + 1e4 * a**2
    np.testing.assert_allclose(b.zeta, c / (2 * b.omega), rtol=1e-12)


@pytest.mark.parametrize("F", [0.25, 1.0, 4.0])
def test_seed_backbone_is_the_phase_resonance_locus(F):
    """Multi-harmonic backbone = harmonic-balance FRF points in phase resonance, to 1e-6.

    At phase resonance the force balances the damping: zeta = F / (2 w^2 a).  The amplitude
    peak of the FRF lies a further zeta^2 (relative) below.
    """
    m = seed_model()
    w = optimize.brentq(lambda x: steady_state(m, x, F, n_harmonics=9, stability=False).phase + np.pi / 2,
                        160.0, 171.0, xtol=1e-12)
    s = steady_state(m, w, F, n_harmonics=9, stability=False)
    b = model_backbone(m.terms, m.coefficients, [s.amplitude], amplitude_laws=m.amplitude_laws, n_harmonics=9)
    assert abs(b.omega[0] / w - 1) < 1e-6
    assert abs(b.zeta[0] / (F / (2 * w**2 * s.amplitude)) - 1) < 1e-5  # higher harmonics differ at O(zeta)
    peak = optimize.minimize_scalar(lambda x: -steady_state(m, x, F, n_harmonics=9, stability=False).amplitude,
                                    bracket=(w - 1, w, w + 0.5), tol=1e-12).x
    assert abs((1 - peak / w) / b.zeta[0] ** 2 - 1) < 0.2


def test_bands_match_monte_carlo():
    rng = np.random.default_rng(3)
    p = np.array([160.0**2, 3e6, 0.5])
    cov = np.diag([40.0, 2e5, 0.01]) ** 2
    a = np.array([0.003, 0.01])
    b = model_backbone("q + -q^3 + q'", p, a, covariance=cov)
    draws = rng.multivariate_normal(p, cov, 2000)
    mc = np.array([model_backbone("q + -q^3 + q'", d, a).omega for d in draws])
    np.testing.assert_allclose(b.omega_stderr, mc.std(axis=0), rtol=0.08)
    assert np.all(b.omega_band[0] < b.omega) and np.all(b.omega_band[1] > b.omega)
    json.dumps(b.summary())
    assert "Backbone (model)" in b.report() and "<pre>" in b._repr_html_()


def test_bad_input():
    with pytest.raises(IdentificationError, match="linear term"):
        model_backbone("-q^3 + q'", [1.0, 1.0], [0.1])
    with pytest.raises(IdentificationError, match="amplitudes"):
        model_backbone("q + q'", [1.0, 1.0], [np.nan])
    with pytest.raises(IdentificationError, match="covariance"):
        model_backbone("q + q'", [1.0, 1.0], [0.1], covariance=np.eye(3))
    with pytest.raises(IdentificationError, match="no oscillation"):
        model_backbone("q + -q^3", [1.0, 1e6], [0.1])


def _records(F, omegas, noise, rng):
    m = seed_model()
    out = []
    for w in omegas:
        s = steady_state(m, w, F, n_harmonics=9, stability=False)
        t, Q, qdd = synthesize_record(s, fs=4000.0, duration=1.5, noise=noise, rng=rng)
        out.append(steady_state_signals(t, Q, qdd, frequency_hz=w / (2 * np.pi), n_harmonics=5))
    return m, out


def test_stepped_sine_points_follow_the_model_backbone():
    """Each record's equivalent linearisation lies on the model backbone (1 % noise)."""
    rng = np.random.default_rng(11)
    omegas = np.linspace(167.5, 171.0, 15)
    m, sig = _records(1.0, omegas, 0.01, rng)
    pts = equivalent_linearisation(sig, force_level=[1.0] * len(sig))
    exact = model_backbone(m.terms, m.coefficients, pts.amplitude, amplitude_laws=m.amplitude_laws, n_harmonics=5)
    dev = (pts.omega - exact.omega) / pts.omega_stderr
    assert np.all(np.abs(pts.omega / exact.omega - 1) < 2e-4)
    assert np.all(np.abs(dev) < 5)  # the stated errors are honest
    near = np.abs(omegas / pts.omega - 1) < 2e-3
    np.testing.assert_allclose(pts.zeta[near], exact.zeta[near], rtol=0.05)
    res = phase_resonance_points(pts)
    assert len(res) == 1 and res.meta["force_level"] == [1.0]
    ex = model_backbone(m.terms, m.coefficients, res.amplitude, amplitude_laws=m.amplitude_laws, n_harmonics=5)
    assert abs(res.omega[0] / ex.omega[0] - 1) < 1e-4
    assert abs(res.zeta[0] / ex.zeta[0] - 1) < 0.03
    json.dumps(pts.summary())


def test_backbone_select_and_sort():
    b = Backbone([3.0, 1.0, 2.0], [1.0, 2.0, 3.0], 0.1, 0.0, 0.0, "ringdown", meta={"k": [30, 10, 20]})
    s = b.sorted()
    assert s.amplitude.tolist() == [1.0, 2.0, 3.0] and s.meta["k"] == [10, 20, 30]
    assert b.select([True, False, True]).meta["k"] == [30, 20]
    assert abs(b.decades() - np.log10(3)) < 1e-12
