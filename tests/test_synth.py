"""Synthetic steady-state records."""

from __future__ import annotations

import numpy as np
import pytest

from jointid.errors import RecordError
from jointid.simulate.hbm import steady_state
from jointid.simulate.model import seed_model
from jointid.simulate.synth import synthesize_record


@pytest.fixture(scope="module")
def state():
    return steady_state(seed_model(), 169.0, 1.0)


def test_noise_free_record_is_the_steady_state(state):
    fs, duration, t0 = 4096.0, 0.3137, 1.2345  # non-integer number of periods, arbitrary start
    t, Q, qdd = synthesize_record(state, fs, duration, t0=t0)
    n = round(duration * fs)
    assert t.shape == Q.shape == qdd.shape == (n,)
    np.testing.assert_allclose(t, t0 + np.arange(n) / fs)
    np.testing.assert_allclose(Q, np.sin(169.0 * t), atol=1e-14)
    np.testing.assert_array_equal(qdd, state.acceleration(t))
    assert (duration * 169.0 / (2 * np.pi)) % 1 > 0.05  # really not whole periods
    # the record satisfies the equation of motion: Q - q'' = h(q, q') (seed Eq 14)
    h = seed_model().terms.restoring_force(state.q(t), state.velocity(t), state.theta)
    np.testing.assert_allclose(Q - qdd, h, atol=1e-7)


def test_start_time_shifts_the_phase(state):
    period = 2 * np.pi / state.omega
    _, Q1, a1 = synthesize_record(state, 2000.0, 0.05, t0=0.0)
    _, Q2, a2 = synthesize_record(state, 2000.0, 0.05, t0=3 * period)
    np.testing.assert_allclose(Q1, Q2, atol=1e-12)
    np.testing.assert_allclose(a1, a2, rtol=1e-9, atol=1e-9 * np.max(np.abs(a1)))
    _, Q3, _ = synthesize_record(state, 2000.0, 0.05, t0=period / 4)
    np.testing.assert_allclose(Q3[0], 1.0)


def test_noise_is_seeded_independent_and_scaled(state):
    kw = dict(fs=20000.0, duration=5.0, noise=0.05)
    t, Q, a = synthesize_record(state, rng=7, **kw)
    _, Q_again, a_again = synthesize_record(state, rng=np.random.default_rng(7), **kw)
    np.testing.assert_array_equal(Q, Q_again)
    np.testing.assert_array_equal(a, a_again)
    _, Q_other, _ = synthesize_record(state, rng=8, **kw)
    assert not np.array_equal(Q, Q_other)
    eQ = Q - state.force(t)
    ea = a - state.acceleration(t)
    rms = lambda x: np.sqrt(np.mean(x**2))  # noqa: E731
    assert rms(eQ) == pytest.approx(0.05 * rms(state.force(t)), rel=0.02)
    assert rms(ea) == pytest.approx(0.05 * rms(state.acceleration(t)), rel=0.02)
    assert abs(np.corrcoef(eQ, ea)[0, 1]) < 0.02  # independent channels
    assert abs(np.mean(eQ)) < 5 * 0.05 * rms(state.force(t)) / np.sqrt(t.size)


@pytest.mark.parametrize(
    "kwargs",
    [dict(fs=0.0, duration=1.0), dict(fs=100.0, duration=-1.0), dict(fs=100.0, duration=1.0, noise=-0.1),
     dict(fs=100.0, duration=0.001), dict(fs=np.nan, duration=1.0)],
)
def test_bad_arguments(state, kwargs):
    with pytest.raises(RecordError):
        synthesize_record(state, **kwargs)
