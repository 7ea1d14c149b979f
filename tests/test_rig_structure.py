"""The campaign's beam as a structure model (app/rig_structure.py) and laws side by side (joints/parallel.py)."""

import numpy as np
import pytest

from jointid.app.rig_structure import beam_structure_model, sensor_acceleration
from jointid.errors import StructureError
from jointid.joints import Iwan4, Jenkins, PolynomialLaw
from jointid.joints.parallel import Parallel
from jointid.modal.structure import Structure
from jointid.rig.plan import structure_section
from jointid.rig.rig import seed_rig


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
    fa, s1 = law.force(1e-3, 0.1, s)
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
