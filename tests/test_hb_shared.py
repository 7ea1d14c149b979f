"""Pieces the two harmonic-balance engines share: the warm-started sweep and the continuation loop."""

import warnings
from types import SimpleNamespace

import numpy as np

from jointid.errors import ConvergenceWarning
from jointid.joints import PolynomialLaw
from jointid.simulate import hbm
from jointid.simulate.model import seed_model
from jointid.simulate.structure_hb import CondensedHB, warm_sweep


def test_warm_sweep_starts_each_point_from_the_secant_of_the_two_before():
    """A fake solver whose solution is linear in frequency: the secant guess is exact from the third
    point on; harmonics beyond those both neighbours carry are dropped; a repeated frequency
    restarts from the last point."""
    seen = []

    def solve(f, guess):
        seen.append(guess)
        H = 1 + int(f) % 2  # harmonic count varying with the frequency
        return SimpleNamespace(hz=f, joint=np.arange(2 * H + 1.0)[None, :] * f)

    out = warm_sweep(solve, [1.0, 2.0, 4.0, 4.0], lambda p: p.hz)
    assert seen[0] is None and seen[1] is out[0]
    np.testing.assert_allclose(seen[2], np.arange(3.0)[None, :] * 4.0, rtol=1e-15)  # common 3 coefficients
    np.testing.assert_array_equal(seen[3], out[2].joint)  # f1 == f2: the last point, not a division by zero


def test_both_continuations_warn_at_the_callers_line_when_stopped():
    engine = CondensedHB([100.0], 0.02, [[1.0]], [1.0], [PolynomialLaw({"-q^3": -1.0e6})])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        curve = engine.continuation(80.0, 130.0, [0, 0, 1.0], 3, max_steps=3)
        resp = hbm.frequency_response(seed_model(), 3.0, omega_range=(150, 190), max_steps=3)
    msgs = [w for w in caught if issubclass(w.category, ConvergenceWarning)]
    assert len(msgs) == 2 and all(w.filename == __file__ for w in msgs)
    assert len(curve) == 4 and len(resp) == 4  # the start and three steps
    assert all("partial curve" in str(w.message) for w in msgs)


def test_the_self_excited_denominator_is_the_plain_one_to_the_bit_at_xi_zero():
    """``modal_denominator`` serves the FRFs (xi = 0) and the nonlinear modes (xi != 0) with one
    formula; at xi = 0 it equals ``Omega^2 - w^2 + 2 i zeta Omega w`` bit for bit (signed zeros too)."""
    from jointid.numerics.receptance import modal_denominator

    rng = np.random.default_rng(7)
    om, ze, w = rng.uniform(1, 1e4, (30, 1)), rng.uniform(0, 0.3, (30, 1)), rng.uniform(0, 2e4, (1, 25))
    ze[0], w[0, 0] = 0.0, 0.0
    plain = om**2 - w**2 + 2j * ze * om * w
    assert np.array_equal(modal_denominator(om, ze, w).view(float), plain.view(float))
    xi = 3.0
    np.testing.assert_allclose(modal_denominator(om, ze, w, xi), plain - 1j * xi * w, rtol=1e-13)
