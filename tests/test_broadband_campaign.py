"""Broadband records (multisine, random) in a campaign: broadband force-state mapping through identify."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from jointid.app.workflow import identify_campaign
from jointid.cli import main
from jointid.identify.broadband import simulate_response
from jointid.identify.terms import library
from jointid.io.campaign import write_campaign, write_csv_record

ROOT = Path(__file__).resolve().parents[1]
SILVERBOX = ROOT.parent / "shared" / "data" / "silverbox" / "SNLS80mV.mat"
TERMS = "q + -q^3 + q'"
W1, K3, C, GAIN = 2 * np.pi * 20.0, 4e5, 2 * 0.02 * 2 * np.pi * 20.0, 0.5  # m = 1 / GAIN
FS, N, AMP = 256.0, 2048, 150.0  # lines to 30 Hz; k3 q^2 about 1.5 % of omega1^2


def _multisine(rng, n_lines=240):
    k = np.arange(1, n_lines + 1)
    X = np.zeros(N // 2 + 1, complex)
    X[k] = np.exp(2j * np.pi * rng.random(k.size))
    u = np.fft.irfft(X, N)
    return AMP * u / np.std(u)


def _simulate(u):
    """``m q'' + c q' + w1^2 q - k3 q^3 = u`` with the voltage-like input ``u`` (gain 0.5)."""
    theta = np.array([W1**2 / GAIN, K3 / GAIN, C / GAIN])
    q, _ = simulate_response(library(TERMS), theta, 1.0 / GAIN, u, FS)
    return q


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    folder = tmp_path_factory.mktemp("bb") / "camp"
    rng = np.random.default_rng(7)
    entries = []
    for i in range(3):
        u = np.tile(_multisine(rng), 3)  # three periods: the first is the transient
        q = _simulate(u)
        t = np.arange(u.size) / FS
        write_csv_record(folder / f"ms_{i}.csv", t, {"force": u, "displacement": q + 1e-4 * np.std(q) *
                                                      rng.standard_normal(q.size)})
        entries.append({"file": f"ms_{i}.csv", "preload": 1, "force_level": "2V", "excitation": "multisine",
                        "period_s": N / FS})
    # a held-out random test: low-passed noise, not a multisine
    e = rng.standard_normal(8 * N)
    E = np.fft.rfft(e)
    E[np.fft.rfftfreq(e.size, 1 / FS) > 30.0] = 0.0
    u = np.fft.irfft(E, e.size)
    u = AMP * u / np.std(u)
    q = _simulate(u)
    write_csv_record(folder / "random.csv", np.arange(u.size) / FS, {"force": u, "displacement": q})
    entries.append({"file": "random.csv", "preload": 1, "force_level": "2V", "excitation": "random"})
    write_campaign(folder, "broadband", entries)
    return folder


def test_broadband_records_recover_the_model_and_predict_the_held_out_record(campaign):
    res = identify_campaign(campaign, terms=TERMS, force_gain="unknown")
    assert res.records == () and res.groups == ()  # no stepped-sine record
    (g,) = res.broadband
    assert g.estimation == ("ms_0.csv", "ms_1.csv", "ms_2.csv") and g.error is None
    d = g.fit.derived()
    assert d["f1_hz"][0] == pytest.approx(20.0, rel=1e-3)
    assert d["zeta"][0] == pytest.approx(0.02, rel=2e-2)
    assert d["k3/m"][0] == pytest.approx(K3, rel=2e-2)
    assert d["gain"][0] == pytest.approx(GAIN, rel=1e-3)
    (h,) = g.held_out
    assert h["file"] == "random.csv" and h["relative_error"] < 0.01
    s = res.summary()["broadband"][0]
    assert s["held_out"][0]["rms_error"] == h["rms_error"] and s["f1_hz"] == pytest.approx(20.0, rel=1e-3)
    assert "held out random.csv" in g.report()


def test_a_bad_broadband_record_does_not_lose_the_group(campaign, tmp_path):
    import shutil

    folder = tmp_path / "c"
    shutil.copytree(campaign, folder)
    (folder / "ms_1.csv").write_text("time,force,displacement\n0,1,2\n")
    res = identify_campaign(folder, terms=TERMS, force_gain="unknown")
    (g,) = res.broadband
    assert g.fit is not None and len(g.failed) == 1 and "ms_1.csv" in g.failed[0]
    assert g.held_out and g.held_out[0]["relative_error"] < 0.01


@pytest.mark.skipif(not SILVERBOX.is_file(), reason="Silverbox SNLS80mV.mat not found in ../shared/data")
def test_silverbox_multisines_as_a_campaign_reproduce_the_arrow_error(tmp_path):
    """The ten SNLS80mV multisine realisations are the estimation records, the arrow (samples
    86-40086, after its leading zeros) the held-out random record: 0.40 mV, as the benchmark."""
    from jointid.io.datasets import load_silverbox_snls80mv
    from jointid.signal.broadband import find_periodic_segments

    rec = load_silverbox_snls80mv()
    u, y, fs = rec["u"], rec["y"], rec.fs
    n = int(rec.meta["samples_per_period"])
    t = np.arange(u.size) / fs
    entries = []
    for i, s in enumerate(find_periodic_segments(u, n)):
        write_csv_record(tmp_path / "c" / f"ms_{i}.csv", t[s] - t[s.start], {"force": u[s], "displacement": y[s]})
        entries.append({"file": f"ms_{i}.csv", "preload": "silverbox", "force_level": "SNLS80mV",
                        "excitation": "multisine", "period_s": n / fs})
    a = slice(86, 40086)
    write_csv_record(tmp_path / "c" / "arrow.csv", t[a], {"force": u[a], "displacement": y[a]})
    entries.append({"file": "arrow.csv", "preload": "silverbox", "force_level": "SNLS80mV", "excitation": "random"})
    write_campaign(tmp_path / "c", "silverbox", entries)
    assert main(["identify", str(tmp_path / "c"), "--out", str(tmp_path / "o"), "--terms", "q + -q^3 + q^2 + q'",
                 "--force-gain", "unknown", "--quiet", "--no-figures"]) == 0
    (g,) = json.loads((tmp_path / "o" / "results.json").read_text())["broadband"]
    (h,) = g["held_out"]
    assert len(g["estimation"]) == 10 and h["file"] == "arrow.csv"
    assert 1e3 * h["rms_error"] == pytest.approx(0.40, abs=0.01)
    assert g["f1_hz"] == pytest.approx(68.58, rel=0.01)  # the data set's reference f_n
