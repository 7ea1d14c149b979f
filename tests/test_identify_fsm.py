import re
import warnings

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from conftest import consistent_record
from jointid.errors import IdentificationError, IllConditionedWarning
from jointid.identify.fsm import ForceStateMapping, PooledForceStateMapping, band_average
from jointid.identify.terms import Term, library, term
from jointid.signal.harmonics import steady_state_signals


def _signals(coefs, terms="q + -q^3 + q'", n=7, **kw):
    t, Q, a, q, v = consistent_record(coefs, terms, **kw)
    w = kw.get("omega", 30.0)
    return steady_state_signals(t, Q, a, frequency_hz=w / (2 * np.pi), n_harmonics=n)


def test_seed_terms_recovered_exactly():
    coefs = [900.0, 5e6, 0.7]
    fit = ForceStateMapping().fit(_signals(coefs)).result_
    assert np.allclose(fit.coefficients, coefs, rtol=1e-9)
    assert fit.omega1 == pytest.approx(30.0, rel=1e-12)
    assert fit.k3 == pytest.approx(5e6, rel=1e-9)
    assert "k3" in fit.equation()


@pytest.mark.parametrize(
    "terms, coefs",
    [
        ("q + -q^3 + q' + |q'|q' + q'^3", [900.0, -2e6, 0.4, 3.0, 50.0]),
        ("q + -q^3 + q' + sign(q')", [900.0, 1e6, 0.4, 0.05]),
        ("q + -q^3 + q^5 + q'", [900.0, 1e6, 3e9, 0.2]),
        ("q + q^2 + q'", [900.0, 300.0, 0.3]),
    ],
)
def test_richer_libraries_recovered(terms, coefs):
    # an even term creates even harmonics and a mean: give q a richer content
    amps = ((1, 0.01, 0.002), (2, 3e-4, 0.0), (3, 0.0, 2e-4), (5, 1e-5, 0.0))
    sig = _signals(coefs, terms, n=9, amps=amps)
    fit = ForceStateMapping(terms).fit(sig).result_
    assert np.allclose(fit.coefficients, coefs, rtol=1e-6)


def test_user_term_extends_library():
    quartic_damping = Term("q^2 q'^2 sgn", "d", lambda q, v: q**2 * v * np.abs(v), kind="damping")
    lib = library("q + q'") + quartic_damping
    coefs = [900.0, 0.5, 2e3]
    fit = ForceStateMapping(lib).fit(_signals(coefs, lib)).result_
    assert np.allclose(fit.coefficients, coefs, rtol=1e-7)


def test_pooled_matches_truth_and_is_better_conditioned_under_noise():
    rng = np.random.default_rng(7)
    true = dict(w2=900.0, k3=4e6)
    sigs, cs = [], []
    for i, (A, c) in enumerate([(0.004, 0.3), (0.008, 0.5), (0.012, 0.7), (0.016, 0.9)]):
        t, Q, a, q, v = consistent_record([true["w2"], true["k3"], c], amps=((1, A, 0.0), (3, 0.0, A**3 * 5)))
        Q = Q + 0.005 * np.std(Q) * rng.standard_normal(Q.size)
        a = a + 0.005 * np.std(a) * rng.standard_normal(a.size)
        sigs.append(steady_state_signals(t, Q, a, frequency_hz=30 / (2 * np.pi), n_harmonics=5))
        cs.append(c)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IllConditionedWarning)
        singles = [ForceStateMapping().fit(s).result_ for s in sigs]
        pooled = PooledForceStateMapping().fit(sigs).result_
    band = band_average(singles)
    err_pooled = abs(pooled.k3 / true["k3"] - 1)
    err_band = abs(band["k3"] / true["k3"] - 1)
    assert err_pooled < 0.02
    assert err_pooled < err_band
    assert pooled.get_stderr("k3") < np.mean([s.stderr[1] for s in singles])
    assert np.allclose(pooled.get("c"), cs, rtol=0.02)
    assert pooled.omega1 == pytest.approx(30.0, rel=1e-4)


def test_too_few_harmonics_for_k3_is_refused():
    with pytest.raises(IdentificationError, match="at least 3"):
        ForceStateMapping().fit(_signals([900.0, 1e6, 0.5], n=2))


def test_ill_conditioned_regression_warns_with_condition_number():
    near_dup = Term("q+1e-9q^3", "k_dup", lambda q, v: q + 1e-9 * q**3)
    lib = library("q + -q^3 + q'") + near_dup
    with pytest.warns(IllConditionedWarning, match=r"condition number \d"):
        ForceStateMapping(lib).fit(_signals([900.0, 1e6, 0.5, 0.0], lib))


def test_k3_not_resolved_at_tiny_amplitude_warns():
    rng = np.random.default_rng(0)
    t, Q, a, q, v = consistent_record([900.0, 1e6, 0.5], amps=((1, 1e-5, 0.0),))
    a = a + 0.01 * np.std(a) * rng.standard_normal(a.size)
    sig = steady_state_signals(t, Q, a, frequency_hz=30 / (2 * np.pi), n_harmonics=5)
    with pytest.warns(IllConditionedWarning, match=r"k3 not resolved.*condition number"):
        ForceStateMapping().fit(sig)


def test_unknown_term_is_a_clear_error():
    with pytest.raises(IdentificationError, match=re.escape("unknown term 'q^7'")):
        library("q + q^7")
    assert term("q^3").name == "-q^3"


@settings(max_examples=20, deadline=None)
@given(shift=st.floats(0.0, 100.0), unit=st.floats(0.01, 100.0))
def test_identification_invariant_to_time_shift_and_force_units(shift, unit):
    """Scaling force and acceleration by u scales omega1^2 by 1, c by 1 and k3 by 1/u^2."""
    coefs = [900.0, 5e6, 0.7]
    t, Q, a, q, v = consistent_record(coefs)
    base = ForceStateMapping().fit(steady_state_signals(t, Q, a, n_harmonics=7)).result_
    moved = ForceStateMapping().fit(steady_state_signals(t + shift, unit * Q, unit * a, n_harmonics=7)).result_
    assert moved.omega1 == pytest.approx(base.omega1, rel=1e-9)
    assert moved.c == pytest.approx(base.c, rel=1e-6)
    assert moved.k3 * unit**2 == pytest.approx(base.k3, rel=1e-6)
