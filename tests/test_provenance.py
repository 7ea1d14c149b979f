"""Who ran what: ``provenance`` in results.json and study.json, a line in the reports, and a
resumed study refused when its campaigns were made by other jointid code."""

from __future__ import annotations

import json

import pytest

from jointid.app.provenance import code_fingerprint
from jointid.cli import main

PLAN = """
[study]
name = "provenance"
campaigns = {n}
seed = 4

[[model]]
preload = "sim"
omega1 = 170.0
coefficients = {{ k3 = 5e6 }}
amplitude_laws = {{ c = [0.08, 70.0, 1e4] }}

[excitation]
force_levels = [1.0, 2.0]
omega_start = 160.0
omega_stop = 180.0
n_frequencies = 5

[acquisition]
fs = 2000.0
periods = 10
noise = 0.01
"""

KEYS = {"versions", "code_fingerprint", "plan_fingerprint", "host", "executor", "workers", "wall_s", "cpu_s"}


def _check(p, executor="in-process"):
    assert KEYS <= set(p)
    assert set(p["versions"]) == {"jointid", "numpy", "scipy", "dask", "distributed", "python"}
    assert p["versions"]["numpy"] and p["versions"]["python"]
    assert p["code_fingerprint"] == code_fingerprint() and len(p["code_fingerprint"]) == 16
    assert p["executor"] == executor and p["workers"] == 1
    assert p["wall_s"] > 0 and p["cpu_s"] > 0 and p["host"]


@pytest.mark.filterwarnings("ignore::jointid.errors.JointidWarning")
def test_identify_records_its_provenance(tmp_path, capsys):
    from jointid.app.paper_example import paper_config
    from jointid.app.synthesis import load_simulation_config, simulate_campaign

    cfg = paper_config(n_frequencies=4, noise=0.01, seed=1, write_frequency=False, periods=8)
    camp = simulate_campaign(load_simulation_config(cfg), tmp_path / "camp")
    out = tmp_path / "res"
    assert main(["identify", str(camp), "--out", str(out), "--no-figures", "--no-reprediction", "--quiet"]) in (0, 1)
    res = json.loads((out / "results.json").read_text())
    _check(res["provenance"])
    assert res["provenance"]["plan_fingerprint"] is None
    for name in ("report.txt", "report.html"):
        assert f"code {code_fingerprint()}" in (out / name).read_text()


def test_study_records_its_provenance_and_refuses_to_mix_code_versions(tmp_path, capsys):
    plan = tmp_path / "plan.toml"
    plan.write_text(PLAN.format(n=2))
    out = tmp_path / "study"
    assert main(["study", str(plan), "--out", str(out), "--no-report"]) == 0
    stdout = capsys.readouterr().out
    assert f"code {code_fingerprint()}" in stdout
    study = json.loads((out / "study.json").read_text())
    _check(study["provenance"])
    assert study["provenance"]["plan_fingerprint"] == study["plan_fingerprint"]
    lines = [json.loads(t) for t in (out / "campaigns.jsonl").read_text().splitlines()]
    assert [line["code"] for line in lines] == [code_fingerprint()] * 2

    # the same campaigns as if made by another jointid: a resume with more campaigns is refused
    for line in lines:
        line["code"] = "0123456789abcdef"
    (out / "campaigns.jsonl").write_text("".join(json.dumps(line) + "\n" for line in lines))
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    plan.write_text(PLAN.format(n=3))
    assert main(["study", str(plan), "--out", str(out), "--no-report", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "other jointid code" in err and "0123456789abcdef" in err and "--allow-version-mix" in err
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()} == before  # nothing run, nothing changed
    assert main(["study", str(plan), "--out", str(out), "--no-report", "--quiet", "--allow-version-mix"]) == 0
    codes = [json.loads(t)["code"] for t in (out / "campaigns.jsonl").read_text().splitlines()]
    assert codes == ["0123456789abcdef"] * 2 + [code_fingerprint()]


def test_the_code_fingerprint_follows_the_source(tmp_path, monkeypatch):
    """A changed source file changes the fingerprint (a development checkout keeps its version number)."""
    import shutil
    from pathlib import Path

    import jointid
    from jointid.app import provenance

    pkg = Path(jointid.__file__).parent
    copy = tmp_path / "jointid"
    shutil.copytree(pkg, copy, ignore=shutil.ignore_patterns("__pycache__", "*.png", "*.csv", "*.h5"))

    def fingerprint_of(root):
        monkeypatch.setattr(provenance, "__file__", str(root / "app" / "provenance.py"))
        provenance.code_fingerprint.cache_clear()
        try:
            return provenance.code_fingerprint()
        finally:
            provenance.code_fingerprint.cache_clear()

    a = fingerprint_of(copy)
    (copy / "app" / "records.py").write_text((copy / "app" / "records.py").read_text() + "\n# changed\n")
    b = fingerprint_of(copy)
    assert a == fingerprint_of(pkg) and a != b
