"""Set-up of a new user: the example files come with the package, every command-line option
says what it does, the package's names are discoverable, ``backbone`` takes a results folder,
``modal`` writes where it says, and ``identify`` says what it is doing."""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import pytest

import jointid
from jointid.cli import EXIT_INPUT, EXIT_OK, EXIT_PARTIAL, build_parser, main

REPO = Path(__file__).resolve().parents[1]

CONFIG = """\
[[model]]
preload = 120
terms = "q + -q^3 + q'"
omega1 = 170.0
coefficients = { k3 = 5e6 }
amplitude_laws = { c = [0.08, 70.0, 1e4] }
[excitation]
force_levels = [1.0, 2.0]
omega_start = 160.0
omega_stop = 180.0
n_frequencies = 10
[acquisition]
fs = 2000.0
periods = 20.0
noise = 0.01
seed = 5
n_harmonics = 7
"""


def _subcommands(parser):
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


def test_every_option_of_every_subcommand_has_help():
    parser = build_parser()
    missing = []
    for name, sub in {"": parser, **_subcommands(parser)}.items():
        for action in sub._actions:
            if isinstance(action, (argparse._HelpAction, argparse._SubParsersAction)):
                continue
            if not (action.help or "").strip() or action.help == argparse.SUPPRESS:
                missing.append(f"jointid {name} {'/'.join(action.option_strings) or action.dest}")
    assert not missing, "options without help text: " + ", ".join(missing)
    assert {"identify", "simulate", "example", "backbone", "modal", "demo", "study", "import"} <= set(_subcommands(parser))


def test_public_data_options_have_help(monkeypatch):
    """``public-data`` has its own parser (jointid.app.public_data.main): caught as it parses."""
    seen = []

    def catch(self, args=None, namespace=None):
        seen.append(self)
        raise SystemExit(0)

    monkeypatch.setattr(argparse.ArgumentParser, "parse_args", catch)
    with pytest.raises(SystemExit):
        main(["public-data", "--help"])
    (parser,) = seen
    missing = [a.option_strings for a in parser._actions if not (a.help or "").strip()]
    assert {"--out", "--only"} <= {o for a in parser._actions for o in a.option_strings}
    assert not missing, missing


def test_public_names_are_listed_and_import_stays_light():
    names = dir(jointid)
    for name in ("identify_campaign", "IdentifySettings", "simulate_campaign", "load_campaign", "frequency_response",
                 "ForceStateMapping", "JointidError", "__version__"):
        assert name in names and name in jointid.__all__
    for name in jointid.__all__:  # every listed name resolves
        assert getattr(jointid, name) is not None, name
    with pytest.raises(AttributeError, match="no attribute 'nonsense'"):
        jointid.nonsense  # noqa: B018
    code = ("import sys, jointid; assert 'identify_campaign' in dir(jointid); "
            "heavy = [m for m in ('numpy', 'scipy', 'matplotlib', 'jointid.app') if m in sys.modules]; "
            "assert not heavy, heavy")
    subprocess.run([sys.executable, "-c", code], check=True)


def test_example_files_come_with_the_package_and_are_copied_without_overwriting(tmp_path, monkeypatch, capsys):
    shipped = jointid.example_files()
    assert {"noisy_softening.toml", "unesp_import.toml", "study.toml"} <= set(shipped)
    assert all(shipped.values())  # each says what it is
    # the repository's examples/ is the package's folder: one copy of each file
    assert (REPO / "examples").resolve() == (REPO / "src" / "jointid" / "examples").resolve()
    monkeypatch.chdir(tmp_path)
    assert main(["example", "--list"]) == EXIT_OK
    listed = capsys.readouterr().out
    assert all(name in listed for name in shipped)
    assert main(["example", "--copy", "all"]) == EXIT_OK
    for name in shipped:
        copied = (tmp_path / "examples" / name).read_bytes()
        assert copied == (REPO / "src" / "jointid" / "examples" / name).read_bytes()
    (tmp_path / "examples" / "study.toml").write_text("# mine\n", encoding="utf-8")
    capsys.readouterr()
    assert main(["example", "--copy", "study.toml"]) == EXIT_INPUT
    err = capsys.readouterr().err
    assert "study.toml" in err and "exists" in err
    assert (tmp_path / "examples" / "study.toml").read_text(encoding="utf-8") == "# mine\n"  # left as it was
    assert main(["example", "--copy", "noisy_softening.toml", "study.toml", "--to", "mine"]) == EXIT_OK
    assert sorted(p.name for p in (tmp_path / "mine").iterdir()) == ["noisy_softening.toml", "study.toml"]
    assert main(["example", "--copy", "no_such.toml"]) == EXIT_INPUT
    assert "no_such.toml" in capsys.readouterr().err
    assert not (tmp_path / "example-out").exists()  # --list / --copy do not run the numerical example


@pytest.fixture(scope="module")
def identified(tmp_path_factory):
    """A small simulated campaign identified with the summary figures, and with all figures."""
    root = tmp_path_factory.mktemp("setup")
    (root / "sim.toml").write_text(CONFIG, encoding="utf-8")
    assert main(["simulate", str(root / "sim.toml"), "--out", str(root / "camp"), "--quiet"]) == EXIT_OK
    codes = {level: main(["identify", str(root / "camp"), "--out", str(root / f"res-{level}"), "--figures", level,
                          "--no-reprediction"]) for level in ("summary", "all")}
    return root, codes


def test_identify_says_what_it_is_doing_and_figure_levels(identified, capsys):
    root, codes = identified
    assert set(codes.values()) <= {EXIT_OK, EXIT_PARTIAL}
    summary = {p.name for p in (root / "res-summary" / "figures").iterdir()}
    every = {p.name for p in (root / "res-all" / "figures").iterdir()}
    assert summary and summary < every
    assert not any(n.startswith(("parameters_", "hysteresis_")) for n in summary)
    assert any(n.startswith("parameters_") for n in every)
    # the figure level changes no number
    a, b = (json.loads((root / f"res-{lv}" / "results.json").read_text()) for lv in ("summary", "all"))
    a.pop("run_id"), b.pop("run_id"), a.pop("provenance"), b.pop("provenance")
    assert a == b
    capsys.readouterr()
    out = root / "res-quiet"
    assert main(["identify", str(root / "camp"), "--out", str(out), "--no-figures", "--no-reprediction"]) in (0, 1)
    err = capsys.readouterr().err
    stages = [line for line in err.splitlines() if line.startswith("jointid identify: ")]
    assert len(stages) >= 3 and all(line.endswith("s in all]") for line in stages), err
    assert "identified" in err and "written" in err
    assert main(["identify", str(root / "camp"), "--out", str(out), "--no-figures", "--no-reprediction",
                 "--quiet"]) in (0, 1)
    assert "jointid identify: " not in capsys.readouterr().err


def test_backbone_takes_a_results_folder_and_has_a_default_output(identified, tmp_path, monkeypatch, capsys):
    root, _ = identified
    res = root / "res-summary"
    assert main(["backbone", str(res), "--quiet"]) == EXIT_OK
    default = root / "res-summary-backbone"
    assert sorted(p.name for p in default.iterdir() if p.suffix != ".png") == [".jointid-run", "backbones.json"]
    assert list(default.glob("backbone_*.png"))
    assert main(["backbone", str(res / "results.json"), "--out", str(tmp_path / "bb"), "--quiet"]) == EXIT_OK
    assert list((tmp_path / "bb").glob("backbone_*.png"))
    capsys.readouterr()
    assert main(["backbone", str(root / "camp")]) == EXIT_INPUT  # a folder without results.json
    err = capsys.readouterr().err
    assert "results.json" in err and "Errno" not in err
    assert main(["backbone", str(tmp_path / "missing")]) == EXIT_INPUT
    assert "no such file" in capsys.readouterr().err


def test_modal_writes_to_a_default_folder(tmp_path, monkeypatch, capsys):
    (tmp_path / "beam.toml").write_text("[structure]\nmodel = 'seed-bolted-beam'\nforce_position = 0.05\n"
                                        "sensors = { accel_42 = 0.42 }\n", encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    assert main(["modal", "beam.toml"]) == EXIT_OK
    assert "written to modal-out" in capsys.readouterr().out
    assert (tmp_path / "modal-out" / "modal.json").is_file()
