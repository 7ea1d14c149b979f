"""The slider laws' projected AFT (``aft_projected``: force and ``P (df/du) E`` a monotone stretch at a
time, without the dense time Jacobian) against the dense routine ``_slider_aft`` (which
tests/test_slider_aft.py holds equal to the sample loop to the bit), and by finite differences.
"""

from __future__ import annotations

import numpy as np
import pytest

from jointid.joints import DiscreteIwan, Iwan4, Jenkins
from jointid.joints import sliders
from jointid.numerics.aft import aft_basis


def _motion(rng, n, H, scale=1e-3, quantum=None):
    t = 2 * np.pi * np.arange(n) / n
    h = np.arange(H + 1)
    c = rng.normal(size=H + 1) * scale / (1.0 + h)
    s = rng.normal(size=H + 1) * scale / (1.0 + h)
    u = (c[:, None] * np.cos(h[:, None] * t) + s[:, None] * np.sin(h[:, None] * t)).sum(axis=0)
    if quantum is not None:  # flat stretches, repeated extremes
        u = np.round(u / quantum) * quantum
    return u


def _case(rng, trial):
    H = int(rng.integers(1, 8))
    n = int(rng.choice([16, 32, 64, 256]))
    n = max(n, 4 * (H + 1))
    m = int(rng.integers(1, 120))
    k = rng.uniform(0.1, 2.0, m) * 1e4
    # slip displacements from all-stuck (x100) through microslip to macroslip (x0.01)
    phi = np.sort(rng.uniform(0.0, 1.5, m)) * 1e-3 * [0.01, 1.0, 100.0][trial % 3] + 1e-9
    u = _motion(rng, n, H, quantum=2e-4 if trial % 5 == 0 else None)
    return H, n, k, phi, u


def _rel(got, want, floor):
    return float(np.abs(got - want).max()) / max(float(np.abs(want).max()), floor)


def test_projected_equals_dense_on_random_motions():
    rng = np.random.default_rng(2027)
    worst_f = worst_j = 0.0
    fast = 0
    for trial in range(240):
        H, n, k, phi, u = _case(rng, trial)
        E, _, P = aft_basis(H, n, "F")
        kind = trial % 4
        centre = kind == 1
        if centre:
            x0 = np.full(k.size, 0.5 * (u.max() + u.min()))
        elif kind == 2:
            x0 = rng.normal(size=k.size) * 2e-3  # an arbitrary start: some elements slip in the first sweep only
        else:
            x0 = np.zeros(k.size)
        out = sliders._slider_aft_projected(u, k, phi, x0, P, E, centre)
        f0, D0 = sliders._slider_aft(u, k, phi, x0, True, centre)
        if out is None:  # only motions with steps at the rounding of u -+ phi go the dense way
            continue
        fast += 1
        f1, J1 = out
        J0 = P @ D0 @ E
        K = float(k.sum())
        # relative to the largest value, except deep in macroslip (trial % 3 == 0: f ~ sum F_i << K u,
        # J ~ 0 or a few stuck elements), where the reference's own ``K u - x @ k`` and its sums
        # over slipping elements round at eps K u and eps K: there relative to 1 % of K u and to K
        # (a wrong slip state or column is an error of some k_i, >= K / 2000 here)
        macro = trial % 3 == 0
        worst_f = max(worst_f, _rel(f1, f0, 1e-2 * K * float(np.abs(u).max()) if macro else 0.0))
        worst_j = max(worst_j, _rel(J1, J0, K if macro else 0.0))
    assert fast >= 200
    assert worst_f <= 1e-13, worst_f
    assert worst_j <= 1e-13, worst_j


@pytest.mark.parametrize("law", [
    Iwan4(F_S=3.0, K_T=2e4, chi=-0.4, beta=0.3, n_sliders=60),
    DiscreteIwan(np.linspace(1e3, 4e3, 40), np.linspace(0.5, 3.0, 40)),
    Jenkins(kt=1e4, Fs=2.0),
])
@pytest.mark.parametrize("state0", [None, "centre"])
def test_law_method_and_finite_differences(law, state0):
    rng = np.random.default_rng(7)
    H, n = 5, 64
    E, _, P = aft_basis(H, n, "F")
    c = rng.normal(size=2 * H + 1) * 1e-4 / (1.0 + np.arange(2 * H + 1))
    c[1] += 4e-4
    f, J = law.aft_projected(E @ c, P, E, state0=state0)
    f0, D0 = law.aft(E @ c, state0=state0)
    assert _rel(f, f0, 0.0) <= 1e-13
    assert _rel(J, P @ D0 @ E, 0.0) <= 1e-13
    h = 1e-11
    fd = np.empty_like(J)
    for j in range(c.size):
        e = np.zeros_like(c)
        e[j] = h
        fp = law.aft(E @ (c + e), jacobian=False, state0=state0)[0]
        fm = law.aft(E @ (c - e), jacobian=False, state0=state0)[0]
        fd[:, j] = P @ (fp - fm) / (2 * h)
    assert _rel(J, fd, 0.0) <= 1e-5


def test_nonfinite_and_tiny_steps_take_the_dense_path():
    law = DiscreteIwan([1e3, 2e3], [0.1, 0.3])
    E, _, P = aft_basis(3, 16, "F")
    u = 1e-3 * np.cos(2 * np.pi * np.arange(16) / 16)
    u[3] = np.nextafter(u[2], 1.0)  # a step below the rounding of u - phi
    assert sliders._slider_aft_projected(u, law.stiffness, law.slip_displacement, np.zeros(2), P, E) is None
    f, J = law.aft_projected(u, P, E)
    f0, D0 = law.aft(u)
    assert np.array_equal(f, f0) and np.array_equal(J, P @ D0 @ E)
    u[5] = np.nan
    f, J = law.aft_projected(u, P, E)
    assert np.isnan(f).any()


def test_engine_uses_the_projection_to_rounding():
    """CondensedHB.aft with a law offering aft_projected equals the dense path of the same law."""
    from jointid.simulate.structure_hb import CondensedHB

    class Dense:  # the same law without the optional method
        def __init__(self, law):
            self.law = law

        def aft(self, u_t, v_t=None, **kw):
            return self.law.aft(u_t, v_t, **kw)

    law = Iwan4(F_S=3.0, K_T=2e4, chi=-0.4, beta=0.3, n_sliders=60)
    args = ([80.0, 300.0], [0.01, 0.02], np.array([[1.0, 0.5]]), np.array([1.0, 0.3]))
    a = CondensedHB(*args, [law], k_model=1.5e4)
    b = CondensedHB(*args, [Dense(law)], k_model=1.5e4)
    rng = np.random.default_rng(3)
    H, N = 7, 64
    U = rng.normal(size=(1, 2 * H + 1)) * 1e-4
    U[0, 1] += 5e-4
    Fa, Ja, _ = a.aft(U, 90.0, H, N)
    Fb, Jb, _ = b.aft(U, 90.0, H, N)
    assert _rel(Fa, Fb, 0.0) <= 1e-13
    assert _rel(Ja, Jb, 0.0) <= 1e-13
