"""``jointid predict RESULTS.json`` with the hysteretic joint law that ``identify --terms auto`` selected.

Ground truth: single-mode campaigns ``q'' + c q' + k q + f_joint(q) = Q cos(omega t)`` with a Jenkins or a
discrete Iwan joint (60 sliders), made by the Runge-Kutta time integration of ``test_hysteretic_fsm`` (exact
play operator; no harmonic balance of jointid), 0.5 % noise, written as a campaign folder; ``identify --terms
auto`` on the two lower force levels of the design; ``predict`` at the design's top level and at 1.75 x the top
fitted level.  The peaks are compared with the generating law's own peak by the predictor's estimator on a finer
basis (:func:`truth_peak`: 9 harmonics and 1024 time samples against predict's 5 and 512; converged to ~1e-7 of
the frequency), so that the printed z measures the prediction's error, not the truth's.  That truth is checked
against a dense sweep of dwells of the generating model by the same time integration (no harmonic balance, no
truncation to harmonics): at its 256 steps a period they differ by ~1e-4 in frequency (Jenkins, 14: -9.7e-5;
+1.1e-4 at 512 steps, -1.0e-6 at 1024: the parabola through close dwells of a stepped slider motion), which is
4-12 standard errors of the predicted peak: it was the truth of the z printed before (+12, +11).
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
from test_hysteretic_fsm import (
    IWAN,
    IWAN_LEVELS,
    JENKINS,
    JENKINS_LEVELS,
    C,
    K,
    campaign,
    integrate,
    sliders_of,
)

from jointid.app.predict_hysteretic import HystereticModel, hysteretic_response
from jointid.cli import main
from jointid.identify.hysteretic import first_harmonic_peak
from jointid.joints import Jenkins


def _q_max(q_period, n_harmonics=60):
    """``max_t |q|`` of one period of equispaced samples (its harmonic series to machine precision)."""
    from jointid.signal.harmonics import series_max_abs

    X = np.fft.rfft(q_period)[: n_harmonics + 1] * (2.0 / q_period.size)
    c = np.empty(2 * n_harmonics + 1)
    c[0] = X[0].real / 2
    c[1::2], c[2::2] = X[1:].real, -X[1:].imag
    return series_max_abs(c)


def dense_sweep_peak(law, Q):
    """``(frequency_hz, q_max)`` of the generating model by time integration: 21 dwells over +-1 % of the
    first-harmonic peak, 21 over the two steps about the largest, and the parabola through the three largest."""
    sl = sliders_of(law)

    def dwells(ws):
        steps = 256
        _, q, _, err = integrate(K, C, sl.stiffness, sl.slip_displacement, np.full(ws.size, Q), ws, steps=steps,
                                 record=1, sub=1)
        assert err.max() < 1e-5
        return np.array([_q_max(x[-steps:]) for x in q])

    fp, _ = first_harmonic_peak(K, C, law, Q)
    ws = 2 * np.pi * fp * np.linspace(0.99, 1.01, 21)
    q = dwells(ws)
    i = int(np.argmax(q))
    assert 0 < i < ws.size - 1
    ws = np.linspace(ws[i - 1], ws[i + 1], 21)
    q = dwells(ws)
    j = int(np.argmax(q))
    assert 0 < j < ws.size - 1
    c = np.polyfit(ws[j - 1:j + 2] - ws[j], q[j - 1:j + 2], 2)
    x = -c[1] / (2 * c[0])
    return (ws[j] + x) / (2 * np.pi), float(np.polyval(c, x))


def true_model(law) -> HystereticModel:
    """The generating single-mode model as predict solves it (zero covariance)."""
    if isinstance(law, Jenkins):
        return HystereticModel("jenkins", ("k", "c", "kt", "Fs", "slip_displacement"),
                               np.array([K, C, law.kt, law.Fs, law.slip_displacement]), np.zeros((5, 5)))
    return HystereticModel("iwan4", ("k", "c", "K_T", "F_S", "chi", "beta", "phi_max"),
                           np.array([K, C, law.K_T, law.F_S, law.chi, law.beta, law.phi_max]), np.zeros((7, 7)),
                           law.n_sliders, law.phi_min_ratio)


def truth_peak(law, Q, n_harmonics=9, n_time=1024):
    """``(frequency_hz, q_max)`` of the generating law by predict's own estimator on a finer basis: the band about
    the peak of its curve (continued as predict does, 5 harmonics), its steady states solved again at
    ``n_harmonics`` harmonics and ``n_time`` samples (predict: 5 and 512) and the quartic through them.
    Jenkins, Q = 14: 30.9421893 Hz; 30.9421884 at 13 harmonics and 2048 samples; predict's own estimate on
    the true law 30.9421865; the dense sweep of the generator by time integration at 1024 steps a period
    30.9421579 (-9.7e-5 at 256 steps, +1.1e-4 at 512)."""
    from jointid.app.predict_hysteretic import _band_peak

    tm = true_model(law)
    out = hysteretic_response(tm, Q, (28.0, 34.0), 5, uncertainty=False)
    assert "peak_band" in out, out["notes"]  # the quartic across the band located it, not the fallback
    omegas, sol = out["peak_band"]
    peak = _band_peak(tm.engine(), Q, omegas, sol, n_harmonics, n_time=n_time)
    assert peak is not None
    return peak[:2]


def _write_campaign(folder, data, rng, noise=0.005):
    from jointid.io.campaign import write_campaign, write_csv_record

    t, a, Qs, ws = data
    entries = []
    for i in range(len(Qs)):
        F = Qs[i] * np.cos(ws[i] * t[i])
        F = F + noise * np.std(F) * rng.standard_normal(F.size)
        A = a[i] + noise * np.std(a[i]) * rng.standard_normal(a[i].size)
        rel = f"records/{i:04d}.csv"
        write_csv_record(folder / rel, t[i], {"force": F, "accel": A})
        entries.append({"file": rel, "frequency_hz": float(ws[i] / (2 * np.pi)), "force_level": float(Qs[i]),
                        "preload": "p"})
    write_campaign(folder, "hysteretic predict test", entries, coordinates="modal")
    return folder


CASES = {"jenkins": (JENKINS, JENKINS_LEVELS, 0.06), "iwan4": (IWAN, IWAN_LEVELS, 0.05)}


@pytest.mark.slow
@pytest.mark.parametrize("law_name", list(CASES))
def test_predict_with_the_selected_hysteretic_law(law_name, tmp_path, capsys):
    law, levels, span = CASES[law_name]
    fitted, top = levels[:2], levels[2]
    above = 1.75 * fitted[-1]
    camp = _write_campaign(tmp_path / "campaign", campaign(law, fitted, span), np.random.default_rng(5))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        code = main(["identify", str(camp), "--terms", "auto", "--out", str(tmp_path / "res"), "--no-figures",
                     "--quiet"])
    assert code in (0, 1)  # 1: records flagged by the polynomial plausibility checks, not this test's subject
    sel = json.loads((tmp_path / "res" / "results.json").read_text())["selection"][0]
    assert sel["hysteretic_model"] is not None and sel["hysteretic_model"]["law"] == law_name, sel["selected"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        code = main(["predict", str(tmp_path / "res"), "--force-levels", f"{top},{above}", "--out",
                     str(tmp_path / "pred"), "--quiet"])
    assert code == 0
    d = json.loads((tmp_path / "pred" / "results.json").read_text())
    assert d["models"][0]["joint_law"] == law_name and d["models"][0]["joint_law_model"]["law"] == law_name
    for pred, (tol_f, tol_a) in zip(d["predictions"], ((0.05, 2.0), (0.1, 3.0))):
        assert pred["joint_law"] == law_name and pred["error"] is None and pred["extrapolated"]
        f_true, q_true = truth_peak(law, pred["modal_force"])
        f_sweep, q_sweep = dense_sweep_peak(law, pred["modal_force"])
        ef = 100 * (pred["peak_frequency_hz"] / f_true - 1)
        ea = 100 * (pred["peak_q_max"] / q_true - 1)
        zf = (pred["peak_frequency_hz"] - f_true) / pred["peak_frequency_hz_stderr"]
        za = (pred["peak_q_max"] - q_true) / pred["peak_q_max_stderr"]
        with capsys.disabled():
            print(f"\n{law_name} F = {pred['force_level']:g}: peak {pred['peak_frequency_hz']:.6f} Hz "
                  f"({ef:+.4f} %, z {zf:+.2g}), q_max {pred['peak_q_max']:.6g} ({ea:+.3f} %, z {za:+.2g}); truth "
                  f"{f_true:.7f} Hz, {q_true:.7g}; dense sweep of the generator {100 * (f_sweep / f_true - 1):+.4f} "
                  f"%, {100 * (q_sweep / q_true - 1):+.3f} % from the truth")
        assert abs(ef) < tol_f and abs(ea) < tol_a
        # one noisy campaign: the prediction within 4 of its standard errors of the truth (a calibrated z
        # exceeds 4 once in 16000); against the biased sweep the frequency's z was +12 (Jenkins, 14)
        assert abs(zf) < 4.0 and abs(za) < 4.0, (zf, za)
        # the truth and the generator's time integration agree to the sweep's error (~1e-4 in frequency)
        assert abs(f_sweep / f_true - 1) < 3e-4 and abs(q_sweep / q_true - 1) < 1e-3
        for key in ("peak_frequency_hz", "peak_q_max"):
            se = pred[key + "_stderr"]
            assert se is not None and 0 < se < 0.01 * pred[key]
            lo, hi = pred[key + "_ci95"]
            assert lo < pred[key] < hi
        assert len(pred["curve"]["frequency_hz"]) == len(pred["curve"]["q_max"]) > 20
        tc = pred["time_integration_check"]
        assert tc["error"] is None and abs(tc["relative_difference"]) < 1e-3, tc


def _hysteretic_results(folder, law, cov_scale=1e-4):
    """A results.json as identify writes it with a hysteretic pick: the generating law itself as the selected
    model (no identification), a linear stand-in in ``models``, modal force = force level."""
    if isinstance(law, Jenkins):
        names, values = ["k", "c", "kt", "Fs", "slip_displacement"], [K, C, law.kt, law.Fs, law.slip_displacement]
        name = "jenkins"
    else:
        names = ["k", "c", "K_T", "F_S", "chi", "beta", "phi_max"]
        values, name = [K, C, law.K_T, law.F_S, law.chi, law.beta, law.phi_max], "iwan4"
    se = [cov_scale * abs(v) for v in values]
    hm = {"law": name, "parameters": dict(zip(names, values)), "stderr": dict(zip(names, se)),
          "covariance": np.diag(np.square(se)).tolist(), "joint_law": law.summary()}
    k1 = K + (law.kt if name == "jenkins" else law.K_T)
    d = {"jointid_version": "test", "run_id": "handmade",
         "models": [{"preload": "p", "terms": ["q", "q'"], "amplitude_laws": {}, "parameter_names": ["omega1^2", "c"],
                     "parameters": [k1, C], "stderr": [1.0, 1e-3], "covariance": [[1.0, 0.0], [0.0, 1e-6]],
                     "q_max_range": [5e-4, 2e-3], "frequency_hz_range": [29.0, 33.0]}],
         "groups": [{"preload": "p", "force_level": F, "pooled": {}} for F in (6.0, 10.0)],
         "reprediction": {"groups": [{"preload": "p", "force_level": F, "forcing": F} for F in (6.0, 10.0)]},
         "selection": [{"preload": "p", "selected": name, "stand_in": "linear", "hysteretic_model": hm}]}
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "results.json").write_text(json.dumps(d))
    return folder / "results.json"


def test_handmade_hysteretic_results_predict_with_the_law(tmp_path):
    """The law of a results.json's hysteretic selection is solved, named in results.json, near the dense sweep."""
    from jointid.app.predict import predict_from_results

    file = _hysteretic_results(tmp_path / "res", JENKINS)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = predict_from_results(file, "14", n_harmonics=3, uncertainty=False)
    (pred,) = res.predictions
    assert pred.joint_law == "jenkins" and pred.error is None
    d = pred.summary()
    assert d["joint_law"] == "jenkins" and d["joint_law_model"]["parameters"]["kt"] == JENKINS.kt
    assert res.summary()["models"][0]["joint_law"] == "jenkins"
    f_fh, q_fh = first_harmonic_peak(K, C, JENKINS, 14.0)  # the first harmonic only: close, not equal
    assert abs(pred.peak_frequency_hz / f_fh - 1) < 5e-3 and abs(pred.peak_q_max / q_fh - 1) < 0.05
    assert "jenkins joint law" in pred.report()
    tc = d["time_integration_check"]  # the peak's steady state integrated in time (no harmonics, no AFT)
    assert tc["error"] is None and abs(tc["relative_difference"]) < 1e-3
    assert tc["q_max_harmonic_balance"] == pytest.approx(pred.peak_q_max, rel=1e-4)


def test_bad_hysteretic_model_is_refused_naming_the_file(tmp_path, capsys):
    from jointid.app.predict import predict_from_results
    from jointid.errors import RecordError

    file = _hysteretic_results(tmp_path / "res", JENKINS)
    d = json.loads(file.read_text())
    d["selection"][0]["hysteretic_model"]["law"] = "bouc-wen"
    file.write_text(json.dumps(d))
    with pytest.raises(RecordError, match="results.json.*hysteretic_model.*'bouc-wen'"):
        predict_from_results(file, "14", uncertainty=False)
    code = main(["predict", str(file), "--force-levels", "14", "--out", str(tmp_path / "out"), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and "bouc-wen" in err and "Traceback" not in err


def test_too_few_harmonics_are_caught_by_the_time_integration(tmp_path):
    """One harmonic misses the slipping joint's higher harmonics: the time integration from the peak's steady
    state settles 0.6 % away, and the prediction says to give more harmonics."""
    from jointid.app.predict import predict_from_results

    file = _hysteretic_results(tmp_path / "res", JENKINS)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        (pred,) = predict_from_results(file, "14", n_harmonics=1, uncertainty=False).predictions
    assert abs(pred.time_check["relative_difference"]) > 2e-3
    assert any("give more (--harmonics)" in n for n in pred.notes)
