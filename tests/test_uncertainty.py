"""Calibrated uncertainties and the preload model: known parameters recovered with honest intervals."""

import tracemalloc
import warnings

import numpy as np
import pytest

from jointid.app.paper_example import PAPER, paper_config
from jointid.app.study import StudyPlan, run_campaign, run_study, study_statistics
from jointid.app.synthesis import load_simulation_config, simulate_campaign
from jointid.app.workflow import identify_campaign
from jointid.errors import IdentificationError
from jointid.identify.fsm import ForceStateMapping
from jointid.identify.laws import fit_damping_law
from jointid.identify.model import PreloadForceStateMapping, parameter_names
from jointid.identify.regression import lstsq_from_reduced, pooled_solve
from jointid.identify.terms import library
from jointid.identify.uncertainty import LowRankCovariance, pooled_covariance, sandwich
from jointid.signal.harmonics import steady_state_signals
from jointid.simulate.hbm import frequency_response
from jointid.simulate.model import SingleModeModel, seed_model
from jointid.simulate.synth import synthesize_record

EXACT = PAPER["exact"]


def _plan(campaigns, seed, n_frequencies=(4, 6), periods=(6, 15)):
    """Random campaigns: noise 0.1-2 %, hardening or softening, 2-4 levels, frequency given or not,
    random record lengths and sampling rates."""
    return StudyPlan.from_mapping({
        "study": {"name": "calibration", "campaigns": campaigns, "seed": seed},
        "model": [{"preload": "p", "terms": "q + -q^3 + q'", "omega1": 170.0, "coefficients": {"k3": 5e6},
                   "amplitude_laws": {"c": [0.08, 70.0, 1e4]}}],
        "excitation": {"omega_start": 160.0, "omega_stop": 180.0, "n_frequencies": 9, "force_levels": [1.0]},
        "acquisition": {"fs": 2000.0, "periods": 20.0, "noise": 0.01, "n_harmonics": 9},
        "identify": {"n_harmonics": 5, "repredict": False},
        "vary": {
            "acquisition.noise": {"loguniform": [0.001, 0.02]},
            "model.coefficients.k3": {"uniform": [3e6, 6e6], "random_sign": True},
            "excitation.force_levels": {"uniform": [0.4, 2.0], "size": [2, 4]},
            "acquisition.fs": {"uniform": [1500.0, 4000.0]},
            "acquisition.periods": {"integers": list(periods)},
            "excitation.n_frequencies": {"integers": list(n_frequencies)},
            "acquisition.write_frequency": {"choice": [True, False]},
        },
    })


CALIBRATED = ("groups.omega1", "groups.k3", "models.omega1", "models.k3", "models.damping.c0",
              "models.damping.c1", "models.damping.c2", "records.c", "records.c_pooled")


def _complete(s):
    """Every estimate present; records left out of the pooled fits by a plausibility flag (a few
    percent of clean simulated records) have no pooled ``c``."""
    if s["parameter"] == "records.c_pooled":
        return s["n_missing"] <= 0.05 * s["n"]
    return s["n_missing"] == 0


def _calibration(campaigns, seed, out=None, **kw):
    """Statistics of ``campaigns`` random campaigns: in this process, or (``out``) as a study on two local
    workers (the same lines byte for byte, tests/test_dask_study.py) written to ``out``."""
    plan = _plan(campaigns, seed, **kw)
    if out is None:
        lines = [run_campaign(plan, i) for i in range(campaigns)]
    else:
        lines = list(run_study(plan, out, jobs=2, report=False).campaigns)
    assert all(line["status"] == "ok" for line in lines), [line["error"] for line in lines if line["error"]]
    return {s["parameter"]: s for s in study_statistics(lines)}


def test_calibration_small_monte_carlo():
    """20 small random campaigns: the standard errors measure the error (the former ones were 3-30x too
    wide, std(z) 0.03-0.37 for the group and law coefficients)."""
    stats = _calibration(20, 7)
    for name in CALIBRATED:
        s = stats[name]
        assert _complete(s), (name, s["n_missing"])
        assert 0.6 < s["std_z"] < 1.5, (name, s["std_z"])
        assert s["coverage"] >= 0.8, (name, s["coverage"])


@pytest.mark.slow
def test_calibration_monte_carlo_400_campaigns(tmp_path):
    """400 random campaigns: std(z) within 0.8-1.25 and 95 % intervals that cover the truth in 92-98 %.

    A coverage count over n campaigns scatters by sqrt(0.95 * 0.05 / n): 1.5 points at 200, which
    is half the width of the 92-98 % band; 400 campaigns bring it to 1.1 points.
    """
    stats = _calibration(400, 2026, tmp_path / "study", n_frequencies=(5, 9), periods=(8, 30))
    for name in CALIBRATED:
        s = stats[name]
        assert _complete(s), (name, s["n_missing"])
        assert 0.8 <= s["std_z"] <= 1.25, (name, s["std_z"])
        assert 0.92 <= s["coverage"] <= 0.98, (name, s["coverage"])


def _noisy_campaign(tmp_path, k3, levels, noise, seed):
    cfg = paper_config(n_frequencies=41, fs=2000.0, periods=50, noise=noise, seed=seed, write_frequency=False,
                       n_harmonics=9)
    cfg["model"][0]["coefficients"]["k3"] = k3
    cfg["excitation"]["force_levels"] = list(levels)
    cfg["acquisition"]["t0"] = 0.123
    camp = simulate_campaign(load_simulation_config(cfg), tmp_path / "campaign")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return identify_campaign(camp, n_harmonics=5)


def _check_model(res, k3):
    m = res.models["example"]
    assert abs(m.omega1 / EXACT["omega1"] - 1) < 1e-5
    assert abs(m.k3 / k3 - 1) < 0.015
    c0, c1, c2 = m.damping_coefficients
    assert abs(c0 / EXACT["c0"] - 1) < 0.02
    assert abs(c1 / EXACT["c1"] - 1) < 0.02
    assert abs(c2 / EXACT["c2"] - 1) < 0.10
    return m


def test_preload_model_hardening_two_levels(tmp_path):
    """0.5 % noise, hardening, two force levels: the preload model within the stated accuracy."""
    res = _noisy_campaign(tmp_path, -5e6, (0.5, 1.0), 0.005, 11)
    m = _check_model(res, -5e6)
    d = res.summary()["models"][0]
    for key in ("preload", "terms", "omega1", "omega1_stderr", "omega1_ci95", "k3", "k3_stderr", "k3_ci95",
                "damping_coefficients", "damping_stderr", "damping_ci95", "parameter_names", "covariance",
                "n_records", "q_max_range"):
        assert key in d, key
    assert d["parameter_names"] == ["omega1^2", "k3", "c0", "c1", "c2"]
    assert np.shape(d["covariance"]) == (5, 5)
    assert d["n_records"] == 82 and m.n_records == 82
    assert "± " in m.report() and "95 %" in m.report()


@pytest.mark.slow
@pytest.mark.parametrize("k3, levels, noise, seed", [
    (5e6, (0.5, 1.0, 2.0), 0.01, 3),
    (-5e6, (0.5, 1.0, 2.0), 0.01, 4),
    (5e6, (1.0, 2.0), 0.005, 5),
])
def test_preload_model_noisy_campaigns(tmp_path, k3, levels, noise, seed):
    _check_model(_noisy_campaign(tmp_path, k3, levels, noise, seed), k3)


def _records(model, omegas, F, noise, rng, n_harmonics=5, periods=20):
    frf = frequency_response(model, F, omegas, n_harmonics=9, stability=False)
    sigs = []
    for s in frf.states:
        t, Q, a = synthesize_record(s, 2000.0, periods * 2 * np.pi / s.omega, t0=rng.uniform(0, 1), noise=noise,
                                    rng=rng)
        sigs.append(steady_state_signals(t, Q, a, frequency_hz=s.omega / (2 * np.pi), n_harmonics=n_harmonics,
                                         refine_frequency=False))
    return sigs, frf.states


def test_stiffness_amplitude_law_recovered():
    """A law on the linear stiffness, omega^2(q_max) = omega1^2 + s1 q_max, is identified with the damping law."""
    lib = library("q + -q^3 + q'")
    model = SingleModeModel(lib, (0.0, 5e6, 0.0), {"q": (170.0**2, 2e5), "q'": (0.08, 70.0, 1e4)})
    rng = np.random.default_rng(4)
    sigs = []
    for F in (0.5, 1.0, 2.0):
        sigs += _records(model, np.linspace(160, 185, 9), F, 0.002, rng)[0]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = PreloadForceStateMapping(amplitude_laws={"q": 1, "q'": 2}).fit(sigs).result_
    assert r.parameter_names == ("omega1^2", "omega1^2_1", "k3", "c0", "c1", "c2")
    truth = {"omega1^2": 170.0**2, "omega1^2_1": 2e5, "k3": 5e6, "c0": 0.08, "c1": 70.0, "c2": 1e4}
    for name, value in truth.items():
        assert abs(r.get(name) - value) < 4 * r.get_stderr(name), (name, r.get(name), r.get_stderr(name))
    assert abs(r.get("omega1^2_1") / 2e5 - 1) < 0.05


def test_preload_model_input_errors():
    lib = library("q + -q^3 + q'")
    with pytest.raises(IdentificationError, match="no term"):
        PreloadForceStateMapping(amplitude_laws={"q^7": 1}).fit(
            _records(seed_model(), [165.0, 170.0, 175.0], 1.0, 0.0, np.random.default_rng(0))[0])
    sigs = _records(seed_model(), [165.0, 170.0], 1.0, 0.0, np.random.default_rng(0))[0]
    with pytest.raises(IdentificationError, match="at least 3 records"):
        PreloadForceStateMapping().fit(sigs)
    assert parameter_names(lib, (0, 0, 2)) == ("omega1^2", "k3", "c0", "c1", "c2")


def _dense_pooled(reduced, shared, own, rhs, weights):
    """The pooled problem stacked densely (reference for the block-wise elimination)."""
    ns, no, nr = len(shared), len(own), len(reduced)
    blocks = []
    for r, (R, _) in enumerate(reduced):
        B = np.zeros((R.shape[0], ns + no * nr + 1))
        B[:, :ns] = R[:, shared]
        B[:, ns + r * no: ns + (r + 1) * no] = R[:, own]
        B[:, -1] = R[:, rhs]
        blocks.append(weights[r] * B)
    B = np.vstack(blocks)
    return B


def test_blockwise_elimination_matches_dense_pooled_fit_and_sandwich():
    rng = np.random.default_rng(1)
    sigs, _ = _records(seed_model(), np.linspace(162, 178, 6), 1.0, 0.01, rng)
    lib = library("q + -q^3 + q'")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # single records do not resolve k3
        fits = [ForceStateMapping(lib).fit(s).result_ for s in sigs]
    reduced = [(f.reduced, f.n_samples) for f in fits]
    w = rng.uniform(0.5, 2.0, len(fits))
    sol = pooled_solve(reduced, [0, 1], [2], 3, w)
    B = _dense_pooled(reduced, [0, 1], [2], 3, w)
    ref = lstsq_from_reduced(B[:, :-1], B[:, -1], 1000).coefficients
    np.testing.assert_allclose(sol.shared, ref[:2], rtol=1e-10)
    np.testing.assert_allclose(sol.own[:, 0], ref[2:], rtol=1e-10)
    # dense sandwich: records independent, each score in its own columns
    p = B.shape[1] - 1
    M = B[:, :-1].T @ B[:, :-1]
    V = np.zeros((p, p))
    Vs = []
    for r, f in enumerate(fits):
        theta = np.array([sol.shared[0], sol.shared[1], sol.own[r, 0]])
        Vr = f.scores.covariance(theta)
        Vs.append(Vr)
        cols = [0, 1, 2 + r]
        V[np.ix_(cols, cols)] += w[r] ** 4 * Vr
    C = sandwich(M, V)
    pc = pooled_covariance(sol, Vs, 2)
    np.testing.assert_allclose(pc.shared, C[:2, :2], rtol=1e-6)
    np.testing.assert_allclose(pc.own[:, 0, 0], np.diag(C)[2:], rtol=1e-6)
    np.testing.assert_allclose(pc.own_shared[:, 0, :], C[2:, :2], rtol=1e-6, atol=1e-12 * np.abs(C[2:, :2]).max())
    lr = pc.own_factor(0)
    np.testing.assert_allclose(lr.dense(), C[2:, 2:], rtol=1e-6, atol=1e-9 * np.abs(C[2:, 2:]).max())
    # the damping law's congruence and solve agree with the dense matrix
    L = rng.standard_normal((3, len(fits)))
    np.testing.assert_allclose(lr.congruence(L), L @ C[2:, 2:] @ L.T, rtol=1e-6)
    b = rng.standard_normal(len(fits))
    np.testing.assert_allclose(C[2:, 2:] @ lr.solve(b), b, rtol=1e-6, atol=1e-8)


def test_pooled_fit_memory_is_linear_in_records():
    """10,000 records through the block-wise pooled solve and covariance in well under 1 GiB."""
    rng = np.random.default_rng(0)
    nr = 10_000
    reduced = []
    for _ in range(nr):
        R = np.triu(rng.standard_normal((5, 5))) + 3 * np.eye(5)
        reduced.append((R, 1000))
    tracemalloc.start()
    sol = pooled_solve(reduced, [0, 1], [2], 3, np.ones(nr))
    V = [np.eye(3)] * nr
    pc = pooled_covariance(sol, V, 2)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 64 * 2**20, peak  # a dense (rows x records) matrix would take 1.6 GB
    assert pc.own.shape == (nr, 1, 1) and np.all(pc.own > 0)


def test_damping_law_propagates_full_covariance_and_reports_chi2():
    rng = np.random.default_rng(3)
    q = np.linspace(1e-3, 6e-3, 40)
    se = np.full(40, 0.002)
    # records correlated through one shared parameter: C = diag(se^2) + u u^T
    u = 0.003 * np.ones((40, 1))
    C = LowRankCovariance(se**2, u, np.eye(1))
    zs = []
    for _ in range(300):
        c = 0.08 + 70 * q + 1e4 * q**2 + se * rng.standard_normal(40) + u[:, 0] * rng.standard_normal()
        law = fit_damping_law(q, c, se, order=2, c_covariance=C)
        zs.append((law.coefficients[0] - 0.08) / law.stderr[0])
    assert 0.85 < np.std(zs) < 1.15  # the diagonal alone would understate c0's error about 2x
    assert law.dof == 37 and 0.0 <= law.p_value <= 1.0
    assert law.summary()["chi2_dof"] is not None and "chi^2/dof" in law.report()


def test_results_json_intervals(tmp_path):
    """Every stderr of results.json has a *_ci95 sibling; records carry the c_stderr of their own fit."""
    cfg = paper_config(n_frequencies=7, fs=2000.0, periods=15, noise=0.01, seed=2, write_frequency=True,
                       n_harmonics=9)
    cfg["excitation"]["force_levels"] = [0.5, 1.0]
    camp = simulate_campaign(load_simulation_config(cfg), tmp_path / "c")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = identify_campaign(camp, n_harmonics=5)
    s = res.summary()
    g = s["groups"][0]
    lo, hi = g["omega1_ci95"]
    assert lo < g["omega1"] < hi and hi - lo == pytest.approx(2 * 1.959964 * g["omega1_stderr"], rel=1e-6)
    assert g["k3_ci95"] is not None and g["pooled"]["shared_ci95"]["k3"] is not None
    r = s["records"][3]
    for key in ("c_stderr", "c_ci95", "c_pooled_ci95", "omega1_ci95", "ci95", "energy_measured"):
        assert r.get(key) is not None, key
    assert r["energy_measured"] == pytest.approx(r["energy_per_cycle"], rel=0.05)
    law = s["damping_law"][0]
    assert len(law["ci95"]) == 3 and law["p_value"] is not None and "two-step" in law["method"]
    pl = s["power_law"][0]
    assert pl["n_ci95"][0] < pl["n"] < pl["n_ci95"][1]
    assert pl["n_model"] is not None and pl["force_range"][0] < pl["force_range"][1]
    assert len(s["models"]) == 1 and s["models"][0]["preload"] == "example"
    text = res.report()
    assert "95 %" in text and "model" in text


@pytest.mark.slow
def test_unknown_gain_pooled_fit_calibrated():
    """The pooled fit with an unknown force gain: z-scores of omega1, k3/m and each record's c/m of unit spread."""
    from jointid.identify.gain import PooledGainForceStateMapping

    model = seed_model(c_law=(0.5, 0.0, 0.0))
    rng = np.random.default_rng(5)
    frf = frequency_response(model, 1.0, np.linspace(160, 180, 9), n_harmonics=9, stability=False)
    z = []
    for _ in range(40):
        sigs = []
        for s in frf.states:
            t, Q, a = synthesize_record(s, 2000.0, 20 * 2 * np.pi / s.omega, t0=rng.uniform(0, 1), noise=0.01, rng=rng)
            sigs.append(steady_state_signals(t, Q / 3.0, a, frequency_hz=s.omega / (2 * np.pi), n_harmonics=5,
                                             refine_frequency=False))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            r = PooledGainForceStateMapping().fit(sigs).result_
        d = r.derived()
        cm, cs = r.per_record("c")
        z.append([(d["omega1"][0] - 170.0) / d["omega1"][1], (d["k3/m"][0] - 5e6) / d["k3/m"][1]]
                 + list((cm - 0.5) / cs))
    z = np.array(z)
    for k, spread in enumerate(list(z[:, :2].std(axis=0)) + [z[:, 2:].std()]):
        assert 0.75 < spread < 1.35, (k, spread)


def _seed_model_errors(tmp_path, n_frequencies):
    cfg = paper_config(n_frequencies=n_frequencies)
    camp = simulate_campaign(load_simulation_config(cfg), tmp_path / "paper")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = identify_campaign(camp, n_harmonics=9, repredict=False)
    m = res.models["example"]
    values = [m.omega1, m.k3, *m.damping_coefficients]
    return [abs(v / EXACT[k] - 1) for v, k in zip(values, ("omega1", "k3", "c0", "c1", "c2"))]


def test_seed_example_noise_free_through_the_preload_model(tmp_path):
    """The paper's noise-free example on 15 frequencies: the preload model within 1e-8 %."""
    assert max(_seed_model_errors(tmp_path, 15)) < 1e-10


@pytest.mark.slow
def test_seed_example_41_frequencies_preload_model_1e_9_percent(tmp_path):
    """The paper's noise-free example as published (41 frequencies): every parameter within 1e-9 %."""
    assert max(_seed_model_errors(tmp_path, 41)) < 1e-11
