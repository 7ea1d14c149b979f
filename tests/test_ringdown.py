"""Ring-down records: windowed damped-oscillation fit, backbone and free-decay force-state mapping."""

import json

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from jointid.errors import JointidWarning, RecordError
from jointid.identify.backbone import model_backbone
from jointid.identify.ringdown import ringdown_force_state_mapping
from jointid.signal.ringdown import dominant_frequency, fit_decay

FS = 2048.0


def _linear_decay(wn=2 * np.pi * 26.4, z=0.002, a0=0.005, duration=6.0, noise=0.0, seed=0):
    t = np.arange(int(duration * FS)) / FS
    lam = -z * wn + 1j * wn * np.sqrt(1 - z * z)
    acc = (a0 * np.exp(0.3j) * lam**2 * np.exp(lam * t)).real
    acc = acc + noise * np.std(acc[: int(FS)]) * np.random.default_rng(seed).standard_normal(t.size)
    return t, acc, lam


def test_linear_decay_exact_without_noise():
    wn, z = 2 * np.pi * 26.4, 0.002
    t, acc, lam = _linear_decay(wn, z)
    d = fit_decay(t, acc)
    np.testing.assert_allclose(d.omega_n, wn, rtol=1e-9)
    np.testing.assert_allclose(d.zeta, z, rtol=1e-6)
    np.testing.assert_allclose(d.amplitude, 0.005 * np.exp(-z * wn * d.t_centre), rtol=1e-7)
    assert not d.below_noise_floor.any()
    k, se, a = ringdown_force_state_mapping(d, t, acc)
    np.testing.assert_allclose(k[:, 0], wn**2, rtol=1e-7)
    np.testing.assert_allclose(k[:, 1], 2 * z * wn, rtol=1e-5)
    json.dumps(d.summary())
    assert "windows" in d.report()


def test_noisy_decay_errors_are_honest():
    """1 % noise: every estimate lies within 4 of its own standard errors of the truth."""
    wn, z = 2 * np.pi * 26.4, 0.002
    t, acc, _ = _linear_decay(wn, z, noise=0.01, seed=4)
    d = fit_decay(t, acc)
    amp = 0.005 * np.exp(-z * wn * d.t_centre)
    assert np.all(np.abs(d.omega_n - wn) < 4 * d.omega_stderr)
    assert np.all(np.abs(d.zeta - z) < 4 * d.zeta_stderr)
    assert np.all(np.abs(d.amplitude - amp) < 4 * d.amplitude_stderr + 1e-3 * amp)
    top = amp > amp.max() / 3
    assert np.all(np.abs(d.omega_n[top] / wn - 1) < 1e-4) and np.all(np.abs(d.zeta[top] / z - 1) < 0.03)


def test_noise_floor_is_flagged():
    t, acc, _ = _linear_decay(z=0.01, noise=0.01, duration=8.0)
    d = fit_decay(t, acc)
    assert d.below_noise_floor[-1] and not d.below_noise_floor[0]
    b = d.backbone()
    assert len(b) == np.count_nonzero(~d.below_noise_floor) and b.source == "ringdown"
    assert np.all(b.amplitude > 30 * b.amplitude_stderr)


def test_duffing_decay_follows_the_model_backbone():
    """Free decay of q'' + c q' + w1^2 q - k3 q^3 = 0: omega(a), zeta(a) of the model's backbone."""
    w1, k3, c = 170.0, 5e6, 0.6
    sol = solve_ivp(lambda t, y: [y[1], -c * y[1] - w1**2 * y[0] + k3 * y[0] ** 3], (0, 6.0), [0.012, 0.0],
                    t_eval=np.arange(int(6 * FS)) / FS, rtol=1e-11, atol=1e-14, method="DOP853")
    q, v = sol.y
    acc = -c * v - w1**2 * q + k3 * q**3
    d = fit_decay(sol.t, acc)
    ref = model_backbone("q + -q^3 + q'", [w1**2, k3, c], d.amplitude, n_harmonics=7)
    # a window of duration T averages omega^2 over amplitudes: the stated bias is (sigma T)^2 / 6
    # of the nonlinear part of omega^2 (here 0.6 % softening over the decay)
    T = d.n_cycles * 2 * np.pi / d.omega_n
    bias = (d.zeta * d.omega_n * T) ** 2 / 6 * np.abs(w1**2 - ref.omega**2) / (2 * ref.omega**2)
    assert np.all(np.abs(d.omega_n / ref.omega - 1) < 1.5 * bias + 1e-5)
    np.testing.assert_allclose(d.zeta, ref.zeta, rtol=0.01)
    short = fit_decay(sol.t, acc, n_cycles=8.0)
    ref8 = model_backbone("q + -q^3 + q'", [w1**2, k3, c], short.amplitude, n_harmonics=7)
    assert np.max(np.abs(short.omega_n / ref8.omega - 1)) < 0.4 * np.max(np.abs(d.omega_n / ref.omega - 1))


def test_dominant_frequency_and_bad_input():
    t, acc, lam = _linear_decay()
    assert abs(dominant_frequency(t, acc) - lam.imag / (2 * np.pi)) < 0.02
    with pytest.raises(RecordError, match="constant"):
        fit_decay(t, np.ones_like(t))
    with pytest.raises(RecordError, match="periods"):
        fit_decay(t[:100], acc[:100])
    with pytest.raises(RecordError, match="kind"):
        fit_decay(t, acc, kind="jerk")
    bad = acc.copy()
    bad[10] = np.nan
    with pytest.raises(RecordError):
        fit_decay(t, bad)
    with pytest.warns(JointidWarning, match="noise floor"):
        fit_decay(t, np.random.default_rng(0).standard_normal(t.size), frequency_hz=26.0)


def test_invariant_to_time_shift_and_units():
    t, acc, _ = _linear_decay(noise=0.01, seed=9)
    d = fit_decay(t, acc)
    shifted = fit_decay(t + 123.456, acc)
    scaled = fit_decay(t, 1e3 * acc)
    np.testing.assert_allclose(shifted.omega_n, d.omega_n, rtol=1e-9)
    np.testing.assert_allclose(shifted.zeta, d.zeta, rtol=1e-6)
    np.testing.assert_allclose(shifted.amplitude, d.amplitude, rtol=1e-8)
    np.testing.assert_allclose(scaled.amplitude, 1e3 * d.amplitude, rtol=1e-8)
    np.testing.assert_allclose(scaled.zeta, d.zeta, rtol=1e-7)
    np.testing.assert_allclose(scaled.zeta_stderr, d.zeta_stderr, rtol=1e-5)
