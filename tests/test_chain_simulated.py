"""Ground truth: the whole chain recovers known parameters from simulated campaigns."""

import json
import warnings

import numpy as np
import pytest

from jointid.cli import main
from jointid.app.paper_example import PAPER, paper_config, run_paper_example
from jointid.app.synthesis import load_simulation_config, simulate_campaign
from jointid.app.workflow import identify_campaign

EXACT = PAPER["exact"]


def _rel(a, b):
    return abs(a / b - 1)


@pytest.fixture(scope="module")
def paper_result(tmp_path_factory):
    return run_paper_example(tmp_path_factory.mktemp("paper"), n_frequencies=41, figures=False)


def test_paper_example_within_1e_4_percent(paper_result):
    """Eq 19-20, 41 frequencies over 160-180 rad/s, noise-free: every parameter within 1e-4 %."""
    t = paper_result.tables
    for source in ("band_average", "pooled"):
        assert _rel(t["table1"][source]["omega1"], EXACT["omega1"]) < 1e-6
        assert _rel(t["table1"][source]["k3"], EXACT["k3"]) < 1e-6
    for k in ("c0", "c1", "c2"):
        assert _rel(t["table2"][k], EXACT[k]) < 1e-6, (k, t["table2"][k])
    assert _rel(t["table3"]["omega1"], EXACT["omega1"]) < 1e-6
    assert _rel(t["table3"]["k3"], EXACT["k3"]) < 1e-6
    assert abs(t["table3"]["c_quad"]) < 1e-6 and abs(t["table3"]["c_cubic"]) < 1e-6
    assert "paper identified" in paper_result.report()
    assert len(paper_result.eq21.records) == 41 and not paper_result.eq21.failed


def _noisy(tmp_path, k3, seed, noise=0.01, periods=50.0, fs=2000.0, levels=(0.5, 1.0, 2.0), t0=0.123):
    cfg = paper_config(n_frequencies=41, fs=fs, periods=periods, noise=noise, seed=seed, write_frequency=False,
                       n_harmonics=9)
    cfg["model"][0]["coefficients"]["k3"] = k3
    cfg["excitation"]["force_levels"] = list(levels)
    cfg["acquisition"]["t0"] = t0
    camp = simulate_campaign(load_simulation_config(cfg), tmp_path / "campaign")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return identify_campaign(camp, n_harmonics=5)


def _check_noisy(res, k3, frequency_given=False):
    assert not res.failed
    for g in res.groups:
        assert _rel(g.pooled.omega1, EXACT["omega1"]) < 1e-4, g.summary()
        assert _rel(g.pooled.k3, k3) < 0.03, (g.force_level, g.pooled.k3)
    law = res.damping_laws["example"]
    c0, c1, c2 = law.coefficients
    assert _rel(c0, EXACT["c0"]) < 0.03
    assert _rel(c1, EXACT["c1"]) < 0.03
    assert _rel(c2, EXACT["c2"]) < 0.10
    for rec in res.records:  # the frequency was estimated from the force, or given
        assert rec.summary()["frequency_given"] == frequency_given


@pytest.mark.parametrize("k3, seed", [(5e6, 11), (-5e6, 12)], ids=["softening", "hardening"])
def test_noisy_campaign_recovers_parameters(tmp_path, k3, seed):
    """1 % noise on force and acceleration, frequency not given, three force levels."""
    _check_noisy(_noisy(tmp_path, k3, seed), k3)


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(21, 27))
def test_noisy_campaigns_unseen(tmp_path, seed):
    """Campaigns drawn at random (noise 0.5-1 %, sign of k3, levels, length, rate, start time)."""
    rng = np.random.default_rng(seed)
    k3 = float(rng.choice([-1, 1]) * rng.uniform(3e6, 6e6))
    noise = float(rng.uniform(0.005, 0.01))
    n_levels = int(rng.integers(2, 4))
    levels = sorted(rng.uniform(0.4, 2.0, n_levels).round(3))
    res = _noisy(tmp_path, k3, seed, noise=noise, periods=float(rng.uniform(40, 80)), fs=float(rng.uniform(1500, 4000)),
                 levels=levels, t0=float(rng.uniform(0, 100)))
    _check_noisy(res, k3)


def test_same_input_and_seed_give_same_results(tmp_path, monkeypatch):
    """Two simulations with one seed, identified in this process and by two workers: identical results."""
    from jointid.app import records

    monkeypatch.setattr(records, "MIN_PARALLEL_RECORDS", 2)  # two workers even for this small campaign
    outs = []
    for i, jobs in enumerate(("1", "2")):
        cfg = paper_config(n_frequencies=9, noise=0.01, seed=5, write_frequency=False, periods=10)
        camp = simulate_campaign(load_simulation_config(cfg), tmp_path / f"c{i}")
        out = tmp_path / f"o{i}"
        assert main(["identify", str(camp), "--out", str(out), "--no-figures", "--quiet", "--jobs", jobs]) == 0
        outs.append(json.loads((out / "results.json").read_text()))
    for o in outs:
        o["campaign"].pop("folder")
        o.pop("run_id")  # names the output set: new for every run
        o.pop("provenance")  # host, workers, times: who ran it, not what it found
    assert outs[0] == outs[1]


def test_cli_simulate_then_identify_writes_outputs(tmp_path):
    cfg = tmp_path / "sim.toml"
    cfg.write_text(
        """
[campaign]
name = "cli <test>"
[[model]]
preload = 120
omega1 = 170.0
coefficients = { k3 = 5e6 }
amplitude_laws = { c = [0.08, 70.0, 1e4] }
[excitation]
force_levels = [1.0, 2.0]
omega_start = 162.0
omega_stop = 178.0
n_frequencies = 7
[acquisition]
fs = 3000.0
periods = 12.5
"""
    )
    camp = tmp_path / "camp"
    assert main(["simulate", str(cfg), "--out", str(camp), "--quiet"]) == 0
    out = tmp_path / "res"
    assert main(["identify", str(camp), "--out", str(out), "--quiet", "--harmonics", "7"]) == 0
    data = json.loads((out / "results.json").read_text())
    assert len(data["records"]) == 14 and len(data["groups"]) == 2
    assert {"omega1", "f1_hz", "k3", "omega1_mean", "k3_mean"} <= set(data["groups"][0])
    assert data["damping_law"][0]["preload"] == 120 and len(data["damping_law"][0]["coefficients"]) == 3
    assert {"alpha", "n"} <= set(data["power_law"][0])
    for r in data["records"]:
        assert {"file", "preload", "force_level", "frequency_hz", "q_max", "omega1", "k3", "c", "status"} <= set(r)
        assert abs(r["omega1"] / 170 - 1) < 1e-6
    assert (out / "records.csv").is_file() and (out / "groups.csv").is_file()
    assert len(list((out / "figures").glob("*.png"))) >= 4
    page = (out / "report.html").read_text()
    assert "cli &lt;test&gt;" in page and "<test>" not in page  # text from input files is escaped
    assert page.count("data:image/png;base64,") >= 4  # figures embedded: the page opens offline


def test_unknown_force_gain_gives_the_calibrated_result(tmp_path):
    """A campaign whose force column is a voltage (force / 0.37) identifies the same omega1, k3, c(q_max)."""
    from jointid.io.campaign import load_campaign, read_record, write_campaign, write_csv_record

    cfg = paper_config(n_frequencies=15, noise=0.0, periods=12)
    camp = simulate_campaign(load_simulation_config(cfg), tmp_path / "force")
    entries = []
    for spec in load_campaign(camp).records:
        rec = read_record(spec)
        write_csv_record(tmp_path / "volt" / spec.file, rec.time,
                         {"force": rec.channels["force"] / 0.37, "accel": rec.channels["accel"]})
        entries.append({"file": spec.file, "force_level": spec.force_level, "preload": spec.preload})
    write_campaign(tmp_path / "volt", "voltage", entries)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ref = identify_campaign(camp, n_harmonics=7)
        res = identify_campaign(tmp_path / "volt", n_harmonics=7, force_gain="unknown")
    g, g0 = res.groups[0], ref.groups[0]
    assert g.gain.gain == pytest.approx(0.37, rel=1e-6)
    assert g.pooled.omega1 == pytest.approx(EXACT["omega1"], rel=1e-8)
    assert g.pooled.k3 == pytest.approx(g0.pooled.k3, rel=1e-5)
    law, law0 = res.damping_laws["example"], ref.damping_laws["example"]
    assert np.allclose(law.coefficients, law0.coefficients, rtol=1e-5)
    s = res.summary()
    assert s["groups"][0]["force_gain"] == pytest.approx(0.37, rel=1e-6)
    assert all(abs(r["omega1"] / 170 - 1) < 1e-6 and r["k3"] is None for r in s["records"])
    assert main(["identify", str(tmp_path / "volt"), "--out", str(tmp_path / "o"), "--quiet", "--no-figures",
                 "--force-gain", "unknown", "--harmonics", "7"]) == 0


def test_shipped_example_config_runs(tmp_path):
    from pathlib import Path

    from jointid.io.campaign import load_campaign

    cfg = Path(__file__).resolve().parents[1] / "examples" / "noisy_softening.toml"
    assert main(["simulate", str(cfg), "--out", str(tmp_path / "c"), "--quiet"]) == 0
    assert len(load_campaign(tmp_path / "c").records) == 123


def test_rounded_manifest_frequencies_are_corrected_from_the_force(tmp_path):
    """A manifest logging frequencies to 0.01 Hz (as test controllers do) still gives the right laws."""
    import re

    cfg = paper_config(n_frequencies=41, noise=0.01, seed=8, periods=50, fs=2000.0, write_frequency=True)
    cfg["model"][0]["coefficients"]["k3"] = 5e6
    cfg["excitation"]["force_levels"] = [0.5, 1.0, 2.0]
    camp = simulate_campaign(load_simulation_config(cfg), tmp_path / "c")
    manifest = camp / "campaign.toml"
    text = re.sub(r"frequency_hz = ([0-9.e+-]+)", lambda m: f"frequency_hz = {float(m.group(1)):.2f}",
                  manifest.read_text())
    manifest.write_text(text)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = identify_campaign(camp, n_harmonics=5)
    assert any("differs from the force's" in w for r in res.records for w in r.warnings)
    _check_noisy(res, 5e6, frequency_given=True)
