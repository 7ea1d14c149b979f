"""Model-adequacy checks: a model that holds passes, a wrong one is flagged with the reason."""

import json
import warnings

import numpy as np
import pytest

from jointid.errors import IdentificationError
from jointid.identify.adequacy import P_LIMIT, check_adequacy, level_equality
from jointid.signal.harmonics import steady_state_signals

from test_selection import TRUTH, campaign


def _check(sigs, lev, terms="q - q^3 + q'", **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return check_adequacy(sigs, lev, terms, **kw)


def test_cubic_model_holds_on_cubic_data():
    sigs, lev = campaign(TRUTH["cubic"], 31, 0.01, n_frequencies=7)
    a = _check(sigs, lev, labels=list(range(len(sigs))), preload="sim")
    assert a.adequate, a.report()
    assert a.joint_dof == 4 and a.joint_p > P_LIMIT
    assert [e.name for e in a.equality] == ["omega1^2", "k3"]
    assert 0.2 < np.median([r.misfit for r in a.records]) < 2.0  # explained to the noise
    d = json.loads(json.dumps(a.summary()))
    # the restoring force is explained; its harmonics above the first to the noise
    assert d["explained_force"] > 0.9999 and 0.0 < d["explained_harmonics"] < 1.0
    assert 0.5 < d["harmonic_residual_to_noise"] < 2.0
    assert d["outliers"] == [] and "holds" in d["verdict"]
    assert "holds" in a.report()


def test_cubic_model_flagged_on_amplitude_dependent_stiffness():
    """A microslip-like joint (omega^2 falling with q_max) fitted as a cubic spring: k3 differs across levels."""
    sigs, lev = campaign(TRUTH["amplitude-dependent stiffness"], 32, 0.005, n_frequencies=7)
    a = _check(sigs, lev)
    assert not a.adequate
    k3 = next(e for e in a.equality if e.name == "k3")
    assert k3.differs and k3.p_value < 1e-6 and k3.ratio > 1.1
    assert "k3 changes" in a.verdict and "the cubic model does not hold at this preload" in a.verdict
    assert np.median([r.misfit for r in a.records]) > 10 and a.harmonic_residual_to_noise > 10
    # the selected family passes the same checks
    good = _check(sigs, lev, "q + q'", amplitude_laws={"q": 2, "q'": 2})
    assert good.adequate, good.report()
    # named by its laws too: the same terms without a stiffness law are the linear model
    assert good.model_name == "amplitude-dependent stiffness" and "linear" not in good.report()
    assert _check(sigs, lev, "q + q'", amplitude_laws={"q'": 2}).model_name == "linear"


def test_outlier_record_found():
    """A record of another structure (omega1^2 0.04 % higher) among a level is the one outlier."""
    sigs, lev = campaign(TRUTH["cubic"], 33, 0.005, n_frequencies=9)
    from jointid.simulate.hbm import frequency_response
    from jointid.simulate.model import SingleModeModel
    from jointid.simulate.synth import synthesize_record

    other = SingleModeModel("q - q^3 + q'", (1.0004 * 170.0**2, 5e6, 0.0), {"q'": (0.08, 70.0, 1e4)})
    s = frequency_response(other, 1.0, [171.0], n_harmonics=9, stability=False).states[0]
    t, Q, acc = synthesize_record(s, 2000.0, 20 * 2 * np.pi / s.omega, noise=0.005, rng=1)
    k = lev.index(1.0) + 5
    sigs[k] = steady_state_signals(t, Q, acc, frequency_hz=s.omega / (2 * np.pi), n_harmonics=5,
                                   refine_frequency=False)
    a = _check(sigs, lev, labels=[f"r{i}" for i in range(len(sigs))])
    assert a.outliers == (f"r{k}",), a.report()
    assert "far off the model" in " ".join(a.messages)


def test_level_equality_closed_form():
    """Two levels with known covariances: chi2 and p as computed by hand."""
    from types import SimpleNamespace

    def fit(v, s):
        return SimpleNamespace(shared_names=("omega1^2", "k3"), shared=np.array(v),
                               covariance=SimpleNamespace(shared=np.diag(np.square(s))))

    eq, chi2, dof, p = level_equality([(1, fit([1.0, 2.0], [0.1, 0.5])), (2, fit([1.3, 2.0], [0.1, 0.5]))])
    assert dof == 2 and chi2 == pytest.approx(0.3**2 / 0.02)
    assert eq[0].chi2 == pytest.approx(4.5) and eq[1].chi2 == pytest.approx(0.0)
    assert eq[0].ratio == pytest.approx(1.3) and "changes by 30 %" in eq[0].describe()
    assert level_equality([(1, fit([1.0, 2.0], [0.1, 0.5]))])[2] == 0


def test_adequacy_input_errors():
    sigs, lev = campaign(TRUTH["cubic"], 34, 0.01, levels=(1.0, 2.0), n_frequencies=4)
    with pytest.raises(IdentificationError, match="force levels given"):
        check_adequacy(sigs, lev[:-1])


def test_adequacy_plot():
    sigs, lev = campaign(TRUTH["cubic"], 35, 0.01, n_frequencies=5)
    ax = _check(sigs, lev).plot()
    assert len(ax.get_legend().get_texts()) == 2


def test_identify_writes_adequacy_and_its_figure(tmp_path):
    """Every identify run assesses its model: results.json adequacy and the level-equality figure."""
    from jointid.app.paper_example import paper_config
    from jointid.app.synthesis import load_simulation_config, simulate_campaign
    from jointid.app.workflow import identify_campaign
    from jointid.report.output import write_results

    cfg = paper_config(n_frequencies=5, fs=2000.0, periods=20, noise=0.005, seed=8, write_frequency=True,
                       n_harmonics=9)
    cfg["excitation"]["force_levels"] = [0.5, 2.0]
    camp = simulate_campaign(load_simulation_config(cfg), tmp_path / "campaign")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = identify_campaign(camp, repredict=False)
        write_results(res, tmp_path / "out", figures=True)
    d = json.loads((tmp_path / "out" / "results.json").read_text())
    assert d["adequacy"][0]["adequate"] is True and d["adequacy"][0]["level_equality"]["dof"] == 2
    assert d["selection"] == []
    assert list((tmp_path / "out").rglob("adequacy_example.png"))
    assert "Model adequacy per preload" in res.report()


def test_nothing_to_test_is_not_called_adequate():
    """One force level and no preload model: the verdict says 'not assessed', never 'holds'."""
    from jointid.identify.adequacy import assess_preload

    sigs, lev = campaign(TRUTH["cubic"], 36, 0.01, levels=(1.0,), n_frequencies=4)
    a = assess_preload(None, [], sigs, lev, [])
    assert a.adequate is None and a.summary()["adequate"] is None
    assert a.verdict.startswith("not assessed") and "not assessed" in a.report()
    one = _check(sigs, lev)  # with the preload model: records checked, equality not tested
    assert one.adequate and "not tested" in " ".join(one.messages)


def test_drifting_level_found():
    """omega1^2 creeping up by 0.1 % per record (a warming rig) during one level's dwells: a drift there."""
    from jointid.simulate.hbm import steady_state
    from jointid.simulate.model import SingleModeModel
    from jointid.simulate.synth import synthesize_record

    sigs, lev = campaign(TRUTH["cubic"], 37, 0.005, n_frequencies=9)
    rng = np.random.default_rng(5)
    idx = [i for i, x in enumerate(lev) if x == 1.0]
    for k, i in enumerate(idx):
        w = 2 * np.pi * sigs[i].frequency_hz
        m = SingleModeModel("q - q^3 + q'", ((1 + 1e-3 * k) * 170.0**2, 5e6, 0.0), {"q'": (0.08, 70.0, 1e4)})
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            s = steady_state(m, w, 1.0, n_harmonics=9)
        t, Q, acc = synthesize_record(s, 2000.0, 20 * 2 * np.pi / w, t0=rng.uniform(0, 1), noise=0.005, rng=rng)
        sigs[i] = steady_state_signals(t, Q, acc, frequency_hz=w / (2 * np.pi), n_harmonics=5, refine_frequency=False)
    a = _check(sigs, lev)
    assert a.drift[1.0]["drifts"] and a.drift[1.0]["slope_per_record"] > 0, a.drift
    assert not a.drift[0.5]["drifts"] and not a.drift[2.0]["drifts"]
    assert any("trends with the record order" in m for m in a.messages)


def test_coulomb_model_holds_on_coulomb_data_within_the_fitted_harmonics():
    """sign(q') has harmonics beyond the 5 fitted; compared within them, the model that made the data holds,
    and its friction coefficient is recovered there (the regression over all harmonics finds it 10 % low)."""
    sigs, lev = campaign(TRUTH["Coulomb + viscous"], 2001, 0.005, n_frequencies=11, n_time=4096)
    a = _check(sigs, lev, "q + q' + sign(q')")
    assert a.adequate, a.report()
    assert a.joint_p > P_LIMIT and np.median([r.misfit for r in a.records]) < 2.0
    assert "beyond the 5 fitted harmonics (sign(q') 6.7 %)" in a.report()
    assert "f_c 0.08" in a.report() and "within the band 0.100" in a.report()
    # a wrong model on the same data is still flagged, and so is this model on data it did not make
    assert not _check(sigs, lev, "q - q^3 + q'").adequate
    other, lev2 = campaign(TRUTH["cubic"], 2002, 0.005, n_frequencies=11)
    flagged = _check(other, lev2, "q + q' + sign(q')")
    assert not flagged.adequate and "does not hold" in flagged.verdict


def test_preload_model_of_coulomb_friction_within_the_fitted_harmonics():
    """The preload model compares within the fitted harmonics by itself when a term has energy beyond them."""
    from jointid.identify.model import PreloadForceStateMapping

    sigs, _ = campaign(TRUTH["Coulomb + viscous"], 2003, 0.01, n_frequencies=9, n_time=4096)
    laws = {"q'": 2}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        band = PreloadForceStateMapping("q + q' + sign(q')", amplitude_laws=laws).fit(sigs).result_
        full = PreloadForceStateMapping("q + q' + sign(q')", amplitude_laws=laws, in_band=False).fit(sigs).result_
    assert band.in_band and not full.in_band and band.summary()["in_band"] is True
    assert abs(band.get("f_c") - 0.1) < 4 * band.get_stderr("f_c")
    assert full.get("f_c") < 0.1 - 10 * full.get_stderr("f_c")  # square-wave harmonics beyond the 5th left out
    # a model without such terms is fitted as before
    cubic = PreloadForceStateMapping("q - q^3 + q'").fit(sigs).result_
    assert not cubic.in_band


def test_sampled_jump_widens_only_the_in_band_equality_test():
    """sign(q')'s jump is sampled: the levels' in-band fits count the alias of its instant (one sample,
    in phase with the motion); the same rows without the signals, and a model without the jump, are unchanged."""
    from jointid.identify.adequacy import in_band_level_fits
    from jointid.identify.fsm import own_fits
    from jointid.identify.terms import library

    sigs, lev = campaign(TRUTH["Coulomb + viscous"], 2004, 0.005, n_frequencies=5, n_time=1024)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fits = own_fits(library("q + q' + sign(q')"), sigs, None, True)
        cubic = own_fits(library("q - q^3 + q'"), sigs, None, True)
    _, _, th0, c0 = in_band_level_fits(fits, lev, ["omega1^2"])
    _, _, th1, c1 = in_band_level_fits(fits, lev, ["omega1^2"], signals_list=sigs)
    for a, b, x, y in zip(c0, c1, th0, th1):
        assert np.array_equal(x, y) and b[0, 0] > 1.2 * a[0, 0]
    # the added variance follows the sample interval: the same records at half the rate
    half = [steady_state_signals(s.t[::2], s.force[::2], s.accel_measured[::2], frequency_hz=s.frequency_hz,
                                 n_harmonics=5) for s in sigs]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fh = own_fits(library("q + q' + sign(q')"), half, None, True)
    _, _, _, c2 = in_band_level_fits(fh, lev, ["omega1^2"], signals_list=half)
    assert all(c[0, 0] - 2 * a[0, 0] > 2.0 * (b[0, 0] - a[0, 0]) for a, b, c in zip(c0, c1, c2))
    _, _, _, d0 = in_band_level_fits(cubic, lev, signals_list=None)
    _, _, _, d1 = in_band_level_fits(cubic, lev, signals_list=sigs)
    assert all(np.array_equal(a, b) for a, b in zip(d0, d1))
