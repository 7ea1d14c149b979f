"""What the command line prints: warnings counted per group, repeated errors as one line with
a count, the paper's band average named and flagged, failures shown even with --quiet,
progress as plain lines in logs, natural term algebra accepted and nonsense refused."""

from __future__ import annotations

import numpy as np
import pytest

from jointid.app.synthesis import load_simulation_config, simulate_campaign
from jointid.cli import EXIT_INPUT, EXIT_OK, EXIT_PARTIAL, main
from jointid.io.campaign import write_campaign, write_csv_record

from conftest import consistent_record

CONFIG = {
    "campaign": {"name": "console test"},
    "model": [{"preload": 120, "terms": "q + -q^3 + q'", "omega1": 170.0, "coefficients": {"k3": 5e6},
               "amplitude_laws": {"c": [0.08, 70.0, 1e4]}}],
    "excitation": {"force_levels": [1.0], "omega_start": 160.0, "omega_stop": 180.0, "n_frequencies": 12},
    "acquisition": {"fs": 2000.0, "periods": 20.0, "noise": 0.01, "seed": 5, "n_harmonics": 7},
}


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    return simulate_campaign(load_simulation_config(CONFIG), tmp_path_factory.mktemp("console") / "campaign")


@pytest.fixture
def broken(tmp_path):
    """A campaign whose 12 records all lack the force column, and one good record."""
    t, Q, a, _, _ = consistent_record([900.0, 1e3, 0.5], omega=31.0, fs=1000.0, duration=3.0)
    write_csv_record(tmp_path / "good.csv", t, {"force": Q, "accel": a})
    entries = [{"file": "good.csv", "preload": 1, "force_level": 1.0}]
    for i in range(12):
        write_csv_record(tmp_path / f"r{i:02d}.csv", t, {"accel": np.sin(2 * np.pi * (25 + 0.2 * i) * t)})
        entries.append({"file": f"r{i:02d}.csv", "preload": 1, "force_level": 1.0})
    write_campaign(tmp_path, "broken", entries)
    return tmp_path


def test_identify_prints_band_average_as_such_and_warnings_per_group(campaign, tmp_path, capsys):
    code = main(["identify", str(campaign), "--out", str(tmp_path / "out"), "--no-figures"])
    out = capsys.readouterr().out
    assert code in (EXIT_OK, EXIT_PARTIAL)
    assert "k3 band avg" in out and "the paper's Table 5 number" in out
    band = [line for line in out.splitlines() if "band average" in line and "preload 120" in line]
    assert len(band) == 1 and "N/m³" in band[0] and "±" in band[0]
    warn = [line for line in out.splitlines() if " x k3 not resolved by the data" in line]
    assert len(warn) == 1 and warn[0].strip().startswith("preload 120, F = 1 N:")  # one line per group and kind


def test_repeated_errors_are_one_line_with_a_count_even_when_quiet(broken, tmp_path, capsys):
    for quiet in ([], ["--quiet"]):
        code = main(["identify", str(broken), "--out", str(tmp_path / f"out{len(quiet)}"), "--no-figures",
                     "--no-reprediction"] + quiet)
        captured = capsys.readouterr()
        text = captured.out + captured.err
        lines = [line for line in text.splitlines() if "force" in line and "record" in line.lower()
                 and ("missing" in line or "column" in line or "failed" in line.lower())]
        assert code == EXIT_PARTIAL, text
        assert len(lines) == 1, text  # twelve failures, one line
        assert "12 records" in lines[0]


def test_simulate_progress_is_plain_lines_in_a_log(tmp_path, capsys):
    cfg = tmp_path / "sim.toml"
    cfg.write_text("[[model]]\nomega1 = 170.0\ncoefficients = { k3 = 5e6, c = 0.5 }\n"
                   "[excitation]\nforce_levels = [1.0, 2.0]\nomega_start = 165.0\nomega_stop = 175.0\n"
                   "n_frequencies = 3\n[acquisition]\nfs = 1000.0\nperiods = 4\n", encoding="utf-8")
    assert main(["simulate", str(cfg), "--out", str(tmp_path / "camp")]) == EXIT_OK
    err = capsys.readouterr().err
    assert "steady states: 2/2 (100 %)" in err
    assert "\r" not in err and "\x1b" not in err


def test_natural_term_algebra_on_the_command_line(campaign, tmp_path, capsys):
    code = main(["identify", str(campaign), "--out", str(tmp_path / "a"), "--no-figures", "--no-reprediction",
                 "--quiet", "--terms", "q - q^3 + q'"])
    assert code in (EXIT_OK, EXIT_PARTIAL)
    code = main(["identify", str(campaign), "--out", str(tmp_path / "b"), "--no-figures", "--terms", "q + qq^3"])
    err = capsys.readouterr().err
    assert code == EXIT_INPUT and "qq^3" in err



def test_a_preload_whose_model_cannot_be_fitted_says_why_naming_it_once(tmp_path):
    """One record: its group is identified, the preload's model (laws over its records) cannot be, and
    results.json says why, naming the preload once (it read "preload 120: preload 120: ...")."""
    import json

    from jointid.app.paper_example import paper_config
    from jointid.app.synthesis import load_simulation_config, simulate_campaign
    from jointid.cli import main

    cfg = paper_config(n_frequencies=1, fs=2000.0, periods=15, noise=0.01, seed=3)
    cfg["excitation"]["force_levels"] = cfg["excitation"]["force_levels"][:1]
    camp = simulate_campaign(load_simulation_config(cfg), tmp_path / "camp")
    main(["identify", str(camp), "--out", str(tmp_path / "res"), "--quiet", "--figures", "none", "--no-reprediction"])
    models = json.loads((tmp_path / "res" / "results.json").read_text())["models"]
    errors = [m["error"] for m in models if m.get("error")]
    assert errors and all("needs at least" in e and e.count("preload ") == 1 for e in errors), errors
