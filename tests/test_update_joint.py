"""Updating a structure model's joint law to measured first harmonics (issue 22, item 5).

The measurements are made by the harmonic balance of the true model at 27 harmonics (the fit
uses 9; with 5 the Jenkins stiffness came out 1.4 standard errors off in a trial, so 9 is the
default), 0.5 % complex Gaussian noise on every first harmonic, three force levels of 13
dwells each, swept upwards.  The structure: two masses in a chain (x1 to ground 4e4 N/m, x1
to x2 2e4 N/m), a Jenkins joint from x1 to ground left out of the matrices, force at x2.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from jointid.app.update_joint import (
    MeasuredFRF,
    _with_law,
    read_measured_frf,
    update_joint,
)
from jointid.cli import main
from jointid.errors import IdentificationError, ManifestError, RecordFileNotFoundError
from jointid.io.structure_model import read_structure_model
from jointid.simulate.structure import structure_from_spec
from jointid.simulate.structure_hb import to_complex

TRUE = {"kt": 1.2e4, "Fs": 4.0}  # the start in the file: kt 1e4, Fs 5
LEVELS = (1.0, 2.5, 5.0)
FREQS = np.linspace(21.8, 25.0, 13)
NOISE = 0.005


def write_model(folder, law='law = "jenkins"\nparameters = { kt = 1.0e4, Fs = 5.0 }', zeta=0.01, name="two"):
    M = np.diag([1.0, 0.5])
    K = np.array([[6e4, -2e4], [-2e4, 2e4]])
    np.savez(folder / "two.npz", M=M, K=K, dof_names=np.array(["x1", "x2"]))
    path = folder / f"{name}.toml"
    path.write_text(f'[model]\nname = "two masses"\n[matrices]\nfile = "two.npz"\n[damping]\nmodal = {zeta}\n'
                    f'[[joint]]\nname = "slip"\ndofs = ["x1"]\n{law}\nk_model = 0\n'
                    '[force]\ndofs = { "x2" = 1.0 }\n[response]\ndofs = ["x2"]\n')
    return path


def true_first_harmonics(model_path, levels=LEVELS, freqs=FREQS, n_harmonics=27):
    m, _ = structure_from_spec(read_structure_model(model_path))
    mt = _with_law(m, 0, m.joints[0].law.replace(**TRUE))
    lv, fr, X = [], [], []
    for F in levels:
        prev = None
        for f in freqs:
            prev = mt.solve(f, F, n_harmonics, guess=prev)
            lv.append(F)
            fr.append(f)
            X.append(to_complex(mt.modal.shape("x2") @ prev.modal)[1])
    return np.array(lv), np.array(fr), np.array(X)


def campaign(clean, rng, path="synthetic"):
    lv, fr, X = clean
    se = NOISE * np.abs(X)
    Xn = X + se * (rng.standard_normal(X.size) + 1j * rng.standard_normal(X.size))
    return MeasuredFRF(path, lv, fr, ("x2",) * lv.size, Xn, se)


def thin(meas):
    """Every other dwell (7 of 13 per level): the fast tests' campaigns."""
    return meas.subset(np.isin(np.round(meas.frequency_hz, 9), np.round(FREQS[::2], 9)))


def write_csv(path, meas):
    lines = ["# first harmonics of x2, a stepped sine swept upwards", "force_level,frequency_hz,dof,a1,b1,se"]
    for F, f, d, x, s in zip(meas.force_level, meas.frequency_hz, meas.dof, meas.X, meas.se):
        lines.append(f"{float(F)!r},{float(f)!r},{d},{float(x.real)!r},{float(-x.imag)!r},{float(s)!r}")
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    folder = tmp_path_factory.mktemp("update")
    model = write_model(folder)
    return folder, model, true_first_harmonics(model)


def test_parameters_recovered_within_their_intervals(setup):
    _, model, clean = setup
    res = update_joint(model, thin(campaign(clean, np.random.default_rng(1))), heldout=False)
    for k, v in TRUE.items():
        lo, hi = res.ci95[k]
        assert lo < v < hi, (k, v, res.ci95[k])
        assert res.stderr[k] < 0.01 * v  # 21 points at 0.5 %: both parameters well determined
        assert abs(res.estimate[k] - v) < 3 * res.stderr[k]
    assert 0.6 < res.chi2_per_dof < 1.5 and res.adequate and res.summary()["fit_adequate"] is True
    assert res.dof == 2 * 21 - 2
    # the start was far away (kt -17 %, Fs +25 %): the fit moved
    assert abs(res.estimate["Fs"] / 5.0 - 1) > 0.1


def test_measured_csv_roundtrip_and_cli(setup, tmp_path, capsys):
    _, model, clean = setup
    meas = thin(campaign(clean, np.random.default_rng(2)))
    csv = write_csv(tmp_path / "measured.csv", meas)
    back = read_measured_frf(csv)
    np.testing.assert_allclose(back.X, meas.X, rtol=1e-15)
    out = tmp_path / "upd"
    code = main(["update", str(model), str(csv), "--out", str(out), "--parameters", "Fs", "--no-heldout",
                 "--quiet"])
    assert code == 1  # inadequate (see below): a status a script can see
    res = json.loads((out / "results.json").read_text())
    for key in ("parameters", "stderr", "ci95", "chi2_per_dof", "heldout", "units", "correlation"):
        assert key in res
    assert list(res["parameters"]) == ["Fs"]
    assert (out / "report.txt").is_file() and (out / "figures" / "update_fit.png").is_file()
    # kt held at its wrong start (1e4 vs 1.2e4): Fs cannot make up for it, chi2/dof says so
    assert res["chi2_per_dof"] > 10 and any("does not fit" in w for w in res["warnings"])
    assert res["fit_adequate"] is False and "does not fit" in capsys.readouterr().err


@pytest.mark.parametrize("text, what", [
    ("force_level,frequency_hz,dof,a1,b1\n1,20,x2,1e-3,0\n", "missing column(s) se"),
    ("force_level,frequency_hz,dof,a1,b1,se\n1,20,x2,abc,0,1e-5\n", "line 2, column a1: not a number"),
    ("force_level,frequency_hz,dof,a1,b1,se\n1,20,x2,1e-3,0,0\n", "line 2, column se: must be > 0"),
    ("force_level,frequency_hz,dof,a1,b1,se\n1,20,,1e-3,0,1e-5\n", "line 2, column dof: empty"),
    ("# only a comment\n", "no data rows"),
    ("# a comment\nforce_level,frequency_hz,dof,a1,b1,se\n\n1,20,x2,1e-3,inf,1e-5\n", "line 4, column b1: not finite"),
])
def test_bad_measured_file(tmp_path, text, what):
    p = tmp_path / "m.csv"
    p.write_text(text)
    with pytest.raises(ManifestError, match=r"m\.csv: .*" + what.replace("(", r"\(").replace(")", r"\)")):
        read_measured_frf(p)


def test_bad_update_requests(setup, tmp_path):
    _, model, clean = setup
    meas = campaign(clean, np.random.default_rng(3))
    with pytest.raises(ManifestError, match="no parameter.*K_T.*its parameters: kt, Fs"):
        update_joint(model, meas, parameters=["K_T"])
    with pytest.raises(ManifestError, match="no joint named 'bolt'"):
        update_joint(model, meas, joint="bolt")
    other = MeasuredFRF("m.csv", meas.force_level, meas.frequency_hz, ("x9",) * meas.X.size, meas.X, meas.se)
    with pytest.raises(ManifestError, match="m.csv: dof 'x9' is not a DOF"):
        update_joint(model, other)
    with pytest.raises(IdentificationError, match="1 points cannot determine 2 parameters"):
        update_joint(model, meas.subset(np.arange(meas.X.size) == 0))
    with pytest.raises(RecordFileNotFoundError):
        read_measured_frf(tmp_path / "absent.csv")


def test_cli_bad_input_exit_2(setup, tmp_path, capsys):
    _, model, _ = setup
    bad = tmp_path / "m.csv"
    bad.write_text("force_level,frequency_hz,dof,a1,b1,se\n1,20,x2,1e-3,0,-1\n")
    assert main(["update", str(model), str(bad), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "line 2, column se: must be > 0" in err[0]
    assert main(["update", str(tmp_path / "none.toml"), str(bad), "--out", str(tmp_path / "o")]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1


def test_out_onto_an_input_folder_is_refused_and_nothing_is_deleted(setup, tmp_path, capsys):
    """--out on the folder holding the model and the measured file (not an output set): exit 2, files kept."""
    _, model, clean = setup
    csv = write_csv(model.parent / "measured.csv", thin(campaign(clean, np.random.default_rng(4))))
    before = sorted(p.name for p in model.parent.iterdir())
    for out in (model.parent, csv.parent / "."):
        assert main(["update", str(model), str(csv), "--out", str(out), "--quiet"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "did not write as an output set" in err[0]
    assert sorted(p.name for p in model.parent.iterdir()) == before and csv.read_text()


@pytest.mark.slow
def test_monte_carlo_z_scores_and_heldout(setup):
    """20 campaigns: the standard errors are calibrated (std z within 0.7-1.4, mean within 0.7).

    49 s of one core measured (user time; 130-145 s wall on a loaded machine); with 7 dwells a level instead of 13
    std z came out 0.90 (kt) and 0.75 (Fs), nearer the bound, so the full campaigns are kept.
    """
    _, model, clean = setup
    z = {k: [] for k in TRUE}
    for seed in range(20):
        res = update_joint(model, campaign(clean, np.random.default_rng(100 + seed)), heldout=False)
        for k, v in TRUE.items():
            z[k].append((res.estimate[k] - v) / res.stderr[k])
    for k, zk in z.items():
        zk = np.array(zk)
        print(k, "mean z", zk.mean(), "std z", zk.std(ddof=1))
        assert 0.7 < zk.std(ddof=1) < 1.4, (k, zk)
        assert abs(zk.mean()) < 0.7, (k, zk)
    # leave-one-level-out on one campaign: the top level predicted from the two lower ones
    res = update_joint(model, campaign(clean, np.random.default_rng(7)))
    top = next(h for h in res.heldout if h["force_level"] == max(LEVELS))
    print(res.report())
    assert abs(top["peak_frequency_error_pct"]) < 0.1
    assert abs(top["peak_amplitude_error_pct"]) < 2.0
    assert top["rms_amplitude_error_pct"] < 1.5
    assert math.isfinite(top["model_peak_frequency_hz"])


REPO = __import__("pathlib").Path(__file__).resolve().parents[1]


def _lap_model(folder):
    """The lap_joint.toml of docs/formats.md, written into ``folder`` with examples/ linked."""
    text = (REPO / "docs" / "formats.md").read_text(encoding="utf-8")
    i = text.index("# file: lap_joint.toml")
    (folder / "lap_joint.toml").write_text(text[i:text.index("```", i)], encoding="utf-8")
    (folder / "examples").symlink_to(REPO / "examples", target_is_directory=True)
    return folder / "lap_joint.toml"


def test_shipped_lap_example_reads(tmp_path):
    meas = read_measured_frf(REPO / "examples" / "lap_joint_measured.csv")
    assert meas.X.size == 27 and set(meas.dof) == {"B.w10"} and meas.levels() == [0.5, 2.0, 5.0]
    m, _ = structure_from_spec(read_structure_model(_lap_model(tmp_path)))
    assert "B.w10" in m.modal.dof_names and set(m.joints[0].law.parameters) == {"F_S", "K_T", "chi", "beta"}


@pytest.mark.slow
def test_shipped_lap_example_is_what_its_generator_writes(tmp_path):
    import sys

    sys.path.insert(0, str(REPO / "tests"))
    import lap_joint_measured

    out = lap_joint_measured.write_measured(_lap_model(tmp_path), tmp_path / "m.csv")
    new, shipped = read_measured_frf(out), read_measured_frf(REPO / "examples" / "lap_joint_measured.csv")
    np.testing.assert_array_equal(new.frequency_hz, shipped.frequency_hz)
    np.testing.assert_allclose(new.X, shipped.X, rtol=1e-5)


def test_a_polynomial_joint_law_is_updated_by_its_coefficient_names(tmp_path):
    """A cubic spring with viscous damping in the joint: ``k3`` and ``c`` (the names of the law's
    ``parameters``) fitted to first harmonics of the true model at 27 harmonics, 0.5 % noise."""
    model = write_model(tmp_path, 'law = "polynomial"\nparameters = { "-q^3" = -5.0e10, "q\'" = 4.0 }', 0.002, "cubic")
    truth = {"k3": -8.0e10, "c": 6.0}
    m, _ = structure_from_spec(read_structure_model(model))
    mt = _with_law(m, 0, m.joints[0].law.replace(**truth))
    lv, fr, X = [], [], []
    for F in (1.0, 3.0):
        prev = None
        for f in np.linspace(21.0, 25.5, 10):
            prev = mt.solve(f, F, 27, guess=prev)
            lv.append(F)
            fr.append(f)
            X.append(to_complex(mt.modal.shape("x2") @ prev.modal)[1])
    X = np.array(X)
    rng = np.random.default_rng(7)
    se = NOISE * np.abs(X)
    meas = MeasuredFRF("synthetic", np.array(lv), np.array(fr), ("x2",) * X.size,
                       X + se * (rng.standard_normal(X.size) + 1j * rng.standard_normal(X.size)), se)
    res = update_joint(model, meas, parameters=["k3", "c"], heldout=False)
    print({k: (res.estimate[k], res.stderr[k]) for k in truth}, res.chi2_per_dof)
    for k, v in truth.items():
        assert abs(res.estimate[k] - v) < 3 * res.stderr[k], (k, res.estimate[k], res.stderr[k])
        assert res.stderr[k] < 0.1 * abs(v)
    assert res.adequate
    with pytest.raises((ManifestError, IdentificationError), match="k5"):
        update_joint(model, meas, parameters=["k5"], heldout=False)
