"""Time integration and shooting cross-check harmonic balance."""

from __future__ import annotations

import numpy as np
import pytest

from jointid.errors import ConvergenceError, RecordError
from jointid.simulate.hbm import frequency_response, steady_state
from jointid.simulate.model import SingleModeModel, seed_model
from jointid.simulate.timeint import PeriodicOrbit, integrate, periodic_orbit

W1 = 170.0
AGREE = 1e-6  # required relative agreement of the steady-state amplitude


def duffing(k3, c=1.0):
    return SingleModeModel("q + -q^3 + q'", (W1**2, k3, c))


@pytest.mark.parametrize("omega", [160.0, 167.0, 169.5, 170.0, 172.0, 178.0])
def test_hb_and_shooting_agree_for_seed_model(omega):
    """Seed Eq 19-20 with the q_max closure, incl. the resonance peak (169.5 rad/s)."""
    m = seed_model()
    hb = steady_state(m, omega, 1.0)
    ti = periodic_orbit(m, omega, 1.0)  # independent start: linear part, closed on its amplitude
    assert isinstance(ti, PeriodicOrbit)
    assert ti.q_max == pytest.approx(hb.q_max, rel=AGREE)
    assert ti.closure_residual < 1e-9
    np.testing.assert_allclose(ti.theta, m.coefficients_at(ti.q_max))
    assert ti.stable and hb.stable


def test_hb_and_shooting_agree_on_hardening_curve_with_fold():
    """k3 < 0 strong enough for a fold: compare on both stable branches and check the
    middle branch is unstable for both Hill's method and the monodromy matrix."""
    m = duffing(-5e7, 1.0)
    r = frequency_response(m, 1.0, omega_range=(160.0, 190.0))
    f1, f2 = r.folds
    w_lo, w_hi = r.omega[f2], r.omega[f1]
    # single-valued but strongly nonlinear point just below the lower fold, independent start
    w = w_lo - 0.5
    hb = steady_state(m, w, 1.0)
    ti = periodic_orbit(m, w, 1.0)
    assert hb.q_max == pytest.approx(ti.q_max, rel=AGREE)
    assert hb.stable and ti.stable
    # in the three-solution band: upper and lower stable branches, middle unstable
    w_mid = 0.5 * (w_lo + w_hi)
    checked = set()
    for i in range(len(r)):
        if abs(r.omega[i] - w_mid) > 0.6 or i in r.folds:
            continue
        branch = "upper" if i < f1 else ("middle" if i < f2 else "lower")
        if branch in checked:
            continue
        checked.add(branch)
        st = r.state(i)
        orbit = periodic_orbit(m, st.omega, 1.0, guess=st)  # the HB state only selects the branch
        assert orbit.q_max == pytest.approx(st.q_max, rel=AGREE)
        assert orbit.stable == st.stable == (branch != "middle")
        # Floquet multipliers = exp(exponents * period)
        mu = np.sort(np.abs(orbit.floquet_multipliers))
        np.testing.assert_allclose(mu, np.sort(np.abs(np.exp(st.floquet_exponents * st.period))), rtol=1e-6)
    assert checked == {"upper", "middle", "lower"}


def test_hb_and_shooting_agree_for_hardening_seed_law():
    """Hardening cubic with the seed's amplitude-dependent damping, on the upper branch."""
    m = seed_model(k3=-1e8)
    r = frequency_response(m, 1.0, omega_range=(160.0, 190.0), stability=False)
    f1 = r.folds[0]
    i = int(np.argmin(np.abs(r.omega[:f1] - 175.0)))  # upper branch, three solutions coexist
    st = r.state(i)
    assert r.omega[r.folds[1]] < st.omega < r.omega[f1]
    # the state selects the branch; a perturbed q_max makes the closure loop iterate
    orbit = periodic_orbit(m, st.omega, 1.0, guess=st, q_max_guess=1.02 * st.q_max)
    assert orbit.closure_iterations > 2
    assert orbit.q_max == pytest.approx(st.q_max, rel=AGREE)
    assert orbit.stable


def test_finite_difference_jacobian_shooting():
    m = seed_model()
    a = periodic_orbit(m, 171.0, 1.0, jacobian="fd")
    b = steady_state(m, 171.0, 1.0)
    assert a.q_max == pytest.approx(b.q_max, rel=AGREE)


def test_asymmetric_model_hb_vs_shooting():
    m = SingleModeModel("q + q^2 + q'", (W1**2, 3e5, 1.0))
    hb = steady_state(m, 168.0, 1.0)
    ti = periodic_orbit(m, 168.0, 1.0)
    assert ti.q_max == pytest.approx(hb.q_max, rel=AGREE)


def test_integrate_from_rest_reaches_the_harmonic_balance_state():
    """Heavy damping so the transient dies quickly: compare the last period pointwise."""
    m = SingleModeModel("q + -q^3 + q'", (W1**2, 5e6, 40.0))
    omega = 165.0
    T = 2 * np.pi / omega
    t = np.linspace(0.0, 60 * T, 60 * 64 + 1)
    traj = integrate(m, omega, 1.0, t)
    hb = steady_state(m, omega, 1.0)
    last = t > 59 * T
    scale = hb.q_max
    np.testing.assert_allclose(traj.q[last], hb.q(t[last]), atol=1e-8 * scale)
    np.testing.assert_allclose(traj.acceleration[last], hb.acceleration(t[last]), atol=1e-8 * scale * omega**2)
    np.testing.assert_allclose(traj.force, np.sin(omega * t))
    assert traj.summary()["n_samples"] == t.size


def test_integrate_needs_q_max_for_amplitude_laws():
    m = seed_model()
    t = np.linspace(0, 0.1, 11)
    with pytest.raises(RecordError, match="q_max"):
        integrate(m, 170.0, 1.0, t)
    traj = integrate(m, 170.0, 1.0, t, q_max=1e-3)
    np.testing.assert_array_equal(traj.theta, m.coefficients_at(1e-3))
    with pytest.raises(RecordError):
        integrate(m, 170.0, 1.0, t[::-1], q_max=1e-3)


def test_periodic_orbit_trajectory_is_periodic():
    m = seed_model()
    orbit = periodic_orbit(m, 169.0, 1.0)
    traj = orbit.trajectory(n_samples=2048, n_periods=2)
    assert traj.q[-1] == pytest.approx(orbit.q0, abs=1e-9 * orbit.q_max)
    assert np.max(np.abs(traj.q)) == pytest.approx(orbit.q_max, rel=1e-5)
    assert orbit.summary()["stable"] is True


def test_shooting_failure_raises_convergence_error():
    with pytest.raises(ConvergenceError, match="omega=170"):
        periodic_orbit(seed_model(), 170.0, 1.0, max_iter=1, tol=1e-14)
