"""The campaign's beam as a structure model (app/rig_structure.py) and laws side by side (joints/parallel.py)."""

import numpy as np
import pytest

from jointid.app.rig_structure import (
    beam_structure_model,
    joint_start_from_modal,
    sensor_acceleration,
)
from jointid.app.update_joint import MeasuredFRF, update_structure_joint
from jointid.errors import ManifestError, StructureError
from jointid.joints import Iwan4, Jenkins, PolynomialLaw
from jointid.joints.parallel import Parallel
from jointid.modal.structure import Structure
from jointid.rig.plan import structure_section
from jointid.rig.rig import seed_rig
from jointid.simulate.structure import JointElement, ModalModel, StructureModel
from jointid.simulate.structure_hb import to_complex


def _rig_law(rig):
    jl = rig.joint_laws["rotation"]
    ip = jl.iwan
    return Parallel((Iwan4(F_S=ip.F_S, K_T=ip.K_T, chi=ip.chi, beta=ip.beta, n_sliders=jl.n_elements,
                           phi_min_ratio=jl.phi_min_ratio), PolynomialLaw({"-q^3": jl.k3})))


def test_structure_model_of_the_campaign_table_with_the_rigs_law_reproduces_the_rig():
    """Built from the [structure] table the campaign writes (beam, force and sensor positions) with the rig's own
    law as a Parallel(Iwan4, cubic) element on the joint rotation: the rig's steady states at 6 N near resonance
    at both accelerometers to 1e-5 (same harmonics; the law's stuck stiffness taken out as the beam holds it)."""
    rig = seed_rig(120)
    s = Structure.from_mapping(structure_section(rig, rig.beam))
    model = beam_structure_model(s, _rig_law(rig), 0.0015, n_modes=rig.n_modes)
    assert model.joints[0].k_model == pytest.approx(rig.joint_laws["rotation"].iwan.K_T)
    f1 = rig.linear_frequencies_hz[0]
    for f in (0.995 * f1, 0.999 * f1):
        st = rig.steady_state(f, 6.0)
        p = model.solve(f, 6.0, st.n_harmonics)
        for i, name in enumerate(rig.model.sensor_names):
            a_rig = -(st.omega**2) * (rig.model.sensor_shapes[i] @ (st.modal[:, 1] - 1j * st.modal[:, 2]))
            assert abs(sensor_acceleration(model, p, name) / a_rig - 1) < 1e-5
    # a wrong law is seen: without the cubic the 6 N response differs by far more
    lin = beam_structure_model(s, _rig_law(rig).replace(k3=0.0), 0.0015, n_modes=rig.n_modes)
    st = rig.steady_state(0.997 * f1, 6.0)
    p = lin.solve(0.997 * f1, 6.0, st.n_harmonics)
    a_rig = -(st.omega**2) * (rig.model.sensor_shapes[1] @ (st.modal[:, 1] - 1j * st.modal[:, 2]))
    assert abs(sensor_acceleration(lin, p, "accel_42") / a_rig - 1) > 1e-3


def test_parallel_law_is_the_sum_of_its_parts():
    iw = Iwan4(F_S=2.0, K_T=2000.0, chi=-0.4, beta=0.5, n_sliders=40)
    cub = PolynomialLaw({"-q^3": 3e5, "q'": 0.7})
    law = Parallel((iw, cub))
    assert law.parameters == {**iw.parameters, **cub.parameters} and law.rate_dependent and not law.masing
    t = 2 * np.pi * np.arange(64) / 64
    u, v = 2e-3 * np.cos(t) + 4e-4 * np.sin(3 * t), -2e-3 * np.sin(t)
    f, du, dv = law.aft(u, v, velocity_jacobian=True)
    f1, du1 = iw.aft(u)
    f2, du2, dv2 = cub.aft(u, v, velocity_jacobian=True)
    np.testing.assert_allclose(f, f1 + f2, rtol=1e-14, atol=0)
    np.testing.assert_allclose(du, du1 + du2, rtol=1e-14, atol=0)
    np.testing.assert_allclose(dv, dv2, rtol=1e-14, atol=0)
    a = np.array([1e-4, 1e-3])
    np.testing.assert_allclose(law.dissipation(a, 30.0), iw.dissipation(a) + cub.dissipation(a, 30.0), rtol=1e-14)
    np.testing.assert_allclose(law.backbone(a), iw.backbone(a) + cub.backbone(a), rtol=1e-14)
    # time stepping: states one after the other
    s = law.initial_state()
    assert s.shape == (iw.n_state,)
    fa, _ = law.force(1e-3, 0.1, s)
    fb, _ = iw.force(1e-3, 0.1, iw.initial_state())
    assert fa == pytest.approx(float(fb) - 3e5 * 1e-9 + 0.07, rel=1e-12)
    # replace by name, routed to the part that has it
    r = law.replace(k3=1.0, chi=-0.2)
    assert r.parameters["k3"] == 1.0 and r.parameters["chi"] == -0.2 and law.parameters["k3"] == 3e5
    with pytest.raises(StructureError, match="no parameter"):
        law.replace(mu=1.0)
    with pytest.raises(StructureError, match="clash"):
        Parallel((Jenkins(kt=1.0, Fs=1.0), Jenkins(kt=2.0, Fs=1.0)))
    with pytest.raises(StructureError, match="two or more"):
        Parallel((iw,))


def test_start_values_carry_a_modal_iwan_law_onto_the_joint():
    """An Iwan + cubic law on the joint seen in a modal coordinate (u = psi q) is an Iwan law in q with R_q =
    psi^(chi+3) R_u: the start values rebuild the joint's micro-slip (R, chi) and cubic with the engineer's K_T."""
    psi = -0.37
    joint = Iwan4(F_S=16.0, K_T=2000.0, chi=-0.3, beta=0.4)
    modal = Iwan4(F_S=abs(psi) * joint.F_S, K_T=psi**2 * joint.K_T, chi=joint.chi, beta=joint.beta)
    st = joint_start_from_modal(modal, psi**4 * 1.5e7, psi, K_T=2500.0)
    back = Iwan4(F_S=st["F_S"], K_T=st["K_T"], chi=st["chi"], beta=st["beta"])
    assert back.R == pytest.approx(joint.R, rel=1e-12) and back.chi == joint.chi and st["k3"] == pytest.approx(1.5e7)
    # the same micro-slip force below both phi_max: the nonlinear parts K_T u - f(u) agree
    a = np.array([1e-4, 1e-3])
    np.testing.assert_allclose(back.K_T * a - back.backbone(a), joint.K_T * a - joint.backbone(a), rtol=1e-10)


def test_update_structure_joint_recovers_a_modal_damping_ratio_with_the_law():
    """zeta_1 fitted beside the joint's slip force: first harmonics made by the model itself (0.2 % noise) with
    zeta_1 = 0.002 and Fs = 0.5 are recovered from zeta_1 = 0.0015, Fs = 0.8 within their 95 % intervals."""
    modal = ModalModel.from_hz([10.0, 40.0], [0.0015, 0.002], ["x1", "x2"], [[0.8, 0.5], [1.0, -0.6]])
    true = StructureModel(ModalModel.from_hz([10.0, 40.0], [0.002, 0.002], ["x1", "x2"], [[0.8, 0.5], [1.0, -0.6]]),
                          [JointElement("j", None, "x1", Jenkins(kt=300.0, Fs=0.5), 300.0)], {"x2": 1.0})
    rng = np.random.default_rng(3)
    lv, fr, X = [], [], []
    for F in (0.2, 0.4):
        for f in np.linspace(9.6, 10.4, 7):
            p = true.solve(f, F, 3)
            lv.append(F), fr.append(f), X.append(to_complex(true.modal.shape("x2") @ p.modal)[1])
    X = np.array(X)
    se = 0.002 * np.abs(X)
    Xn = X + se * (rng.standard_normal(X.size) + 1j * rng.standard_normal(X.size))
    meas = MeasuredFRF("<simulated>", np.array(lv), np.array(fr), ("x2",) * X.size, Xn, se)
    start = StructureModel(modal, [JointElement("j", None, "x1", Jenkins(kt=300.0, Fs=0.8), 300.0)], {"x2": 1.0})
    res = update_structure_joint(start, meas, parameters=["Fs", "zeta_1"], n_harmonics=3, heldout=False)
    for k, v in (("Fs", 0.5), ("zeta_1", 0.002)):
        lo, hi = res.ci95[k]
        assert lo < v < hi and abs(res.estimate[k] / v - 1) < 0.05
    assert res.fitted["structure"].modal.zeta[0] == pytest.approx(res.estimate["zeta_1"])
    with pytest.raises(ManifestError, match="no parameter"):
        update_structure_joint(start, meas, parameters=["zeta_3"], heldout=False)
