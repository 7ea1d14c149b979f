"""The demo report as a test engineer reads it (slow: runs the whole demo): the summary first,
a unit on every figure axis, the checks and timings in an appendix, version, date and run id."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import pytest
from html_page import parse_page
from matplotlib.ticker import FixedFormatter

from jointid.report.demo_report import demo_figures

pytestmark = pytest.mark.slow

CHROMIUM = shutil.which("chromium") or ("/usr/bin/chromium" if Path("/usr/bin/chromium").exists() else None)
UNIT = re.compile(r"\[[^\]]+\]")


@pytest.fixture(scope="module")
def demo(demo_run):
    return demo_run


def test_demo_report_opens_with_the_summary(demo):
    page = (demo.out_dir / "report.html").read_text(encoding="utf-8")
    doc = parse_page(page)
    first, img = doc.position("table"), doc.position("img")
    assert first < img and first < doc.heading("Appendix: acceptance checks and timings")
    head = doc.tables[0].text()
    assert "Identified model per preload" in doc.tables[0].caption
    # the selected model's quantities (which ones depends on the family the data select: k3 only with a cubic)
    for text in ("120", "540", "f1", "omega1", "rad/s", "Hz", "95 % interval"):
        assert text in head, text
    assert not re.search(r"\d\.\d{9,}", head)
    before_figures = " ".join(v.text() if k == "table" else v for k, v in doc.outline[first:img])
    assert "Table 4" in before_figures and "Table 5" in before_figures
    for text in ("k3", "N/m³", "c0", "N s/m"):  # the paper's cubic beside it, in its units
        assert text in before_figures, text
    # the acceptance checks and timings are in the appendix, after every figure
    last_img = doc.last_position("img")
    assert doc.position("table", lambda t: t.caption == "acceptance checks") > last_img
    assert doc.position("table", lambda t: t.caption.startswith("run time per stage")) > last_img


def test_demo_report_shows_version_date_and_the_run_id_of_its_results(demo):
    page = (demo.out_dir / "report.html").read_text(encoding="utf-8")
    run_id = json.loads((demo.out_dir / "results.json").read_text())["run_id"]
    meta = parse_page(page).meta
    assert run_id and run_id in meta and "jointid " in meta and "date " in meta


def test_every_demo_figure_axis_has_a_unit(demo):
    for name, _, fig in demo_figures(demo):
        for ax in fig.axes:
            if not ax.axison:
                continue
            for axis, label in ((ax.xaxis, ax.get_xlabel()), (ax.yaxis, ax.get_ylabel())):
                if not isinstance(axis.get_major_formatter(), FixedFormatter):  # named categories: no unit
                    assert UNIT.search(label), (name, label)


@pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed (apt-get install -y chromium)")
def test_demo_report_in_headless_chromium_has_the_summary_first(demo, tmp_path):
    url = (demo.out_dir / "report.html").resolve().as_uri()
    cmd = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
           f"--user-data-dir={tmp_path / 'p'}", "--dump-dom", url]
    dom = subprocess.run(cmd, check=True, timeout=120, capture_output=True, text=True).stdout
    doc = parse_page(dom)
    assert doc.position("table") < doc.position("img")
    assert doc.tables[0].caption.startswith("Identified model per preload")
