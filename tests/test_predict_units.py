"""Units of the force levels from ``identify`` through ``jointid predict`` (``force_level_unit``).

identify writes ``force_level_unit``: ``"N"`` with a known force gain, ``"V"`` with an identified one (the
levels are excitation amplitudes), ``None`` when the levels are labels; predict carries it into its
``results.json`` (top level and each prediction), its report lines, table header and figure legends; a
results.json without the key (written before it existed) predicts without a unit.  A structure model's
predictions (``predict MODEL.toml``) are in N, the model's force.
"""

from __future__ import annotations

import json
import re
import warnings
from types import SimpleNamespace

import numpy as np
import pytest
from test_predict import _handmade

from jointid.cli import main

CONFIG = {
    "campaign": {"name": "force-level units"},
    "model": [{"preload": 120, "terms": "q + -q^3 + q'", "omega1": 170.0, "coefficients": {"k3": 5e6, "c": 0.5}}],
    "excitation": {"force_levels": [0.5, 1.0], "omega_start": 160.0, "omega_stop": 180.0, "n_frequencies": 6},
    "acquisition": {"fs": 2000.0, "periods": 12.0, "noise": 0.01, "seed": 3, "n_harmonics": 7},
}


@pytest.fixture(scope="module")
def identified(tmp_path_factory):
    """``identify`` with a known and an unknown force gain: ``{gain: results folder}``."""
    from jointid.app.synthesis import load_simulation_config, simulate_campaign

    root = tmp_path_factory.mktemp("units")
    camp = simulate_campaign(load_simulation_config(CONFIG), root / "campaign")
    out = {}
    for gain in ("known", "unknown"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            main(["identify", str(camp), "--out", str(root / gain), "--no-figures", "--quiet", "--force-gain", gain])
        out[gain] = root / gain
    return out


def test_identify_writes_the_unit_of_its_force_levels(identified):
    units = {g: json.loads((f / "results.json").read_text())["force_level_unit"] for g, f in identified.items()}
    assert units == {"known": "N", "unknown": "V"}


def test_predict_of_an_identification_carries_its_unit(identified, tmp_path):
    out = tmp_path / "pred"
    assert main(["predict", str(identified["known"]), "--force-levels", "0.75", "--out", str(out),
                 "--no-uncertainty", "--quiet"]) in (0, 1)
    p = json.loads((out / "results.json").read_text())
    assert p["force_level_unit"] == "N" and [e["force_level_unit"] for e in p["predictions"]] == ["N"]


@pytest.mark.parametrize("unit", ["N", "V"])
def test_predict_writes_the_unit_into_its_set(tmp_path, unit):
    folder = _handmade(tmp_path / "r")
    d = json.loads((folder / "results.json").read_text())
    (folder / "results.json").write_text(json.dumps({**d, "force_level_unit": unit}))
    out = tmp_path / "pred"
    assert main(["predict", str(folder), "--force-levels", "1.5", "--out", str(out), "--no-uncertainty",
                 "--quiet"]) == 0
    p = json.loads((out / "results.json").read_text())
    assert p["force_level_unit"] == unit and [e["force_level_unit"] for e in p["predictions"]] == [unit]
    text = (out / "report.txt").read_text()
    assert f"at force levels 1.5 {unit}" in text and f"F = 1.5 {unit} (Q = " in text
    assert f"force level [{unit}]" in (out / "report.html").read_text()


def test_labels_and_no_groups_have_no_unit():
    from jointid.app.campaign_result import CampaignResult
    from jointid.app.records import IdentifySettings

    def unit(levels, gain="known"):
        groups = tuple(SimpleNamespace(force_level=v) for v in levels)
        return CampaignResult("c", "r", IdentifySettings(force_gain=gain), (), groups, {}).force_level_unit

    assert unit([1.0, np.float64(2.0), 3]) == "N" and unit([1.0, np.int64(2)], "unknown") == "V"
    assert unit(["0.14-0.23 N", "0.37-0.56 N"]) is None and unit([1.0, "high"]) is None and unit([]) is None
    assert unit([True]) is None


def test_results_without_the_key_predict_without_a_unit(tmp_path):
    """An older results.json (no force_level_unit): no unit anywhere, as before; the same file with the key
    gets it in the report and in the figure's legend."""
    from jointid.app.predict import predict_from_results
    from jointid.report.predict_plots import plot_predictions, prediction_rows

    d = json.loads((_handmade(tmp_path / "r") / "results.json").read_text())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        old = predict_from_results(d, [1.5], uncertainty=False)
        new = predict_from_results({**d, "force_level_unit": "N"}, [1.5], uncertainty=False)
    (p_old,), (p_new,) = old.predictions, new.predictions
    assert old.summary()["force_level_unit"] is None and p_old.summary()["force_level_unit"] is None
    assert "F = 1.5 (Q = " in p_old.report() and "F = 1.5 N (Q = " in p_new.report()
    assert "force level" in prediction_rows([p_old])[0] and "force level [N]" in prediction_rows([p_new])[0]
    legend = [t.get_text() for t in plot_predictions([p_new]).get_legend().get_texts()]
    assert legend and all(re.match(r"F = 1\.5 N\b", t) for t in legend), legend
    legend = [t.get_text() for t in plot_predictions([p_old]).get_legend().get_texts()]
    assert legend and all(re.match(r"F = 1\.5(?! N)", t) for t in legend), legend
    for bad in (3.0, "", None):  # not a unit: none
        assert predict_from_results({**d, "force_level_unit": bad}, [1.5], uncertainty=False).force_level_unit is None


def test_demo_results_carry_the_unit_when_the_preloads_agree(tmp_path):
    from jointid.app.predict import _identifications, force_level_unit

    d = json.loads((_handmade(tmp_path / "r") / "results.json").read_text())
    same = {"preloads": [{"identification": {**d, "force_level_unit": "V"}} for _ in range(2)]}
    mixed = {"preloads": [{"identification": {**d, "force_level_unit": u}} for u in ("V", "N")]}
    assert force_level_unit(_identifications(same)) == "V" and force_level_unit(_identifications(mixed)) is None


def test_structure_model_predictions_are_in_newtons():
    from jointid.app.structure_predict import LevelPrediction, StructurePrediction

    lv = LevelPrediction(2.0, frequency_hz=[80.0], amplitude={"x": [1e-3]},
                         peaks={"x": {"peak_frequency_hz": 80.0, "peak_amplitude": 1e-3}}, n_points=1,
                         newton_iterations_mean=2.0, max_residual=1e-12, seconds_per_point=1e-3)
    res = StructurePrediction("m.toml", {"name": "m", "n_modes": 1, "joints": []},
                              {"n_harmonics": 5, "n_time": 32}, [lv, LevelPrediction(5.0, error="no steady state")])
    s = res.summary()
    assert s["force_level_unit"] == "N" and [e["force_level_unit"] for e in s["predictions"]] == ["N", "N"]
    lines = res.lines()
    assert lines[1].startswith("F = 2 N: x peak") and lines[2] == "F = 5 N: FAILED: no steady state"
