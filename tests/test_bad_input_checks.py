"""Plausibility checks: each corruption of a record is flagged, clean noisy records never are.

A small simulated campaign of the seed's numerical example (2 % noise) is identified clean
and with one record corrupted as a careless or unlucky test would corrupt it; the corrupted
record is flagged with the numbers that triggered the flag and left out of the pooled fit,
which then recovers the model of the clean records.
"""

import json
import warnings

import numpy as np
import pytest

from jointid.app.paper_example import PAPER, paper_config
from jointid.app.synthesis import load_simulation_config, simulate_campaign
from jointid.app.workflow import identify_campaign
from jointid.cli import main
from jointid.io.campaign import load_campaign, read_record, write_csv_record
from jointid.signal.checks import Flag, check_live, clipping_flag, scale_outliers

BAD = 4  # the record near resonance


def _campaign(folder, seed=3, noise=0.02, write_frequency=True, periods=20):
    cfg = paper_config(n_frequencies=9, fs=2000.0, periods=periods, noise=noise, seed=seed,
                       write_frequency=write_frequency)
    return simulate_campaign(load_simulation_config(cfg), folder)


def _identify(camp, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return identify_campaign(camp, **kw)


def corrupt(spec, kind, rng=None):
    """Rewrite a record file with one corruption."""
    rng = np.random.default_rng(0) if rng is None else rng
    d = read_record(spec)
    t, Q, a = d.time, d.channels["force"].copy(), d.channels["accel"].copy()
    if kind == "clipped":
        p = 0.4 * np.abs(a).max()
        a = np.clip(a, -p, p)
    elif kind == "in_g":
        a = a / 9.81
    elif kind == "sign_flipped":
        a = -a
    elif kind == "time_in_ms":
        t = t * 1000.0
    elif kind == "swapped":
        Q, a = a, Q
    elif kind == "dead_sensor":
        a = 1e-3 * a.std() * rng.standard_normal(a.size)
    elif kind == "transient":
        tau = (t[-1] - t[0]) / 4
        a = a + a.std() * np.exp(-(t - t[0]) / tau) * np.cos(0.97 * 170.0 * (t - t[0]))
    elif kind == "force_clipped":
        p = 0.7 * np.abs(Q).max()
        Q = np.clip(Q, -p, p)
    else:  # pragma: no cover
        raise ValueError(kind)
    write_csv_record(spec.path, t, {"force": Q, "accel": a})


EXPECTED = {
    "clipped": {"clipping"},
    "force_clipped": {"clipping"},
    "in_g": {"scale_outlier"},
    "sign_flipped": {"negative_input_power", "channel_swap"},
    "time_in_ms": {"time_unit"},
    "swapped": {"channel_swap", "negative_input_power"},
    "dead_sensor": {"dead_channel"},
    "transient": {"transient"},
}


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    camp = _campaign(tmp_path_factory.mktemp("clean"), write_frequency=False)
    return camp, _identify(camp)


def test_clean_noisy_campaigns_are_not_flagged(tmp_path, clean):
    """2 % noise, several seeds, frequency given or estimated: no record is flagged."""
    camp, res = clean
    assert all(r.ok and not r.flags for r in res.records), [r.flags for r in res.records]
    for seed in (11, 12):
        res = _identify(_campaign(tmp_path / f"c{seed}", seed=seed, write_frequency=bool(seed % 2)))
        assert all(r.ok and not r.flags for r in res.records), [(r.spec.index, r.flags) for r in res.records]
        assert res.summary()["flagged"] == []


@pytest.mark.parametrize("kind", sorted(EXPECTED))
def test_each_corruption_is_flagged_and_left_out(tmp_path, clean, kind):
    camp = _campaign(tmp_path / "c", write_frequency=False)
    corrupt(load_campaign(camp).records[BAD], kind)
    res = _identify(camp)
    bad = res.records[BAD]
    assert bad.ok and not bad.usable, (bad.status, bad.error)
    names = {f.name for f in bad.flags}
    assert names & EXPECTED[kind], (kind, bad.flags)
    for f in bad.flags:
        assert f.values and f.message
    others = [r for r in res.records if r.spec.index != BAD]
    assert all(r.usable for r in others), [(r.spec.index, r.flags) for r in others]
    g = res.groups[0]
    assert BAD not in g.record_indices and len(g.record_indices) == len(others)
    # the pooled fit of the clean records is that of the clean campaign, not dragged by the bad one
    ref = clean[1].groups[0].pooled
    assert g.pooled.omega1 == pytest.approx(ref.omega1, rel=2e-3)
    assert g.pooled.omega1 == pytest.approx(PAPER["exact"]["omega1"], rel=5e-3)
    s = res.summary()
    assert [d["index"] for d in s["flagged"]] == [BAD]
    assert s["records"][BAD]["flags"][0]["name"] in EXPECTED[kind] | {"negative_stiffness", "clipping"}
    json.dumps(s["records"][BAD]["flags"])  # JSON-safe


def test_keep_flagged_puts_the_record_back(tmp_path):
    camp = _campaign(tmp_path / "c", write_frequency=False)
    corrupt(load_campaign(camp).records[BAD], "transient")
    res = _identify(camp, keep_flagged=True)
    assert BAD in res.groups[0].record_indices
    assert res.summary()["flagged"][0]["in_pooled_fits"] is True
    assert res.summary()["settings"]["keep_flagged"] is True
    out = tmp_path / "o"
    assert main(["identify", str(camp), "--out", str(out), "--quiet", "--no-figures", "--keep-flagged"]) == 1
    assert json.loads((out / "results.json").read_text())["groups"][0]["records"].count(BAD) == 1


def test_stuck_channel_fails_the_record_with_its_channel(tmp_path):
    camp = _campaign(tmp_path / "c")
    spec = load_campaign(camp).records[2]
    d = read_record(spec)
    write_csv_record(spec.path, d.time, {"force": d.channels["force"], "accel": np.full(d.time.size, 9.81)})
    res = _identify(camp)
    r = res.records[2]
    assert r.status == "failed" and "'accel'" in r.error and "constant (9.81" in r.error
    assert sum(o.usable for o in res.records) == 8


def test_checks_units():
    t = np.arange(4000) / 2000.0
    x = np.sin(2 * np.pi * 13.0 * t)
    assert clipping_flag(x, "a") is None
    q = np.round(x * 2**11) / 2**11  # a 12-bit converter is not clipping
    assert clipping_flag(q, "a") is None
    f = clipping_flag(np.clip(x, -0.95, 0.95), "a")
    assert f.name == "clipping" and f.values["samples_at_limit"] > 100
    with pytest.raises(ValueError, match="zero at every sample"):
        check_live(np.zeros(5), "force")
    assert scale_outliers({0: 1.0, 1: 1.1, 2: 0.9}, factor=1.5) == {}
    assert scale_outliers({0: 1.0, 1: 1.1}, factor=1.5) == {}  # too few to judge
    fl = Flag("x", "msg", {"a": np.float64(1.5)})
    assert fl.summary() == {"name": "x", "message": "msg", "values": {"a": 1.5}}
    assert "x" in fl._repr_html_() and fl.report() == "x: msg"


@pytest.mark.parametrize("kind", ["sign_flipped", "swapped"])
def test_a_whole_group_with_flipped_channels_gives_no_number(tmp_path, kind):
    """Off resonance a flipped sign hides in the noise; the group's other records give it away."""
    camp = _campaign(tmp_path / "c")
    for spec in load_campaign(camp).records:
        corrupt(spec, kind)
    res = _identify(camp)
    assert all(r.ok and r.flags for r in res.records), [(r.spec.index, r.flags) for r in res.records]
    g = res.groups[0]
    assert g.record_indices == () and g.pooled is None
    out = tmp_path / "o"
    assert main(["identify", str(camp), "--out", str(out), "--quiet", "--no-figures"]) == 1
    s = json.loads((out / "results.json").read_text())
    assert len(s["flagged"]) == 9 and s["groups"][0].get("omega1") is None


@pytest.mark.parametrize("noise, k3, periods, fs, levels", [
    (0.001, -5e6, 6, 1500.0, [0.4, 1.7]),   # hardening, low noise, short records: few periods per half
    (0.02, 3e6, 15, 4000.0, [0.5, 2.0]),    # softening, 2 % noise
])
def test_varied_clean_campaigns_are_not_flagged(tmp_path, noise, k3, periods, fs, levels):
    """A damping law that grows faster than a power law, few records per group, short records:
    no flag on clean data (the damping trend check allows the resonant record above the line)."""
    cfg = paper_config(n_frequencies=5, fs=fs, periods=periods, noise=noise, seed=4, write_frequency=False)
    cfg["model"][0]["coefficients"]["k3"] = k3
    cfg["excitation"]["force_levels"] = levels
    res = _identify(simulate_campaign(load_simulation_config(cfg), tmp_path / "c"))
    assert all(r.ok and not r.flags for r in res.records), [(r.spec.index, r.flags) for r in res.records]
