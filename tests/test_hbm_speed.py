"""Harmonic balance after the speed work: the same curves and the same stability.

* Floquet exponents from the 2x2 monodromy matrix agree with Hill's method.
* The seed Duffing curve (stored from the earlier continuation) is reproduced: every
  stored point is a steady state of the current solver, and the folds agree.
* The Jacobian shortcuts (constant derivatives of linear terms, viscous damping through
  ``P E D``, Horner sums of the amplitude laws) change no number.
* The peak of ``q`` (for the ``c(q_max)`` closure) is exact to rounding.
"""

import json
import pathlib

import numpy as np
import pytest

from jointid.simulate import hbm
from jointid.simulate.hbm import frequency_response, steady_state
from jointid.simulate.model import SingleModeModel, seed_model

DATA = pathlib.Path(__file__).parent / "data" / "seed_duffing_curve_reference.json"
DUFFING = SingleModeModel("q + -q^3 + q'", (170.0**2, 5e6, 0.5))


def _multipliers(lam, omega):
    mu = np.exp(lam * (2 * np.pi / np.asarray(omega))[:, None])
    return np.sort_complex(mu)


@pytest.mark.parametrize(
    "model, omegas",
    [
        (seed_model(), np.linspace(160, 180, 41)),
        (SingleModeModel("q + -q^3 + q'", (170.0**2, -5e7, 1.0)), None),  # folds, unstable middle branch
        (SingleModeModel("q + q^2 + q'", (170.0**2, 2e4, 0.8)), np.linspace(150, 190, 21)),  # even harmonics
        (SingleModeModel("q + -q^3 + q' + q'^3", (170.0**2, 5e6, 0.5, 20.0)), np.linspace(160, 180, 21)),
    ],
)
def test_monodromy_exponents_agree_with_hill(model, omegas):
    if omegas is None:
        r = frequency_response(model, 1.0, omega_range=(160.0, 190.0), stability=False)
    else:
        r = frequency_response(model, 1.0, omegas, stability=False)
    p = hbm._Problem(model, 1.0, 9)
    lam = p.floquet_batch(r.coefficients, r.omega, r.theta)
    lam_hill = p.hill_batch(r.coefficients, r.omega, r.theta)
    assert np.max(np.abs(_multipliers(lam, r.omega) - _multipliers(lam_hill, r.omega))) < 1e-8
    away = np.ones(len(r), bool)
    for i in r.folds:  # at a fold one exponent is zero: its sign is rounding
        away[max(i - 1, 0) : i + 2] = False
    assert np.array_equal((lam.real.max(axis=1) < 0)[away], (lam_hill.real.max(axis=1) < 0)[away])
    # Liouville: the exponents sum to minus the mean of dh/dq'
    assert np.allclose(lam.sum(axis=1).real, lam_hill.sum(axis=1).real, rtol=1e-9, atol=1e-12)


def test_seed_duffing_curve_is_reproduced():
    ref = json.loads(DATA.read_text())
    r = frequency_response(DUFFING, 1.0, omega_range=(160.0, 180.0), n_harmonics=9, n_time=128)
    assert len(r.folds) == len(ref["folds"]) == 2
    ref_folds = np.array(ref["omega"])[ref["folds"]]
    np.testing.assert_allclose(r.fold_omegas, ref_folds, rtol=1e-9)
    # every stored point is a steady state of the current solver (same branch, same q_max)
    for w, qm, c in zip(ref["omega"], ref["q_max"], ref["coefficients"]):
        s = steady_state(DUFFING, w, 1.0, guess=np.array(c), stability=False)
        assert s.q_max == pytest.approx(qm, rel=1e-9)
    # and every new point is the steady state the solver reaches from near it (at a
    # fold the two branches meet: a neighbouring root lies within sqrt of the tolerance)
    assert np.all(r.residual_norm <= 1e-12)
    for i, (w, qm, c) in enumerate(zip(r.omega, r.q_max, r.coefficients)):
        if i in r.folds:
            continue
        s = steady_state(DUFFING, w, 1.0, guess=c * 1.001, stability=False)
        assert s.q_max == pytest.approx(qm, rel=1e-9)
    assert r.stable[: r.folds[0]].all() and not r.stable[r.folds[0] + 1 : r.folds[1]].any()


def test_amplitude_scale_without_laws_needs_no_solution():
    p = hbm._Problem(DUFFING, 1.0, 9)
    assert hbm._amplitude_scale(p, 160.0, 180.0, 1e-12) == pytest.approx(1.0 / (0.5 * 170.0), rel=1e-9)
    q = hbm._Problem(seed_model(), 1.0, 9)  # with laws: the coarse sweep of earlier releases
    assert 0.003 < hbm._amplitude_scale(q, 160.0, 180.0, 1e-12) < 0.01


@pytest.mark.parametrize("spec, coefs", [("q + -q^3 + q'", (28900.0, 5e6, 0.5)),
                                         ("q + q^2 + q'^3 + q^2 q'", (28900.0, 3e4, 5.0, 2e3))])
def test_jacobian_matches_finite_differences(spec, coefs):
    model = SingleModeModel(spec, coefs)
    p = hbm._Problem(model, 1.0, 9)
    s = steady_state(model, 168.0, 1.0, stability=False)
    z = s.coefficients[p.active] * 1.01
    ev = p.evaluate(z, 168.0, jacobian=True, domega=True)
    J = np.empty_like(ev["J"])
    for k in range(z.size):
        h = 1e-6 * max(abs(z[k]), 1e-6)
        zp, zm = z.copy(), z.copy()
        zp[k] += h
        zm[k] -= h
        J[:, k] = (p.evaluate(zp, 168.0, jacobian=False)["R"] - p.evaluate(zm, 168.0, jacobian=False)["R"]) / (2 * h)
    np.testing.assert_allclose(ev["J"], J, rtol=1e-5, atol=1e-6 * np.abs(J).max())
    dw = 1e-5
    Jw = (p.evaluate(z, 168.0 + dw, jacobian=False)["R"] - p.evaluate(z, 168.0 - dw, jacobian=False)["R"]) / (2 * dw)
    np.testing.assert_allclose(ev["Jw"], Jw, rtol=1e-5, atol=1e-6 * np.abs(Jw).max())


def test_amplitude_laws_by_horner_are_polyval():
    m = seed_model()
    p = hbm._Problem(m, 1.0, 9)
    for qm in np.linspace(0.0, 0.02, 57):
        assert np.array_equal(p.coefficients_at(qm), m.coefficients_at(qm))


@pytest.mark.parametrize(
    "model, omegas",
    [
        (seed_model(), np.linspace(160, 180, 401)),
        (SingleModeModel("q + -q^3 + q'", (170.0**2, -5e7, 1.0)), np.linspace(160, 190, 301)),  # jumps down
        (SingleModeModel("q + -q^3 + q'", (170.0**2, -5e7, 1.0)), np.linspace(190, 160, 301)),  # jumps up
        (SingleModeModel("q + q^2 + q'^3", (170.0**2, 3e4, 20.0)), np.linspace(150, 190, 201)),
    ],
)
def test_batched_sweep_equals_the_point_by_point_sweep(model, omegas, monkeypatch):
    batched = frequency_response(model, 1.0, omegas)
    monkeypatch.setattr(hbm, "BATCH_GUESS", -1.0)  # no batches: every point on its own
    single = frequency_response(model, 1.0, omegas)
    np.testing.assert_allclose(batched.q_max, single.q_max, rtol=1e-10)
    np.testing.assert_allclose(batched.coefficients, single.coefficients, rtol=0,
                               atol=1e-10 * np.abs(single.coefficients).max())
    assert np.array_equal(batched.stable, single.stable)
    jumps = np.flatnonzero(np.abs(np.diff(single.q_max)) > 0.2 * single.q_max[1:])
    assert np.array_equal(jumps, np.flatnonzero(np.abs(np.diff(batched.q_max)) > 0.2 * batched.q_max[1:]))


@pytest.mark.parametrize("odd", [True, False])
def test_peak_search_is_exact_to_rounding(odd):
    """Both peak searches (one state, many states) give ``max |q|`` to rounding, for nearly
    sinusoidal and for strongly distorted random series (most take several Newton steps
    before one falls below ``PEAK_STEP``, whose value is carried by Taylor), against a
    fine grid refined by a bounded scalar search."""
    from scipy.optimize import minimize_scalar

    model = DUFFING if odd else SingleModeModel("q + q^2 + q'", (170.0**2, 2e4, 0.8))
    p = hbm._Problem(model, 1.0, 9)
    rng = np.random.default_rng(3)
    k = np.arange(p.kh.size)
    X = np.empty((40, p.active.size))
    for r in range(X.shape[0]):
        decay = 0.02 if r < 20 else 0.8  # nearly sinusoidal, then distorted
        X[r] = rng.standard_normal(p.active.size) * 1e-3
        X[r, p.a_idx] *= decay**k
        X[r, p.b_idx] *= decay**k
    vals, taus, signs = p.peak_batch(X)
    grid = 2 * np.pi * np.arange(1 << 16) / (1 << 16)
    for r, x in enumerate(X):
        def q(tau, x=x):
            return float((hbm._basis_at(np.atleast_1d(tau), p.H)[:, p.active] @ x)[0])
        dense = hbm._basis_at(grid, p.H)[:, p.active] @ x
        i = int(np.argmax(np.abs(dense)))
        h = grid[1]
        best = minimize_scalar(lambda s: -abs(q(s)), bounds=(grid[i] - h, grid[i] + h), method="bounded",
                               options={"xatol": 1e-12})
        exact = abs(q(best.x))
        assert vals[r] == pytest.approx(exact, rel=1e-14, abs=0)
        assert p.peak(x)[0] == pytest.approx(exact, rel=1e-14, abs=0)
        assert signs[r] * q(taus[r]) == pytest.approx(exact, rel=1e-14, abs=0)
