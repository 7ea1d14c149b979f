"""Harmonic balance: closed forms, folds and stability, amplitude closure, errors."""

from __future__ import annotations

import json

import numpy as np
import pytest

from jointid.errors import ConvergenceError, JointidError, RecordError
from jointid.simulate.hbm import (
    FrequencyResponse,
    SteadyState,
    frequency_response,
    linear_frf,
    steady_state,
)
from jointid.simulate.model import SingleModeModel, seed_model

W1 = 170.0


def duffing(k3, c=1.0, w1=W1):
    """``q'' + c q' + w1^2 q - k3 q^3 = F sin``; k3 < 0 is hardening."""
    return SingleModeModel("q + -q^3 + q'", (w1**2, k3, c))


def dense_max_abs(state, n=200_001):
    t = np.linspace(0.0, state.period, n)
    return float(np.max(np.abs(state.q(t))))


# --------------------------------------------------------------------------- closed forms


def test_linear_model_matches_analytic_frf():
    lin = SingleModeModel("q + q'", (W1**2, 0.5))
    w = np.linspace(150.0, 190.0, 161)
    r = frequency_response(lin, 2.0, w)
    X = linear_frf(lin, w, 2.0)
    np.testing.assert_allclose(r.amplitude, np.abs(X), rtol=1e-10)
    np.testing.assert_allclose(r.phase, np.angle(X), atol=1e-10)
    np.testing.assert_allclose(r.q_max, np.abs(X), rtol=1e-10)
    assert np.max(np.abs(r.coefficients[:, 3:])) < 1e-12 * np.max(r.amplitude)
    # one frequency on its own, and the linear FRF helper's closed form
    s = steady_state(lin, W1, 2.0)
    assert s.amplitude == pytest.approx(2.0 / (0.5 * W1), rel=1e-10)
    assert abs(linear_frf(lin, 160.0)) == pytest.approx(1 / abs(W1**2 - 160.0**2 + 1j * 0.5 * 160.0), rel=1e-14)


def test_linear_stiffness_with_amplitude_dependent_damping_closes_on_its_amplitude():
    m = SingleModeModel("q + q'", (W1**2, 0.0), {"q'": (0.08, 70.0, 1e4)})
    w = np.linspace(165.0, 175.0, 41)
    r = frequency_response(m, 1.0, w)
    X = np.array([linear_frf(m, wi, 1.0, q_max=qm) for wi, qm in zip(w, r.q_max)])
    np.testing.assert_allclose(r.amplitude, np.abs(X), rtol=1e-10)
    np.testing.assert_allclose(r.q_max, r.amplitude, rtol=1e-10)


@pytest.mark.parametrize("k3", [-1e6, -5e6, 5e6])
@pytest.mark.parametrize("omega", [165.0, 170.0, 175.0])
def test_single_harmonic_balance_is_the_first_order_duffing_relation(k3, omega):
    """With H = 1: A^2 [(w1^2 - 3/4 k3 A^2 - w^2)^2 + (c w)^2] = F^2 exactly."""
    F, c = 1.0, 1.0
    s = steady_state(duffing(k3, c), omega, F, n_harmonics=1)
    A = s.amplitude
    keq = W1**2 - 0.75 * k3 * A**2
    assert A == pytest.approx(F / abs(keq - omega**2 + 1j * c * omega), rel=1e-9)


def test_higher_harmonics_correct_the_first_order_relation_at_second_order():
    """Away from resonance the H = 9 amplitude differs from the first-order relation by
    O(eps^2), eps = 3/4 |k3| A^2 / w1^2: bounded by eps^2 and scaling as eps^2."""
    F, c, omega = 1.0, 1.0, 165.0
    errs, epss = [], []
    for k3 in (-5e6, -2e7):
        s = steady_state(duffing(k3, c), omega, F, n_harmonics=9)
        A = s.amplitude
        eps = 0.75 * abs(k3) * A**2 / W1**2
        keq = W1**2 - 0.75 * k3 * A**2
        err = abs(A * abs(keq - omega**2 + 1j * c * omega) / F - 1.0)
        assert 0.0 < err < eps**2
        errs.append(err)
        epss.append(eps)
    order = np.log(errs[1] / errs[0]) / np.log(epss[1] / epss[0])
    assert order == pytest.approx(2.0, abs=0.05)


def test_peak_of_weakly_damped_duffing_lies_on_the_backbone():
    c, k3, F = 0.2, -5e6, 1.0
    r = frequency_response(duffing(k3, c), F, omega_range=(160.0, 200.0))
    assert len(r.folds) == 2
    i = r.folds[0]  # the resonance peak is the first (upper) fold of a hardening curve
    A, wf = r.amplitude[i], r.omega[i]
    eps = 0.75 * abs(k3) * A**2 / W1**2
    w_backbone = np.sqrt(W1**2 - 0.75 * k3 * A**2)
    assert abs(wf - w_backbone) / (w_backbone - W1) < eps**2
    assert A * c * wf == pytest.approx(F, rel=1e-3)  # damping-limited peak F / (c w)


# ------------------------------------------------------------------- folds and stability


def test_hardening_continuation_passes_both_folds_and_flags_middle_branch_unstable():
    m = duffing(-5e7, 1.0)
    r = frequency_response(m, 1.0, omega_range=(160.0, 190.0))
    assert r.method == "continuation"
    assert r.omega[0] == 160.0 and r.omega[-1] == 190.0
    assert len(r.folds) == 2
    f1, f2 = r.folds
    assert r.omega[f1] > r.omega[f2]  # hardening: upper fold to the right of the lower fold
    assert r.q_max[f1] > r.q_max[f2]
    # omega increases, decreases between the folds, increases again
    assert np.all(np.diff(r.omega[: f1 + 1]) > 0)
    assert np.all(np.diff(r.omega[f1 : f2 + 1]) < 0)
    assert np.all(np.diff(r.omega[f2:]) > 0)
    # Hill: stable outside, unstable strictly between the folds (saddle: real exponent > 0)
    assert r.stable[:f1].all() and r.stable[f2 + 1 :].all()
    assert not r.stable[f1 + 1 : f2].any()
    mid = r.floquet_exponents[f1 + 1 : f2]
    assert np.all(mid[:, 0].real > 0) and np.all(np.abs(mid[:, 0].imag) < 1e-9)
    # at the folds one exponent crosses zero
    for i in r.folds:
        assert abs(r.floquet_exponents[i, 0]) < 1e-4
    # the up-sweep (fast path) jumps down just after the upper fold
    w = np.linspace(160.0, 190.0, 301)
    s = frequency_response(m, 1.0, w)
    j = int(np.argmax(-np.diff(s.q_max)))
    assert w[j] <= r.omega[f1] <= w[j + 1]
    assert s.stable.all()


def test_softening_seed_law_with_strong_cubic_has_two_folds():
    r = frequency_response(seed_model(k3=1e8), 1.0, omega_range=(150.0, 180.0))
    assert len(r.folds) == 2
    lo, hi = r.folds
    assert r.omega[lo] > r.omega[hi]  # softening: the peak fold lies to the left
    assert not r.stable[lo + 1 : hi].any()
    assert r.stable[:lo].all() and r.stable[hi + 1 :].all()


def test_hill_exponents_of_linear_system():
    c = 0.6
    lin = SingleModeModel("q + q'", (W1**2, c))
    for omega in (160.0, 175.0):
        s = steady_state(lin, omega, 1.0)
        lam = s.floquet_exponents
        np.testing.assert_allclose(lam.real, -c / 2, atol=1e-9)
        wd = np.sqrt(W1**2 - c**2 / 4)
        np.testing.assert_allclose(np.sort(np.abs(lam.imag)), abs(wd - omega), rtol=1e-9)
        assert s.stable


# ------------------------------------------------------------------------ closure, paper


@pytest.mark.parametrize("omega", [160.0, 168.0, 169.5, 170.0, 171.0, 180.0])
def test_q_max_closure_is_satisfied(omega):
    m = seed_model()
    s = steady_state(m, omega, 1.0)
    # q_max is max |q| of the harmonic series, to machine precision
    dense = dense_max_abs(s)
    assert dense <= s.q_max * (1 + 1e-13)
    assert dense >= s.q_max * (1 - 1e-9)
    # the coefficients are those of the amplitude law at q_max
    np.testing.assert_array_equal(s.theta, m.coefficients_at(s.q_max))
    assert s.residual_norm <= 1e-12
    # the time-domain equation of motion holds (harmonic truncation error only)
    t = np.linspace(0, s.period, 1001)
    r = s.acceleration(t) + s.restoring_force(t) - s.force(t)
    assert np.max(np.abs(r)) < 1e-7 * s.force_amplitude


def test_paper_example_sweep():
    """Seed Fig 4: 401 points, 160-180 rad/s, F = 1; sweep agrees with single solves and
    with continuation, peak below the linear natural frequency (softening)."""
    m = seed_model()
    w = np.linspace(160.0, 180.0, 401)
    r = frequency_response(m, 1.0, w)
    assert isinstance(r, FrequencyResponse) and len(r) == 401
    assert r.stable.all() and r.folds == ()
    assert np.max(r.residual_norm) <= 1e-12
    i = int(np.argmax(r.q_max))
    assert 169.0 < w[i] < 170.0
    assert 6.0e-3 < r.q_max[i] < 6.6e-3
    for j in (0, 150, i, 400):
        s = steady_state(m, w[j], 1.0)
        assert r.q_max[j] == pytest.approx(s.q_max, rel=1e-10)
    rc = frequency_response(m, 1.0, omega_range=(160.0, 180.0))
    assert rc.folds == ()
    for j in range(0, len(rc), 7):
        s = steady_state(m, rc.omega[j], 1.0, guess=rc.state(j))
        assert rc.q_max[j] == pytest.approx(s.q_max, rel=1e-10)
    # a state from the response is a SteadyState with the closure satisfied
    st = r.state(i)
    assert isinstance(st, SteadyState)
    np.testing.assert_array_equal(st.theta, m.coefficients_at(st.q_max))


def test_even_terms_use_all_harmonics():
    m = SingleModeModel("q + q^2 + q'", (W1**2, 3e5, 1.0))
    s = steady_state(m, 168.0, 1.0)
    assert abs(s.coefficients[0]) > 0  # static offset of an asymmetric spring
    assert abs(s.coefficients[3]) + abs(s.coefficients[4]) > 0  # second harmonic
    t = np.linspace(0, s.period, 801)
    r = s.acceleration(t) + s.restoring_force(t) - s.force(t)
    assert np.max(np.abs(r)) < 1e-8
    assert dense_max_abs(s) == pytest.approx(s.q_max, rel=1e-9)


def test_guess_and_more_harmonics():
    m = seed_model()
    s = steady_state(m, 169.0, 1.0)
    s2 = steady_state(m, 169.2, 1.0, guess=s)
    s3 = steady_state(m, 169.2, 1.0, guess=s.coefficients[:3])
    assert s2.q_max == pytest.approx(s3.q_max, rel=1e-12)
    s15 = steady_state(m, 169.2, 1.0, n_harmonics=15)
    assert s15.q_max == pytest.approx(s2.q_max, rel=1e-10)


# ------------------------------------------------------------------------ errors, output


def test_convergence_failure_raises_convergence_error_with_clear_message():
    with pytest.raises(ConvergenceError) as info:
        steady_state(seed_model(), 170.0, 1.0, tol=0.0, max_iter=3)
    msg = str(info.value)
    assert "omega=170" in msg and "F=1" in msg and "max_iter=3" in msg
    assert isinstance(info.value, JointidError) and isinstance(info.value, RuntimeError)


def test_bad_inputs():
    m = seed_model()
    with pytest.raises(RecordError):
        steady_state(m, -1.0, 1.0)
    with pytest.raises(RecordError):
        steady_state(m, 170.0, 1.0, n_harmonics=0)
    with pytest.raises(ValueError):
        frequency_response(m, 1.0)
    with pytest.raises(ValueError):
        frequency_response(m, 1.0, [170.0], omega_range=(160, 180))
    with pytest.raises(ValueError):
        frequency_response(m, 1.0, omega_range=(170, 170))


def test_summary_and_plot(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    r = frequency_response(duffing(-5e7), 1.0, omega_range=(160.0, 190.0))
    d = r.summary()
    json.dumps(d)
    assert len(d["folds"]) == 2 and d["n_unstable"] > 0
    json.dumps(r.state(0).summary())
    assert "fold at omega" in r.report()
    fig, ax = r.plot(linear=True)
    styles = {line.get_linestyle() for line in ax.get_lines()}
    assert "--" in styles and "-" in styles
    fig.savefig(tmp_path / "frf.png")
    s = frequency_response(seed_model(), 1.0, np.linspace(160, 180, 41))
    fig2, ax2 = s.plot(quantity="amplitude", linear=s.q_max)
    assert ax2.get_ylabel() == "fundamental amplitude [m]"
    import matplotlib.pyplot as plt

    plt.close(fig)
    plt.close(fig2)
