"""The ground-floor numerics: one AFT basis for both harmonic-balance engines, peak refinement."""

import numpy as np
import pytest

from jointid.numerics import aft_basis, basis_at, modal_denominator, parabolic_peak, refine_peak


@pytest.mark.parametrize("H, N", [(1, 8), (3, 32), (9, 128), (9, 256)])
def test_aft_basis_is_the_harmonic_convention(H, N):
    E, D, P = aft_basis(H, N)
    tau = 2 * np.pi * np.arange(N) / N
    x = np.random.default_rng(H).standard_normal(2 * H + 1)
    q = x[0] + sum(x[2 * k - 1] * np.cos(k * tau) + x[2 * k] * np.sin(k * tau) for k in range(1, H + 1))
    dq = sum(k * (x[2 * k] * np.cos(k * tau) - x[2 * k - 1] * np.sin(k * tau)) for k in range(1, H + 1))
    np.testing.assert_allclose(E @ x, q, rtol=0, atol=1e-12 * np.abs(x).sum())
    np.testing.assert_allclose(E @ (D @ x), dq, rtol=0, atol=1e-12 * H * np.abs(x).sum())
    np.testing.assert_allclose(P @ E, np.eye(2 * H + 1), rtol=0, atol=1e-13)  # N > 2H: exact projection
    np.testing.assert_array_equal(basis_at(tau, H), E)  # the same rows at the grid's phases


@pytest.mark.parametrize("H, N", [(3, 32), (9, 256)])
def test_projection_orders_hold_the_same_numbers(H, N):
    """The single-mode solver (``"C"``) and the rig's reduced model (``"F"``) share one basis:
    equal values, only the memory order of ``P`` differs (which BLAS kernel a product uses)."""
    Ec, Dc, Pc = aft_basis(H, N)
    Ef, Df, Pf = aft_basis(H, N, "F")
    for a, b in ((Ec, Ef), (Dc, Df), (Pc, Pf)):
        np.testing.assert_array_equal(a, b)
        assert not a.flags.writeable and not b.flags.writeable
    assert Ec.flags.c_contiguous and Ef.flags.c_contiguous and Pc.flags.c_contiguous
    assert Pf.flags.f_contiguous and Pf.T.flags.c_contiguous
    assert aft_basis(H, N, "F") is aft_basis(H, N, "F")  # cached
    g = np.random.default_rng(0).standard_normal((4, N))
    np.testing.assert_allclose(g @ Pf.T, g @ Pc.T, rtol=1e-13, atol=1e-15)
    with pytest.raises(ValueError, match="projection_order"):
        aft_basis(H, N, "K")


def test_both_engines_use_the_shared_basis():
    import jointid.rig.reduced as reduced
    import jointid.rig.rig as rig
    from jointid.simulate import hbm

    assert hbm._basis is aft_basis and hbm._basis_at is basis_at
    assert not hasattr(reduced, "_aft_basis")
    assert rig.parabolic_peak is parabolic_peak and rig.refine_peak is refine_peak


def test_parabolic_peak_of_a_parabola_is_its_vertex():
    x = np.linspace(0.0, 1.0, 11)
    y = 2.0 - 3.0 * (x - 0.437) ** 2
    xp, yp = parabolic_peak(x, y)
    assert xp == pytest.approx(0.437, abs=1e-12) and yp == pytest.approx(2.0, abs=1e-12)
    assert parabolic_peak(x, x) == (1.0, 1.0)  # largest sample at the end: no parabola


def test_refine_peak_halves_until_xtol():
    def f(x):
        return 1.0 / ((1.0 - x**2) ** 2 + (0.02 * x) ** 2)

    x0 = np.linspace(0.9, 1.1, 5)
    xs, ys = refine_peak(f, x0, f(x0), 1e-7)
    i = int(np.argmax(ys))
    assert xs[i + 1] - xs[i] <= 1e-7 and xs[i] - xs[i - 1] <= 1e-7
    exact = np.sqrt(1.0 - 0.02**2 / 2)  # maximum of f
    assert parabolic_peak(xs, ys)[0] == pytest.approx(exact, abs=1e-9)


def test_modal_denominator_is_the_state_space_receptance():
    """``1 / modal_denominator`` is ``C (i w I - A)^-1 B`` of ``q'' + 2 zeta Omega q' + Omega^2 q = f``."""
    for Om, ze in ((3.0, 0.02), (170.0, 0.3)):
        A = np.array([[0.0, 1.0], [-(Om**2), -2 * ze * Om]])
        for w in (0.0, 0.5 * Om, Om, 4.1 * Om):
            H = np.linalg.solve(1j * w * np.eye(2) - A, [0.0, 1.0])[0]
            assert 1.0 / modal_denominator(Om, ze, w) == pytest.approx(H, rel=1e-12)
    # broadcast: modes down, frequencies across
    d = modal_denominator(np.array([[1.0], [2.0]]), np.array([[0.1], [0.2]]), np.array([0.5, 1.0, 3.0]))
    assert d.shape == (2, 3) and d[1, 2] == pytest.approx(4.0 - 9.0 + 2j * 0.2 * 2.0 * 3.0)
