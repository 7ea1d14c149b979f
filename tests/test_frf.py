"""Linear FRFs: simulation by modal superposition, H1, coherence, modal fit."""

from __future__ import annotations

import numpy as np
import pytest

from jointid.errors import IdentificationError, RecordError
from jointid.modal import modal_analysis, seed_bolted_beam, simulate_beam_response
from jointid.signal.frf import fit_modes, h1_estimate, modal_frf, simulate_modal_response

FS = 4096.0


@pytest.fixture(scope="module")
def modes():
    return modal_analysis(seed_bolted_beam(120), 6)


@pytest.mark.parametrize("output", ["displacement", "velocity", "acceleration"])
def test_simulation_steady_state_matches_closed_form(output):
    """Sine input: steady state equals Im(H e^{i w t}) up to the first-order-hold error."""
    wr, zeta = np.array([2 * np.pi * 20.0, 2 * np.pi * 90.0]), np.array([0.02, 0.01])
    pf, po = np.array([0.3, -0.5]), np.array([[1.0, 0.7], [0.2, -1.1]])
    fs, f = 20000.0, 25.0
    t = np.arange(int(8 * fs)) / fs
    r = simulate_modal_response(wr, zeta, pf, po, np.sin(2 * np.pi * f * t), fs, output=output)
    H = modal_frf([f], wr, zeta, pf, po, output)[:, 0]
    k = t > 6.0
    exact = np.imag(H[:, None] * np.exp(2j * np.pi * f * t[None, k]))
    assert np.max(np.abs(r.response[:, k] - exact)) < 2e-4 * np.max(np.abs(exact))
    # internal consistency of the modal states
    assert np.allclose(r.qdd, pf[:, None] * np.sin(2 * np.pi * f * t) - 2 * (zeta * wr)[:, None] * r.qd
                       - (wr**2)[:, None] * r.q, atol=1e-6 * np.max(np.abs(r.qdd)))


@pytest.fixture(scope="module")
def random_test(modes):
    rng = np.random.default_rng(1)
    nperseg = 2**15  # 0.125 Hz resolution
    n = 10 * nperseg
    force = rng.standard_normal(n)
    r = simulate_beam_response(modes, force, FS, 0.05, [0.30, 0.42], damping_ratio=0.01, n_modes=5)
    noisy = r.response + 0.02 * np.std(r.response, axis=1, keepdims=True) * rng.standard_normal(r.response.shape)
    return force, noisy, h1_estimate(force, noisy, FS, nperseg=nperseg)


def test_h1_recovers_first_three_frequencies_within_0p2_percent(modes, random_test):
    """The FRF at the tip accelerometer (x = 42 cm, the seed's Fig 9), 2 % output noise."""
    _, _, est = random_test
    fit = fit_modes(est, 3, channel=1, f_range=(5.0, 700.0))
    err = fit.frequencies_hz / modes.frequencies_hz[:3] - 1
    assert np.all(np.abs(err) < 0.002), err
    assert np.allclose(fit.damping_ratios, 0.01, rtol=0.2)
    assert np.all(fit.fit_errors < 0.1)
    assert "mode" in fit.report()
    # at x = 30 cm mode 2 is close to its node: automatic picking refuses noise spikes
    with pytest.raises(IdentificationError, match="peaks"):
        fit_modes(est, 3, channel=0, f_range=(5.0, 300.0))
    fit0 = fit_modes(est, channel=0, bands=[(20.0, 33.0), (440.0, 500.0)])
    assert np.all(np.abs(fit0.frequencies_hz / modes.frequencies_hz[[0, 2]] - 1) < 0.002)


def test_h1_matches_the_closed_form_frf(modes):
    """Periodic (FFT) simulation: H1 equals the closed-form FRF; FOH: close at low frequency."""
    rng = np.random.default_rng(2)
    nperseg = 2**13
    force = rng.standard_normal(8 * nperseg)
    sel = list(range(5))
    for method, f_max, tol in (("fft", 1500.0, 0.01), ("foh", 150.0, 0.01)):
        r = simulate_beam_response(modes, force, FS, 0.05, [0.30, 0.42], damping_ratio=0.05, n_modes=5,
                                   method=method)
        est = h1_estimate(force, r.response, FS, nperseg=nperseg)
        H = modal_frf(est.frequency_hz, modes.omega[:5], 0.05, modes.shape_at([0.05], sel)[0],
                      modes.shape_at([0.30, 0.42], sel))
        band = (est.frequency_hz > 10) & (est.frequency_hz < f_max) & (est.coherence[1] > 0.99)
        assert np.count_nonzero(band) > 100
        rel = np.abs(est.H[1, band] / H[1, band] - 1)
        assert np.median(rel) < tol, (method, np.median(rel))
    assert est.n_averages == 15 and est.frequency_hz[1] == pytest.approx(0.5)


def test_fit_modes_on_exact_frf_is_exact():
    f = np.linspace(1, 300, 6000)
    wr, zeta = 2 * np.pi * np.array([30.0, 150.0]), np.array([0.005, 0.02])
    H = modal_frf(f, wr, zeta, [0.2, 0.4], [1.0, -0.8])
    fit = fit_modes((f, H), 2)
    assert np.allclose(fit.frequencies_hz, [30.0, 150.0], rtol=1e-6)
    assert np.allclose(fit.damping_ratios, zeta, rtol=1e-4)
    assert np.allclose(fit.modal_constants.real, [0.2, -0.32], rtol=1e-3)
    assert np.allclose(fit.synthesize([30.0]), modal_frf([30.0], wr, zeta, [0.2, 0.4], [1.0, -0.8]), rtol=1e-2)
    explicit = fit_modes((f, H), bands=[(25, 35)])
    assert explicit.frequencies_hz[0] == pytest.approx(30.0, rel=1e-6)


def test_frf_bad_input():
    f = np.linspace(1, 100, 500)
    H = modal_frf(f, [2 * np.pi * 30.0], 0.01, [1.0], [1.0])
    with pytest.raises(IdentificationError, match="peaks"):
        fit_modes((f, H), 3)
    with pytest.raises(IdentificationError, match="FRF points"):
        fit_modes((f, H), bands=[(29.9, 30.1)])
    with pytest.raises(RecordError):
        h1_estimate(np.ones(100), np.ones(99), 100.0)
    with pytest.raises(ValueError, match="Nyquist|fs/2"):
        simulate_modal_response([2 * np.pi * 600.0], 0.01, [1.0], [[1.0]], np.ones(10), 1000.0)
