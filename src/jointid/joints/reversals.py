"""Slider laws whose alternating frequency/time map reverses at the exact extrema of the motion.

:class:`ExactReversals` wraps a rate-independent (Masing) slider law of this package
(:class:`~jointid.joints.Jenkins`, :class:`~jointid.joints.DiscreteIwan`,
:class:`~jointid.joints.Iwan4`); its ``aft`` inserts the extrema of the trigonometric
polynomial through the samples before the law's own map, its time-step protocol
(``force``, ``initial_state``) is the wrapped law's.
"""

from __future__ import annotations

import numpy as np

__all__ = ["ExactReversals"]


class ExactReversals:
    """A slider law (Masing, rate independent) whose AFT reverses at the exact extrema of the motion.

    The sampled map of a slider law reverses the sliders at the largest and smallest
    *sample*, not at the extremum of the motion between samples: its force is off by
    ``O(N^-2)`` and, worse, jumps as an extremum crosses a sample, which makes the peak of a
    response jagged in frequency at the 1e-5 level (a finite-difference derivative over one
    standard error is then noise).  The motion samples of harmonic balance are a trigonometric
    polynomial of degree below ``N / 2``; its extrema (zeros of the spectral derivative,
    Newton from the bracketing samples) are inserted as extra samples, the law's ``aft`` runs on
    the augmented sequence (a rate-independent law depends on the order of the values only),
    and the inserted samples are dropped.  The Jacobian is exact: at an extremum ``u'(t*) = 0``,
    so ``d u(t*) / d u_j`` is the trigonometric interpolation weight of sample ``j`` at ``t*``.
    """

    rate_dependent = False

    def __init__(self, law):
        self.law = law

    def __repr__(self):
        return f"ExactReversals({self.law!r})"

    # the time-step protocol is the wrapped law's (a time integration reverses at its own extrema)
    @property
    def n_state(self) -> int:
        return self.law.n_state

    def initial_state(self, shape=()):
        return self.law.initial_state(shape)

    def force(self, u, v, state):
        return self.law.force(u, v, state)

    @staticmethod
    def _extrema(u):
        n = u.size
        K = (n - 1) // 2
        c = np.fft.rfft(u)[1:K + 1] * (2.0 / n)  # u = c0 + sum Re(c_k e^{i k t}), t = 2 pi j / n
        k = np.arange(1, K + 1)
        t = 2 * np.pi * np.arange(n) / n
        v = (np.exp(1j * np.outer(t, k)) @ (1j * k * c)).real
        j = np.flatnonzero(v * np.roll(v, -1) < 0)
        if j.size == 0:
            return np.zeros(0), np.zeros((0, n))
        h = 2 * np.pi / n
        ts = t[j] + h * v[j] / (v[j] - v[(j + 1) % n])  # linear zero of u' between the samples
        for _ in range(6):  # Newton on u'(t) = 0
            z = np.exp(1j * np.outer(ts, k))
            d1 = (z @ (1j * k * c)).real
            d2 = (z @ (-(k**2) * c)).real
            ts = np.clip(ts - d1 / np.where(d2 == 0, 1e-300, d2), t[j], t[j] + h)
        # trigonometric interpolation weights of the samples at ts (degree K, n > 2K)
        dt = ts[:, None] - t[None, :]
        W = (1.0 + 2.0 * np.cos(np.multiply.outer(dt, k)).sum(axis=-1)) / n
        return ts, W

    def aft(self, u_t, v_t=None, *, velocity_jacobian=False, jacobian=True):
        u = np.asarray(u_t, float)
        if u.ndim != 1:
            out = [self.aft(x, jacobian=jacobian) for x in u.reshape(-1, u.shape[-1])]
            f = np.array([o[0] for o in out]).reshape(u.shape)
            D = None if not jacobian else np.array([o[1] for o in out]).reshape(u.shape + (u.shape[-1],))
            return (f, D, None if D is None else np.zeros_like(D)) if velocity_jacobian else (f, D)
        n = u.size
        ts, W = self._extrema(u)
        t = 2 * np.pi * np.arange(n) / n
        times = np.concatenate([t, ts])
        vals = np.concatenate([u, W @ u])
        order = np.argsort(times, kind="stable")
        f_aug, D_aug = self.law.aft(vals[order], jacobian=jacobian)
        pos = np.empty(order.size, dtype=np.intp)
        pos[order] = np.arange(order.size)  # where each original / inserted sample sits in the sequence
        f = f_aug[pos[:n]]
        D = None
        if jacobian:
            D_aug = np.asarray(D_aug)[pos[:n]]
            D = D_aug[:, pos[:n]] + D_aug[:, pos[n:]] @ W
        if velocity_jacobian:
            return f, D, None if D is None else np.zeros_like(D)
        return f, D
