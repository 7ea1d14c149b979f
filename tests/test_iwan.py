"""The rig's joint law: closed forms of Segalman's four-parameter Iwan model and the protocol.

Closed forms (Segalman 2005): full stiffness K_T at small amplitude, macro-slip force
F_S, virgin loading curve, dissipation per cycle 4 R u0^(3+chi) / ((chi+2)(chi+3)) and
its force form, which grows as F^(3+chi) in micro-slip.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from jointid.errors import StructureError
from jointid.rig.iwan import IwanParameters, JenkinsElements, JointLaw, discretize_iwan

N = 1024
TAU = 2 * np.pi * np.arange(N) / N


def loop_energy(law, u0, n=N):
    """Energy dissipated in one steady cycle ``u = u0 sin(tau)`` (closed loop integral of f du)."""
    tau = 2 * np.pi * np.arange(n) / n
    f, _ = law.periodic_force(np.outer(np.atleast_1d(u0), np.sin(tau)))
    du = np.outer(np.atleast_1d(u0), np.cos(tau))
    return np.sum(f * du, axis=-1) * 2 * np.pi / n


@pytest.fixture(params=[(-0.5, 1.0), (-0.2, 0.3), (0.0, 0.0)], ids=["chi-0.5", "chi-0.2", "chi0-beta0"])
def law(request):
    chi, beta = request.param
    return JointLaw(IwanParameters(F_S=3.0, K_T=2500.0, chi=chi, beta=beta), n_elements=200)


def test_parameter_relations(law):
    p = law.iwan
    cont = p.R * p.phi_max ** (p.chi + 1) / (p.chi + 1)
    assert cont + p.S == pytest.approx(p.K_T, rel=1e-12)
    assert p.R * p.phi_max ** (p.chi + 2) / (p.chi + 2) + p.S * p.phi_max == pytest.approx(p.F_S, rel=1e-12)
    assert p.S == pytest.approx(p.beta * cont, rel=1e-12, abs=1e-12)


def test_discretisation_keeps_stiffness_and_slip_force(law):
    e = law.elements
    assert e.total_stiffness == pytest.approx(law.iwan.K_T, rel=1e-12)
    assert e.slip_force == pytest.approx(law.iwan.F_S, rel=1e-12)
    assert law.linear_stiffness == pytest.approx(law.iwan.K_T, rel=1e-12)


def test_full_stiffness_at_small_amplitude(law):
    u0 = 1e-7 * law.iwan.phi_max  # below the smallest slip displacement
    f, _ = law.periodic_force(u0 * np.sin(TAU))
    assert np.max(f) / u0 == pytest.approx(law.iwan.K_T, rel=1e-10)
    # a time-stepped virgin loading sees the same stiffness
    fs, _ = law.force(u0, None, law.initial_state())
    assert fs / u0 == pytest.approx(law.iwan.K_T, rel=1e-10)


def test_macroslip_force(law):
    p = law.iwan
    state = law.initial_state()
    for u in np.linspace(0, 3 * p.phi_max, 301)[1:]:
        f, state = law.force(u, None, state)
    assert f == pytest.approx(p.F_S, rel=1e-12)  # every element slips: F_S, whatever the discretisation
    f, _ = law.periodic_force(2 * p.phi_max * np.sin(TAU))
    assert np.max(f) == pytest.approx(p.F_S, rel=1e-12)
    assert float(p.backbone(5 * p.phi_max)) == p.F_S


def test_virgin_loading_follows_the_closed_form(law):
    p = law.iwan
    u = np.linspace(0, 0.95 * p.phi_max, 400)[1:]
    state = law.initial_state()
    f = []
    for ui in u:
        fi, state = law.force(ui, None, state)
        f.append(fi)
    np.testing.assert_allclose(f, p.backbone(u), rtol=5e-3)


def test_dissipation_matches_segalman_closed_form(law):
    p = law.iwan
    u0 = p.phi_max * np.array([1e-3, 1e-2, 0.1, 0.3, 0.7, 0.99, 1.5, 3.0])
    np.testing.assert_allclose(loop_energy(law, u0), p.dissipation(u0), rtol=1e-2)


def test_microslip_dissipation_power_law(law):
    """In micro-slip D grows as F^(3 + chi), and D(F) tends to Segalman's small-force form."""
    p = law.iwan
    fine = JointLaw(p, n_elements=400, phi_min_ratio=1e-10)  # elements down to the test amplitudes
    F0 = p.F_S * np.geomspace(1e-6, 1e-4, 7)
    D = loop_energy(fine, p.displacement_at_force(F0))
    slope = np.polyfit(np.log(F0), np.log(D), 1)[0]
    assert slope == pytest.approx(3 + p.chi, abs=0.01)
    np.testing.assert_allclose(D, p.microslip_dissipation(F0), rtol=2e-2)
    # at larger forces the exact D(u0(F)) still holds; the asymptote drifts as the joint softens
    F1 = p.F_S * np.geomspace(1e-3, 0.5, 6)
    np.testing.assert_allclose(loop_energy(law, p.displacement_at_force(F1)),
                               p.dissipation(p.displacement_at_force(F1)), rtol=1e-2)


def test_periodic_evaluation_equals_time_marching():
    """The AFT evaluation is the steady state a time integration reaches, minor loops included."""
    law = JointLaw(IwanParameters(2.0, 2000.0, -0.4, 0.5), k3=1e7, n_elements=80)
    u = 1.2e-3 * (np.sin(TAU) + 0.3 * np.sin(3 * TAU) + 0.15 * np.sin(7 * TAU))  # odd: range symmetric
    f_periodic, state0 = law.periodic_force(u)
    state = law.initial_state()
    f_march = np.empty((3, N))
    states = []
    for period in range(3):
        for j in range(N):
            f_march[period, j], state = law.force(u[j], None, state)
            if j == 0:
                states.append(state)
    scale = np.max(np.abs(f_periodic))
    np.testing.assert_allclose(f_march[2], f_periodic, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(states[2], state0, rtol=0, atol=1e-15)  # state after sample 0 of a cycle


def test_periodic_force_batch_equals_rows():
    law = JointLaw(IwanParameters(2.0, 2000.0, -0.4, 0.5), n_elements=40)
    U = np.outer([2e-4, 1e-3, 4e-3], np.sin(TAU[::8])) + 1e-4 * np.cos(3 * TAU[::8])
    F, S = law.periodic_force(U)
    for i in range(3):
        f, s = law.periodic_force(U[i])
        np.testing.assert_allclose(F[i], f, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(S[i], s, rtol=1e-12, atol=1e-18)


def test_jacobian_matches_finite_differences():
    law = JointLaw(IwanParameters(3.0, 2400.0, -0.4, 0.5), k3=4e7, n_elements=60)
    n = 128
    tau = 2 * np.pi * np.arange(n) / n
    u = 1.5e-3 * np.sin(tau) + 2e-4 * np.cos(3 * tau) + 1e-4 * np.sin(2 * tau + 0.3)
    f, _, D = law.periodic_force(u, jacobian=True)
    h = 1e-10
    fb, _ = law.periodic_force(u[None, :] + h * np.eye(n))
    D_fd = ((fb - f[None, :]) / h).T
    assert np.max(np.abs(D - D_fd)) < 1e-6 * np.max(np.abs(D))


def test_state_is_explicit_and_law_is_immutable():
    law = JointLaw(IwanParameters(2.0, 2000.0, -0.4, 0.5), n_elements=20)
    state = law.initial_state((3,))
    assert state.shape == (3, law.n_state)
    before = state.copy()
    f, new = law.force(np.array([1e-3, -2e-3, 5e-3]), None, state)
    np.testing.assert_array_equal(state, before)  # the input state is not changed
    assert new is not state and f.shape == (3,)
    with pytest.raises(dataclasses.FrozenInstanceError):
        law.k3 = 1.0
    with pytest.raises(ValueError):
        law.elements.stiffness[0] = 1.0


def test_cubic_only_law_and_sign_convention():
    law = JointLaw(None, k3=2e6)
    u = np.linspace(-1e-3, 1e-3, 5)
    f, _ = law.force(u, None, law.initial_state(5))
    np.testing.assert_allclose(f, -2e6 * u**3)  # seed sign: k3 > 0 softens
    assert law.linear_stiffness == 0.0
    fp, s0 = law.periodic_force(1e-3 * np.sin(TAU))
    np.testing.assert_allclose(fp, -2e6 * (1e-3 * np.sin(TAU)) ** 3)
    assert s0.shape == (0,)


@pytest.mark.parametrize("kw", [dict(F_S=-1.0), dict(K_T=0.0), dict(chi=-1.0), dict(chi=1.5), dict(beta=-0.1),
                                dict(F_S=np.nan)])
def test_invalid_parameters_are_refused(kw):
    args = dict(F_S=1.0, K_T=1000.0, chi=-0.5, beta=0.5)
    args.update(kw)
    with pytest.raises(StructureError):
        IwanParameters(**args)


def test_invalid_discretisation_is_refused():
    p = IwanParameters(1.0, 1000.0, -0.5, 0.5)
    with pytest.raises(StructureError):
        discretize_iwan(p, 1)
    with pytest.raises(StructureError):
        discretize_iwan(p, 10, phi_min_ratio=2.0)
    with pytest.raises(StructureError):
        JenkinsElements([1.0, -1.0], [1e-3, 1e-3])
