"""Nonlinear modes by the extended periodic motion concept (jointid.simulate.nlmodes).

Checked against closed forms (linear modes with proportional damping; the first-harmonic
describing function of Jenkins and discrete Iwan joints), against the energy balance of the
multi-harmonic solution, and against the rig's own uncondensed backbone of its reduced beam.
"""

import numpy as np
import pytest

from jointid.errors import ConvergenceError, StructureError
from jointid.joints import DiscreteIwan, Jenkins, PolynomialLaw
from jointid.simulate.nlmodes import epmc_backbone, epmc_point
from jointid.simulate.structure import JointElement, LinearModel, StructureModel
from jointid.simulate.structure_hb import CondensedHB


def test_linear_structure_gives_its_natural_frequencies_and_damping_ratios():
    """Three modes coupled by a linear joint spring with stiffness-proportional viscous damping
    (C = beta K overall): EPMC returns the modes of the coupled stiffness and zeta = beta omega / 2."""
    rng = np.random.default_rng(4)
    Om = np.array([60.0, 170.0, 410.0])
    beta = 2e-4
    psi = rng.normal(size=(1, 3))
    dk = 5.0e4
    law = PolynomialLaw({"q": dk, "q'": beta * dk})
    engine = CondensedHB(Om, beta * Om / 2, psi, np.zeros(3), [law])
    lam = np.linalg.eigvalsh(np.diag(Om**2) + dk * psi.T @ psi)
    w_true = np.sqrt(lam)
    assert np.all(np.abs(w_true - Om) > 0.02 * Om)  # the joint moves every mode
    for r in range(3):
        bb = epmc_backbone(engine, r, [1e-4, 1e-3, 1e-2], n_harmonics=3)
        np.testing.assert_allclose(bb.omega, w_true[r], rtol=1e-10)
        np.testing.assert_allclose(bb.damping_ratio, beta * w_true[r] / 2, rtol=1e-10)
        p = bb.points[-1]
        assert abs(p.modal[r, 1] - 1e-2) < 1e-15 and p.modal[r, 2] == 0.0  # amplitude and phase normalisation


@pytest.mark.parametrize("law", [Jenkins(kt=5.0e3, Fs=1.0),
                                 DiscreteIwan([2.0e3, 1.5e3, 1.0e3, 0.5e3], [0.2, 0.4, 0.7, 1.2])])
def test_one_dof_slider_joint_against_the_describing_function(law):
    """One DOF, linear stiffness 1e4 plus the joint, one harmonic: omega^2 = K0 + k_eq(a) and
    zeta = D(a) / (2 pi omega^2 a^2) in closed form (the describing function / Masing loop)."""
    K0 = 1.0e4
    engine = CondensedHB([100.0], 0.0, [[1.0]], [0.0], [law])
    a_slip = np.atleast_1d(law.slip_displacement)
    amps = np.geomspace(0.3 * a_slip.min(), 30.0 * a_slip.max(), 7)  # from stuck to mostly slipped
    bb = epmc_backbone(engine, 0, amps, n_harmonics=1, n_time=1024)
    k_eq, _ = law.first_harmonic(amps)
    w = np.sqrt(K0 + k_eq)
    zeta = law.dissipation(amps) / (2 * np.pi * w**2 * amps**2)
    assert np.ptp(w) > 0.1 * w.max()  # the backbone spans a real softening (18 % for the Jenkins joint)
    np.testing.assert_allclose(bb.omega, w, rtol=1e-6)  # AFT sampling error at 1024 samples: 2e-7
    np.testing.assert_allclose(bb.damping_ratio, zeta, rtol=1e-4, atol=1e-4 * zeta.max())
    assert bb.damping_ratio[0] == pytest.approx(0.0, abs=1e-12)  # stuck: no loss


def _two_mass_jenkins():
    K = np.array([[3.0e4, -1.0e4], [-1.0e4, 1.5e4]])
    lin = LinearModel(np.diag([1.0, 0.7]), K, ["x1", "x2"], zeta=[0.01, 0.02])
    return StructureModel(lin, [JointElement("bolt", "x1", "x2", Jenkins(kt=8.0e3, Fs=2.0), k_model=0.0)],
                          {"x1": 1.0})


def test_multi_harmonic_mode_balances_the_energy():
    """With 7 harmonics the power of the self-excitation equals the modal damping's plus the
    joint's dissipation (the harmonic balance is exact in the kept harmonics), and higher
    harmonics are present."""
    st = _two_mass_jenkins()
    e = st.engine
    for r in (0, 1):
        bb = epmc_backbone(e, r, np.geomspace(1e-4, 1e-1, 7), n_harmonics=7)
        assert bb.joint_amplitude.min() < 2.5e-4 < bb.joint_amplitude.max()  # from stuck to slipping
        for p in bb.points:
            H = p.n_harmonics
            kw = np.repeat(np.arange(1, H + 1), 1) * p.omega
            a_m, b_m = p.modal[:, 1::2], p.modal[:, 2::2]
            vel2 = (kw**2 * (a_m**2 + b_m**2)).sum(axis=1)  # 2/T int eta'^2 dt, per mode
            a_u, b_u = p.joint[:, 1::2], p.joint[:, 2::2]
            fa, fb = p.joint_force[:, 1::2], p.joint_force[:, 2::2]
            joint = (kw * (fa * b_u - fb * a_u)).sum()  # 2/T oint f du
            pumped = p.xi * vel2.sum()
            lost = (2 * e.zeta * e.omega * vel2).sum() + joint
            assert pumped == pytest.approx(lost, rel=1e-8)
        assert bb.damping_ratio.max() > 1.5 * bb.damping_ratio[0]  # slip adds damping (1.85x, 4.9x)
        fj = bb.points[-1].joint_force[0]
        assert np.hypot(fj[5], fj[6]) > 0.1 * np.hypot(fj[1], fj[2])  # the slipping joint's third harmonic


def test_mode_is_a_periodic_orbit_of_a_time_integration():
    """Two modes, a hardening cubic spring with displacement-dependent damping (smooth), 15
    harmonics, at an amplitude where the frequency has risen 39 %: started from the EPMC
    point, an independent time integration (DOP853) of the self-excited equations returns to
    its initial state after one period (measured 1e-11 in displacement, 1e-9 in velocity)."""
    from scipy.integrate import solve_ivp

    Om, ze = np.array([50.0, 130.0]), np.array([0.01, 0.02])
    psi = np.array([[0.8, -0.6]])
    law = PolynomialLaw({"-q^3": -4e6, "q^2 q'": 3e3})
    engine = CondensedHB(Om, ze, psi, np.zeros(2), [law])
    H = 15
    bb = epmc_backbone(engine, 0, np.geomspace(1e-3, 0.05, 6), H)
    assert bb.frequency_hz[-1] > 1.35 * Om[0] / (2 * np.pi) and bb.damping_ratio[-1] > 1.2 * ze[0]
    p = bb.points[-1]
    k = np.arange(1, H + 1)
    y0 = np.concatenate([p.modal[:, 0] + p.modal[:, 1::2].sum(axis=1), (p.modal[:, 2::2] * k * p.omega).sum(axis=1)])

    def rhs(t, y):
        eta, v = y[:2], y[2:]
        u, ud = psi @ eta, psi @ v
        f, _ = law.force(u, ud, law.initial_state(u.shape))
        return np.concatenate([v, -(2 * ze * Om - p.xi) * v - Om**2 * eta - psi.T @ np.atleast_1d(f)])

    sol = solve_ivp(rhs, (0.0, 2 * np.pi / p.omega), y0, method="DOP853", rtol=1e-12, atol=1e-14)
    yT = sol.y[:, -1]
    assert np.linalg.norm(yT[:2] - y0[:2]) < 1e-8 * np.linalg.norm(y0[:2])
    assert np.linalg.norm(yT[2:] - y0[2:]) < 1e-7 * np.linalg.norm(y0[2:])


def test_bad_input_names_the_problem():
    st = _two_mass_jenkins()
    with pytest.raises(StructureError, match="mode 2 out of range"):
        epmc_backbone(st.engine, 2, [1e-3])
    with pytest.raises(StructureError, match="amplitudes must be positive"):
        epmc_backbone(st.engine, 0, [1e-3, -1.0])
    with pytest.raises(StructureError, match="n_time"):
        epmc_point(st.engine, 0, 1e-3, 5, n_time=8)
    e = CondensedHB([0.0, 50.0], 0.01, [[0.0, 1.0]], [1.0, 0.0], [Jenkins(kt=1e3, Fs=1.0)])
    with pytest.raises(StructureError, match="rigid-body"):
        epmc_point(e, 0, 1e-3)
    with pytest.raises(ConvergenceError, match="amplitude"):
        epmc_point(st.engine, 0, 1e-2, 3, max_iter=1)


def test_predict_writes_the_backbones_of_the_modes_in_the_band(tmp_path):
    """`jointid predict MODEL.toml` on the documented lap joint: the backbone of the mode in the
    band (mode 3, 84.19 Hz stuck) starts at the stuck mode, softens and damps as the Iwan joint
    slips, and the forced peaks at 0.5 N and 5 N lie next to it (measured 0.35 % and 0.95 % above
    the backbone frequency at the peak's amplitude: the forced peak of a mode damped 2-4 % is not
    on the undamped-like backbone exactly)."""
    import json

    from jointid.cli import EXIT_OK, main
    from test_structure_model_file import REPO, doc_example

    (tmp_path / "examples").symlink_to(REPO / "examples", target_is_directory=True)
    lap = tmp_path / "lap_joint.toml"
    lap.write_text(doc_example(), encoding="utf-8")
    out = tmp_path / "lap-out"
    assert main(["predict", str(lap), "--force-levels", "0.5,5", "--frequency-range", "72", "88", "--harmonics", "3",
                 "--out", str(out), "--quiet"]) == EXIT_OK
    res = json.loads((out / "results.json").read_text())
    assert (out / "figures" / "backbones.png").is_file()
    assert len(res["predictions"]) == 2  # the frequency responses are still there
    (bb,) = res["backbones"]
    assert bb["mode"] == 3 and bb["error"] == ""
    assert bb["linear_frequency_hz"] == pytest.approx(res["model"]["frequencies_hz"][2])
    f, z, a = (np.array(bb[k]) for k in ("frequency_hz", "damping_ratio", "amplitude"))
    assert len(f) == len(z) == len(a) == 20 and np.all(np.diff(a) > 0)
    assert bb["linear_frequency_hz"] * 0.99 < f[0] < bb["linear_frequency_hz"]
    assert np.all(np.diff(f) < 0) and f[-1] < 0.9 * f[0]  # softening as the joint slips
    assert np.all(z > bb["linear_damping_ratio"]) and z.max() > 10 * bb["linear_damping_ratio"]
    assert bb["max_residual"] < 1e-9
    ra = np.array(bb["response_amplitude"]["B.w10"])
    for p in res["predictions"]:
        pk = p["peaks"]["B.w10"]
        f_bb = np.interp(np.log(pk["peak_amplitude"]), np.log(ra), f)
        assert abs(pk["peak_frequency_hz"] / f_bb - 1) < 0.015


MODAL_TOML = """
[model]
name = "two modes"

[modal]
frequencies_hz = [20.0, 22.0]
damping_ratios = [0.01, 0.01]
dof_names = ["a", "b", "tip"]
shapes = [[0.0, 1.0], [1.0, 1.0], [1.0, 0.0]]

[[joint]]
name = "slip"
dofs = ["a", "b"]
law = "jenkins"
parameters = { kt = 3000.0, Fs = 0.02 }

[force]
dofs = { "tip" = 1.0 }

[response]
dofs = ["tip"]

[predict]
frequency_range_hz = [15.0, 30.0]
force_levels = [0.05, 0.2]
n_harmonics = 3
"""


def test_predict_lists_a_mode_the_force_does_not_excite(tmp_path):
    """Modal data: mode 2 is neither loaded nor moved by the joint, so it has no amplitude scale:
    listed in settings and the report, not computed; mode 1 softens from its stuck frequency
    sqrt(20^2 + kt / (2 pi)^2) Hz as the Jenkins joint slips."""
    from jointid.app.structure_predict import predict_structure

    p = tmp_path / "MODEL.toml"
    p.write_text(MODAL_TOML, encoding="utf-8")
    res = predict_structure(p)
    assert res.settings["backbone_modes"] == [1] and res.settings["backbone_modes_not_excited"] == [2]
    assert "not excited" in res.report()
    (b,) = res.backbones
    assert b.mode == 1 and b.error == ""
    stuck = np.sqrt(20.0**2 + 3000.0 / (2 * np.pi) ** 2)
    assert b.frequency_hz[0] == pytest.approx(stuck, rel=1e-9)  # below the slip amplitude: exactly stuck
    assert b.frequency_hz[-1] < 20.0 * 1.05 and np.all(np.diff(b.frequency_hz) <= 1e-12)
    assert res.summary()["backbones"][0]["joint_amplitude"]["slip"][-1] > 10 * 0.02 / 3000.0
