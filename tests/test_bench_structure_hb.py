"""The named benchmark case of benchmarks/bench_structure_hb.py at reduced size.

The written case files load back to the benchmark's matrices, and a model rebuilt only from
them (the reduced matrices and the written slider set, through the joints package's
DiscreteIwan) reproduces the benchmark's harmonic-balance points; the printed residuals are
small and the full-DOF baseline agrees with the condensed engine.
"""

import importlib
import json
import pathlib
import re

import numpy as np
import pytest
import scipy.io

from jointid.joints import DiscreteIwan
from jointid.simulate.structure_hb import CondensedHB

BENCH = pathlib.Path(__file__).resolve().parents[1] / "benchmarks"


@pytest.fixture()
def bench(monkeypatch):
    monkeypatch.syspath_prepend(str(BENCH))
    return importlib.import_module("bench_structure_hb")


def test_case_files_load_back_and_reproduce_the_printed_points(bench, tmp_path, capsys):
    out = bench.main(["--n-modes", "4", "--force-levels", "6", "--max-steps", "3", "--repeat", "1",
                      "--check-points", "0", "--write-case", str(tmp_path)])
    text = capsys.readouterr().out
    case = bench.build_case(4)
    e = case["structure"].engine

    # the files load back to the same matrices
    z = np.load(tmp_path / "case.npz")
    for key in ("M", "K", "joint_selection", "force_vector"):
        assert np.array_equal(z[key], case[key]), key
    assert list(z["dof_names"]) == case["dof_names"]
    assert np.array_equal(scipy.io.mmread(str(tmp_path / "M.mtx")).toarray(), case["M"])
    assert np.array_equal(scipy.io.mmread(str(tmp_path / "K.mtx")).toarray(), case["K"])
    assert np.array_equal(scipy.io.mmread(str(tmp_path / "joint_selection.mtx")).ravel(), case["joint_selection"])
    assert np.array_equal(scipy.io.mmread(str(tmp_path / "force_vector.mtx")).ravel(), case["force_vector"])
    for key in ("Phi", "M_red", "K_red", "C_red", "joint_selection_red"):
        assert np.array_equal(scipy.io.mmread(str(tmp_path / f"{key}.mtx")), z[key]), key
    # the reduced model is the FE model's reduction, the slider set the law's
    Phi = z["Phi"]
    scale = np.abs(z["K_red"]).max()
    assert np.allclose(Phi.T @ z["M"] @ Phi, z["M_red"], atol=1e-9)
    assert np.allclose(Phi.T @ z["K"] @ Phi, z["K_red"], rtol=0, atol=1e-9 * scale)
    assert np.allclose(z["joint_selection"] @ Phi, z["joint_selection_red"].ravel(), rtol=1e-12, atol=0)
    assert np.allclose(Phi.T @ z["force_vector"], z["force_vector_red"], rtol=1e-12, atol=0)
    assert z["slider_stiffness"].sum() == pytest.approx(float(z["iwan_K_T"]), rel=1e-12)
    assert z["slider_slip_force"].sum() == pytest.approx(float(z["iwan_F_S"]), rel=1e-12)
    desc = json.loads((tmp_path / "case.json").read_text())
    assert set(desc["files"]) == {p.name for p in tmp_path.iterdir()}
    assert desc["settings"]["n_harmonics"] == 7 and desc["settings"]["n_time"] == 256
    ref = json.loads((tmp_path / "reference.json").read_text())["levels"][0]
    assert ref["frequency_hz"] == [p.frequency_hz for p in out["levels"][0]["curve"].points]

    # a model built from the files alone solves the printed points to the engine's tolerance
    om = np.sqrt(np.diag(z["K_red"]))
    other = CondensedHB(om, np.diag(z["C_red"]) / (2 * om), z["joint_selection_red"], z["force_vector_red"],
                        [DiscreteIwan(z["slider_stiffness"], z["slider_slip_force"])], z["k_model"])
    H, N = int(z["n_harmonics"]), int(z["n_time"])
    level = out["levels"][0]
    for p in level["curve"].points:
        ev = other.evaluate(p.joint.ravel(), p.omega, p.force, H, N, jacobian=False)
        assert np.linalg.norm(ev["R"]) / np.linalg.norm(p.joint) < 1e-8
    assert level["points"] >= 3 and level["max_residual"] < 1e-8
    assert level["condensed_vs_full"] < 1e-8  # the full-DOF baseline finds the same orbits
    it_c, it_f = level["fixed_iterations"]
    assert abs(it_c - it_f) <= 1.0  # in as many Newton steps: the baseline is not handicapped
    # the printed row carries those numbers
    row = next(line for line in text.splitlines() if line.strip().startswith("6.00"))
    printed = [float(x) for x in re.findall(r"[-+]?\d+\.?\d*(?:e[-+]\d+)?", row)]
    assert printed[1] == level["points"] and printed[5] < 1e-8
    assert printed[5] == pytest.approx(level["max_residual"], rel=0.06)
    assert e.n_modes == 4
