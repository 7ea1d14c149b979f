"""``jointid modal --frf`` on the virtual rig's random test: the first modes of a lightly damped beam."""

from __future__ import annotations

import json

import numpy as np
import pytest

from jointid.cli import main
from jointid.io.campaign import write_csv_record
from jointid.io.uff import write_uff
from jointid.rig.plan import MeasurementPlan, as_built_structure
from jointid.rig.rig import seed_rig

STRUCTURE = """
[structure]
model = "seed-bolted-beam"
force_position = {x_f}
force_column = "force"
[structure.sensors]
accel_30 = 0.30
accel_42 = 0.42
"""


@pytest.fixture(autouse=True)
def _in_a_scratch_folder(tmp_path, monkeypatch):
    """``modal`` without ``--out`` writes ``modal-out`` in the working folder: never the repository's."""
    monkeypatch.chdir(tmp_path)


@pytest.fixture(scope="module", params=[120, 540])
def random_test(request, tmp_path_factory):
    """The demo's random test (default plan: 0.1 N rms to 700 Hz, 128 s at 2048 Hz) written as UFF 58."""
    preload = request.param
    rig = seed_rig(preload)
    plan = MeasurementPlan()
    rng = np.random.default_rng(np.random.default_rng(0).spawn(2)[[120, 540].index(preload)])
    rec = rig.random_test(plan.random, plan.acquisition, rng, source="random")
    folder = tmp_path_factory.mktemp(f"random_{preload}")
    write_uff(folder / "random.uff", rec, binary=True)
    (folder / "s.toml").write_text(STRUCTURE.format(x_f=as_built_structure(rig)["force_position"]))
    return folder, rig, rec


def test_modal_frf_finds_the_first_three_modes_within_0p05_percent(random_test):
    folder, rig, _ = random_test
    out = folder / "out"
    code = main(["modal", str(folder / "s.toml"), "--frf", str(folder / "random.uff"), "--response", "accel_42",
                 "--out", str(out)])
    assert code == 0
    fit = json.loads((out / "modal.json").read_text())["frf_fit"]
    err = np.array(fit["frequencies_hz"]) / rig.linear_frequencies_hz[:3] - 1
    assert np.all(np.abs(err) < 5e-4), err
    assert all(fit["trusted"]) and min(fit["stable_orders"]) >= 6
    # the damping ratios are those of a lightly damped beam (0.15 % material + joint)
    assert np.all((np.array(fit["damping_ratios"]) > 0.001) & (np.array(fit["damping_ratios"]) < 0.003))
    # the noise peaks examined were refused, each with a reason
    refused = [c for c in fit["candidates"] if not c["trusted"]]
    assert refused and all(c["reason"] for c in refused)


def test_modal_frf_options_bands_range_and_order(random_test, capsys):
    folder, rig, _ = random_test
    f1, f2 = rig.linear_frequencies_hz[:2]
    args = ["modal", str(folder / "s.toml"), "--frf", str(folder / "random.uff"), "--response", "accel_42"]
    assert main(args + ["--bands", f"{0.95 * f1:.2f}-{1.05 * f1:.2f},{0.95 * f2:.2f}-{1.05 * f2:.2f}",
                        "--order", "4"]) == 0
    text = capsys.readouterr().out
    assert "mode 2" in text and "mode 3" not in text and "4/4" in text
    # a range holding one mode cannot give three: the message names the file and channel
    assert main(args + ["--f-range", "20", "100"]) == 2
    err = capsys.readouterr().err
    assert "random.uff" in err and "accel_42" in err and "trusted" in err
    assert main(args + ["--bands", "30-20"]) == 2
    assert "--bands" in capsys.readouterr().err


def test_modal_frf_refuses_a_noise_record(tmp_path, capsys):
    """Response unrelated to the force: no peak is trusted, the message says why."""
    rng = np.random.default_rng(3)
    fs, n = 1024.0, 2**17
    (tmp_path / "s.toml").write_text(STRUCTURE.format(x_f=0.05))
    write_csv_record(tmp_path / "noise.csv", np.arange(n) / fs,
                     {"force": rng.standard_normal(n), "accel_42": rng.standard_normal(n)})
    assert main(["modal", str(tmp_path / "s.toml"), "--frf", str(tmp_path / "noise.csv"), "--modes", "1",
                 "--response", "accel_42"]) == 2
    err = capsys.readouterr().err
    assert "noise.csv" in err and "found 0 trusted" in err
