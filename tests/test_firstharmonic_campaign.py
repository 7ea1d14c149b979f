"""A campaign of first-harmonic records (and a ring-down without force) through identify: results.json in the
identify schema, one bad record failing alone, the CLI writing the set."""

from __future__ import annotations

import json

import numpy as np
import pytest

from jointid.app.firstharmonic_campaign import identify_first_harmonic_campaign
from jointid.app.workflow import identify_campaign
from jointid.errors import JointidWarning
from jointid.cli import main
from jointid.identify.firstharmonic import AmplitudeLaw, FirstHarmonicLevel, FirstHarmonicModel, repredict_level
from jointid.io.campaign import write_campaign, write_csv_record
from jointid.io.firsth import FirstHarmonicRecord, write_first_harmonic_csv

TRUTH = FirstHarmonicModel(AmplitudeLaw("poly2"), AmplitudeLaw("poly1"), 60.0,
                           np.array([-0.5, -0.4, -0.2, 80.0, -0.008, 0.004, 0.001, 0.003]))


def _campaign(folder, bad=False, ringdown=True, seed=0):
    rng = np.random.default_rng(seed)
    entries = []
    for k, F0 in enumerate((0.15, 0.4, 0.8, 1.2)):
        f = np.linspace(79.0, 81.0, 31)
        F = F0 * (1 - 0.25 * np.exp(-((f - 79.9) / 0.25) ** 2))
        a = repredict_level(TRUTH, FirstHarmonicLevel(f, F, 0.0, np.ones(f.size), 0.0)).accel_predicted
        H = TRUTH.frf(2 * np.pi * f, a) * (1 + 0.01 * (rng.standard_normal(f.size) + 1j * rng.standard_normal(f.size)))
        rec = FirstHarmonicRecord(f, F, np.zeros(f.size), np.abs(H) * F, np.angle(H))
        write_first_harmonic_csv(folder / f"records/{k:04d}.csv", rec)
        entries.append({"file": f"records/{k:04d}.csv", "excitation": "first-harmonic", "force_level": F0,
                        "preload": "beam"})
    if bad:
        (folder / "records/0009.csv").write_text("frequency_hz,force,accel\n80,1,2\n", encoding="utf-8")
        entries.append({"file": "records/0009.csv", "excitation": "first-harmonic", "force_level": 9.0,
                        "preload": "beam"})
    if ringdown:  # the driving point's acceleration after an impact: no force column
        t = np.arange(0, 3.0, 1 / 2000)
        amp = 30 * np.exp(-0.002 * 2 * np.pi * 80 * t)
        f_inst = TRUTH.omega_n(amp) / (2 * np.pi)
        x = amp * np.sin(2 * np.pi * np.cumsum(f_inst) / 2000) + 0.01 * rng.standard_normal(t.size)
        write_csv_record(folder / "records/0010.csv", t, {"accel": x})
        entries.append({"file": "records/0010.csv", "excitation": "ringdown", "preload": "beam"})
    write_campaign(folder, "synthetic first harmonics", entries)
    return folder


def test_identify_dispatches_a_first_harmonic_campaign_and_keeps_the_identify_schema(tmp_path):
    camp = _campaign(tmp_path / "camp", bad=True)
    with pytest.warns(JointidWarning, match="record failed"):
        res = identify_first_harmonic_campaign(camp, laws=("poly2", "poly1"))
    s = json.loads(json.dumps(res.summary()))  # JSON-safe
    for key in ("records", "groups", "damping_law", "power_law", "models", "reprediction", "backbones", "adequacy",
                "selection", "flagged", "n_records", "n_failed"):
        assert key in s
    assert s["n_records"] == 6 and s["n_failed"] == 1
    bad = [r for r in s["records"] if r["status"] != "ok"][0]
    assert "records/0009.csv" in bad["error"] and "record 4" in bad["error"] and "accel_phase" in bad["error"]
    model = s["backbones"]["preloads"][0]["model"]
    assert "driving point" in model["amplitude_unit"] and "m/s^2" in model["amplitude_unit"]
    assert len(model["amplitude"]) == len(model["frequency_hz"]) == len(model["zeta"])
    # the ring-down backbone is drawn against the same amplitude and follows the same law
    ring = s["backbones"]["preloads"][0]["ringdown"][0]
    a = np.array(ring["amplitude"])
    np.testing.assert_allclose(np.array(ring["frequency_hz"]), TRUTH.omega_n(a) / (2 * np.pi), rtol=2e-4)
    fit = s["first_harmonic"][0]["fit"]
    z = (np.array(fit["parameters"][:4]) - TRUTH.params[:4]) / np.array(fit["stderr"][:4])  # a_ref differs: laws below
    assert np.all(np.abs(z) < 4)
    a, wn, se = (np.array(model[k]) for k in ("amplitude", "omega", "omega_stderr"))
    assert np.all(np.abs(wn - TRUTH.omega_n(a)) < 4 * se)
    for pr in s["reprediction"]["groups"]:
        assert pr["amplitude_rms_rel"] < 0.03 and pr["phase_rms_deg"] < 2


def test_mixed_with_time_records_is_refused(tmp_path):
    from jointid.errors import IdentificationError

    camp = _campaign(tmp_path / "camp", ringdown=False)
    t = np.arange(0, 1, 1e-3)
    write_csv_record(camp / "records/0011.csv", t, {"force": np.sin(50 * t), "accel": np.sin(50 * t)})
    text = (camp / "campaign.toml").read_text() + '\n[[record]]\nfile = "records/0011.csv"\nforce_level = 1\n'
    (camp / "campaign.toml").write_text(text)
    with pytest.raises(IdentificationError, match="first-harmonic records are identified on their own"):
        identify_campaign(camp)


@pytest.mark.slow
def test_cli_identify_writes_the_set(tmp_path, capsys):
    camp = _campaign(tmp_path / "camp")
    code = main(["identify", str(camp), "--out", str(tmp_path / "res"), "--quiet"])
    assert code == 0
    s = json.loads((tmp_path / "res" / "results.json").read_text())
    assert s["record_type"] == "first-harmonic" and s["run_id"]
    assert s["selection"][0]["selected"] == ["poly2", "poly1"]  # chosen by leave-one-level-out: the true laws
    assert (tmp_path / "res" / "figures" / "frf_beam.png").is_file()
    assert (tmp_path / "res" / "report.html").is_file()


def test_options_of_time_records_are_reported_as_unused(tmp_path):
    from jointid.app.records import IdentifySettings

    camp = _campaign(tmp_path / "camp", ringdown=False)
    with pytest.warns(JointidWarning, match="n_harmonics not used"):
        res = identify_first_harmonic_campaign(camp, IdentifySettings(n_harmonics=3), laws=("poly2", "poly1"),
                                               lolo=False)
    assert "n_harmonics not used" in res.summary()["warnings"][0] and "note: n_harmonics" in res.report()
