"""Ring-down of one mode without a force: zero-phase band limit, skipped impact, backbone in signal amplitude."""

from __future__ import annotations

import numpy as np
import pytest

from jointid.errors import RecordError
from jointid.signal.ringdown import band_limit, modal_ringdown, monotone_check

FS = 4000.0


def _impact(noise=0.0, seed=0, T=4.0, zeta=0.002):
    """Mode 1: softening, f = 80 (1 - 0.004 a / 20) Hz at acceleration amplitude a; mode 2 at 222 Hz, stronger."""
    t = np.arange(-0.05, T, 1 / FS)
    tp = np.clip(t, 0, None)
    a = 20.0 * np.exp(-zeta * 2 * np.pi * 80 * tp)
    f = 80.0 * (1 - 0.004 * a / 20)
    phase = 2 * np.pi * np.cumsum(f) / FS
    x = np.where(t >= 0, a * np.sin(phase) + 60.0 * np.exp(-0.004 * 2 * np.pi * 222 * tp)
                 * np.sin(2 * np.pi * 222 * tp), 0.0)
    x = x + noise * np.random.default_rng(seed).standard_normal(t.size)
    return t, x, (lambda amp: 80.0 * (1 - 0.004 * amp / 20))


def test_band_limited_decay_gives_the_softening_backbone_against_the_acceleration_amplitude():
    t, x, f_of_a = _impact(noise=0.05)
    d = modal_ringdown(t, x, f_range=(60, 100), n_cycles=16, hop_cycles=8)
    b = d.backbone(measure="signal", amplitude_unit="m/s^2")
    assert len(b) > 10 and b.meta["amplitude_unit"] == "m/s^2"
    # the amplitude is the acceleration envelope, the frequency follows the law, zeta the decay
    err = b.frequency_hz - f_of_a(b.amplitude)
    assert np.all(np.abs(err) < 4 * b.omega_stderr / (2 * np.pi) + 2e-5 * 80), err / (b.omega_stderr / (2 * np.pi))
    assert np.all(np.abs(b.zeta - 0.002) < 4 * b.zeta_stderr + 1e-5)
    env = 20.0 * np.exp(-0.002 * 2 * np.pi * 80 * np.asarray(b.meta["t_centre"]))
    np.testing.assert_allclose(b.amplitude, env, rtol=0.01)
    mono = monotone_check(b.amplitude, b.omega, b.omega_stderr)
    assert mono["monotone"] and mono["trend"] == "decreasing"


def test_without_the_band_limit_the_second_mode_spoils_the_fit():
    from jointid.signal.ringdown import fit_decay

    t, x, f_of_a = _impact()
    raw = fit_decay(t, x, frequency_hz=80.0, n_cycles=16, hop_cycles=8, start=0.2).backbone()
    assert np.max(np.abs(raw.frequency_hz / 80.0 - 1)) > 1e-3  # the 222 Hz mode is in the windows


def test_the_noise_floor_is_flagged_and_left_out():
    t, x, _ = _impact(noise=0.5, T=6.0, zeta=0.004)
    d = modal_ringdown(t, x, frequency_hz=80.0, n_cycles=16, hop_cycles=8)
    assert d.below_noise_floor[-1] and not d.below_noise_floor[0]
    b = d.backbone(measure="signal")
    assert len(b) == int(np.count_nonzero(~d.below_noise_floor))


def test_bad_band_is_refused():
    t, x, _ = _impact()
    with pytest.raises(RecordError, match="Nyquist"):
        band_limit(t, x, (60.0, 3000.0))
    with pytest.raises(RecordError, match="measure"):
        modal_ringdown(t, x, f_range=(60, 100)).backbone(measure="velocity")


@pytest.mark.slow
def test_band_limited_standard_errors_are_calibrated():
    """std(z) of the windows' frequency and damping over noisy impacts (non-overlapping windows).

    The softening decay drifts inside its first windows beyond the noise (``misfit``): those keep
    their own residual's level and are conservative; the others are calibrated to the noise.
    """
    zf, zz, mis = [], [], []
    for seed in range(8):
        t, x, f_of_a = _impact(noise=0.05, seed=seed)
        b = modal_ringdown(t, x, f_range=(60, 100), n_cycles=16, hop_cycles=16).backbone(measure="signal")
        zf += list((b.frequency_hz - f_of_a(b.amplitude)) / (b.omega_stderr / (2 * np.pi)))
        zz += list((b.zeta - 0.002) / b.zeta_stderr)
        mis += b.meta["misfit"]
    zf, zz, mis = np.array(zf), np.array(zz), np.array(mis, bool)
    assert 0 < mis.sum() < 0.4 * mis.size  # the drift of the first windows, not the whole decay
    ok = ~mis
    assert 0.8 < np.std(zf[ok]) < 1.25 and 0.8 < np.std(zz[ok]) < 1.25, (np.std(zf[ok]), np.std(zz[ok]))
    assert np.max(np.abs(zf[mis])) < 3 and np.max(np.abs(zz[mis])) < 3


def test_a_decay_whose_first_window_fits_nothing_is_a_record_error(monkeypatch):
    import jointid.signal.ringdown as rd

    t, x, _ = _impact(noise=0.05)
    monkeypatch.setattr(rd, "_fit_window", lambda *a, **k: (np.full(5, np.nan), np.eye(5), 1.0, 1.0, 1.0))
    with pytest.raises(RecordError, match="fits no decaying oscillation"):
        rd.fit_decay(t, x, frequency_hz=80.0, n_cycles=16, hop_cycles=8)
