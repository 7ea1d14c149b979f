"""Re-prediction of measured nonlinear FRFs by harmonic balance (seed Fig 10) and loop errors."""

from __future__ import annotations

import json

import numpy as np
import pytest

from jointid.app.paper_example import paper_config
from jointid.app.reprediction import identified_model, repredict_group
from jointid.app.synthesis import load_simulation_config, simulate_campaign
from jointid.app.workflow import identify_campaign
from jointid.cli import main
from jointid.simulate.hbm import frequency_response
from jointid.simulate.model import SingleModeModel


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    """The seed's numerical example (Eq 19-20), 1 % noise, 15 dwells across mode 1."""
    cfg = paper_config(n_frequencies=15, noise=0.01, seed=5, write_frequency=False, periods=10)
    return simulate_campaign(load_simulation_config(cfg), tmp_path_factory.mktemp("rep") / "c")


def test_identify_writes_reprediction_and_loops(campaign, tmp_path):
    out = tmp_path / "o"
    assert main(["identify", str(campaign), "--out", str(out), "--quiet"]) == 0
    rep = json.loads((out / "results.json").read_text())["reprediction"]
    (g,) = rep["groups"]
    # the model solved at each dwell's own frequency and forcing reproduces the dwell (1 % noise)
    assert g["point_rms_error_percent"] < 0.5
    assert len(g["point_errors"]) == 15 and len(g["measured"]) == 15
    # 15 dwells over 3 Hz do not resolve a 0.16 Hz peak: said, not hidden
    assert g["peak_resolved"] is False and g["dwell_spacing_hz"] > 0.5 * g["bandwidth_hz"]
    (loop,) = rep["loops"]
    assert loop["filtered"]["rms_difference"] < 0.15
    assert (out / "figures" / "reprediction_example.png").is_file()
    assert "Re-predicted FRFs" in (out / "report.txt").read_text()


def test_reprediction_peak_against_the_true_model(campaign):
    """The re-predicted peak equals the true model's harmonic-balance peak (identification error only)."""
    from jointid.app.paper_example import PAPER

    with pytest.warns(Warning):  # per-record k3 of off-resonance dwells is not resolved (pooled k3 is)
        res = identify_campaign(campaign, repredict=False)
    assert res.repredictions == ()
    g = res.groups[0]
    r = repredict_group(res, g, n_points=81)
    e = PAPER["exact"]
    model = SingleModeModel("q + -q^3 + q'", (e["omega1"] ** 2, e["k3"], 0.0), {"q'": (e["c0"], e["c1"], e["c2"])})
    assert identified_model(res, g).omega1 == pytest.approx(e["omega1"], rel=1e-3)
    true = frequency_response(model, r.forcing, 2 * np.pi * np.linspace(26.8, 27.2, 801), n_harmonics=5,
                              stability=False)
    mag = true.omega**2 * true.amplitude / r.forcing
    k = int(np.argmax(mag))
    assert r.peak_predicted[0] == pytest.approx(true.omega[k] / (2 * np.pi), rel=5e-4)
    assert r.peak_predicted[1] == pytest.approx(mag[k], rel=0.03)
    assert "measured points rms" in r.report() and r.summary()["reference"] == "measured dwells"


def test_refined_peak_of_a_linear_resonance():
    """Closed form: the acceleration FRF of a linear mode peaks at omega1 / sqrt(1 - 2 zeta^2)."""
    from jointid.rig.rig import parabolic_peak, refine_peak

    w1, zeta = 2 * np.pi * 26.4, 0.002

    def mag(f):
        w = 2 * np.pi * np.asarray(f)
        return np.abs(w**2 / (w1**2 - w**2 + 2j * zeta * w1 * w))

    exact = w1 / np.sqrt(1 - 2 * zeta**2) / (2 * np.pi)
    f0 = np.linspace(26.213, 26.613, 11)  # 40 mHz apart, off the peak: the 0.1 Hz wide peak is barely sampled
    coarse, coarse_top = parabolic_peak(f0, mag(f0))
    f, m = refine_peak(mag, f0, mag(f0), 5e-5 * exact)
    fine, top = parabolic_peak(f, m)
    assert abs(coarse / exact - 1) > 5e-5 and abs(coarse_top / mag(exact) - 1) > 0.01  # the coarse parabola
    assert abs(fine / exact - 1) < 1e-7 and top == pytest.approx(float(mag(exact)), rel=1e-6)
    assert np.all(np.diff(f) > 0) and f.size < f0.size + 40  # bracketed halving: a few points only
    # a largest sample at the end of the samples brackets no peak: nothing is added
    f_end, _ = refine_peak(mag, f0[:4], mag(f0[:4]), 1e-6)
    assert f_end.size == 4


@pytest.fixture(scope="module")
def demo(demo_run):
    """The demo at 120 and 540 N (seed 0): the paper's tables with the seed cubic,
    the FRFs re-predicted with the model the data select for each preload."""
    return demo_run


@pytest.mark.slow
def test_demo_repredictions_within_limits(demo):
    """Issue target: every level's re-predicted peak against the rig's exact FRF within 0.3 %
    (amplitude) and 0.02 % (frequency).

    Measured with seed 0: the micro-slip + cubic model selected at both preloads, fitted over
    the preload's three levels, gives at most 0.0038 % (frequency) and 0.12 % (amplitude).
    """
    reps = [r for pr in demo.preloads for r in pr.repredictions]
    assert len(reps) == 6
    for pr in demo.preloads:
        assert pr.result.selections[pr.preload].selected != "cubic"
        for r in pr.repredictions:
            assert r.reference_kind == "exact" and "omega1^2" in r.model.amplitude_laws  # a stiffness law
            assert abs(r.peak_frequency_error_percent) < 0.02, r.report()
            assert abs(r.peak_amplitude_error_percent) < 0.3, r.report()
    # identify's own re-predictions (against the dwells) are in every preload's result
    assert all(pr.result.repredictions for pr in demo.preloads)


@pytest.mark.slow
def test_demo_seed_cubic_repredictions(demo):
    """The seed cubic (no selection) re-predicts every level's peak within 0.3 % (amplitude) and
    0.025 % (frequency).

    Measured with seed 0 (seeds 1 and 2 alike): amplitude within 0.15 %, frequency within
    0.0222 % (120 N, 6 N), the model's own error: at that level the group's cubic puts the
    first-harmonic stiffness of its largest dwell (q_max 5.0 mm) 0.046 % above the dwell's
    own, because the Iwan joint's stiffness falls about linearly with amplitude, not with its
    square (the adequacy check rejects the cubic at both preloads, and the selection prefers
    the micro-slip law, which meets 0.02 %: previous test).
    """
    from dataclasses import replace

    from jointid.app.demo import _reprediction

    for pr in demo.preloads:
        cubic = replace(pr.result, selections={})
        for level in demo.settings.plan.force_levels:
            r = _reprediction(pr.campaign, cubic, pr.structure, level, demo.settings.reprediction_points)
            assert r.reference_kind == "exact" and set(r.model.amplitude_laws) == {"c"}  # c(q_max) only
            assert abs(r.peak_frequency_error_percent) < 0.025, r.report()
            assert abs(r.peak_amplitude_error_percent) < 0.3, r.report()
