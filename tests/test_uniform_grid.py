"""Uniformly sampled records: the rotated-table path agrees with the general path.

The general path evaluates the sinusoids at every time stamp; the uniform path rotates
one table (signal.harmonics._uniform_moments).  Both must give the same numbers to
rounding, and the one-pass check of a given frequency must decide as the full
refinement does.
"""

import warnings

import numpy as np
import pytest

from jointid.errors import JointidWarning, RecordError
from jointid.signal import harmonics as hm
from jointid.signal.harmonics import (
    check_time_base,
    estimate_frequency,
    fit_harmonics,
    steady_state_signals,
)

W = 2 * np.pi * 26.4837
FS = 2000.0


def _record(n=60001, t0=0.0, noise=0.0, seed=0):
    t = t0 + np.arange(n) / FS
    tau = t - t0
    rng = np.random.default_rng(seed)
    force = 3.0 * np.sin(W * tau + 0.3) + 0.2 * np.sin(2 * W * tau) + 0.1
    accel = -2.0 * np.sin(W * tau - 0.4) + 0.3 * np.cos(3 * W * tau + 1.0) + 0.05 * np.sin(5 * W * tau)
    force = force + noise * rng.standard_normal(n)
    accel = accel + noise * rng.standard_normal(n)
    return t, force, accel


def test_uniform_step_accepts_exact_grids_and_refuses_rounded_stamps():
    t, _, _ = _record()
    assert hm._uniform_step(t) == pytest.approx(1 / FS, rel=1e-12)
    assert hm._uniform_step(t + 1234.5678) is not None
    assert hm._uniform_step(np.round(np.arange(60001) / 3000.0, 6)) is None  # written to 1 us
    assert hm._uniform_step(t[:1000]) is None  # short records take the general path
    assert hm._time_step(t)[1] == hm._uniform_step(t)


@pytest.mark.parametrize("t0", [0.0, 1234.5678])
@pytest.mark.parametrize("n", [8192, 60001, 100000])
def test_table_fit_equals_the_general_fit(n, t0):
    t, _, accel = _record(n, t0, noise=0.01)
    dt = hm._uniform_step(t)
    assert dt is not None
    fast, r_fast = hm._streaming_fit(None, accel, W, 6, t0, "accel", dt)
    slow, r_slow = hm._streaming_fit(t - t[0], accel, W, 6, t0, "accel")
    c, c0 = fast.coefficients, slow.coefficients
    # the general path reads the phase off each (rounded) time stamp, the table off n dt:
    # they differ by the stamps' rounding, a phase of H omega ulp(t) at most
    stamp_phase = 6 * W * np.spacing(t[-1])
    assert np.max(np.abs(c - c0)) <= (1e-12 + 0.1 * stamp_phase) * np.max(np.abs(c0))
    assert r_fast == pytest.approx(r_slow, rel=1e-9)


def test_weighted_moments_match_direct_sums():
    t, force, _ = _record(20000)
    dt = hm._uniform_step(t)
    G, b, G1, G2, b1 = hm._uniform_moments(force, W * dt, 3, weighted=True)
    A = hm._basis(np.arange(t.size) * dt, W, 3)
    idx = np.arange(t.size, dtype=float)
    for got, want in ((G, A.T @ A), (b, A.T @ force), (G1, A.T @ (idx[:, None] * A)),
                      (G2, A.T @ (idx[:, None] ** 2 * A)), (b1, A.T @ (idx * force))):
        assert np.max(np.abs(got - want)) <= 1e-11 * np.max(np.abs(want))


def test_blocks_and_basis_blocks_rotate_the_table_exactly():
    t, force, accel = _record(70000, 5.0)
    sig = steady_state_signals(t, force, accel, frequency_hz=W / (2 * np.pi), n_harmonics=5)
    assert sig._uniform_dt is not None
    H, t0 = sig.acceleration.n_harmonics, sig.acceleration.t0
    for (sl, A), (sl2, q, v, a) in zip(sig.basis_blocks(), sig.blocks()):
        ref = hm._basis(t[sl] - t0, sig.omega, H)
        assert sl == sl2
        assert np.max(np.abs(A - ref)) < 1e-11
        assert np.allclose(q, sig.displacement(t[sl]), rtol=0, atol=1e-11 * np.abs(q).max())
        assert np.allclose(a, sig.acceleration(t[sl]), rtol=0, atol=1e-11 * np.abs(a).max())


def test_estimated_frequency_is_the_fixed_point_of_the_general_refinement():
    t, force, _ = _record(100000, 2.0, noise=0.5, seed=3)
    f = estimate_frequency(t, force)
    x = force - force.mean()
    tau = t - t[0]
    coef = hm._gn_pass(tau, x, 2 * np.pi * f, 5, None)[1]
    step, _, _ = hm._gn_pass(tau, x, 2 * np.pi * f, 5, coef)  # general path, Jacobian at f
    assert abs(step) * tau[-1] < 1e-8  # a further step would not move the phase
    assert f == pytest.approx(W / (2 * np.pi), rel=1e-6)
    step1, se, _, _ = hm._uniform_gn(x, 2 * np.pi * f, 1 / FS, 5)
    assert abs(step1) < 1e-3 * se  # the estimate's own standard error dwarfs any step left


@pytest.mark.parametrize("offset_hz, replaced", [(1e-6, False), (4e-5, False), (1e-4, True), (4e-3, True)])
def test_one_pass_check_of_a_given_frequency(offset_hz, replaced):
    t, force, accel = _record(60001, noise=0.01)  # 30 s: 4e-5 Hz drifts 7.5e-3 rad, 1e-4 Hz 0.019 rad
    f_true = W / (2 * np.pi)
    f_given = f_true + offset_hz
    drift = 2 * np.pi * offset_hz * (t[-1] - t[0])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sig = steady_state_signals(t, force, accel, frequency_hz=f_given, n_harmonics=5)
    warned = [w for w in caught if issubclass(w.category, JointidWarning)]
    assert (drift > hm.DRIFT_TOL) == replaced
    if replaced:
        assert len(warned) == 1 and "differs from the force's" in str(warned[0].message)
        assert sig.frequency_hz == pytest.approx(estimate_frequency(t, force, start_hz=f_given), rel=1e-13)
    else:
        assert not warned
        assert sig.frequency_hz == f_given


def test_time_base_errors_name_the_first_bad_sample_in_any_block():
    t = np.arange(100000) / FS
    bad = t.copy()
    bad[70001] = bad[70000]
    with pytest.raises(RecordError, match="sample 70001"):
        check_time_base(bad)
    jump = t.copy()
    jump[90000:] += 0.5 / FS
    with pytest.raises(RecordError, match="step 89999"):
        check_time_base(jump)


def test_fit_harmonics_on_a_uniform_grid_matches_a_shifted_origin():
    t, _, accel = _record(50000, 3.0)
    s1, _ = fit_harmonics(t, accel, W, 5)
    s2, _ = fit_harmonics(t, accel, W, 5, t0=float(t[0]))  # general path, same origin
    assert np.max(np.abs(s1.coefficients - s2.coefficients)) <= 1e-12 * np.max(np.abs(s2.coefficients))
