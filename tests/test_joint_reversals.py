"""ExactReversals (jointid.joints.reversals): a slider law's AFT reversing at the exact extrema of the motion."""

import numpy as np
import pytest

from jointid.joints import ExactReversals, Iwan4, Jenkins


def test_exact_reversals_jacobian_and_samples_on_the_extrema():
    """The wrapped law's Jacobian against central differences; where the extrema lie on samples the force is the
    plain law's; where they lie between samples the reversal uses the true extremum (closed-form backbone)."""
    law = Iwan4(2.0, 1000.0, -0.5, 0.5, n_sliders=20, phi_min_ratio=1e-3)
    w = ExactReversals(law)
    n = 64
    t = 2 * np.pi * np.arange(n) / n
    u = 0.004 * np.cos(t + 0.3) + 0.0008 * np.sin(3 * t + 0.1) + 0.0002
    _, D = w.aft(u)
    Dn = np.empty_like(D)
    for m in range(n):
        e = np.zeros(n)
        e[m] = 1e-9
        Dn[:, m] = (w.aft(u + e, jacobian=False)[0] - w.aft(u - e, jacobian=False)[0]) / 2e-9
    assert np.abs(D - Dn).max() < 1e-6 * np.abs(D).max()
    u0 = 0.004 * np.cos(t)  # extrema at samples 0 and n/2
    assert np.allclose(w.aft(u0, jacobian=False)[0], law.aft(u0, jacobian=False)[0], rtol=0, atol=1e-12)
    jen = Jenkins(1000.0, 2.0)
    phase = np.pi / n  # the maximum half-way between two samples: the plain law reverses below it
    u1 = 0.004 * np.cos(t + phase)
    f_exact = ExactReversals(jen).aft(u1, jacobian=False)[0]
    f_plain = jen.aft(u1, jacobian=False)[0]
    # sample 0 is the first after the maximum (t = -pi / n), still stuck: Fs - kt (a - u) with the true a = 0.004
    j = 0
    assert f_exact[j] == pytest.approx(2.0 - 1000.0 * (0.004 - u1[j]), rel=1e-9)
    assert abs(f_plain[j] - f_exact[j]) > 1e-4


def test_exact_reversals_time_step_protocol_is_the_wrapped_laws():
    law = Jenkins(1000.0, 2.0)
    w = ExactReversals(law)
    s, s2 = w.initial_state(), law.initial_state()
    assert w.n_state == law.n_state and np.array_equal(s, s2)
    for u in (0.001, 0.004, -0.003, 0.0):
        (f, s), (f2, s2) = w.force(u, 0.0, s), law.force(u, 0.0, s2)
        assert f == f2 and np.array_equal(s, s2)
    assert f == pytest.approx(-2.0 + 1000.0 * (0.0 - (-0.003)), rel=1e-12)  # stuck after slipping back at -Fs
