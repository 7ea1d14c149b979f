"""The Brake-Reuss beam (shared data): the four levels fitted together, leave one level out, Monte Carlo std(z),
the hammer backbone, and the identify set written by public-data."""

from __future__ import annotations

import json

import numpy as np
import pytest

from jointid.errors import RecordFileNotFoundError

try:
    from jointid.io.datasets import shared_data_dir

    BRB = shared_data_dir() / "brb_cenedese"
except RecordFileNotFoundError:  # pragma: no cover - data not beside the repository
    BRB = None

pytestmark = pytest.mark.skipif(BRB is None or not (BRB / "ForceControlledFrequencyResponses.mat").is_file(),
                                reason="../shared/data/brb_cenedese is not available")


def _levels():
    from scipy.io import loadmat

    from jointid.identify.firstharmonic import FirstHarmonicLevel

    fr = loadmat(BRB / "ForceControlledFrequencyResponses.mat", squeeze_me=True, struct_as_record=False)["FRdata"]
    return [FirstHarmonicLevel(lv.frequency, lv.force, 0.0, lv.amplitude, lv.phase, f"level {k + 1}")
            for k, lv in enumerate(fr.ForceControl)]


def test_four_levels_fitted_together_are_repredicted_from_their_measured_forces():
    from jointid.identify.firstharmonic import fit_first_harmonic, leave_one_level_out

    levels = _levels()
    fit = fit_first_harmonic(levels, "poly4", "poly2")
    for pr in fit.predictions:
        print(pr.label, f"{100 * pr.amplitude_rms_rel:.2f} %", f"{pr.phase_rms_deg:.2f} deg")
        assert pr.amplitude_rms_rel < 0.05 and pr.phase_rms_deg < 4.0
    mm, se = fit.modal_mass
    assert 1.9 < mm < 2.1 and se < 0.02 * mm  # kg at accelerometer 3
    assert abs(fit.low_level["z_vs_joint"]) < 3  # the lowest level alone agrees with the joint fit
    top = leave_one_level_out(levels, "poly4", "poly2")[-1]["peaks"]
    print("top level from the other three:", top)
    assert abs(top["amplitude_error_rel"]) < 0.03 and abs(top["frequency_error_rel"]) < 5e-4


def test_hammer_backbone_is_monotone_above_the_noise_floor_and_meets_the_stepped_sine_one():
    from scipy.io import loadmat

    from jointid.app.firstharmonic_campaign import compare_with_model, ringdown_backbone
    from jointid.identify.firstharmonic import fit_first_harmonic

    hi = loadmat(BRB / "HammerImpact.mat", squeeze_me=True, struct_as_record=False)["HIdata"]
    b, d, mono = ringdown_backbone(hi.time, hi.acc3, 80.4)
    print(mono)
    assert mono["monotone"] and mono["trend"] == "decreasing"  # softening: lower frequency at larger amplitude
    assert b.amplitude.max() / b.amplitude.min() > 10  # more than a decade above the floor
    c = compare_with_model(fit_first_harmonic(_levels(), "poly4", "poly2"), b)
    print(c)
    assert c["n_windows"] > 10 and abs(c["delta_f_hz"]["max"]) < 0.2  # the same mode within 0.25 %


@pytest.mark.slow
def test_public_data_writes_the_brb_identify_set(tmp_path):
    """The worked example end to end: law selection, every check of docs/public-data.md, DIR/brb/results.json."""
    from jointid.app.public_data import main

    assert main(["--only", "brb", "--out", str(tmp_path)]) == 0
    s = json.loads((tmp_path / "brb" / "results.json").read_text())
    c = s["public_data_checks"]
    print(json.dumps({k: c[k] for k in ("levels", "lolo_top", "hammer")}, indent=1, default=str))
    print("std(z):", c["monte_carlo"]["std_z"])
    for lv in c["levels"]:
        assert lv["amplitude_rms_rel"] < 0.05 and lv["phase_rms_deg"] < 4.0
    assert abs(c["lolo_top"]["amplitude_error_rel"]) < 0.03 and abs(c["lolo_top"]["frequency_error_rel"]) < 5e-4
    lo, hi = c["monte_carlo"]["std_z_range"]
    assert 0.8 < lo and hi < 1.25
    assert c["hammer"]["monotone"]
    model = s["backbones"]["preloads"][0]["model"]
    assert "first-harmonic acceleration amplitude at the driving point" in model["amplitude_unit"]
    assert model["frequency_hz"] and model["zeta"] and len(model["amplitude"]) == len(model["zeta"])
    assert (tmp_path / "brb" / "figures" / "frf_BRB.png").is_file()
    assert (tmp_path / "brb" / "figures" / "backbone_BRB.png").is_file()
