"""The micro-slip power law c0 + c1 q_max^p: closed forms, recovery from simulated campaigns, selection."""

import json
import warnings

import numpy as np
import pytest

from jointid.identify.model import PreloadForceStateMapping
from jointid.identify.powerlaw import PowerLaw
from jointid.app.heldout_scoring import single_mode_model
from jointid.identify.selection import select_model
from jointid.identify.terms import library
from jointid.simulate.hbm import frequency_response
from jointid.simulate.model import SingleModeModel

from test_selection import campaign

W2 = 170.0**2
#: An Iwan-like single-mode joint: stiffness loss and damping growth as q_max^0.7 (chi = -0.3).
TRUTH = SingleModeModel("q + q'", (0.0, 0.0), {"q": PowerLaw(W2, -3e4, 0.7), "q'": PowerLaw(0.1, 20.0, 0.7)})
TRUE_PARAMETERS = np.array([W2, -3e4, 0.7, 0.1, 20.0, 0.7])
LAWS = {"q": "power", "q'": "power"}


def _fit(sigs, terms="q + q'", laws=LAWS):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return PreloadForceStateMapping(terms, amplitude_laws=laws).fit(sigs).result_


def test_power_law_value_derivative_jacobian():
    law = PowerLaw(0.1, 20.0, 0.7)
    q, h = 2e-3, 1e-9
    assert law.value(q) == pytest.approx(0.1 + 20.0 * q**0.7, rel=1e-14)
    assert law.derivative(q) == pytest.approx((law.value(q + h) - law.value(q - h)) / (2 * h), rel=1e-6)
    J = law.jacobian(q)
    for j in range(3):
        d = np.zeros(3)
        d[j] = 1e-6 * max(abs(law.parameters[j]), 1.0)
        fd = (PowerLaw(*(np.array(law.parameters) + d)).value(q) - PowerLaw(*(np.array(law.parameters) - d)).value(q))
        assert J[j] == pytest.approx(fd / (2 * d[j]), rel=1e-6)
    assert law.chi == pytest.approx(-0.3)
    assert json.loads(json.dumps(law.summary()))["exponent"] == 0.7
    with pytest.raises(ValueError, match="exponent"):
        PowerLaw(0.1, 1.0, 0.0)


def test_harmonic_balance_of_power_laws_meets_the_describing_function():
    """Linear terms with amplitude laws respond harmonically: A |K(A) - w^2 + i w C(A)| = F exactly."""
    F = 1.0
    omegas = np.linspace(160.0, 180.0, 21)
    frf = frequency_response(TRUTH, F, omegas, n_harmonics=3, stability=False)
    A = np.asarray(frf.q_max)
    K, C = TRUTH.amplitude_laws["omega1^2"].value(A), TRUTH.amplitude_laws["c"].value(A)
    w = np.asarray(frf.omega)
    np.testing.assert_allclose(A * np.hypot(K - w**2, w * C), F, rtol=1e-9)


def test_preload_model_recovers_the_power_laws_with_calibrated_errors():
    sigs, _ = campaign(TRUTH, 0, 0.005, n_frequencies=7)
    m = _fit(sigs)
    assert m.parameter_names == ("omega1^2", "omega1^2_1", "p(omega1^2)", "c0", "c1", "p(c)")
    z = (m.parameters - TRUE_PARAMETERS) / m.stderr
    assert np.all(np.abs(z) < 4), z
    assert abs(m.get("p(c)") - 0.7) < 0.03 and abs(m.get("p(omega1^2)") - 0.7) < 0.01
    # the coefficient at an amplitude and its standard error (delta method through the exponent)
    val, se = m.coefficient_at("c", 3e-3)
    assert abs(val - TRUTH.amplitude_laws["c"].value(3e-3)) < 4 * se
    assert np.allclose(m.coefficients_at(3e-3), TRUTH.coefficients_at(3e-3), rtol=0.02)
    d = json.loads(json.dumps(m.summary()))
    assert d["amplitude_laws"] == {"omega1^2": "power", "c": "power"}
    assert "c power law" in m.report() and "p(c)" in m.report()
    # the fitted model as a simulation model: the same coefficients at any amplitude
    sm = single_mode_model(library(m.terms), m.law_orders, m.parameters)
    assert np.allclose(sm.coefficients_at(1e-3), m.coefficients_at(1e-3), rtol=1e-12)


def test_micro_slip_family_selected_and_explains_the_data_to_the_noise():
    sigs, lev = campaign(TRUTH, 1, 0.01, n_frequencies=7)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sel = select_model(sigs, lev, fit_selected=False)
    assert sel.selected == "micro-slip", sel.report()
    s = sel.selected_score
    assert s.chi2 / s.dof < 1.6, sel.report()
    assert sel.score("amplitude-dependent stiffness").bic > s.bic + 10  # the polynomial laws do not fit
    assert s.cv_amplitude_rms_percent < 1.0  # held-out levels solved by harmonic balance with the power laws
    row = next(r for r in json.loads(json.dumps(sel.summary()))["ranking"] if r["selected"])
    assert row["amplitude_laws"] == {"q": "power", "q'": "power"}
    assert "p(c)" in row["parameter_names"]


@pytest.mark.slow
def test_power_law_standard_errors_calibrated_over_30_campaigns():
    """z-scores of all six parameters over 30 campaigns (0.5 % and 1 % noise): rms within 0.7-1.4."""
    zs = []
    for k in range(30):
        sigs, _ = campaign(TRUTH, 500 + k, 0.005 if k % 2 else 0.01, n_frequencies=7)
        m = _fit(sigs)
        zs.append((m.parameters - TRUE_PARAMETERS) / m.stderr)
    rms = np.sqrt(np.mean(np.square(zs), axis=0))
    print("rms z", dict(zip(("omega1^2", "s", "p'", "c0", "c1", "p"), np.round(rms, 2))))
    assert np.all((rms > 0.7) & (rms < 1.4)), rms


def test_model_backbone_of_power_laws():
    """The preload model's backbone (also from its results.json entry): omega = sqrt(K(a)), zeta = C(a) / (2 omega)."""
    from jointid.app.backbones import preload_model_backbone

    sigs, _ = campaign(TRUTH, 2, 0.005, n_frequencies=5)
    m = _fit(sigs)
    for model in (m, json.loads(json.dumps(m.summary()))):
        b = preload_model_backbone(model, n_points=5)
        a = np.asarray(b.amplitude)
        K, C = TRUTH.amplitude_laws["omega1^2"].value(a), TRUTH.amplitude_laws["c"].value(a)
        assert np.all(np.abs(b.omega - np.sqrt(K)) < 4 * b.omega_stderr)
        assert np.all(np.abs(b.zeta - C / (2 * np.sqrt(K))) < 4 * b.zeta_stderr)


def test_adequacy_of_micro_slip_plus_cubic():
    """A law on the stiffness: each level is fitted with the model's own laws before k3 is compared across levels,
    so the model that made the data holds; the cubic without the laws is flagged."""
    from jointid.identify.adequacy import check_adequacy

    truth = SingleModeModel("q - q^3 + q'", (0.0, 2e6, 0.0),
                            {"q": PowerLaw(W2, -3e4, 0.7), "q'": PowerLaw(0.1, 20.0, 0.7)})
    sigs, lev = campaign(truth, 300, 0.01, n_frequencies=9)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        good = check_adequacy(sigs, lev, "q - q^3 + q'", amplitude_laws=LAWS)
        bad = check_adequacy(sigs, lev, "q - q^3 + q'")
    assert good.adequate and good.verdict == "the micro-slip + cubic model holds", good.report()
    assert [e.name for e in good.equality] == ["k3"]
    assert not bad.adequate and "the cubic model does not hold" in bad.verdict
