"""Joint laws fitted to backbones: closed forms of the Iwan first harmonic, recovery from synthetic backbones."""

import json
import re

import numpy as np
import pytest

from jointid.errors import IdentificationError
from jointid.identify.backbone import Backbone
from jointid.identify.jointlaw import (
    JointModes,
    _iwan_model,
    _jenkins_g,
    fit_cubic_viscous,
    fit_iwan,
    fit_joint_laws,
    iwan_harmonic_stiffness_integral,
)
from jointid.rig.iwan import IwanParameters, JenkinsElements, JointLaw
from jointid.rounding import format_estimate

U = np.cos(2 * np.pi * np.arange(4096) / 4096)


@pytest.mark.parametrize("s", [0.05, 0.3, 0.7, 0.95])
def test_jenkins_first_harmonic(s):
    f, _ = JenkinsElements([1.0], [s]).periodic_force(U)
    assert abs(2 * np.mean(f * U) - _jenkins_g(s)) < 1e-6


@pytest.mark.parametrize("chi", [-0.5, -0.3, 0.0])
def test_iwan_first_harmonic_closed_form(chi):
    """k_1 - K_T = -R I(chi) u0^(chi+1) and D = 4 R u0^(chi+3) / ((chi+2)(chi+3)) against the discretised law."""
    law = JointLaw(IwanParameters(16.0, 2000.0, chi, 0.4), k3=0.0, n_elements=400)
    p = law.iwan
    for u0 in (1e-4 * p.phi_max, 0.05 * p.phi_max):
        f, _ = law.periodic_force(u0 * U)
        k1 = 2 * np.mean(f * U) / u0
        ref = -p.R * iwan_harmonic_stiffness_integral(chi) * u0 ** (chi + 1)
        assert abs((k1 - p.K_T) / ref - 1) < 2e-3
    with pytest.raises(IdentificationError):
        iwan_harmonic_stiffness_integral(-1.0)


def _synthetic(modes, p, a, noise, rng, law="iwan"):
    from jointid.identify.jointlaw import _MODELS

    w, z = _MODELS[law](p, a, modes if isinstance(modes, JointModes) else JointModes.single(modes))
    sw, sz = noise * 1e-3 * w, noise * z
    return Backbone(a, w + sw * rng.standard_normal(a.size), z + sz * rng.standard_normal(a.size), sw, sz, "model")


MODES = JointModes([166.0, 990.0, 2964.0], [0.0015, 0.0015, 0.0015], [0.57, -1.9, 2.4])
TRUE = np.array([166.0, 0.0015, 25000.0, -0.3, 1.5e7])


def test_iwan_recovered_from_a_noisy_backbone():
    rng = np.random.default_rng(5)
    a = np.geomspace(1.5e-4, 5e-3, 20)
    b = _synthetic(MODES, TRUE, a, 0.005, rng)  # 5e-6 on omega, 0.5 % on zeta
    fit = fit_iwan(b, MODES, K_T=2273.0)
    for name, v in zip(("Omega", "zeta_0", "R", "chi", "k3"), TRUE):
        assert abs(fit.get(name) - v) < 4 * fit.get_stderr(name), name
    assert abs(fit.get("chi") + 0.3) < 0.05
    u = fit.u_ref
    D = 4 * 25000.0 * u ** 2.7 / (1.7 * 2.7)
    assert abs(fit.get("D_ref") / D - 1) < 0.05
    assert fit.adequacy["chi2_red"] < 2.0
    assert set(fit.not_determined) == {"F_S", "K_T", "beta"}
    # F_S(beta) inverts Segalman's R(F_S, K_T, chi, beta)
    F = float(fit.slip_force(0.4))
    assert abs(IwanParameters(F, 2273.0, fit.get("chi"), 0.4).R / fit.get("R") - 1) < 1e-9
    bb = fit.backbone(a)
    assert np.all(np.abs(bb.omega - b.omega) < 4 * np.hypot(bb.omega_stderr, b.omega_stderr))
    s = fit.summary()
    json.dumps(s)
    assert "slip_force_given_beta" in s and "not determined" in fit.report()
    # the report rounds each parameter to its standard error (the one formatter), with its 95 % interval
    chi = next(line for line in fit.report().splitlines() if line.strip().startswith("chi ="))
    assert chi.strip() == f"chi = {format_estimate(fit.get('chi'), fit.get_stderr('chi'))}"
    assert "95 % [" in chi and len(re.findall(r"\d", chi.split("±")[0])) <= 6


def test_single_mode_and_cubic_viscous_alternative():
    rng = np.random.default_rng(2)
    a = np.geomspace(1e-3, 1e-2, 12)
    p = np.array([170.0, 0.001, 2e6, 50.0, 4000.0])
    b = _synthetic(0.8, p, a, 0.002, rng, law="cubic-viscous")
    fits = fit_joint_laws(b, 0.8)
    cv = fits["cubic-viscous"]
    np.testing.assert_allclose(cv.values, p, rtol=0.05)
    assert cv.adequacy["aic"] < fits["iwan"].adequacy["aic"]
    b2 = _synthetic(0.8, np.array([170.0, 0.001, 3e4, -0.4, 0.0]), a, 0.002, rng)
    assert fit_iwan(b2, 0.8).adequacy["aic"] < fit_cubic_viscous(b2, 0.8).adequacy["aic"]
    assert abs(fit_iwan(b2, 0.8, cubic=False).get("chi") + 0.4) < 0.05


def test_bad_input():
    b = Backbone([1e-3, 2e-3], [100.0, 99.9], [0.01, 0.011], 0.01, 1e-4, "model")
    with pytest.raises(IdentificationError, match="at least 4"):
        fit_iwan(b, 0.5)
    with pytest.raises(IdentificationError, match="joint shape"):
        fit_iwan(b, 0.0)
    with pytest.raises(IdentificationError, match="joint shapes"):
        JointModes([1.0, 2.0], 0.0, [0.0, 1.0])
    with pytest.raises(IdentificationError, match="K_T"):
        fit_cubic_viscous(Backbone(np.geomspace(1e-3, 1e-2, 5), 100.0, 0.01, 0.01, 1e-4, "model"), 0.5).slip_force(0.1)


def test_modes_from_fe_model():
    from jointid.modal.analysis import modal_analysis
    from jointid.modal.beam import seed_bolted_beam

    modes = modal_analysis(seed_bolted_beam(120), 3)
    jm = JointModes.from_modal_model(modes, "rotation", 0.0015)
    _, dth = modes.fe.relative_motion(modes.shapes)
    np.testing.assert_allclose(jm.shapes, dth)
    w, z = _iwan_model(np.array([jm.omega[0], 0.0015, 0.0, -0.3, 0.0]), np.array([1e-3]), jm)
    assert abs(w[0] - jm.omega[0]) < 1e-9 * jm.omega[0] and abs(z[0] - 0.0015) < 1e-12
