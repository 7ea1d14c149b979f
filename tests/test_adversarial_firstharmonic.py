"""Adversarial first-harmonic campaigns through identify: a ring-down of noise or of another mode, a level
written in rad/s, bad manifest choices, a physical campaign, ring-downs alone, and the verdict line of the
model (which model, whether it holds and why) on stderr."""

from __future__ import annotations

import functools
import json

import numpy as np
import pytest

from jointid.app import firstharmonic_campaign as fhc
from jointid.app.firstharmonic_campaign import (
    compare_with_model,
    identify_first_harmonic_campaign,
    is_first_harmonic_campaign,
)
from jointid.cli import main
from jointid.errors import IdentificationError, JointidWarning
from jointid.identify.backbone import Backbone
from jointid.io.campaign import load_campaign, write_csv_record
from test_firstharmonic_campaign import _campaign

LAWS = ("poly2", "poly1")


def _identify(camp):
    """Fast identification (laws given, no leave-one-level-out); the campaign's problems warn once."""
    with pytest.warns(JointidWarning, match="problem"):
        return identify_first_harmonic_campaign(camp, laws=LAWS, lolo=False)


def _by_file(res):
    return {r.spec.file: r for r in res.records}


def _edit_manifest(camp, old, new):
    path = camp / "campaign.toml"
    text = path.read_text()
    assert old in text
    path.write_text(text.replace(old, new, 1))


@pytest.fixture
def fast_identify(monkeypatch):
    """``jointid identify`` with the laws given (no selection): the CLI path in a second or two."""
    monkeypatch.setattr(fhc, "identify_first_harmonic_campaign",
                        functools.partial(identify_first_harmonic_campaign, laws=LAWS, lolo=False))


def test_a_ringdown_of_pure_noise_fails_alone(tmp_path):
    camp = _campaign(tmp_path / "camp")
    t = np.arange(0, 3.0, 1 / 2000)
    write_csv_record(camp / "records/0010.csv", t, {"accel": np.random.default_rng(3).standard_normal(t.size)})
    res = _identify(camp)  # was a ValueError (min() of an empty ring-down) in compare_with_model
    rec = _by_file(res)
    assert not rec["records/0010.csv"].ok
    err = rec["records/0010.csv"].error
    assert err.startswith("records/0010.csv [record 4, channel 'accel']: ") and "noise" in err
    assert err.count("records/0010.csv") == 1
    assert all(r.ok for f, r in rec.items() if f != "records/0010.csv")
    assert res.preloads[0].fit is not None and not res.preloads[0].ringdowns
    json.dumps(res.summary())


def test_compare_with_model_of_an_empty_ringdown_is_a_note(tmp_path):
    camp = _campaign(tmp_path / "camp", ringdown=False)
    res = identify_first_harmonic_campaign(camp, laws=LAWS, lolo=False)
    empty = Backbone(*(np.zeros(0) for _ in range(5)), "ringdown", np.zeros(0), "")
    c = compare_with_model(res.preloads[0].fit, empty)
    assert c["overlap"] is None and c["n_windows"] == 0 and "no window" in c["note"]


def test_a_level_written_in_rad_per_s_fails_alone(tmp_path):
    camp = _campaign(tmp_path / "camp")
    path = camp / "records/0000.csv"
    rows = path.read_text().splitlines()
    out = [rows[0]]
    for ln in rows[1:]:
        cells = ln.split(",")
        cells[0] = "%.17g" % (2 * np.pi * float(cells[0]))
        out.append(",".join(cells))
    path.write_text("\n".join(out) + "\n")
    res = _identify(camp)  # was a traceback (the ring-down compared with a model that fitted nothing)
    rec = _by_file(res)
    err = rec["records/0000.csv"].error
    assert not rec["records/0000.csv"].ok
    assert err.startswith("records/0000.csv [record 0, channel 'frequency_hz']: ") and "rad/s" in err
    assert [r.ok for f, r in rec.items() if f != "records/0000.csv"] == [True] * 4
    p = res.preloads[0]
    assert p.fit is not None and len(p.fit.levels) == 3 and len(p.ringdowns) == 1
    assert abs(p.fit.get("f0_hz") - 80.0) < 0.1


@pytest.mark.parametrize("old, new, words", [
    ('excitation = "first-harmonic"', 'excitation = "first-harmonic"\ncontrol = "velocity"',
     ["control", "'velocity'", "record 0"]),
    ('excitation = "first-harmonic"', 'excitation = "first-harmonics"',
     ["excitation", "'first-harmonics'", "did you mean 'first-harmonic'?", "record 0"]),
    ('excitation = "first-harmonic"\ncontrol = "force"', 'excitation = "first-harmonic"\ncontrol = "forse"',
     ["control", "'forse'", "did you mean 'force'?", "record 0"]),
], ids=["control unknown", "excitation misspelt", "control misspelt"])
def test_a_bad_manifest_choice_fails_its_record_only(tmp_path, old, new, words):
    camp = _campaign(tmp_path / "camp")
    if "control" in old:
        _edit_manifest(camp, 'excitation = "first-harmonic"', 'excitation = "first-harmonic"\ncontrol = "force"')
    _edit_manifest(camp, old, new)
    assert is_first_harmonic_campaign(load_campaign(camp))  # was: "also has ['stepped-sine'] records"
    res = _identify(camp)
    rec = _by_file(res)
    err = rec["records/0000.csv"].error
    assert not rec["records/0000.csv"].ok and err.startswith("records/0000.csv [record 0]: ")
    for w in words:
        assert w in err
    assert "stepped-sine'] records" not in err
    assert res.preloads[0].fit is not None and len(res.preloads[0].fit.levels) == 3


def test_a_ringdown_of_another_mode_is_not_used(tmp_path):
    camp = _campaign(tmp_path / "camp")
    t = np.arange(0, 3.0, 1 / 2000)
    x = 30 * np.exp(-0.002 * 2 * np.pi * 200 * t) * np.sin(2 * np.pi * 200 * t)
    x = x + 1e-3 * np.random.default_rng(1).standard_normal(t.size)
    write_csv_record(camp / "records/0010.csv", t, {"accel": x})
    res = _identify(camp)  # was accepted: a backbone drawn from the leakage of the 200 Hz mode, exit 0
    rec = _by_file(res)["records/0010.csv"]
    assert not rec.ok
    assert rec.error.startswith("records/0010.csv [record 4, channel 'accel']: ")
    assert "200 Hz" in rec.error and "another mode" in rec.error
    assert not res.preloads[0].ringdowns


def test_a_physical_first_harmonic_campaign_is_refused(tmp_path, capsys):
    camp = _campaign(tmp_path / "camp")
    _edit_manifest(camp, 'coordinates = "modal"',
                   'coordinates = "physical"\n[structure]\nforce_column = "force"\n'
                   'mode_shape = { force = 0.02, accel = 2.0 }\n[structure.sensors]\naccel = 0.5\n')
    with pytest.raises(IdentificationError, match=r"coordinates = \"physical\".*\[structure\]"):
        is_first_harmonic_campaign(load_campaign(camp))
    code = main(["identify", str(camp), "--out", str(tmp_path / "o"), "--figures", "none", "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and "campaign.toml" in err and "physical" in err and "Traceback" not in err


def test_a_campaign_of_ringdowns_only_has_nothing_to_identify(tmp_path, capsys):
    camp = _campaign(tmp_path / "camp")
    text = (camp / "campaign.toml").read_text()
    head = text.split("[[record]]")[0]
    (camp / "campaign.toml").write_text(head + '[[record]]\nfile = "records/0010.csv"\nexcitation = "ringdown"\n'
                                               'preload = "beam"\n')
    code = main(["identify", str(camp), "--out", str(tmp_path / "o"), "--figures", "none", "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and "only ring-down records" in err and "nothing to identify" in err
    assert not (tmp_path / "o" / "results.json").exists()


def test_the_verdict_line_names_the_model_and_why_it_does_not_hold(tmp_path, capsys, fast_identify):
    camp = _campaign(tmp_path / "camp", ringdown=False)
    path = camp / "records/0003.csv"  # a smooth misfit along frequency in the top level: not white
    rows = path.read_text().splitlines()
    out = [rows[0]]
    for k, ln in enumerate(rows[1:]):
        cells = ln.split(",")
        cells[3] = "%.17g" % (float(cells[3]) * (1 + 0.08 * np.sin(2 * np.pi * k / 15)))
        out.append(",".join(cells))
    path.write_text("\n".join(out) + "\n")
    code = main(["identify", str(camp), "--out", str(tmp_path / "o"), "--figures", "none"])
    err = capsys.readouterr().err
    assert code == 1
    assert "None" not in err and "0 preload model(s)" not in err
    assert "1 nonlinear-mode model(s) of 1 preload(s)" in err
    line = next(ln for ln in err.splitlines() if "does NOT hold" in ln)
    assert line.startswith("preload beam: the nonlinear-mode (amplitude-dependent natural frequency, law poly2, "
                           "and damping ratio, law poly1) model used does NOT hold: ")
    assert "not white along frequency" in line and "lag-1" in line and "limit" in line
    s = json.loads((tmp_path / "o" / "results.json").read_text())
    a = s["adequacy"][0]
    assert a["adequate"] is False and a["model"].startswith("nonlinear-mode") and a["verdict"] in line


def test_no_verdict_line_when_the_model_holds(tmp_path, capsys, fast_identify):
    camp = _campaign(tmp_path / "camp", ringdown=False)
    code = main(["identify", str(camp), "--out", str(tmp_path / "o"), "--figures", "none"])
    err = capsys.readouterr().err
    assert code == 0 and "does NOT hold" not in err and "None" not in err
    assert "1 nonlinear-mode model(s)" in err and "0 preload model(s)" not in err
    a = json.loads((tmp_path / "o" / "results.json").read_text())["adequacy"][0]
    assert a["adequate"] is True and a["verdict"].startswith("the residuals are white") and "nonlinear-mode" in a["model"]
