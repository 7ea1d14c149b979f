"""Backbones through the campaign workflow: identify computes them, results.json keeps them, the CLI draws them."""

import json

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from jointid.app.backbones import backbones_from_results, preload_model_backbone
from jointid.app.workflow import identify_campaign
from jointid.cli import main
from jointid.identify.backbone import model_backbone
from jointid.io.campaign import write_campaign, write_csv_record
from jointid.simulate.hbm import steady_state
from jointid.simulate.model import seed_model
from jointid.simulate.synth import synthesize_record

pytestmark = pytest.mark.filterwarnings("ignore::jointid.errors.JointidWarning")


def _campaign(folder, bad_ringdown=False, label=None, ringdown_time_unit=1.0):
    """Seed model in modal coordinates: stepped sine at two levels and one free decay."""
    m = seed_model()
    rng = np.random.default_rng(0)
    records = []
    for F in (0.5, 2.0):
        for i, w in enumerate(np.linspace(166.0, 171.0, 7)):
            s = steady_state(m, w, F, n_harmonics=9, stability=False)
            t, Q, qdd = synthesize_record(s, fs=2000.0, duration=1.0, noise=0.005, rng=rng)
            rel = f"records/F{F:g}_{i}.csv"
            write_csv_record(folder / rel, t, {"force": Q, "accel": qdd})
            level = F if label is None else label(F)
            records.append({"file": rel, "frequency_hz": w / (2 * np.pi), "force_level": level, "preload": 1})
    def rhs(t, y):
        return [y[1], -0.08 * y[1] - 170.0**2 * y[0] + 5e6 * y[0] ** 3]

    t = np.arange(8000) / 2000.0
    sol = solve_ivp(rhs, (0, t[-1]), [0.01, 0.0], t_eval=t, rtol=1e-11, atol=1e-14, method="DOP853")
    acc = -0.08 * sol.y[1] - 170.0**2 * sol.y[0] + 5e6 * sol.y[0] ** 3
    if bad_ringdown:
        acc[100] = np.nan
    write_csv_record(folder / "ringdown/R.csv", t / ringdown_time_unit, {"force": np.zeros_like(t), "accel": acc})
    records.append({"file": "ringdown/R.csv", "force_level": 2.0 if label is None else label(2.0), "preload": 1,
                    "excitation": "ringdown"})
    write_campaign(folder, "backbone test", records)
    return m


@pytest.fixture(scope="module")
def identified(tmp_path_factory):
    folder = tmp_path_factory.mktemp("camp")
    m = _campaign(folder)
    return m, identify_campaign(folder, repredict=False)


def test_identify_computes_backbones(identified):
    m, res = identified
    bb = res.backbones
    assert bb is not None and bb.error is None
    # the ring-down record is identified with the backbones, not counted as a failed stepped-sine record
    assert not res.failed and all(r.spec.excitation == "stepped-sine" for r in res.records)
    p = bb[1]
    assert p.model is not None and len(p.ringdown) == 1 and p.stepped is not None
    # the stepped-sine points lie on the generating model's backbone
    ex = model_backbone(m.terms, m.coefficients, p.stepped.amplitude, amplitude_laws=m.amplitude_laws, n_harmonics=5)
    assert np.max(np.abs(p.stepped.omega / ex.omega - 1)) < 2e-4
    # the ring-down of q'' + 0.08 q' + 170^2 q - 5e6 q^3 = 0 follows its own backbone
    rd = p.ringdown[0]
    ref = model_backbone("q + -q^3 + q'", [170.0**2, 5e6, 0.08], rd.amplitude, n_harmonics=5)
    assert np.max(np.abs(rd.omega / ref.omega - 1)) < 1e-4
    assert np.max(np.abs(rd.zeta / ref.zeta - 1)) < 0.02
    # the identified model's backbone, with bands, over the measured range
    assert np.all(p.model.omega_stderr > 0)
    s = res.summary()
    json.dumps(s)
    assert s["backbones"]["preloads"][0]["ringdown"][0]["n_points"] == len(rd)
    again = preload_model_backbone(s["models"][0], amplitudes=p.model.amplitude)
    np.testing.assert_allclose(again.omega, p.model.omega, rtol=1e-12)
    np.testing.assert_allclose(again.omega_stderr, p.model.omega_stderr, rtol=1e-6)


def test_bad_ringdown_record_does_not_lose_the_backbones(tmp_path):
    _campaign(tmp_path, bad_ringdown=True)
    res = identify_campaign(tmp_path, repredict=False)
    p = res.backbones[1]
    assert p.stepped is not None and not p.ringdown
    (key, msg), = p.errors.items()
    assert "ringdown/R.csv" in msg and "accel" in msg


def test_a_ringdown_far_from_the_identified_mode_is_left_out_and_said(tmp_path):
    """A ring-down whose time column is in ms rings at 1/1000 of the mode the stepped sines identify: it is
    not a backbone of that mode (it was drawn at 0.027 Hz beside a 27 Hz model, exit 0)."""
    _campaign(tmp_path, ringdown_time_unit=1e-3)
    res = identify_campaign(tmp_path, repredict=False)
    p = res.backbones[1]
    assert p.stepped is not None and not p.ringdown
    (key, msg), = p.errors.items()
    assert key.startswith("record ") and "ringdown/R.csv" in msg and "0.000995 times" in msg and "in ms" in msg, msg


def test_force_levels_given_as_text_labels_keep_the_backbones(tmp_path):
    """A manifest may name its levels in text ("0.5 N"): the backbones group by the label, not by a number."""
    _campaign(tmp_path, label=lambda F: f"{F:g} N")
    bb = identify_campaign(tmp_path, repredict=False).backbones
    assert bb.error is None, bb.error
    levels = bb[1].phase_resonance.meta["force_level"]
    assert levels and set(levels) <= {"0.5 N", "2 N"}


def test_cli_backbone_draws_a_saved_result(identified, tmp_path):
    _, res = identified
    (tmp_path / "res").mkdir()
    (tmp_path / "res" / "results.json").write_text(json.dumps(res.summary()))
    assert main(["backbone", str(tmp_path / "res" / "results.json"), "--out", str(tmp_path / "fig"), "--quiet"]) == 0
    assert (tmp_path / "fig" / "backbone_1.png").stat().st_size > 1000
    cb = backbones_from_results(tmp_path / "res" / "results.json")
    assert cb[1].stepped is not None and len(cb[1].ringdown) == 1
    assert main(["backbone", str(tmp_path / "missing.json"), "--out", str(tmp_path / "fig2")]) == 2
