"""The slider (play-operator) AFT evaluated a monotone stretch at a time equals the sample loop to the bit.

The oracle below is the sample-by-sample implementation that ``joints/sliders._slider_aft`` had
before it was vectorised; the current routine must give the same force and Jacobian exactly
(``np.array_equal``, not a tolerance) on random multi-harmonic motions, batches, many reversals,
flat stretches, constant motions, arbitrary start states, with and without the Jacobian and
the centred start.
"""

from __future__ import annotations

import numpy as np
import pytest

from jointid.joints import DiscreteIwan, Iwan4, Jenkins
from jointid.errors import StructureError
from jointid.joints import sliders


def _oracle(u, k, phi, x0, jacobian, centre=False):
    """Sample loop over two sweeps (the routine before vectorisation, kept verbatim)."""
    u = np.asarray(u, float)
    n = u.shape[-1]
    batch = u.shape[:-1]
    m = k.size
    x = np.array(np.broadcast_to(x0, batch + (m,)), dtype=float)
    ktot = float(k.sum())
    f = np.empty(u.shape)
    last = np.full(x.shape, -1, dtype=np.intp)
    lasts = np.empty((n,) + x.shape, dtype=np.intp) if jacobian else None
    for step in range(2 * n):
        j = step % n
        uj = u[..., j, None]
        xn = np.minimum(np.maximum(x, uj - phi), uj + phi)
        if jacobian:
            last = np.where(xn != x, j, last)
        x = xn
        if step >= n:
            f[..., j] = ktot * u[..., j] - x @ k
            if jacobian:
                lasts[j] = last
    if not jacobian:
        return f, None
    nb = int(np.prod(batch, dtype=int))
    L = lasts.reshape(n, nb, m)
    rows = np.broadcast_to(np.arange(n)[:, None, None], L.shape)
    bidx = np.broadcast_to(np.arange(nb)[None, :, None], L.shape)
    w = np.broadcast_to(k, L.shape)
    seen = L >= 0
    flat = (bidx * n * n + rows * n + L)[seen]
    D = -np.bincount(flat, weights=w[seen], minlength=nb * n * n).astype(float).reshape(nb, n, n)
    D[:, np.arange(n), np.arange(n)] += ktot
    if centre:
        k_never = (np.where(L[0] < 0, k, 0.0)).sum(axis=-1)
        ub = u.reshape(nb, n)
        imax, imin = np.argmax(ub, axis=-1), np.argmin(ub, axis=-1)
        D[np.arange(nb), :, imax] -= 0.5 * k_never[:, None]
        D[np.arange(nb), :, imin] -= 0.5 * k_never[:, None]
    return f, D.reshape(batch + (n, n))


def _motion(rng, batch, n, H, scale=1e-3, quantum=None):
    """Random multi-harmonic periodic motions with harmonics 0..H (mean included)."""
    t = 2 * np.pi * np.arange(n) / n
    c = rng.normal(size=batch + (H + 1,)) * scale / (1.0 + np.arange(H + 1)) ** 0.5
    s = rng.normal(size=batch + (H + 1,)) * scale / (1.0 + np.arange(H + 1)) ** 0.5
    h = np.arange(H + 1)
    u = (c[..., None] * np.cos(h[:, None] * t) + s[..., None] * np.sin(h[:, None] * t)).sum(axis=-2)
    if quantum is not None:  # flat stretches and repeated extremes
        u = np.round(u / quantum) * quantum
    return u


def _sliders(rng, m, scale=1e-3):
    k = rng.uniform(0.1, 2.0, m) * 1e4
    phi = np.sort(rng.uniform(0.0, 1.5, m)) * scale + 1e-9
    return k, phi


def _same(got, want):
    f, D = got
    f0, D0 = want
    assert f.shape == f0.shape and np.array_equal(f, f0, equal_nan=True)  # NaN where the sample loop has NaN
    if D0 is None:
        assert D is None
    else:
        assert D.shape == D0.shape and np.array_equal(D, D0, equal_nan=True)


CASES = [  # batch, n, highest harmonic, sliders, quantum
    ((), 256, 7, 101, None),
    ((), 64, 31, 40, None),  # up to Nyquist: a reversal at nearly every sample
    ((3,), 128, 5, 17, None),
    ((1,), 32, 3, 5, None),
    ((2, 3), 48, 11, 9, None),
    ((4,), 40, 6, 12, 2e-4),  # flats
    ((), 16, 2, 1, None),  # one element (Jenkins)
    ((5,), 7, 3, 3, None),
    ((2,), 2, 1, 4, None),
    ((2,), 1, 0, 4, None),
]


@pytest.mark.parametrize("batch,n,H,m,quantum", CASES)
@pytest.mark.parametrize("jacobian", [True, False])
def test_equals_sample_loop(batch, n, H, m, quantum, jacobian):
    rng = np.random.default_rng(abs(hash((batch, n, H, m))) % 2**32)
    for trial in range(3):
        u = _motion(rng, batch, n, H, quantum=quantum)
        k, phi = _sliders(rng, m)
        # start states: virgin, arbitrary (outside the motion's range too), and centred
        starts = [(np.zeros(batch + (m,)), False), (rng.normal(size=batch + (m,)) * 2e-3, False)]
        if n:
            mid = 0.5 * (u.max(axis=-1) + u.min(axis=-1))
            starts.append((np.broadcast_to(mid[..., None], batch + (m,)), True))
        for x0, centre in starts:
            _same(sliders._slider_aft(u, k, phi, x0, jacobian, centre), _oracle(u, k, phi, x0, jacobian, centre))


@pytest.mark.parametrize("jacobian", [True, False])
def test_constant_and_blocked(monkeypatch, jacobian):
    rng = np.random.default_rng(7)
    k, phi = _sliders(rng, 30)
    u = np.full((3, 50), 4e-4)
    u[1] = -2e-4
    x0 = rng.normal(size=(3, 30)) * 1e-3
    _same(sliders._slider_aft(u, k, phi, x0, jacobian), _oracle(u, k, phi, x0, jacobian))
    # long motions go in blocks of samples: the same numbers with tiny blocks
    u = _motion(rng, (3,), 96, 9)
    want = _oracle(u, k, phi, x0, jacobian, False)
    for block in (2 * 3 * 30, 5 * 3 * 30, 97 * 3 * 30):
        monkeypatch.setattr(sliders, "BLOCK_ELEMENTS", block)
        _same(sliders._slider_aft(u, k, phi, x0, jacobian), want)


def test_laws_through_the_public_aft():
    rng = np.random.default_rng(3)
    law = Iwan4(F_S=2.0, K_T=2000.0, chi=-0.4, beta=0.5, n_sliders=100)
    el = law.sliders
    for batch in [(), (4,)]:
        u = _motion(rng, batch, 256, 7, scale=1.5e-3)
        for state0 in (None, "centre"):
            f, D = law.aft(u, state0=state0)
            if state0 is None:
                x0 = np.zeros(batch + (el.n_elements,))
            else:
                x0 = np.broadcast_to((0.5 * (u.max(-1) + u.min(-1)))[..., None], batch + (el.n_elements,))
            _same((f, D), _oracle(u, el.stiffness, el.slip_displacement, x0, True, state0 == "centre"))
    jk = Jenkins(kt=1e4, Fs=3.0)
    u = _motion(rng, (), 64, 5)
    _same(jk.aft(u), _oracle(u, np.array([1e4]), np.array([3e-4]), np.zeros(1), True))
    with pytest.raises(StructureError, match="state0"):
        DiscreteIwan([1.0], [1.0]).aft(u, state0="middle")


@pytest.mark.parametrize("jacobian", [True, False])
def test_rounding_ties_and_non_finite(jacobian):
    """Steps below the rounding of ``u -+ phi`` (the bound does not move although ``u`` does: the
    latest slip lies before the stretch's end) and non-finite samples (the sample path's rules)."""
    rng = np.random.default_rng(11)
    up = np.linspace(-1.2e-3, 1e-7, 30)
    top = 1e-7 + np.arange(1, 7) * 2e-23  # strictly increasing, below the spacing of 1e-7 - 5e-4
    u = np.concatenate([up, top, np.linspace(1e-7, -1.2e-3, 30)[1:], up[1:5]])
    assert np.all(np.diff(top) > 0)
    k = rng.uniform(0.1, 2.0, 7) * 1e4
    phi = np.array([1e-9, 1e-6, 1e-4, 5e-4, 5.5e-4, 6e-4, 2e-3])
    batch = np.stack([u, u[::-1], np.roll(u, 17)])
    for x0 in (np.zeros((3, 7)), rng.normal(size=(3, 7)) * 1e-3):
        _same(sliders._slider_aft(batch, k, phi, x0, jacobian), _oracle(batch, k, phi, x0, jacobian))
    bad = batch.copy()
    bad[0, 5], bad[1, 40], bad[2, 0] = np.nan, np.inf, -np.inf
    with np.errstate(invalid="ignore"):
        _same(sliders._slider_aft(bad, k, phi, np.zeros((3, 7)), jacobian), _oracle(bad, k, phi, np.zeros((3, 7)), jacobian))
