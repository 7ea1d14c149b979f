"""`jointid public-data --out DIR` writes one self-contained report.html of its worked examples."""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

import pytest

from jointid.cli import main

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"


@pytest.mark.skipif(not (DATA / "unesp_bolted_beam").exists() or not (DATA / "f16_gvt_sinesweep_uliege").exists(),
                    reason="public data sets not found in ../shared/data")
def test_public_data_writes_a_self_contained_report(tmp_path):
    out = tmp_path / "pd"
    with contextlib.redirect_stdout(io.StringIO()):
        code = main(["public-data", "--out", str(out), "--only", "unesp", "--only", "f16"])
    assert code == 0
    page = (out / "report.html").read_text()
    assert page.startswith("<!DOCTYPE html>") and page.rstrip().endswith("</html>")
    # one section per example run, its figure embedded (the same bytes as the PNG file), no link outside
    assert "UNESP bolted beam, sine dwells" in page and "F-16 GVT sine sweep" in page
    assert "Silverbox" not in page  # only the examples that ran
    assert page.count("data:image/png;base64,") == 2
    assert "<img" in page and "src='http" not in page and 'src="http' not in page and "<script" not in page
    assert {p.name for p in out.iterdir()} == {"report.html", "results.json", "unesp.png", "f16.png", ".jointid-run"}
    # tables of numbers, not a text dump: the per-dwell table with its units
    assert "<table" in page and "tip amplitude q_max [mm]" in page and "c/m [1/s]" in page
    assert "leads the voltage" in page  # the delay's sign said in words


@pytest.mark.skipif(not (DATA / "silverbox_multilevel_noel").exists(), reason="public data sets not found in ../shared/data")
def test_public_data_output_is_one_set_and_never_mixes_with_other_files(tmp_path, capsys):
    from jointid.io.outputset import read_marker

    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("keep")
    assert main(["public-data", "--out", str(mine), "--only", "silverbox"]) == 2
    assert "did not write" in capsys.readouterr().err and [p.name for p in mine.iterdir()] == ["notes.txt"]
    out = tmp_path / "pd"
    for only in ("silverbox", "silverbox"):  # a second run replaces its own earlier set
        assert main(["public-data", "--out", str(out), "--only", only]) == 0
    marker = read_marker(out)
    assert marker["kind"] == "public-data" and set(marker["files"]) == {"report.html", "results.json", "silverbox.png"}
    assert not list(tmp_path.glob(".pd.*"))
