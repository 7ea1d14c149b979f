"""Joint laws (jointid.joints): closed forms, Masing, AFT Jacobians, time stepping = AFT."""

import json
import math

import numpy as np
import pytest
from scipy import integrate

from jointid.errors import StructureError
from jointid.joints import (
    BoucWen,
    DiscreteIwan,
    Iwan4,
    Jenkins,
    PolynomialLaw,
    discretize_iwan4,
    harmonic_motion,
    loop_energy,
)

IWAN = Iwan4(F_S=2.0, K_T=2000.0, chi=-0.5, beta=0.3)
IWAN_NO_DELTA = Iwan4(F_S=5.0, K_T=1.0e5, chi=-0.2, beta=0.0)
RNG_ELEMENTS = np.random.default_rng(3)
DISCRETE = DiscreteIwan(RNG_ELEMENTS.uniform(100, 1000, 12), RNG_ELEMENTS.uniform(0.2, 2.0, 12))
BW = BoucWen(k_z=1.0e4, beta=200.0, gamma=50.0, k_inf=10.0)
BW_C0 = BoucWen(k_z=3.0e3, beta=80.0, gamma=80.0)  # c = gamma - beta = 0


def _rel(a, b):
    return np.max(np.abs(np.asarray(a) - np.asarray(b)) / np.max(np.abs(b)))


def _fd_jacobian(law, u, h, **kw):
    n = u.size
    D = np.empty((n, n))
    for m in range(n):
        e = np.zeros(n)
        e[m] = h
        D[:, m] = (law.aft(u + e, jacobian=False, **kw)[0] - law.aft(u - e, jacobian=False, **kw)[0]) / (2 * h)
    return D


def _irregular_motion(a, n, seed=0):
    """A period with minor loops: fundamental, third and fifth harmonics and an offset."""
    rng = np.random.default_rng(seed)
    t = 2 * np.pi * np.arange(n) / n
    ph = rng.uniform(0, 2 * np.pi, 3)
    return a * (0.1 + np.cos(t + ph[0]) + 0.35 * np.cos(3 * t + ph[1]) + 0.2 * np.sin(5 * t + ph[2]))


# --- Segalman's closed forms against the density's own integrals -------------------------------------
def _density_integrals(law, a):
    """Backbone and dissipation from the slip density by quadrature (independent of the closed forms)."""
    R, c, S, pm = law.R, law.chi, law.S, law.phi_max
    rho = lambda p: R * p**c  # noqa: E731
    lim = min(a, pm)
    # backbone: stuck elements (phi > a) carry phi-spring a, slipped ones their slip force phi
    back = integrate.quad(lambda p: rho(p) * p, 0, lim, epsrel=1e-13, epsabs=0, limit=200)[0]
    if a < pm:
        back += a * integrate.quad(rho, a, pm, epsrel=1e-13, epsabs=0, limit=200)[0]
    back += S * min(a, pm)
    diss = integrate.quad(lambda p: rho(p) * 4 * p * (a - p), 0, lim, epsrel=1e-13, epsabs=0, limit=200)[0]
    diss += 4 * S * pm * max(a - pm, 0.0)
    return back, diss


@pytest.mark.parametrize("law", [IWAN, IWAN_NO_DELTA])
def test_iwan4_parameters_give_stiffness_and_slip_force(law):
    R, c, S, pm = law.R, law.chi, law.S, law.phi_max
    C = R * pm ** (c + 1) / (c + 1)  # stiffness of the continuous part
    assert C + S == pytest.approx(law.K_T, rel=1e-13)
    assert R * pm ** (c + 2) / (c + 2) + S * pm == pytest.approx(law.F_S, rel=1e-13)
    assert S / C == pytest.approx(law.beta, rel=1e-12, abs=1e-15)


@pytest.mark.parametrize("law", [IWAN, IWAN_NO_DELTA])
@pytest.mark.parametrize("ratio", [1e-3, 0.05, 0.4, 0.999, 1.0, 1.7, 5.0])
def test_iwan4_backbone_and_dissipation_closed_forms(law, ratio):
    a = ratio * law.phi_max
    back, diss = _density_integrals(law, a)
    assert law.backbone(a) == pytest.approx(back, rel=1e-9)
    assert law.backbone(-a) == pytest.approx(-back, rel=1e-9)
    assert law.dissipation(a) == pytest.approx(diss, rel=1e-9)
    if ratio <= 1.0:  # micro-slip: the power law a^(3 + chi)
        assert law.dissipation(a) == pytest.approx(4 * law.R * a ** (law.chi + 3) / ((law.chi + 2) * (law.chi + 3)))


def test_iwan4_microslip_power_law_in_force():
    F0 = np.array([1e-4, 1e-3]) * IWAN.F_S
    a = F0 / IWAN.K_T
    slope = np.diff(np.log(IWAN.dissipation(a))) / np.diff(np.log(F0))
    assert slope[0] == pytest.approx(3 + IWAN.chi, rel=1e-12)
    assert IWAN.microslip_dissipation(F0[0]) == pytest.approx(IWAN.dissipation(a[0]), rel=1e-12)


def test_discretised_iwan_keeps_stiffness_and_slip_force_exactly():
    d = discretize_iwan4(IWAN, 40)
    assert d.n_elements == 41  # + the delta element
    assert d.total_stiffness == pytest.approx(IWAN.K_T, rel=1e-13)
    assert d.total_slip_force == pytest.approx(IWAN.F_S, rel=1e-13)


@pytest.mark.parametrize("law", [IWAN, IWAN_NO_DELTA])
def test_discretised_iwan_converges_to_the_closed_forms(law):
    a = law.phi_max * np.array([1e-3, 1e-2, 0.1, 0.3, 0.6, 0.9, 0.999, 1.5, 3.0])
    errs = []
    for n in (100, 400, 1600):
        d = discretize_iwan4(law, n, 1e-6)
        errs.append(max(_rel(d.dissipation(x), law.dissipation(x)) for x in a))
        errs[-1] = max(errs[-1], max(_rel(d.backbone(x), law.backbone(x)) for x in a))
    assert errs[0] > errs[1] > errs[2]
    assert errs[1] / errs[2] > 8  # second order in the interval width
    assert errs[2] < 1e-4


def test_discretised_iwan_aft_loop_converges_to_the_closed_form_dissipation():
    law = Iwan4(F_S=2.0, K_T=2000.0, chi=-0.5, beta=0.3, n_sliders=1600)
    a = law.phi_max * np.array([0.01, 0.3, 0.95, 2.0])
    u = harmonic_motion(a, 8192)
    f, _ = law.aft(u, jacobian=False)
    assert _rel(loop_energy(u, f) / law.dissipation(a), 1.0) < 1e-4


# --- Jenkins: closed forms to 1e-6 ---------------------------------------------------------------------
JENKINS = Jenkins(kt=1000.0, Fs=2.0)


@pytest.mark.parametrize("ratio", [0.5, 1.0, 1.3, 4.0, 25.0])
def test_jenkins_loop_area_equals_closed_form_dissipation(ratio):
    a = ratio * JENKINS.slip_displacement
    u = harmonic_motion(a, 2**14)
    f, _ = JENKINS.aft(u, jacobian=False)
    expected = 4 * JENKINS.Fs * max(a - JENKINS.slip_displacement, 0.0)
    assert JENKINS.dissipation(a) == pytest.approx(expected, rel=1e-15, abs=0)
    assert loop_energy(u, f) == pytest.approx(expected, rel=1e-6, abs=1e-12 * JENKINS.Fs * a)


@pytest.mark.parametrize("a", [1e-3, 4e-3, 2e-2])
def test_discrete_iwan_loop_area_equals_closed_form_dissipation(a):
    u = harmonic_motion(a, 2**14)
    f, _ = DISCRETE.aft(u, jacobian=False)
    phi = DISCRETE.slip_displacement
    expected = sum(4 * F * (a - p) for F, p in zip(DISCRETE.slip_force, phi) if p < a)
    assert 0 < np.sum(phi < a) and DISCRETE.dissipation(a) == pytest.approx(expected, rel=1e-14)
    assert loop_energy(u, f) == pytest.approx(expected, rel=1e-6)


def test_jenkins_backbone_from_time_stepping():
    u = np.linspace(0, 5 * JENKINS.slip_displacement, 501)
    state = JENKINS.initial_state()
    f = []
    for x in u:
        fx, state = JENKINS.force(x, None, state)
        f.append(fx)
    assert _rel(f, JENKINS.backbone(u)) < 1e-12
    assert JENKINS.backbone(1.0) == JENKINS.Fs and JENKINS.backbone(-1e-4) == pytest.approx(-0.1)


# --- Masing: the unloading branch is twice the backbone scaled ------------------------------------------
@pytest.mark.parametrize("law", [JENKINS, DISCRETE, Iwan4(2.0, 2000.0, -0.5, 0.3, n_sliders=1600)])
def test_masing_unloading_branch_is_the_backbone_scaled_by_two(law):
    a = 3e-3 if law is not DISCRETE else 8e-3
    n = 4096
    u = harmonic_motion(a, n)  # starts at the maximum: samples 0 .. n/2 unload to -a
    f, _ = law.aft(u, jacobian=False)
    down = slice(0, n // 2 + 1)
    fa = law.backbone(a) if not isinstance(law, Iwan4) else law.sliders.backbone(a)
    masing = fa - 2 * (law.backbone if not isinstance(law, Iwan4) else law.sliders.backbone)((a - u[down]) / 2)
    assert _rel(f[down], masing) < 1e-12
    if isinstance(law, Iwan4):  # and the continuous closed form, to the discretisation error
        cont = law.backbone(a) - 2 * law.backbone((a - u[down]) / 2)
        assert _rel(f[down], cont) < 3e-5
    # the reloading branch is the unloading one reflected
    up = slice(n // 2, n)
    assert _rel(f[up], -np.interp(-u[up], u[down][::-1], f[down][::-1])) < 1e-6


# --- AFT Jacobians against finite differences -----------------------------------------------------------
@pytest.mark.parametrize(
    "law, a",
    [(JENKINS, 5e-3), (DISCRETE, 6e-3), (Iwan4(2.0, 2000.0, -0.5, 0.3, n_sliders=60), 1.5e-3), (BW, 0.02), (BW_C0, 0.03)],
)
@pytest.mark.parametrize("seed", [0, 1])
def test_aft_jacobian_equals_finite_differences(law, a, seed):
    u = _irregular_motion(a, 64, seed)
    f, D = law.aft(u)
    h = 1e-7 * a
    Dfd = _fd_jacobian(law, u, h)
    assert np.max(np.abs(D - Dfd)) <= 1e-6 * np.max(np.abs(D))
    assert np.allclose(f, law.aft(u, jacobian=False)[0], rtol=0, atol=0)


def test_aft_batches_equal_single_periods():
    u = np.stack([_irregular_motion(4e-3, 32, s) for s in range(3)]).reshape(3, 1, 32)
    for law in (DISCRETE, BW):
        f, D = law.aft(u)
        assert f.shape == (3, 1, 32) and D.shape == (3, 1, 32, 32)
        for i in range(3):
            fi, Di = law.aft(u[i, 0])
            assert np.allclose(f[i, 0], fi, rtol=1e-13, atol=0) and np.allclose(D[i, 0], Di, rtol=1e-12, atol=1e-9)


def test_slider_jacobian_wraps_round_the_period():
    """A slider's state at the start of the period comes from its last slip late in the period."""
    u = 2.5e-3 * np.sin(2 * np.pi * np.arange(16) / 16)  # stuck at sample 0, last slipped at the minimum
    _, D = JENKINS.aft(u)
    assert D[0, 12] == -JENKINS.kt and D[0, 0] == JENKINS.kt  # sample 12 is the minimum
    assert np.count_nonzero(np.triu(D, 1)) > 0


# --- time stepping = AFT on the same samples ---------------------------------------------------------------
@pytest.mark.parametrize("law", [JENKINS, DISCRETE, Iwan4(2.0, 2000.0, -0.5, 0.3, n_sliders=80), BW, BW_C0])
def test_time_stepping_over_a_sine_equals_aft(law):
    n = 200
    a = {Jenkins: 6e-3, DiscreteIwan: 9e-3, Iwan4: 1.2e-3, BoucWen: 0.02}[type(law)]
    u1 = a * np.sin(2 * np.pi * np.arange(n) / n)  # starts from rest at u = 0
    periods = 2 if law.masing else 40
    state = law.initial_state()
    for _ in range(periods):
        f_t = []
        for x in u1:
            fx, state = law.force(x, None, state)
            f_t.append(fx)
    f_aft, _ = law.aft(u1, jacobian=False)
    assert _rel(f_t, f_aft) < (1e-12 if law.masing else 1e-9)


def test_time_stepping_is_batched_like_aft():
    u = np.stack([_irregular_motion(4e-3, 50, s) for s in range(4)])
    state = DISCRETE.initial_state(4)
    for _ in range(2):
        cols = []
        for j in range(50):
            fj, state = DISCRETE.force(u[:, j], None, state)
            cols.append(fj)
    # both start virgin at the first sample's slider position (0), so elements that never slip agree too
    f_aft, _ = DISCRETE.aft(u, jacobian=False)
    assert np.allclose(np.stack(cols, axis=-1), f_aft, rtol=1e-12, atol=1e-12)


# --- Bouc-Wen closed forms -------------------------------------------------------------------------------
@pytest.mark.parametrize("law", [BW, BW_C0])
@pytest.mark.parametrize("a", [1e-4, 3e-3, 0.02, 0.2])
def test_bouc_wen_loop_area_equals_closed_form_dissipation(law, a):
    u = harmonic_motion(a, 2**14)
    f, _ = law.aft(u, jacobian=False)
    assert loop_energy(u, f) == pytest.approx(law.dissipation(a), rel=1e-6)


def test_bouc_wen_dissipation_by_quadrature_of_the_ode():
    """The closed form against a direct numerical solution of dz/du over the steady loop."""
    from scipy.integrate import solve_ivp

    law, a = BW, 0.01

    def ascend(z0):  # du > 0: dz/du = k_z - (beta sign(z) + gamma)|z|; the energy integral rides along
        rhs = lambda u, y: [law.k_z - (law.beta * np.sign(y[0]) + law.gamma) * abs(y[0]), y[0]]  # noqa: E731
        return solve_ivp(rhs, (-a, a), [z0, 0.0], rtol=1e-12, atol=1e-14, method="DOP853").y[:, -1]

    z = 0.0
    for _ in range(60):  # the symmetric loop: z(a) = -z(-a)
        z = ascend(-z)[0]
    zt, area_half = ascend(-z)
    assert zt == pytest.approx(z, rel=1e-9)
    assert law.dissipation(a) == pytest.approx(2 * area_half, rel=1e-8)


def test_bouc_wen_backbone_from_time_stepping_and_not_masing():
    u = np.linspace(0, 0.03, 301)
    state = BW.initial_state()
    f = []
    for x in u:
        fx, state = BW.force(x, None, state)
        f.append(fx)
    assert _rel(f, BW.backbone(u)) < 1e-12
    assert BW.backbone(1.0) == pytest.approx(BW.k_inf + BW.z_s, rel=1e-12)
    assert not BW.masing


# --- polynomial terms: today's model as a joint law ----------------------------------------------------------
SEED = PolynomialLaw({"q": 1.0e4, "-q^3": 2.0e9, "q'": 3.0})


def test_polynomial_law_is_the_seed_restoring_force():
    u, v = 1e-3, 0.2
    f, state = SEED.force(u, v, SEED.initial_state())
    assert f == pytest.approx(1.0e4 * u - 2.0e9 * u**3 + 3.0 * v, rel=1e-15)
    assert state.shape == (0,)
    assert SEED.parameters == {"omega1^2": 1.0e4, "k3": 2.0e9, "c": 3.0}
    assert SEED.units["k3"] == "1/(m^2 s^2)"
    with pytest.raises(StructureError, match="velocity"):
        SEED.force(u, None, SEED.initial_state())
    with pytest.raises(StructureError, match="did you mean"):
        PolynomialLaw({"-q3": 1.0})


@pytest.mark.parametrize("term", ["q'", "|q'|q'", "q'^3", "sign(q')", "q^2 q'", "-q^3", "q^2"])
def test_polynomial_dissipation_closed_forms(term):
    law = PolynomialLaw({"q": 50.0, term: 0.7})
    a, w, n = 0.02, 9.0, 2**14
    t = 2 * np.pi * np.arange(n) / n
    u, v = a * np.cos(t), -a * w * np.sin(t)
    f, _ = law.aft(u, v, jacobian=False)
    D = law.dissipation(a, omega=w)
    if term in ("-q^3", "q^2"):
        assert D == 0 and abs(loop_energy(u, f)) < 1e-12
    else:
        assert loop_energy(u, f) == pytest.approx(D, rel=1e-6)


def test_polynomial_aft_jacobians_equal_finite_differences():
    law = PolynomialLaw({"q": 2.0, "-q^3": 3.0, "q^2 q'": 0.5, "|q'|q'": 0.3, "|q|q": 1.1})
    u = _irregular_motion(0.7, 16)
    v = np.roll(u, 3) * 2.0
    f, Du, Dv = law.aft(u, v, velocity_jacobian=True)
    h = 1e-6
    for m in range(16):
        e = np.zeros(16)
        e[m] = h
        assert np.allclose((law.aft(u + e, v)[0] - law.aft(u - e, v)[0]) / (2 * h), Du[:, m], rtol=1e-7, atol=1e-8)
        assert np.allclose((law.aft(u, v + e)[0] - law.aft(u, v - e)[0]) / (2 * h), Dv[:, m], rtol=1e-7, atol=1e-8)


# --- protocol --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("law", [SEED, JENKINS, DISCRETE, IWAN, BW])
def test_summary_is_json_safe_and_law_is_immutable(law):
    s = json.loads(json.dumps(law.summary()))
    assert s["law"] == law.name and set(s["units"]) == set(law.parameters)
    name = next(iter(law.UNITS), "terms")
    with pytest.raises(AttributeError):
        setattr(law, name, 1.0)
    assert law.initial_state((2, 3)).shape == (2, 3, law.n_state)


def test_bad_parameters_are_structure_errors():
    with pytest.raises(StructureError, match="Jenkins parameter Fs"):
        Jenkins(kt=1.0, Fs=-1.0)
    with pytest.raises(StructureError, match="chi"):
        Iwan4(1.0, 1.0, chi=-1.0, beta=0.0)
    with pytest.raises(StructureError, match="gamma"):
        BoucWen(k_z=1.0, beta=1.0, gamma=2.0)
    with pytest.raises(StructureError, match="same"):
        DiscreteIwan([1.0, 2.0], [1.0])
    assert math.isfinite(IWAN.replace(beta=0.0).S)


def test_the_documented_example_runs(capsys):
    from pathlib import Path

    text = (Path(__file__).resolve().parents[1] / "docs" / "joint-laws.md").read_text(encoding="utf-8")
    blocks = [b.split("```", 1)[0] for b in text.split("```python\n")[1:]]
    assert blocks
    for block in blocks:
        exec(compile(block, "docs/joint-laws.md", "exec"), {})
    ratio = float(capsys.readouterr().out.split()[0])
    assert ratio == pytest.approx(1.0, abs=2e-3)


# --- the rig's own Iwan joint (rig/iwan.py) is the same law -----------------------------------------------
def test_iwan4_agrees_with_the_rig_joint_law():
    from jointid.rig.iwan import IwanParameters, discretize_iwan

    rig = IwanParameters(F_S=2.0, K_T=2000.0, chi=-0.5, beta=0.3)
    law = Iwan4(F_S=2.0, K_T=2000.0, chi=-0.5, beta=0.3, n_sliders=100, phi_min_ratio=1e-5)
    a = law.phi_max * np.array([0.01, 0.5, 0.99, 2.0])
    assert (law.phi_max, law.R, law.S) == pytest.approx((rig.phi_max, rig.R, rig.S), rel=1e-14)
    assert np.allclose(law.backbone(a), rig.backbone(a), rtol=1e-14, atol=0)
    assert np.allclose(law.dissipation(a), rig.dissipation(a), rtol=1e-14, atol=0)
    elements = discretize_iwan(rig, 100, 1e-5)
    assert np.allclose(law.sliders.stiffness, elements.stiffness, rtol=1e-14, atol=0)
    assert np.allclose(law.sliders.slip_displacement, elements.slip, rtol=1e-14, atol=0)
    u = law.phi_max * (0.3 + _irregular_motion(0.8, 64, 5))  # with a mean: the stuck elements' convention matters
    f_rig, _, D_rig = elements.periodic_force(u, jacobian=True)
    f, D = law.aft(u, state0="centre")
    assert np.allclose(f, f_rig, rtol=0, atol=1e-12 * law.F_S)
    assert np.allclose(D, D_rig, rtol=0, atol=1e-12 * law.K_T)
    f_virgin, _ = law.aft(u)  # from the virgin state the stuck elements carry the mean
    assert np.max(np.abs(f_virgin - f_rig)) > 1e-3 * law.F_S


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_centre_state_jacobian_equals_finite_differences(seed):
    u = 2e-3 + _irregular_motion(4e-3, 48, seed)
    f, D = DISCRETE.aft(u, state0="centre")
    Dfd = _fd_jacobian(DISCRETE, u, 1e-10, state0="centre")
    assert np.max(np.abs(D - Dfd)) <= 1e-6 * np.max(np.abs(D))
    assert not np.allclose(D, DISCRETE.aft(u)[1])


def test_polynomial_terms_agree_with_the_term_library():
    """The same named terms as identification uses (until both read one table)."""
    from jointid.conventions import TERMS
    from jointid.identify.terms import STANDARD_TERMS
    from jointid.joints import TERM_FUNCTIONS

    assert set(TERM_FUNCTIONS) == set(TERMS) == set(STANDARD_TERMS)
    rng = np.random.default_rng(7)
    q, v = rng.normal(size=50), rng.normal(size=50)
    for name, t in STANDARD_TERMS.items():
        law = PolynomialLaw({name: 1.7})
        f, Du, Dv = law.aft(q, v, velocity_jacobian=True)
        dq, dv = t.derivatives(q, v)
        assert np.allclose(f, 1.7 * t(q, v), rtol=1e-15, atol=0), name
        assert np.allclose(np.diag(Du), 1.7 * dq, rtol=1e-15, atol=0) and np.allclose(np.diag(Dv), 1.7 * dv), name


@pytest.mark.parametrize("law", [BW, JENKINS, IWAN])
def test_a_constant_motion_keeps_the_state_loaded_from_rest(law):
    f, D = law.aft(np.full(8, 1.5e-3))
    assert np.allclose(f, law.backbone(1.5e-3) if not isinstance(law, Iwan4) else law.sliders.backbone(1.5e-3))
    assert np.all(np.isfinite(D))


# --- first harmonic (equivalent linearisation) -------------------------------------------------------------
def test_first_harmonic_closed_forms_against_the_sampled_force():
    from jointid.joints._core import JointLaw

    for law, amps in ((JENKINS, [1e-3, 3e-3, 1e-2]), (DISCRETE, [1e-3, 5e-3])):
        for a in amps:
            closed = np.array(law.first_harmonic(a))
            sampled = np.array(JointLaw.first_harmonic(law, a, n=2**14))
            assert np.allclose(closed, sampled, rtol=1e-6, atol=1e-9 * law.backbone(1.0)), (law.name, a)
    k, kl = BW.first_harmonic(0.01, n=2**14)
    assert kl == pytest.approx(BW.dissipation(0.01) / (np.pi * 0.01**2), rel=1e-6)


def test_iwan4_first_harmonic_micro_slip_law_and_discretisation():
    from jointid.identify.jointlaw import iwan_harmonic_stiffness_integral

    law = Iwan4(F_S=2.0, K_T=2000.0, chi=-0.5, beta=0.3, n_sliders=1600)
    a = 0.5 * law.phi_max
    k, kl = law.first_harmonic(a)
    assert k == pytest.approx(law.K_T - law.R * a ** (law.chi + 1) * iwan_harmonic_stiffness_integral(law.chi), rel=1e-10)
    assert kl == pytest.approx(law.dissipation(a) / (np.pi * a**2), rel=1e-14)
    for r in (0.1, 0.9, 1.0, 1.5, 4.0):  # continuous closed form vs its discretisation, both sides of phi_max
        cont = np.array(law.first_harmonic(r * law.phi_max))
        disc = np.array(law.sliders.first_harmonic(r * law.phi_max))
        assert np.allclose(disc, cont, rtol=5e-5, atol=0), r


def test_polynomial_first_harmonic_is_the_duffing_backbone():
    k, kl = SEED.first_harmonic(2e-3, omega=120.0, n=256)
    assert k == pytest.approx(1.0e4 - 0.75 * 2.0e9 * 2e-3**2, rel=1e-12)
    assert kl == pytest.approx(3.0 * 120.0, rel=1e-12)
