"""The HTML reports fit a 1400 px wide browser window: no table (or figure) wider than the page.

Each report is opened in headless Chromium at 1400 px with a small script appended that
measures, after layout, the document's scroll width and the right edge of every table,
figure and image; the test fails when any of them passes the page's text column (the body's
content box) or the window.
Skipped when Chromium is not installed.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import warnings
from pathlib import Path
from types import SimpleNamespace

import pytest

CHROMIUM = shutil.which("chromium") or ("/usr/bin/chromium" if Path("/usr/bin/chromium").exists() else None)
pytestmark = pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed (apt-get install -y chromium)")

WIDTH = 1400

_SCRIPT = """<script>window.addEventListener('load', function () {
  var cw = document.documentElement.clientWidth, wide = [];
  var b = document.body.getBoundingClientRect(), st = getComputedStyle(document.body);
  var column = Math.min(cw, b.right - parseFloat(st.paddingRight));
  document.querySelectorAll('table, figure, img, pre').forEach(function (t) {
    var r = t.getBoundingClientRect();
    if (r.right > column + 1) {
      var cap = t.querySelector ? t.querySelector('caption') : null;
      wide.push([t.tagName, Math.round(r.right), (cap ? cap.textContent : (t.alt || '')).slice(0, 80)]);
    }
  });
  var out = {scroll_width: document.documentElement.scrollWidth, client_width: cw, column_right: column,
             wide: wide};
  var d = document.createElement('pre'); d.id = '__width'; d.textContent = JSON.stringify(out);
  document.body.appendChild(d);
});</script>"""


def measure(html_path, tmp_path) -> dict:
    """Layout widths of a report in headless Chromium at :data:`WIDTH` px."""
    page = Path(html_path).read_text(encoding="utf-8")
    probe = tmp_path / ("probe_" + Path(html_path).parent.name + ".html")
    probe.write_text(page.replace("</body>", _SCRIPT + "</body>"), encoding="utf-8")
    cmd = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
           "--disable-background-networking", "--disable-component-update", "--disable-sync",
           f"--user-data-dir={tmp_path / 'profile'}", f"--window-size={WIDTH},1000", "--dump-dom", probe.as_uri()]
    dom = subprocess.run(cmd, check=True, timeout=180, capture_output=True, text=True).stdout
    m = re.search(r'<pre id="__width">(.*?)</pre>', dom, re.S)
    assert m, "the measuring script did not run"
    return json.loads(m.group(1).replace("&quot;", '"').replace("&amp;", "&").replace("&lt;", "<")
                      .replace("&gt;", ">"))


def assert_fits(widths, what):
    assert widths["client_width"] > 1000, widths
    assert widths["scroll_width"] <= widths["client_width"], (what, widths)
    assert not widths["wide"], (what, widths["wide"])


def test_measure_sees_a_table_wider_than_the_page(tmp_path):
    from jointid.report.html import Section, write_html

    sec = Section("wide", tables=[("too many columns", [{f"column number {k}": 123456.789 * k for k in range(40)}],
                                   None)])
    (tmp_path / "wide").mkdir()
    write_html(tmp_path / "wide" / "report.html", "wide", [sec])
    widths = measure(tmp_path / "wide" / "report.html", tmp_path)
    assert widths["wide"] and widths["wide"][0][0] == "TABLE"


def test_identify_report_fits_1400_px(tmp_path):
    from jointid import identify_campaign
    from jointid.app.synthesis import load_simulation_config, simulate_campaign
    from jointid.errors import JointidWarning
    from jointid.report.output import write_results

    config = {
        "campaign": {"name": "width test"},
        "model": [{"preload": 120, "terms": "q + -q^3 + q'", "omega1": 170.0, "coefficients": {"k3": 5e6},
                   "amplitude_laws": {"c": [0.08, 70.0, 1e4]}}],
        "excitation": {"force_levels": [1.0, 2.0], "omega_start": 163.0, "omega_stop": 177.0, "n_frequencies": 7},
        "acquisition": {"fs": 2000.0, "periods": 20.0, "noise": 0.01, "seed": 2, "n_harmonics": 5},
    }
    camp = simulate_campaign(load_simulation_config(config), tmp_path / "campaign")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", JointidWarning)
        result = identify_campaign(camp)
    paths = write_results(result, tmp_path / "out")
    assert_fits(measure(paths["html"], tmp_path), "identify report")


def test_study_report_fits_1400_px(tmp_path):
    import numpy as np

    from jointid.report.study_plots import write_study_report

    names = ["omega1 (sim)", "k3 (sim)", "c0 (sim)", "c1 (sim)", "c2 (sim)", "omega1 (sim, F = 1)",
             "k3 (sim, F = 1)"]
    rng = np.random.default_rng(0)
    stats = [{"grid_point": 0, "parameter": p, "n": 200, "n_missing": 0, "bias": 1.234567e-3, "rmse": 2.3456789e-2,
              "rel_bias": -1.234567e-4, "rel_rmse": 3.4567891e-3, "mean_z": 0.0123456, "std_z": 1.0345678,
              "coverage": 0.945, "coverage_low": 0.9034567, "coverage_high": 0.9712345} for p in names]
    campaigns = [{"grid_point": 0, "index": i, "rows": [{"parameter": p, "z": float(rng.standard_normal())}
                                                        for p in names]} for i in range(40)]
    plan = SimpleNamespace(campaigns=40, points=[{}], seed=2026, fingerprint="0123456789abcdef",
                           vary=[("acquisition.noise", {"loguniform": [0.001, 0.02]}),
                                 ("model.coefficients.k3", {"uniform": [3e6, 6e6], "random_sign": True}),
                                 ("excitation.force_levels", {"uniform": [0.4, 2.0], "size": [2, 4]}),
                                 ("acquisition.write_frequency", {"choice": [True, False]})])
    result = SimpleNamespace(name="width test", plan=plan, campaigns=campaigns, failed=[], statistics=stats)
    (tmp_path / "study").mkdir()
    write_study_report(result, tmp_path / "study" / "report.html")
    page = (tmp_path / "study" / "report.html").read_text(encoding="utf-8")
    assert "{&#x27;" not in page and "{'" not in page  # distributions in words, not Python dicts
    assert_fits(measure(tmp_path / "study" / "report.html", tmp_path), "study report")
