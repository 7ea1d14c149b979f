"""Monte Carlo studies: plans, truth, comparisons, statistics, resumption (in this process)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from jointid.app.study import (
    StudyPlan,
    comparison_rows,
    load_study_plan,
    read_campaign_lines,
    run_campaign,
    run_study,
    study_statistics,
)
from jointid.cli import main
from jointid.errors import ManifestError


def small_plan(campaigns=4, seed=3, noise=0.01, **extra) -> dict:
    """A small study: one preload, 1-2 levels of 5 frequencies, short records."""
    d = {
        "study": {"name": "small", "campaigns": campaigns, "seed": seed},
        "model": [{"preload": "sim", "omega1": 170.0, "coefficients": {"k3": 5e6},
                   "amplitude_laws": {"c": [0.08, 70.0, 1e4]}}],
        "excitation": {"force_levels": [1.0, 2.0], "omega_start": 162.0, "omega_stop": 178.0, "n_frequencies": 5},
        "acquisition": {"fs": 1500.0, "periods": 10, "noise": noise},
        "vary": {
            "acquisition.noise": {"loguniform": [0.003, 0.02]},
            "model.coefficients.k3": {"uniform": [3e6, 6e6], "random_sign": True},
            "excitation.force_levels": {"uniform": [0.6, 2.0], "size": [1, 2]},
            "acquisition.write_frequency": {"choice": [True, False]},
        },
    }
    d.update(extra)
    return d


def test_noise_free_campaign_recovers_its_truth():
    """Without noise every estimate equals the simulated truth: the comparisons pair the right values."""
    d = small_plan(noise=0.0)
    d.pop("vary")
    line = run_campaign(StudyPlan.from_mapping(d), 0)
    assert line["status"] == "ok", line["error"]
    names = {r["parameter"] for r in line["rows"]}
    assert {"groups.omega1", "groups.k3", "damping_law.c0", "damping_law.c1", "damping_law.c2", "records.c_pooled",
            "records.coefficients.omega1^2", "records.coefficients.k3", "records.coefficients.c"} <= names
    assert len([r for r in line["rows"] if r["parameter"] == "groups.k3"]) == 2
    for r in line["rows"]:
        assert r["estimate"] == pytest.approx(r["truth"], rel=1e-7), r
    truth = {r["parameter"]: r["truth"] for r in line["rows"] if not r["parameter"].startswith("records")}
    assert truth["groups.omega1"] == 170.0 and truth["groups.k3"] == 5e6
    assert [truth[f"damping_law.c{k}"] for k in range(3)] == [0.08, 70.0, 1e4]


def _truth():
    return {"preloads": [{"preload": 120, "coefficients": {"omega1^2": 170.0**2, "k3": 5e6}, "laws": {"c": [0.1, 50.0]}}],
            "records": [{"index": 0, "preload": 120, "force_level": 1.0, "q_max": 0.01,
                         "coefficients": {"omega1^2": 170.0**2, "k3": 5e6, "c": 0.6}}]}


def test_comparison_rows_read_models_and_intervals():
    """Preload models, *_ci95 intervals and records' c_stderr are compared when the results give them."""
    summary = {
        "groups": [{"preload": 120, "force_level": 1.0, "omega1": 170.2, "omega1_stderr": 0.1,
                    "omega1_ci95": [169.95, 170.45], "k3": 5.1e6, "k3_stderr": 0.1e6}],
        "damping_law": [{"preload": 120, "coefficients": [0.11, 49.0, 100.0], "stderr": [0.01, 2.0, 10.0]}],
        "models": [{"preload": 120, "omega1": 170.05, "omega1_stderr": 0.01, "omega1_ci95": [170.03, 170.07],
                    "k3": 4.9e6, "k3_stderr": 0.2e6, "k3_ci95": [4.5e6, 5.3e6],
                    "damping_coefficients": [0.1, 51.0, 0.0], "damping_stderr": [0.01, 1.0, 1.0],
                    "damping_ci95": [[0.08, 0.12], [49.0, 53.0], [-2.0, 2.0]]}],
        "records": [{"index": 0, "status": "ok", "omega1": 170.1, "omega1_stderr": 0.05, "c": 0.7, "c_stderr": 0.2, "c_pooled": 0.61, "c_pooled_stderr": 0.02,
                     "coefficients": {"omega1^2": 28900.0, "k3": 4e6, "c": 0.7},
                     "stderr": {"omega1^2": 1.0, "k3": 1e6, "c": 0.2}}],
    }
    rows = {(r["parameter"], r["where"]): r for r in comparison_rows(summary, _truth())}
    g = rows[("groups.omega1", "preload=120, force_level=1.0")]
    assert g["z"] == pytest.approx(2.0) and g["covered"] is True  # the interval decides, not |z|
    assert rows[("groups.k3", "preload=120, force_level=1.0")]["covered"] is True  # |z| = 1 <= 1.96
    assert rows[("damping_law.c2", "preload=120")]["truth"] == 0.0  # the true law is of order 1
    assert rows[("damping_law.c2", "preload=120")]["covered"] is False  # z = 10
    assert rows[("models.omega1", "preload=120")]["covered"] is False  # 170 outside [170.03, 170.07]
    assert rows[("models.k3", "preload=120")]["z"] == pytest.approx(-0.5)
    assert rows[("models.damping.c1", "preload=120")]["ci95"] == [49.0, 53.0]
    assert rows[("models.damping.c1", "preload=120")]["covered"] is True
    assert rows[("records.c", "record 0")]["z"] == pytest.approx(0.5)
    assert rows[("records.omega1", "record 0")]["z"] == pytest.approx(2.0)
    assert rows[("records.omega1", "record 0")]["covered"] is False
    assert rows[("records.c_pooled", "record 0")]["z"] == pytest.approx(0.5)
    assert rows[("records.coefficients.k3", "record 0")]["z"] == pytest.approx(-1.0)
    # a missing estimate (failed group) is kept as missing, not turned into a number
    summary["groups"][0].update(omega1=None, omega1_stderr=None, omega1_ci95=None)
    r = [r for r in comparison_rows(summary, _truth()) if r["parameter"] == "groups.omega1"][0]
    assert r["estimate"] is None and r["z"] is None and r["covered"] is None


def test_statistics_of_known_rows():
    def row(est, se, truth=1.0, ci=None):
        z = (est - truth) / se
        return {"parameter": "p", "where": "", "estimate": est, "stderr": se, "ci95": ci, "truth": truth, "z": z,
                "covered": bool(abs(z) <= 1.96)}

    lines = [{"index": 1, "grid_point": 0, "rows": [row(1.2, 0.1), row(0.9, 0.1)]},
             {"index": 0, "grid_point": 0, "rows": [row(1.0, 0.2), {**row(1.0, 1.0), "estimate": None, "z": None,
                                                                      "covered": None}]}]
    (s,) = study_statistics(lines)
    err = np.array([0.0, 0.2, -0.1])
    assert s["n"] == 4 and s["n_missing"] == 1 and s["n_z"] == 3
    assert s["bias"] == pytest.approx(err.mean())
    assert s["rmse"] == pytest.approx(np.sqrt(np.mean(err**2)))
    assert s["std_z"] == pytest.approx(np.std([0.0, 2.0, -1.0], ddof=1))
    assert s["coverage"] == pytest.approx(2 / 3)
    assert s["coverage_low"] < 2 / 3 < s["coverage_high"]
    assert study_statistics(list(reversed(lines))) == study_statistics(lines)


def test_campaign_seeds_and_draws_are_reproducible():
    plan = StudyPlan.from_mapping(small_plan(campaigns=5, seed=11))
    children = np.random.SeedSequence(11).spawn(5)
    assert [plan.campaign_seed(i) for i in range(5)] == [int(c.generate_state(1, np.uint64)[0]) for c in children]
    a, b = plan.draw(3), StudyPlan.from_mapping(small_plan(campaigns=50, seed=11)).draw(3)
    assert a == b  # more campaigns do not change the earlier ones
    tables, drawn, point = a
    assert 0.003 <= drawn["acquisition.noise"] <= 0.02 and tables["acquisition"]["noise"] == drawn["acquisition.noise"]
    assert 3e6 <= abs(tables["model"][0]["coefficients"]["k3"]) <= 6e6
    assert 1 <= len(drawn["excitation.force_levels"]) <= 2
    assert drawn["excitation.force_levels"] == sorted(drawn["excitation.force_levels"])
    assert plan.draw(4)[1] != a[1]
    assert plan.fingerprint == StudyPlan.from_mapping(small_plan(campaigns=50, seed=11)).fingerprint
    assert plan.fingerprint != StudyPlan.from_mapping(small_plan(seed=12)).fingerprint


def test_grid_points_cycle_over_the_campaigns():
    plan = StudyPlan.from_mapping(small_plan(campaigns=2, grid={"excitation.n_frequencies": [4, 5],
                                                                "acquisition.periods": [8, 12, 16]}))
    assert len(plan.points) == 6 and plan.n_campaigns == 12
    tables, drawn, k = plan.draw(7)
    assert k == 1 and plan.points[1] == {"excitation.n_frequencies": 4, "acquisition.periods": 12}
    assert tables["acquisition"]["periods"] == 12 and tables["excitation"]["n_frequencies"] == 4


@pytest.mark.parametrize("change, match", [
    ({"vary": {"acquisition.noize": {"uniform": [0, 1]}}}, "did you mean 'noise'"),
    ({"vary": {"acquisition.noise": {"uniform": [0.1]}}}, "two finite numbers"),
    ({"vary": {"acquisition.noise": {"gauss": [0, 1]}}}, "unknown key 'gauss'"),
    ({"vary": {"acquisition.noise": {"loguniform": [0.0, 1.0]}}}, "0 < low"),
    ({"vary": {"excitation.force_levels": {"uniform": [1, 2], "size": [3, 2]}}}, "size"),
    ({"grid": {"acquisition.fs": []}}, "non-empty list"),
    ({"studdy": {}}, "did you mean 'study'"),
    ({"vary": {"model.omega1.x": {"uniform": [1, 2]}}}, "below a value"),
    ({"identify": {"harmonics": 5}}, "did you mean 'n_harmonics'"),
    ({"study": {"campaigns": 0}}, "at least 1"),
    ({"acquisition": {"fs": 20.0}}, "below twice"),
])
def test_plan_errors_name_the_file_and_key(tmp_path, change, match):
    d = small_plan()
    d.update(change)
    with pytest.raises(ManifestError, match=match):
        StudyPlan.from_mapping(d, source="plan.toml")
    with pytest.raises(ManifestError, match="plan.toml"):
        StudyPlan.from_mapping(d, source="plan.toml")


def test_study_is_resumed_and_extended(tmp_path):
    """An interrupted results file (a line cut short) is resumed; more campaigns run only the new ones."""
    plan = small_plan(campaigns=3)
    first = run_study(plan, tmp_path / "a", report=False)
    assert first.n_run == 3 and not first.failed
    text = (tmp_path / "a" / "campaigns.jsonl").read_text()
    lines = text.splitlines(keepends=True)
    assert [json.loads(x)["index"] for x in lines] == [0, 1, 2]
    assert len({json.loads(x)["seed"] for x in lines}) == 3
    (tmp_path / "b").mkdir()
    (tmp_path / "b" / "campaigns.jsonl").write_text(lines[2] + lines[0] + lines[1][: len(lines[1]) // 2])
    again = run_study(plan, tmp_path / "b", report=False)
    assert again.n_run == 1
    assert (tmp_path / "b" / "campaigns.jsonl").read_text() == text
    assert again.statistics == first.statistics
    more = run_study(small_plan(campaigns=4), tmp_path / "b", report=False)
    assert more.n_run == 1 and len(more.campaigns) == 4
    assert more.campaigns[:3] == first.campaigns
    with pytest.raises(ManifestError, match="another plan"):
        run_study(small_plan(campaigns=3, seed=4), tmp_path / "b", report=False)
    (tmp_path / "c").mkdir()
    (tmp_path / "c" / "campaigns.jsonl").write_text("{not json\n" + lines[0])
    with pytest.raises(ManifestError, match=r"campaigns.jsonl \[line 1\]"):
        read_campaign_lines(tmp_path / "c" / "campaigns.jsonl")


def test_cli_study_writes_report_and_flags_failed_campaigns(tmp_path, capsys):
    """A campaign that cannot be simulated is reported as failed; the others still give the statistics."""
    plan = tmp_path / "plan.toml"
    plan.write_text("""
[study]
name = "cli <study>"
campaigns = 2
seed = 5
[[model]]
omega1 = 170.0
coefficients = { k3 = 5e6, c = 0.5 }
[excitation]
force_levels = [1.0]
omega_start = 162.0
omega_stop = 178.0
n_frequencies = 4
[acquisition]
fs = 1500.0
periods = 8
noise = 0.01
[grid]
"acquisition.fs" = [1500.0, 50.0]
""")
    out = tmp_path / "out"
    assert main(["study", str(plan), "--out", str(out)]) == 1
    printed = capsys.readouterr().out
    assert "groups.omega1" in printed and "failed" in printed
    study = json.loads((out / "study.json").read_text())
    assert study["n_campaigns"] == 4 and study["n_failed"] == 2
    assert all("below twice the highest excitation frequency" in e for e in study["errors"])
    stats = {s["parameter"]: s for s in study["statistics"] if s["grid_point"] == 0}
    assert stats["groups.omega1"]["n"] == 2 and stats["damping_law.c0"]["n"] == 2
    assert "damping_law.c1" in stats  # the constant damping's true law has c1 = c2 = 0
    html = (out / "report.html").read_text()
    assert "cli &lt;study&gt;" in html and "data:image/png;base64," in html and "http" not in html.split("<body>")[1]
    assert (out / "statistics.csv").read_text().startswith("grid_point,parameter,")
    assert load_study_plan(plan).n_campaigns == 4
    assert main(["study", str(tmp_path / "missing.toml"), "--out", str(out)]) == 2


def test_example_plan_reads(tmp_path):
    from pathlib import Path

    plan = load_study_plan(Path(__file__).resolve().parents[1] / "examples" / "study.toml")
    assert plan.n_campaigns == 200 and len(plan.vary) == 7
    tables, drawn, _ = plan.draw(0)
    assert 2 <= len(tables["excitation"]["force_levels"]) <= 4


def test_progress_in_a_log_is_plain_lines():
    import io

    from jointid.app.parallel import progress_bar

    log = io.StringIO()
    bar = progress_bar(20, "campaigns", file=log)
    for _ in range(20):
        bar.update()
    bar.close()
    lines = log.getvalue().splitlines()
    assert "\r" not in log.getvalue() and 2 <= len(lines) <= 11
    assert lines[-1].startswith("campaigns: 20/20 (100 %)")
    quiet = io.StringIO()
    progress_bar(5, "x", enabled=False, file=quiet).update()
    assert quiet.getvalue() == ""
