"""Standard errors of band-limited ring-down windows (modal_ringdown): the band's correlated noise.

A linear decay, so the truth of every window is exact: frequency ``F0`` and damping ratio ``ZETA``.
"""

from __future__ import annotations

import numpy as np
import pytest

from jointid.signal.ringdown import _noise_acf, band_limit, fit_decay, modal_ringdown

F0, FS, ZETA = 40.0, 1000.0, 0.002


def _decay(seed, noise=0.02, periods=160):
    t = np.arange(-0.05, periods / F0, 1 / FS)
    tp = np.clip(t, 0, None)
    wn = 2 * np.pi * F0
    x = np.where(t >= 0, np.exp(-ZETA * wn * tp) * np.sin(wn * np.sqrt(1 - ZETA**2) * tp), 0.0)
    return t, x + noise * np.random.default_rng(seed).standard_normal(t.size)


def test_the_noise_autocorrelation_is_that_of_band_limited_white_noise():
    t = np.arange(400_000) / FS
    band = (34.0, 46.0)
    acf = _noise_acf(t, band, 4, 120)
    y = band_limit(t, np.random.default_rng(1).standard_normal(t.size), band)[2000:-2000]
    lags = np.arange(0, 120, 7)
    emp = np.array([np.mean(y[: y.size - k] * y[k:]) for k in lags]) / np.mean(y * y)
    assert acf[0] == 1.0
    np.testing.assert_allclose(acf[lags], emp, atol=0.04)  # ~ 2.5 / sqrt(number of correlation times)
    assert np.min(acf) < -0.5  # an oscillating correlation: the band is narrow, far from white


def test_a_linear_decay_has_few_misfit_windows_and_a_drifting_one_has_them_first():
    t, x = _decay(3)
    d = modal_ringdown(t, x, frequency_hz=F0, n_cycles=8, hop_cycles=8)
    assert d.misfit.dtype == bool and d.misfit.sum() <= 1  # 99 % point: ~0.2 of 20 windows by chance
    # the white-noise fit keeps each window's own residual and also says which windows misfit
    fd = fit_decay(t, x, frequency_hz=F0, start=0.0, n_cycles=8)
    assert fd.misfit.shape == (len(fd),) and fd.misfit.sum() <= 2
    # a chirp inside the window (frequency falling 2 % over the first 40 periods): a residual beyond the noise
    tp = np.clip(t, 0, None)
    f = F0 * (1 + 0.02 * np.exp(-tp / 0.5))
    y = np.where(t >= 0, np.exp(-ZETA * 2 * np.pi * F0 * tp) * np.sin(2 * np.pi * np.cumsum(f) / FS), 0.0)
    y = y + 0.02 * np.random.default_rng(3).standard_normal(t.size)
    dd = modal_ringdown(t, y, frequency_hz=F0, n_cycles=8, hop_cycles=8)
    assert dd.misfit[0] and not dd.misfit[-5:].any()
    b = dd.backbone()
    assert b.meta["misfit"] == dd.misfit[~dd.below_noise_floor].tolist()


@pytest.mark.slow
def test_standard_errors_are_calibrated_across_bands_windows_and_overlap():
    """std(z) of frequency and damping ratio in 0.8-1.25 and |mean z| small, for +-15 % and +-50 % bands,
    8, 12 and 16-period windows, hop of a window and of half a window (20 noise draws each).

    Measured: std z 0.88-1.05 (frequency), 0.97-1.10 (damping), |mean| <= 0.13; before (white-noise
    formula scaled by the band's noise bandwidth) 1.45-2.0 for the +-15 % band.
    """
    out = []
    for hw in (0.15, 0.5):
        for nc in (8, 12, 16):
            for hop in (nc, nc / 2):
                zf, zz = [], []
                for seed in range(20):
                    t, x = _decay(seed)
                    b = modal_ringdown(t, x, frequency_hz=F0, half_width=hw * F0, n_cycles=nc,
                                       hop_cycles=hop).backbone()
                    zf += list((b.omega - 2 * np.pi * F0) / b.omega_stderr)
                    zz += list((b.zeta - ZETA) / b.zeta_stderr)
                zf, zz = np.array(zf), np.array(zz)
                out.append((hw, nc, hop, zf.size, zf.std(), zz.std(), zf.mean(), zz.mean()))
    print("\n".join(f"+-{hw:.2f} {nc:2d}/{hop:4.1f} n {n:3d} std {sf:.2f} {sz:.2f} mean {mf:+.2f} {mz:+.2f}"
                    for hw, nc, hop, n, sf, sz, mf, mz in out))
    for hw, nc, hop, n, sf, sz, mf, mz in out:
        assert 0.8 < sf < 1.25 and 0.8 < sz < 1.25, (hw, nc, hop, sf, sz)
        assert abs(mf) < 0.25 and abs(mz) < 0.25, (hw, nc, hop, mf, mz)
