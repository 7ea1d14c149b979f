"""The band average's standard error and resolution (the paper's Table 5 number) are computed by the campaign
identification and carried in results.json; the report reads them and recomputes only for older results."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from jointid.app.paper_example import paper_config
from jointid.app.synthesis import load_simulation_config, simulate_campaign
from jointid.app.workflow import identify_campaign
from jointid.io.results import to_jsonable
from jointid.numerics.intervals import Z95, band_mean_resolution
from jointid.report.summary import band_resolution, table5_rows


@pytest.fixture(scope="module")
def summary(tmp_path_factory):
    cfg = paper_config(n_frequencies=3, fs=2000.0, periods=12, noise=0.01, seed=3)
    root = simulate_campaign(load_simulation_config(cfg), tmp_path_factory.mktemp("band") / "campaign")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = identify_campaign(root, terms="q - q^3 + q'", repredict=False)
    return json.loads(json.dumps(to_jsonable(res.summary())))  # as read back from results.json


def test_band_resolution_is_in_the_results_and_is_what_the_records_give(summary):
    for g in summary["groups"]:
        b = g["band_resolution"]
        k3 = np.array([r["k3"] for r in summary["records"] if r["index"] in g["records"]])
        se = k3.std(ddof=1) / np.sqrt(k3.size)
        assert b["n_records"] == k3.size == len(g["records"]) > 2
        assert b["mean"] == g["k3_mean"] and b["mean"] == pytest.approx(k3.mean(), rel=1e-12)
        assert b["stderr"] == pytest.approx(se, rel=1e-12)
        assert b["ci95"] == pytest.approx([b["mean"] - Z95 * se, b["mean"] + Z95 * se], rel=1e-12)
        assert b["resolved"] == bool(abs(b["mean"]) > Z95 * se)
        assert b["consistent"] == bool(abs(b["mean"] - g["k3"]) <= Z95 * np.hypot(se, g["k3_stderr"]))
        # the report reads it; an older results.json without the key gives the same from the records
        old = {k: v for k, v in g.items() if k != "band_resolution"}
        assert band_resolution(summary, g) == band_resolution(summary, old)


def test_report_reads_the_stored_value_and_falls_back_for_older_results(summary):
    s = json.loads(json.dumps(summary))
    g = s["groups"][0]
    stored = band_resolution(s, g)
    for r in s["records"]:  # records changed after the identification: the stored number is what is reported
        r["k3"] = 5e6 + 1e3 * (r["index"] % 3)
    assert band_resolution(s, g) == stored
    old = {k: v for k, v in g.items() if k != "band_resolution"}
    fresh = band_resolution(s, old)
    assert fresh["resolved"] and fresh["stderr"] != stored["stderr"] and "unresolved" not in fresh["note"]
    s["groups"] = [old]
    assert "unresolved" not in table5_rows(s)[0]["band average"]


def test_band_mean_resolution_edge_cases():
    assert band_mean_resolution([None, float("nan")]) == {}
    one = band_mean_resolution([2.0])
    assert one["mean"] == 2.0 and np.isnan(one["stderr"]) and one["ci95"] is None and not one["resolved"]
    b = band_mean_resolution([1.0, 3.0, None], pooled=10.0, pooled_stderr=0.1)
    assert b["n_records"] == 2 and b["stderr"] == pytest.approx(1.0) and b["consistent"] is False
