"""``jointid update`` on adversarial inputs (an audit's findings): no traceback, bad input refused with one
line naming the file, line and column (exit 2), an implausible fit flagged (exit 1), an unresolved
parameter said with its unbounded interval.

The models and campaigns are those of tests/test_update_joint.py (two masses, Jenkins joint, first harmonics
of x2) and tests/test_update_backbone.py (the shipped two-mass backbone), kept small: each test a few seconds.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import two_mass_backbone as tb
from test_update_joint import FREQS, campaign, true_first_harmonics, write_csv, write_model

from jointid.app.update_joint import MeasuredFRF, read_measured, read_measured_frf, update_joint
from jointid.cli import main
from jointid.errors import ManifestError
from jointid.io.results import to_jsonable

BACKBONE = tb.__file__.rsplit("/", 2)[0] + "/examples/two_mass_backbone.csv"


@pytest.fixture(scope="module")
def two(tmp_path_factory):
    """The two-mass model and a small campaign (three levels, 5 dwells each) written to a CSV file."""
    folder = tmp_path_factory.mktemp("adv")
    model = write_model(folder)
    meas = campaign(true_first_harmonics(model, freqs=FREQS[::3], n_harmonics=9), np.random.default_rng(5))
    return folder, model, meas, write_csv(folder / "frf.csv", meas)


def _one_error_line(capsys):
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    return err[0]


# 1. a huge standard error: an unbounded interval, not an OverflowError


def test_huge_standard_errors_give_an_unbounded_interval_and_a_warning(two, tmp_path, capsys):
    _, model, meas, _ = two
    big = write_csv(tmp_path / "big.csv", MeasuredFRF(meas.path, meas.force_level, meas.frequency_hz, meas.dof,
                                                      meas.X, meas.se * 1e9))
    out = tmp_path / "o"
    assert main(["update", str(model), str(big), "--out", str(out), "--no-heldout", "--quiet"]) in (0, 1)
    res = json.loads((out / "results.json").read_text())
    for k in ("kt", "Fs"):
        assert res["ci95"][k][1] is None  # inf, written as null
        assert any(w.startswith(f"{k} is not resolved") for w in res["warnings"])
    report = (out / "report.txt").read_text()
    assert "(not resolved)" in report and "inf]" in report


#: One dwell a level (the audit's case): without the 5 N level the joint never slips and Fs runs off.
ONE_DWELL_A_LEVEL = """force_level,frequency_hz,dof,a1,b1,se
1.0,21.8,x2,-2.5434436859080185e-05,0.00032028915167761315,1.6045053198415202e-06
2.5,21.8,x2,-6.26413036101537e-05,0.0007987603850596577,4.011263299603798e-06
5.0,21.8,x2,-0.001468050419412608,0.002460576169251165,1.4349438908075236e-05
"""


def test_held_out_fit_running_away_is_said_not_raised(two, tmp_path):
    _, model, _, _ = two
    p = tmp_path / "one.csv"
    p.write_text(ONE_DWELL_A_LEVEL)
    res = update_joint(model, [p], heldout=True)  # exp(log Fs) overflowed in the fit without 5 N
    assert [h["force_level"] for h in res.heldout] == [1.0, 2.5, 5.0]
    assert all(math.isfinite(v) for v in res.estimate.values())
    assert "do not determine every parameter" in res.heldout[2]["note"]
    json.dumps(to_jsonable(res.summary()), allow_nan=False)


# 2. points counted twice


def test_the_same_file_twice_is_refused(two, capsys):
    folder, model, _, csv = two
    with pytest.raises(ManifestError, match="frf.csv: measured file given twice"):
        read_measured([csv, folder / "." / "frf.csv"])
    assert main(["update", str(model), str(csv), str(csv), "--out", str(folder / "o2"), "--quiet"]) == 2
    assert "frf.csv: measured file given twice" in _one_error_line(capsys)


def test_a_repeated_frf_point_is_refused_naming_both_lines(two, tmp_path):
    _, _, _, csv = two
    lines = csv.read_text().splitlines()
    p = tmp_path / "dup.csv"
    # line 3 again at the end with another standard error: the same measured point
    p.write_text("\n".join(lines + [lines[2].rsplit(",", 1)[0] + ",1e-5"]) + "\n")
    n = len(lines) + 1
    with pytest.raises(ManifestError, match=rf"dup\.csv: line {n} repeats the point of line 3 "
                                            r"\(force_level 1, frequency_hz 21\.8, dof x2, a1 "):
        read_measured_frf(p)
    # the same frequency measured again with other first harmonics (a sweep back down through a jump):
    # another point, read
    c = lines[2].split(",")
    c[3] = repr(2 * float(c[3]))
    p.write_text("\n".join(lines + [",".join(c)]) + "\n")
    assert read_measured_frf(p).X.size == len(lines) - 1  # the rows under the comment and header, and the new one
    # the same point in two files
    other = tmp_path / "other.csv"
    other.write_text("\n".join(lines[:2] + [lines[5]]) + "\n")
    with pytest.raises(ManifestError, match=r"other\.csv: line 3 repeats the point of .*frf\.csv: line 6"):
        read_measured([csv, other])


def test_a_repeated_backbone_point_is_refused(tmp_path):
    rows = open(BACKBONE).read().splitlines()
    head = next(i for i, r in enumerate(rows) if not r.startswith("#"))
    p = tmp_path / "bb.csv"
    p.write_text("\n".join(rows + [rows[head + 1]]) + "\n")
    with pytest.raises(ManifestError, match=rf"bb\.csv: line {len(rows) + 1} repeats the point of line {head + 2} "
                                            r"\(dof x2, mode 1, amplitude"):
        read_measured([p])
    # another mode at the same amplitude is another point
    q = tmp_path / "bb2.csv"
    q.write_text("\n".join(rows + [rows[head + 1].rsplit(",", 1)[0] + ",2"]) + "\n")
    _, (bb,) = read_measured([q])
    assert bb.n == len(rows) - head


# 3. a parameter named twice


def test_a_parameter_named_twice_is_refused(two, tmp_path, capsys):
    _, model, _, csv = two
    assert main(["update", str(model), str(csv), "--out", str(tmp_path / "o"), "--parameters", "kt,kt",
                 "--quiet"]) == 2
    assert "kt named more than once" in _one_error_line(capsys)


# 4. a byte-order mark


def test_a_byte_order_mark_is_not_part_of_the_header(two, tmp_path):
    _, _, meas, csv = two
    p = tmp_path / "bom.csv"
    p.write_bytes(b"\xef\xbb\xbf" + csv.read_bytes())
    got, _ = read_measured([p])
    np.testing.assert_array_equal(got.X, read_measured_frf(csv).X)
    b = tmp_path / "bom_bb.csv"
    b.write_bytes(b"\xef\xbb\xbf" + open(BACKBONE, "rb").read())
    _, (bb,) = read_measured([b])
    assert bb.n > 10


# 5. where the error is


def test_an_unknown_dof_names_the_file_line_and_column(two, tmp_path, capsys):
    _, model, _, csv = two
    lines = csv.read_text().splitlines()
    p = tmp_path / "m.csv"
    p.write_text("\n".join(lines[:3] + [lines[3].replace(",x2,", ",x9,")] + lines[4:]) + "\n")
    assert main(["update", str(model), str(p), "--out", str(tmp_path / "o"), "--quiet"]) == 2
    assert "m.csv: line 4, column dof: dof 'x9' is not a DOF" in _one_error_line(capsys)


def test_a_folder_is_said_to_be_a_folder(two, tmp_path, capsys):
    folder, model, _, csv = two
    assert main(["update", str(model), str(folder), "--out", str(tmp_path / "o"), "--quiet"]) == 2
    line = _one_error_line(capsys)
    assert "is a folder" in line and "not found" not in line
    assert main(["update", str(folder), str(csv), "--out", str(tmp_path / "o"), "--quiet"]) == 2
    line = _one_error_line(capsys)
    assert "structure model is a folder" in line and "not found" not in line


# 6. why there is no held-out check


def test_a_single_level_says_why_there_is_no_held_out_check(two):
    _, model, meas, _ = two
    res = update_joint(model, meas.subset(meas.force_level == 2.5), heldout=True)
    s = res.summary()
    assert s["heldout"] == [] and "one force level only" in s["heldout_note"]
    assert "one force level only" in res.report()
    assert "--no-heldout" in update_joint(model, meas.subset(meas.force_level == 2.5), heldout=False).heldout_note


# 7. amplitudes in mm: a confident number far from the start is flagged


def test_a_parameter_ending_orders_of_magnitude_from_its_start_is_flagged(tmp_path, capsys):
    model = tmp_path / "two_mass.toml"
    model.write_text(tb.MODEL_TOML)
    mm = tmp_path / "bb_mm.csv"
    lines = []
    for r in open(BACKBONE).read().splitlines():
        if r.startswith("x2,"):
            c = r.split(",")
            c[1] = repr(1e3 * float(c[1]))
            r = ",".join(c)
        lines.append(r)
    mm.write_text("\n".join(lines) + "\n")
    out = tmp_path / "o"
    assert main(["update", str(model), str(mm), "--out", str(out), "--no-heldout", "--quiet"]) == 1
    res = json.loads((out / "results.json").read_text())
    assert list(res["far_from_start"]) == ["Fs"]
    assert res["far_from_start"]["Fs"] > 100 and "Fs = " in _one_error_line(capsys)
