"""``jointid predict``: the identified model's response at new force levels.

Ground truth: a campaign of a known softening cubic + viscous single-mode model, simulated at
two force levels (0.5 % noise), identified; the model is predicted at the held-out top level
of the campaign design and at 1.75 times the top fitted level, and the located peaks are
compared with the true model's peak from a dense downward frequency sweep (the response
followed down the upper branch, the largest computed point taken: no continuation and no
peak interpolation involved).
"""

from __future__ import annotations

import json
import math
import re
import warnings

import numpy as np
import pytest

from jointid.cli import main

OMEGA1, K3, C = 170.0, 5e6, 0.5
FITTED = (1.0, 2.0)
TOP = 3.0  # the design's top level, left out of the fit
ABOVE = 1.75 * FITTED[-1]


def _config(levels):
    return {
        "campaign": {"name": "cubic + viscous, predict test"},
        "model": [{"preload": "p1", "terms": "q + -q^3 + q'", "omega1": OMEGA1,
                   "coefficients": {"k3": K3, "c": C}}],
        "excitation": {"force_levels": list(levels), "omega_start": 178.0, "omega_stop": 155.0,
                       "n_frequencies": 24},
        "acquisition": {"fs": 2000.0, "periods": 30.0, "noise": 0.005, "seed": 11, "n_harmonics": 7},
    }


@pytest.fixture(scope="module")
def identified(tmp_path_factory):
    from jointid.app.synthesis import simulate_campaign
    from jointid.app.workflow import identify_campaign
    from jointid.report.output import write_results

    root = tmp_path_factory.mktemp("predict")
    camp = simulate_campaign(_config(FITTED), root / "campaign")
    with warnings.catch_warnings():  # the per-record k3 of the lowest level is not resolved: expected
        warnings.simplefilter("ignore")
        res = identify_campaign(camp, damping_order=0)
    write_results(res, root / "results", figures=False, html=False)
    return root / "results"


def _handmade(folder, scale=0.8):
    """A results.json as identify writes it, of the true model itself (no identification): two fitted
    levels whose modal forcing is ``scale`` times the force level."""
    folder.mkdir(parents=True, exist_ok=True)
    theta = [OMEGA1**2, K3, C]
    se = [0.05, 2e3, 3e-4]
    d = {
        "jointid_version": "test", "run_id": "handmade",
        "models": [{"preload": "p1", "terms": ["q", "-q^3", "q'"], "amplitude_laws": {},
                    "parameter_names": ["omega1^2", "k3", "c"], "parameters": theta, "stderr": se,
                    "covariance": np.diag(np.square(se)).tolist(), "q_max_range": [2e-4, 0.02],
                    "frequency_hz_range": [24.7, 28.3], "f1_hz": OMEGA1 / (2 * np.pi)}],
        "groups": [{"preload": "p1", "force_level": F, "pooled": {}} for F in FITTED],
        "reprediction": {"groups": [{"preload": "p1", "force_level": F, "forcing": scale * F,
                                     "quantity": "modal acceleration / modal force",
                                     "measured_frequency_hz": [26.0, 27.0], "measured": [100.0, 300.0]}
                                    for F in FITTED]},
    }
    (folder / "results.json").write_text(json.dumps(d))
    return folder


def test_the_demo_results_give_one_prediction_per_preload(tmp_path, capsys):
    """The demo's results.json (one identification per preload under ``preloads``): each preload's
    model, its own force scaling, one figure per preload."""
    parts = []
    for preload, scale in ((120, 0.1), (540, 0.2)):
        d = json.loads((_handmade(tmp_path / str(preload), scale) / "results.json").read_text())
        for e in d["models"] + d["groups"] + d["reprediction"]["groups"]:
            e["preload"] = preload
        parts.append({"preload": preload, "identification": d})
    demo = tmp_path / "demo-out"
    demo.mkdir()
    (demo / "results.json").write_text(json.dumps({"run_id": "x", "preloads": parts}))
    rc = main(["predict", str(demo), "--force-levels", "10", "--out", str(tmp_path / "o"), "--no-uncertainty",
               "--quiet"])
    assert rc == 0
    d = json.loads((tmp_path / "o" / "results.json").read_text())
    assert [(e["preload"], e["modal_force"]) for e in d["predictions"]] == [(120, pytest.approx(1.0)),
                                                                            (540, pytest.approx(2.0))]
    assert sorted(p.name for p in (tmp_path / "o" / "figures").iterdir()) == ["predict_120.png", "predict_540.png"]
    assert "EXTRAPOLATED" in capsys.readouterr().err


@pytest.fixture
def handmade(tmp_path):
    return _handmade(tmp_path / "results")


def _true_peak(Q, lo_hz):
    """The true model's peak by a dense sweep down from above the linear resonance, where the
    response is single-valued: it follows the upper branch of the softening resonance to its top."""
    from jointid.simulate.hbm import frequency_response
    from jointid.simulate.model import SingleModeModel

    model = SingleModeModel("q + -q^3 + q'", (OMEGA1**2, K3, C))
    w = 2 * np.pi * np.linspace(1.06 * OMEGA1 / (2 * np.pi), lo_hz, 2000)
    r = frequency_response(model, Q, w, n_harmonics=7, stability=False)
    k = int(np.argmax(r.q_max))
    fine = np.linspace(w[max(k - 3, 0)], w[min(k + 3, w.size - 1)], 1201)  # still downward
    fine = np.concatenate([w[:max(k - 3, 0)], fine])
    rf = frequency_response(model, Q, fine, n_harmonics=7, stability=False)
    j = int(np.argmax(rf.q_max))
    return float(fine[j] / (2 * np.pi)), float(rf.q_max[j])


@pytest.mark.slow
def test_peaks_at_held_out_and_higher_level_match_the_true_model(identified, tmp_path):
    from jointid.app.predict import predict_from_results, write_predictions

    res = predict_from_results(identified, [TOP, ABOVE])
    by_level = {p.force_level: p for p in res.predictions}
    for F, f_tol, q_tol in ((TOP, 5e-4, 0.02), (ABOVE, 1e-3, 0.03)):
        p = by_level[F]
        assert p.error is None and p.has_peak, p.report()
        assert p.extrapolated  # both lie above the fitted levels 1-2
        f_true, q_true = _true_peak(F, p.peak_frequency_hz - 1.0)
        assert abs(p.peak_frequency_hz / f_true - 1) < f_tol, (F, p.peak_frequency_hz, f_true)
        assert abs(p.peak_q_max / q_true - 1) < q_tol, (F, p.peak_q_max, q_true)
        # the model's own uncertainty covers the truth (generously: 4.5 se)
        assert 0 < p.peak_frequency_hz_stderr and abs(p.peak_frequency_hz - f_true) < 4.5 * p.peak_frequency_hz_stderr
        assert 0 < p.peak_q_max_stderr and abs(p.peak_q_max - q_true) < 4.5 * p.peak_q_max_stderr
        # the peak is located between the computed points, on the stable upper branch
        f, q = np.asarray(p.frequency_hz), np.asarray(p.q_max)
        assert p.peak_q_max >= q.max()
        assert not np.any(np.isclose(f, p.peak_frequency_hz, rtol=0, atol=1e-12))
        assert p.stable[int(np.argmax(q))]
        assert len(p.folds_hz) == 2 and p.peak_frequency_hz < max(p.folds_hz)
        assert abs(p.time_check["relative_difference"]) < 1e-4  # a time integration agrees at the peak
    paths = write_predictions(res, tmp_path / "out")
    d = json.loads(paths["results"].read_text())
    assert d["kind"] == "predict" and len(d["predictions"]) == 2
    e = d["predictions"][0]
    for key in ("preload", "force_level", "peak_frequency_hz", "peak_q_max", "peak_frequency_hz_stderr",
                "peak_q_max_ci95", "extrapolated", "curve"):
        assert key in e
    assert set(e["curve"]) == {"frequency_hz", "q_max", "stable"}
    assert e["extrapolated"] is True and "EXTRAPOLATED" in paths["report"].read_text()
    assert "extrapolated" in paths["html"].read_text().lower()
    assert [p.name for p in paths["figures"]] == ["predict_p1.png"]


def test_modal_force_scaling_of_the_reprediction_and_the_located_peak(handmade):
    """The force level is scaled to the modal force as identify's re-prediction did (0.8 here), a
    fitted level is not flagged, and the located peak is the true model's (it is the true model)."""
    from jointid.app.predict import predict_from_results

    res = predict_from_results(handmade, "2", uncertainty=False)
    (p,) = res.predictions
    s = res.scaling["p1"]
    assert s["n_levels"] == 2 and s["modal_force_per_unit"] == pytest.approx(0.8, rel=1e-12)
    assert p.modal_force == pytest.approx(1.6, rel=1e-12)
    assert not p.extrapolated and p.has_peak and not p.amplitude_beyond_fitted
    assert math.isnan(p.peak_q_max_stderr)
    # the measured dwells of this fitted level, as fundamental displacement amplitudes
    _, A = p.measured
    assert A == pytest.approx(np.array([100.0, 300.0]) * 1.6 / (2 * np.pi * np.array([26.0, 27.0])) ** 2, rel=1e-12)
    assert p.summary()["measured_dwells"]["frequency_hz"] == [26.0, 27.0]
    chk = p.time_check  # the peak point solved again by shooting on a time integration
    assert chk["error"] is None and abs(chk["relative_difference"]) < 1e-5
    f_true, q_true = _true_peak(1.6, p.peak_frequency_hz - 0.5)
    assert p.peak_frequency_hz == pytest.approx(f_true, rel=2e-6)
    assert p.peak_q_max == pytest.approx(q_true, rel=2e-6)


def test_cli_writes_the_set_and_says_extrapolated(handmade, tmp_path, capsys):
    out = tmp_path / "pred"
    rc = main(["predict", str(handmade), "--force-levels", "1.5,3", "--out", str(out)])
    text = capsys.readouterr().out
    assert rc == 0
    assert "EXTRAPOLATED" in text and "F = 1.5" in text and "95 %" in text
    d = json.loads((out / "results.json").read_text())
    assert [e["extrapolated"] for e in d["predictions"]] == [False, True]
    assert [e["measured_dwells"] is None for e in d["predictions"]] == [True, True]  # neither level was measured
    assert all(e["peak_frequency_hz_ci95"] and e["peak_q_max_stderr"] > 0 for e in d["predictions"])
    assert (out / "report.html").is_file() and "EXTRAPOLATED" in (out / "report.txt").read_text()
    assert (out / "figures" / "predict_p1.png").is_file()
    # each warning of a prediction is its own paragraph of the HTML report, after the prediction's line
    paras = [re.sub(r"\s+", " ", x) for x in re.findall(r"<p>(.*?)</p>", (out / "report.html").read_text(), re.S)]
    warned = [x for x in paras if "warning:" in x]
    assert warned and all(x.startswith("warning:") for x in warned), warned
    # the same command again replaces its own set
    assert main(["predict", str(handmade / "results.json"), "--force-levels", "1.5", "--out", str(out),
                 "--no-uncertainty", "--quiet"]) == 0
    assert len(json.loads((out / "results.json").read_text())["predictions"]) == 1


def test_a_fixed_band_without_the_peak_is_said_and_exits_1(handmade, tmp_path, capsys):
    rc = main(["predict", str(handmade), "--force-levels", "2", "--out", str(tmp_path / "o"),
               "--frequency-range", "27.5", "28.5", "--no-uncertainty"])
    out = capsys.readouterr().out
    assert rc == 1 and "no peak in 27.5-28.5 Hz" in out


@pytest.mark.parametrize("levels", ["-1", "0", "nan", "", "1,,2", "inf", "abc"])
def test_bad_force_levels_exit_2_with_one_line(handmade, tmp_path, capsys, levels):
    rc = main(["predict", str(handmade), "--force-levels", levels, "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1, err
    assert "results.json" in err[0] and "--force-levels" in err[0]
    assert not (tmp_path / "o").exists()


def _bad(tmp_path, text):
    f = tmp_path / "results.json"
    f.write_text(text)
    return f


@pytest.mark.parametrize("text", [
    "not json at all",
    "[1, 2]",
    json.dumps({"campaign": "x"}),
    json.dumps({"models": []}),
    json.dumps({"models": [{"preload": "a", "omega1": None, "parameters": None, "error": "no records"}]}),
    json.dumps({"models": [{"preload": "a", "terms": ["q", "q'"], "amplitude_laws": {}, "parameters": [1.0]}]}),
    json.dumps({"models": [{"preload": "a", "terms": ["q'"], "amplitude_laws": {}, "parameters": [1.0]}]}),
])
def test_bad_results_files_exit_2_naming_the_file(tmp_path, capsys, text):
    f = _bad(tmp_path, text)
    rc = main(["predict", str(f), "--force-levels", "1", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1, err
    assert str(f) in err[0]
    assert not (tmp_path / "o").exists()


def test_missing_results_exit_2(tmp_path, capsys):
    rc = main(["predict", str(tmp_path / "nothing"), "--force-levels", "1", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "nothing" in err[0]


def test_output_folder_is_never_the_results_folder(handmade, capsys):
    rc = main(["predict", str(handmade), "--force-levels", "1", "--out", str(handmade)])
    assert rc == 2
    assert (handmade / "results.json").is_file()


@pytest.mark.slow
def test_peak_standard_errors_are_calibrated_by_monte_carlo(tmp_path):
    """Over campaigns with independent noise, (predicted - true) / se of the held-out top level's
    peak frequency and amplitude has a spread near 1 (a standard error that means what it says)."""
    from jointid.app.predict import predict_from_results
    from jointid.app.synthesis import simulate_campaign
    from jointid.app.workflow import identify_campaign

    f_true = q_true = None
    z = []
    for seed in range(12):
        cfg = _config(FITTED)
        cfg["excitation"]["n_frequencies"] = 16
        cfg["acquisition"].update(seed=100 + seed, periods=20.0)
        camp = simulate_campaign(cfg, tmp_path / f"c{seed}")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = identify_campaign(camp, damping_order=0, repredict=False)
        summary = res.summary()
        summary["reprediction"] = {"groups": [{"preload": "p1", "force_level": F, "forcing": F} for F in FITTED]}
        (p,) = predict_from_results(summary, [TOP]).predictions
        if f_true is None:
            f_true, q_true = _true_peak(TOP, p.peak_frequency_hz - 1.0)
        z.append(((p.peak_frequency_hz - f_true) / p.peak_frequency_hz_stderr,
                  (p.peak_q_max - q_true) / p.peak_q_max_stderr))
    z = np.asarray(z)
    sd = np.sqrt(np.mean(z**2, axis=0))  # about the truth: bias and spread together
    assert np.all(np.abs(z) < 4.5), z
    assert np.all((0.5 < sd) & (sd < 1.7)), (sd, z)


@pytest.mark.parametrize("k3, c", [(-5e6, 0.5), (5e6, 2.0)])
def test_located_peak_of_a_hardening_and_a_mildly_softening_resonance(k3, c):
    """The peak located between the continued points against a dense sequential sweep taken the
    way the upper branch is reached (up in frequency when hardening, down when softening)."""
    from jointid.app.predict import predict_peak
    from jointid.simulate.hbm import frequency_response
    from jointid.simulate.model import SingleModeModel

    model = SingleModeModel("q + -q^3 + q'", (OMEGA1**2, k3, c))
    r, peak, span = predict_peak(model, 1.0, (25.5, 28.5))
    f_peak, q_peak, i = peak
    assert span == (25.5, 28.5) and 0 < i < len(r) - 1
    lo, hi = (f_peak - 0.3, f_peak + 0.05) if k3 < 0 else (f_peak + 0.3, f_peak - 0.05)
    w = 2 * np.pi * np.linspace(lo, hi, 3001)
    sweep = frequency_response(model, 1.0, w, n_harmonics=5, stability=False)
    k = int(np.argmax(sweep.q_max))
    assert 0 < k < w.size - 1
    assert f_peak == pytest.approx(w[k] / (2 * np.pi), abs=2e-4)  # the sweep's spacing, 1.2e-4 Hz
    assert q_peak == pytest.approx(sweep.q_max[k], rel=2e-6)
    assert q_peak >= np.max(r.q_max)


def test_label_force_levels_give_no_scaling_and_an_unknown_extrapolation(handmade):
    from jointid.app.predict import predict_from_results

    d = json.loads((handmade / "results.json").read_text())
    for e in d["groups"] + d["reprediction"]["groups"]:
        e["force_level"] = "low" if e["force_level"] == 1.0 else "high"
    (p,) = predict_from_results(d, [1.0], uncertainty=False).predictions
    assert p.modal_force == 1.0 and not p.extrapolated and p.has_peak
    assert any("not known" in n for n in p.notes)


def test_a_damping_law_that_feeds_energy_in_at_the_peak_is_named():
    """An amplitude law of the q'^3 damping, extrapolated to the predicted peak, turns negative
    there: the prediction says so (the viscous term keeps the total dissipation positive)."""
    from jointid.app.predict import predict_level

    entry = {"preload": "p", "terms": ["q", "-q^3", "q'", "q'^3"], "amplitude_laws": {"q'^3": 1},
             "parameter_names": ["omega1^2", "k3", "c", "c_cubic0", "c_cubic1"],
             "parameters": [OMEGA1**2, K3, C, 0.05, -30.0], "q_max_range": [1e-4, 0.004],
             "frequency_hz_range": [25.5, 28.5]}
    p = predict_level(entry, 1.0, fitted_levels=(0.5,), uncertainty=False)
    assert p.has_peak and p.extrapolated and p.amplitude_beyond_fitted
    assert 0.05 - 30.0 * p.peak_q_max < 0
    (note,) = [n for n in p.notes if "not physical" in n]
    assert "feeds in" in note
    entry["parameters"][-1] = -1.0  # positive at the peak: no such note
    p = predict_level(entry, 1.0, fitted_levels=(0.5,), uncertainty=False)
    assert not any("not physical" in n for n in p.notes)


def test_too_few_harmonics_are_caught_by_the_time_integration_check(handmade):
    from jointid.app.predict import load_results, predict_level

    entry = load_results(handmade)[0]["models"][0]
    p = predict_level(entry, 3.0, n_harmonics=1, uncertainty=False)
    # one harmonic puts the peak past the true fold: shooting finds no orbit there (or another q_max)
    chk = p.time_check
    assert chk["error"] is not None or abs(chk["relative_difference"]) > 1e-3
    assert any("--harmonics" in n for n in p.notes)
    p = predict_level(entry, 3.0, n_harmonics=5, uncertainty=False)
    assert abs(p.time_check["relative_difference"]) < 1e-5 and not any("--harmonics" in n for n in p.notes)
