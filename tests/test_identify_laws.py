import numpy as np
import pytest

from conftest import consistent_record
from jointid.errors import IdentificationError
from jointid.identify.hysteresis import hysteresis_loop
from jointid.identify.laws import dissipated_energy, elastic_force_amplitude, fit_damping_law, fit_power_law
from jointid.signal.harmonics import steady_state_signals


def test_damping_law_exact_polynomial_and_order_choice():
    q = np.linspace(3e-4, 6.5e-3, 41)
    c = 0.08 + 70 * q + 1e4 * q**2
    law = fit_damping_law(q, c, order=2)
    assert np.allclose(law.coefficients, [0.08, 70.0, 1e4], rtol=1e-9)
    lin = fit_damping_law(q, 0.3 + 50 * q, order=1)
    assert np.allclose(lin.coefficients, [0.3, 50.0], rtol=1e-10)
    assert "q_max^2" in law.report()


def test_damping_law_weighted_by_stderr():
    rng = np.random.default_rng(2)
    q = np.linspace(1e-3, 6e-3, 30)
    se = np.where(np.arange(30) % 2 == 0, 1e-4, 1e-1)  # half the points are junk
    c = 0.1 + 40 * q + se * rng.standard_normal(30)
    law = fit_damping_law(q, c, se, order=1)
    assert law.coefficients[1] == pytest.approx(40.0, rel=0.01)


def test_damping_law_needs_enough_records():
    with pytest.raises(IdentificationError, match="at least 3"):
        fit_damping_law([1e-3, 2e-3], [0.1, 0.2], order=2)


def test_viscous_energy_closed_form():
    w, A, c = 30.0, 0.01, 0.4
    vel = np.array([0.0, 0.0, -A * w])  # v = -A w sin(wt)
    assert dissipated_energy(vel, w, lambda v: c * v) == pytest.approx(np.pi * c * w * A**2, rel=1e-12)


def test_coulomb_equivalent_damping_closed_form():
    """A Coulomb force f_c sign(v) dissipates 4 f_c A per cycle: c_eq = 4 f_c / (pi A w)."""
    w, A, fc = 30.0, 0.01, 0.05
    vel = np.array([0.0, 0.0, -A * w])
    U = dissipated_energy(vel, w, lambda v: fc * np.sign(v), n_points=200000)
    assert U == pytest.approx(4 * fc * A, rel=1e-4)
    c_eq = U / (np.pi * w * A**2)
    assert c_eq == pytest.approx(4 * fc / (np.pi * A * w), rel=1e-4)


def test_power_law_exact_and_bounds():
    F = np.geomspace(1, 10, 8)
    law = fit_power_law(F, 0.3 * F**2.4)
    assert law.n == pytest.approx(2.4, abs=1e-12)
    assert law.alpha == pytest.approx(0.3, rel=1e-10)
    assert law.within_bounds
    assert not fit_power_law(F, F**3.5).within_bounds
    with pytest.raises(IdentificationError):
        fit_power_law([1.0], [2.0])


def test_power_law_of_amplitude_dependent_viscous_damping():
    """U = pi c(A) w A^2 and F = w1^2 A: n -> 2 for constant c and -> 3 for c ~ A."""
    w1 = 170.0
    A = np.geomspace(1e-3, 2e-3, 10)
    for c_of_A, n_exact in ((lambda a: 0.5 + 0 * a, 2.0), (lambda a: 80.0 * a, 3.0)):
        U = [dissipated_energy(np.array([0, 0, -a * w1]), w1, lambda v, a=a: c_of_A(a) * v) for a in A]
        F = [elastic_force_amplitude(np.array([0, a, 0.0]), w1) for a in A]
        assert fit_power_law(F, U).n == pytest.approx(n_exact, abs=1e-9)


def test_hysteresis_loop_identified_matches_measured_and_area_is_energy():
    coefs = [900.0, 5e6, 0.7]
    t, Q, a, q, v = consistent_record(coefs, fs=4000.0)
    # q has harmonics 1 and 3, so the cubic force reaches harmonic 9: filter with 9
    sig = steady_state_signals(t, Q, a, frequency_hz=30 / (2 * np.pi), n_harmonics=9)
    loop = hysteresis_loop(sig, "q + -q^3 + q'", coefs, filtered=True)
    assert loop.rms_difference < 1e-8
    U = dissipated_energy(sig.velocity.coefficients, sig.omega, lambda vv: 0.7 * vv)
    assert loop.enclosed_area("identified") == pytest.approx(U, rel=2e-3)
    raw = hysteresis_loop(sig, "q + -q^3 + q'", coefs, filtered=False)
    assert raw.rms_difference < 1e-6


def test_unfiltered_loop_is_averaged_over_periods_under_noise():
    coefs = [900.0, 5e6, 0.7]
    rng = np.random.default_rng(3)
    t, Q, a, q, v = consistent_record(coefs, fs=2000.0, duration=40.0)  # 190 periods
    Q = Q + 0.01 * Q.std() * rng.standard_normal(Q.size)
    a = a + 0.01 * a.std() * rng.standard_normal(a.size)
    sig = steady_state_signals(t, Q, a, frequency_hz=30 / (2 * np.pi), n_harmonics=9)
    raw = hysteresis_loop(sig, "q + -q^3 + q'", coefs, filtered=False)
    assert raw.q.size <= 256
    # per sample the noise is ~2 % of the loop; averaged over 190 periods it drops ~14 times
    assert raw.rms_difference < 0.005
