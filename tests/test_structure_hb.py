"""Multi-mode harmonic balance condensed on the joint DOFs (jointid.simulate.structure_hb).

Checked against an independent long time integration of the same multi-mode model
(:mod:`jointid.simulate.structure_timeint`: scipy's DOP853 with each joint law's time-step
protocol ``force(u, v, state)``), and against the
rig's reduced beam solved with the rig's own Iwan implementation.
"""

import numpy as np
import pytest

from jointid.errors import StructureError
from jointid.joints import DiscreteIwan, Jenkins, PolynomialLaw
from jointid.simulate.structure import JointElement, LinearModel, ModalModel, StructureModel
from jointid.simulate.structure_hb import CondensedHB, to_complex
from jointid.simulate.structure_timeint import integrate_structure


def chain_structure(force_scale=1.0):
    """Four masses in a chain, both ends held by springs; a Jenkins joint between x2 and x3 (its stuck
    stiffness in K) and a hardening cubic spring from x4 to the ground (folds at larger force)."""
    kt = 4.0e4
    k = [2.0e4, 3.0e4, kt, 2.5e4]
    K = np.zeros((4, 4))
    K[0, 0] += k[0]
    K[3, 3] += 1.5e4
    for i, kk in enumerate(k[1:]):
        K[i:i + 2, i:i + 2] += kk * np.array([[1, -1], [-1, 1]])
    M = np.diag([1.5, 0.4, 0.3, 2.0])  # modes at 14.1, 23.7, 49.7, 89.7 Hz: no 1:3 or 1:5 internal resonance near f1
    lin = LinearModel(M, K, ["x1", "x2", "x3", "x4"], zeta=0.02)
    joints = [
        JointElement("bolt", "x2", "x3", Jenkins(kt=kt, Fs=8.0), k_model=kt),
        JointElement("stop", None, "x4", PolynomialLaw({"-q^3": -4.0e9})),
    ]
    return StructureModel(lin, joints, {"x1": 1.0})


def test_time_integration_from_an_hb_point_stays_on_it_and_sees_truncation():
    """The package's integrator (DOP853, joint laws' time steps) started on a 7-harmonic orbit stays on it over
    5 periods (every harmonic); on a 1-harmonic orbit of the same point it sees the cubic stop's truncation."""
    st = chain_structure()
    f = 1.1 * st.modal.frequencies_hz[0]
    p = st.solve(f, 2.0, 7, n_time=256)
    r = integrate_structure(st, p, n_periods=5, dofs=["x1", "x4"])
    assert r.relative_difference < 1e-8 and r.periods == 5 and r.n_steps >= 5 * 60
    assert r.response.shape == (2, 15) and r.joint.shape == p.joint.shape
    assert np.max(np.abs(r.joint - p.joint)) < 1e-7 * np.abs(p.joint).max()
    assert np.allclose(r.response, st.modal.shapes[[0, 3]] @ r.modal, rtol=0, atol=1e-15)
    p1 = st.solve(f, 2.0, 1, n_time=256)
    assert integrate_structure(st, p1, n_periods=5).relative_difference > 1e-4


def test_condensed_hb_matches_linear_receptance_and_converges():
    st = chain_structure()
    A = 1e-5  # tiny force: the joint stays stuck and the cubic stop is negligible (its effect grows as A^2)
    p = st.solve(st.modal.frequencies_hz[0] * 0.8, A, 5)
    X = st.modal.shapes @ to_complex(p.modal)[:, 1]
    w = p.omega
    Hm = st.engine.receptance(w) * st.engine.force_shape
    X_lin = st.modal.shapes @ (Hm * (-1j))  # F sin(wt): complex amplitude -i F
    assert np.max(np.abs(X - X_lin * A)) < 1e-10 * np.max(np.abs(X))
    assert p.residual_norm < 1e-10


def test_continuation_passes_folds_and_solve_agrees():
    st = chain_structure()
    f1 = st.modal.frequencies_hz[0]
    curve = st.frequency_response(0.8 * f1, 1.6 * f1, 2.0, 7)
    assert len(curve.folds) == 2  # the hardening stop bends the resonance right: two turning points
    f = curve.frequency_hz
    i1, i2 = curve.folds
    assert f[i1] > f[i2]  # the upper fold lies at the higher frequency
    # a point of the curve is a fixed-frequency solution from its own neighbourhood
    p = curve.points[i1 - 3]
    q = st.engine.solve(p.omega, p.force, 7, guess=p.joint * (1 + 1e-3))
    assert np.allclose(q.joint, p.joint, rtol=0, atol=1e-7 * np.abs(p.joint).max())


def test_rigid_body_modes_and_bad_input():
    # a free-free pair joined only by the joint's stiffness in K: the rigid mode carries no joint motion
    kt = 1e4
    K = kt * np.array([[1.0, -1.0], [-1.0, 1.0]])
    lin = LinearModel(np.eye(2), K, ["a", "b"], zeta=0.01)
    st = StructureModel(lin, [JointElement("j", "a", "b", Jenkins(kt=kt, Fs=1.0), k_model=kt)], {"a": 1.0})
    assert st.modal.omega[0] == 0.0
    p = st.solve(20.0, 0.5, 5)
    assert p.residual_norm < 1e-10 and np.all(np.isfinite(p.modal))
    with pytest.raises(StructureError, match="mechanism"):
        StructureModel(LinearModel(np.eye(2), np.zeros((2, 2)) + np.diag([0, 1.0]), ["a", "b"], zeta=0.01),
                       [JointElement("j", None, "a", Jenkins(kt=kt, Fs=1.0))], {"a": 1.0})
    with pytest.raises(StructureError, match="DOF"):
        StructureModel(lin, [JointElement("j", "a", "c", Jenkins(kt=kt, Fs=1.0))], {"a": 1.0})
    with pytest.raises(StructureError, match="symmetric"):
        LinearModel(np.eye(2), np.array([[1.0, 2.0], [0.0, 1.0]]), ["a", "b"], zeta=0.01)
    with pytest.raises(StructureError, match="Rayleigh"):
        LinearModel(np.eye(2), K, ["a", "b"])


@pytest.mark.slow
def test_hb_matches_long_time_integration_on_ten_frequencies_and_a_fold():
    """Ten points of the continued curve off the middle (unstable) branch and one two steps before the
    upper fold: the first harmonic of a 30-period integration started on the orbit equals HB to 1e-4.
    (Measured: at most 1.2e-10.  The Jenkins joint slips only near the peak, up to 1.09 times its slip
    displacement; the cubic spring makes the folds.)"""
    st = chain_structure()
    f1 = st.modal.frequencies_hz[0]
    curve = st.frequency_response(0.8 * f1, 1.6 * f1, 2.0, 15, n_time=256)
    i1, i2 = curve.folds
    stable = [i for i in range(len(curve)) if i < i1 or i > i2]
    picks = [stable[k] for k in np.linspace(0, len(stable) - 1, 10).astype(int)]
    picks.append(i1 - 2)  # next to the upper fold, on the stable upper branch
    errs = []
    for i in picks:
        p = curve.points[i]
        errs.append(integrate_structure(st, p, n_periods=30).relative_difference)
    print("frequencies / f1:", np.round(curve.frequency_hz[picks] / f1, 4))
    print("relative fundamental differences:", np.array(errs))
    assert max(errs) < 1e-4

def test_engine_with_a_joints_law_matches_the_rig_on_its_beam():
    """The rig's reduced beam (4 modes, Iwan joint in rotation): the engine with the joints package's
    DiscreteIwan built from the rig's sliders agrees with the rig's harmonic balance, which evaluates
    its own Iwan implementation (rig/iwan.py)."""
    from jointid.rig.rig import seed_rig

    rig = seed_rig(120, joint={"k3": 0.0})
    model = rig.model
    el = model.laws[0].elements
    law = DiscreteIwan(stiffness=el.stiffness, slip_force=el.stiffness * el.slip)
    engine = model.engine([law])
    assert isinstance(engine, CondensedHB)
    f1 = rig.linear_frequencies_hz[0]
    for f, F in ((0.97 * f1, 6.0), (f1, 3.0), (1.01 * f1, 6.0)):
        w = 2 * np.pi * f
        ref = model.harmonic_balance(w, [0.0, 0.0, F], 9)
        got = engine.solve(w, [0.0, 0.0, F], 9)
        scale = np.abs(ref.modal).max()
        assert np.max(np.abs(got.modal - ref.modal)) < 1e-9 * scale
        assert np.max(np.abs(got.joint - ref.joint)) < 1e-9 * np.abs(ref.joint).max()


def test_rate_dependent_law_is_a_viscous_damper_and_continues():
    """A viscous joint (polynomial term q') to the ground: the response is the linear one with the damper's
    modal damping added (the velocity samples and df/dv of the AFT, and d/domega in the continuation)."""
    om = 2 * np.pi * np.array([10.0, 35.0])
    psi = np.array([[0.8, -0.5]])
    pf = np.array([1.0, 0.4])
    c = 3.0
    e = CondensedHB(om, [0.01, 0.01], psi, pf, [PolynomialLaw({"q'": c})])
    w = 2 * np.pi * 9.5
    p = e.solve(w, [0.0, 0.0, 2.0], 3)
    C = np.diag(2 * 0.01 * om) + c * psi.T @ psi
    X = np.linalg.solve(np.diag(om**2) - w**2 * np.eye(2) + 1j * w * C, pf * 2.0 * (-1j))
    assert np.allclose(to_complex(p.modal)[:, 1], X, rtol=1e-10, atol=1e-12 * np.abs(X).max())
    curve = e.continuation(2 * np.pi * 8, 2 * np.pi * 12, [0.0, 0.0, 2.0], 3)
    q = curve.points[len(curve) // 2]
    C = np.diag(2 * 0.01 * om) + c * psi.T @ psi
    Xq = np.linalg.solve(np.diag(om**2) - q.omega**2 * np.eye(2) + 1j * q.omega * C, pf * 2.0 * (-1j))
    assert np.allclose(to_complex(q.modal)[:, 1], Xq, rtol=1e-8, atol=1e-10 * np.abs(Xq).max())
    assert curve.folds == ()


def test_floquet_exponents_linear_limit_and_the_branch_between_folds():
    st = chain_structure()
    e = st.engine
    f1 = st.modal.frequencies_hz[0]
    p = st.solve(0.8 * f1, 1e-6, 5)  # stuck joint, negligible cubic: the linear modes' exponents
    lam, score = e.hill_eigenvalues(p)
    lam = lam[np.argsort(score, kind="stable")[: 2 * e.n_modes]]  # the copies lowest in the harmonics
    wd = e.omega * np.sqrt(1 - e.zeta**2)
    expected = np.concatenate([-e.zeta * e.omega + 1j * wd, -e.zeta * e.omega - 1j * wd])
    # each exponent's copy lowest in the harmonics: the damped natural frequencies themselves
    key = lambda z: z[np.lexsort((z.imag, z.real))]  # noqa: E731
    assert np.allclose(key(lam), key(expected), rtol=1e-8)
    assert e.growth_rate(p) == pytest.approx(-(e.zeta * e.omega).min(), rel=1e-8)
    curve = st.frequency_response(0.8 * f1, 1.6 * f1, 2.0, 7)
    i1, i2 = curve.folds
    flags = [e.is_stable(q) for q in curve.points]
    assert all(flags[:i1 - 1]) and all(flags[i2 + 2:])  # lower and upper branches stable
    assert not any(flags[i1 + 1:i2])  # the middle branch between the folds unstable


def test_stability_agrees_with_time_integration_where_the_upper_branch_loses_it():
    """With a 1:3 internal resonance (modes at 14.8 and 43.3 Hz) the upper branch at 5 N is unstable
    before its fold: Hill's method says so where a time integration started on the orbit leaves it
    (measured: 16.95 Hz, the deviation grows from 1.8e-4 after 25 periods to 1.5e-2 after 75; at 15.92 Hz
    it stays at 8.3e-6 from 10 to 40 periods)."""
    kt = 4.0e4
    K = np.zeros((4, 4))
    K[0, 0] += 2.0e4
    K[3, 3] += 1.5e4
    for i, kk in enumerate([3.0e4, kt, 2.5e4]):
        K[i:i + 2, i:i + 2] += kk * np.array([[1, -1], [-1, 1]])
    lin = LinearModel(np.diag([1.0, 0.8, 0.6, 1.2]), K, ["x1", "x2", "x3", "x4"], zeta=0.02)
    st = StructureModel(lin, [JointElement("bolt", "x2", "x3", Jenkins(kt=kt, Fs=8.0), k_model=kt),
                              JointElement("stop", None, "x4", PolynomialLaw({"-q^3": -4.0e9}))], {"x1": 1.0})
    curve = st.frequency_response(11.0, 20.0, 5.0, 7)
    f = curve.frequency_hz
    i1 = curve.folds[0]
    up = [i for i in range(i1) if f[i] > 15.0]  # the upper branch from 15 Hz to the first fold
    near = lambda f0: min(up, key=lambda i: abs(f[i] - f0))  # noqa: E731
    assert st.engine.is_stable(curve.points[near(15.92)])
    assert not st.engine.is_stable(curve.points[near(16.95)])
