"""The identify report as a test engineer reads it: the summary table first, units on every
figure axis, an error measure on every identified-vs-measured comparison, version, date and
run id, warnings listed; rendered by headless Chromium."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import warnings
from pathlib import Path

import pytest
from html_page import parse_page

from jointid import identify_campaign
from jointid.app.synthesis import load_simulation_config, simulate_campaign
from jointid.errors import JointidWarning
from jointid.report.output import campaign_figures, write_results

CHROMIUM = shutil.which("chromium") or ("/usr/bin/chromium" if Path("/usr/bin/chromium").exists() else None)
UNIT = re.compile(r"\[[^\]]+\]")

#: a small noisy campaign of the seed model (two force levels, 9 dwells each)
CONFIG = {
    "campaign": {"name": "report test <campaign>"},
    "model": [{"preload": 120, "terms": "q + -q^3 + q'", "omega1": 170.0, "coefficients": {"k3": 5e6},
               "amplitude_laws": {"c": [0.08, 70.0, 1e4]}}],
    "excitation": {"force_levels": [1.0, 2.0], "omega_start": 163.0, "omega_stop": 177.0, "n_frequencies": 9},
    "acquisition": {"fs": 2000.0, "periods": 30.0, "noise": 0.01, "seed": 3, "n_harmonics": 7},
}


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    root = tmp_path_factory.mktemp("report")
    camp = simulate_campaign(load_simulation_config(CONFIG), root / "campaign")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", JointidWarning)
        result = identify_campaign(camp)
    paths = write_results(result, root / "out")
    return result, paths, campaign_figures(result)


def test_summary_table_comes_first(written):
    paths = written[1]
    page = paths["html"].read_text(encoding="utf-8")
    doc = parse_page(page)
    first_table = doc.position("table")
    assert first_table < doc.position("img") and first_table < doc.heading("Appendix: settings and checks")
    first = doc.tables[0]
    assert first.caption.startswith("Identified model per preload")
    head = first.text()
    for text in ("f1", "omega1", "rad/s", "Hz", "k3", "N/m³", "c0", "N s/m", "c2", "N s/m³", "95 % interval"):
        assert text in head, text
    # values carry no more digits than the standard error supports
    assert not re.search(r"\d\.\d{9,}", head)
    # the paper's Table 5 follows, with the band average named as such
    assert doc.table("The paper's Table 5") and "band average" in page


def test_version_date_and_run_id_under_the_title(written):
    paths = written[1]
    page = paths["html"].read_text(encoding="utf-8")
    run_id = json.loads(paths["results"].read_text())["run_id"]
    doc = parse_page(page)
    meta = doc.meta
    from jointid import __version__

    assert f"jointid {__version__}" in meta and run_id in meta and re.search(r"date \d{4}-\d\d-\d\d", meta)
    assert doc.position("p", lambda text: text == meta) < doc.position("table")


def _categorical(axis):
    from matplotlib.ticker import FixedFormatter

    return isinstance(axis.get_major_formatter(), FixedFormatter)


def test_every_figure_axis_has_a_unit(written):
    figs = written[2]
    assert len(figs) >= 4
    for name, _, fig in figs:
        for ax in fig.axes:
            if not ax.axison:
                continue
            for axis, label in ((ax.xaxis, ax.get_xlabel()), (ax.yaxis, ax.get_ylabel())):
                if _categorical(axis):  # named categories (candidate models) carry no unit
                    continue
                assert UNIT.search(label), (name, label)


def test_identified_vs_measured_carries_an_error_measure(written):
    _, paths, figs = written
    for name, _, fig in figs:
        if name.startswith("hysteresis"):
            for ax in fig.axes:
                labels = [t.get_text() for t in ax.get_legend().get_texts()]
                assert any("rms difference" in t for t in labels), labels
    table = parse_page(paths["html"].read_text(encoding="utf-8")).table("re-prediction errors")
    assert any(h.startswith("peak frequency error") for h in table.header)
    loops = table.column("loop rms difference (filtered) [%]")
    assert any(re.fullmatch(r"\d+\.\d %", v) for v in loops), loops  # a loop error in the table


def test_warnings_listed_and_checks_in_an_appendix(written):
    paths = written[1]
    page = paths["html"].read_text(encoding="utf-8")
    notes = page[page.index(">Warnings and flagged records</h2>"):]
    assert "k3 not resolved by the data" in notes  # off-resonance dwells do not resolve k3 alone
    assert notes.index("k3 not resolved") < notes.index(">Appendix: settings and checks</h2>")
    assert "report test &lt;campaign&gt;" in page and "<campaign>" not in page


@pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed (apt-get install -y chromium)")
def test_report_renders_in_headless_chromium_summary_first(written, tmp_path):
    paths = written[1]
    url = paths["html"].resolve().as_uri()
    base = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
            "--disable-component-update", "--disable-sync", "--no-first-run", f"--user-data-dir={tmp_path / 'p'}"]
    dom = subprocess.run(base + ["--dump-dom", url], check=True, timeout=120, capture_output=True, text=True).stdout
    # the browser's document: the identified model is the first table, before any figure
    doc = parse_page(dom)
    assert doc.position("table") < doc.position("img")
    assert doc.tables[0].caption.startswith("Identified model per preload")
    shot = tmp_path / "report.png"
    subprocess.run(base + ["--window-size=1200,1600", f"--screenshot={shot}", url], check=True, timeout=120,
                   capture_output=True)
    import matplotlib.image as mpimg

    img = mpimg.imread(shot)
    assert img.shape[:2] == (1600, 1200)
    gray = img[..., :3].mean(axis=-1)
    top = gray[:800]  # the first screen shows the title and the summary table: text and table rules
    assert top.std() > 0.05 and (top < 0.5).mean() > 0.005


def test_loops_are_formed_once_in_the_identification_and_carried(written):
    from jointid.app.reprediction import GroupLoops, group_loops
    from jointid.io.results import to_jsonable

    result, paths, _ = written
    carried = result.hysteresis_loops
    assert carried and all(isinstance(x, GroupLoops) for x in carried)
    assert [(x.preload, x.force_level) for x in carried] == [(g.preload, g.force_level) for g in result.groups
                                                              if g.pooled is not None]
    for x in carried:  # the same loops as formed from the group directly
        best, loops = group_loops(result, result.group(x.preload, x.force_level))
        assert best is x.record
        for key in ("filtered", "unfiltered"):
            assert not isinstance(loops[key], str)
            assert loops[key].rms_difference == getattr(x, key).rms_difference
    # results.json holds the numbers of the carried loops
    stored = json.loads(paths["results"].read_text())["reprediction"]["loops"]
    assert stored == to_jsonable([x.summary() for x in carried])


def test_report_draws_the_carried_loops_without_computing_them(written, monkeypatch):
    import dataclasses

    import jointid.identify.hysteresis as hysteresis

    result = written[0]

    def refuse(*args, **kwargs):
        raise AssertionError("the report computed a hysteresis loop")

    monkeypatch.setattr(hysteresis, "hysteresis_loop", refuse)
    names = [n for n, _, _ in campaign_figures(result)]
    drawn = [n for n in names if n.startswith("hysteresis_")]
    assert len(drawn) == len(result.hysteresis_loops) > 0
    bare = dataclasses.replace(result, hysteresis_loops=())  # nothing carried: nothing drawn
    assert not [n for n, _, _ in campaign_figures(bare) if n.startswith("hysteresis_")]
