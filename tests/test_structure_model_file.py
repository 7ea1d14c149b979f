"""MODEL.toml: a linear model from a matrix file with joint elements (jointid.io.structure_model)."""

import re
from pathlib import Path

import numpy as np
import pytest
import scipy.io

from jointid.errors import ManifestError, RecordFileNotFoundError, StructureError
from jointid.io.structure_model import read_structure_model
from jointid.joints import Iwan4
from jointid.simulate.structure import structure_from_spec
from jointid.simulate.structure_hb import to_complex

REPO = Path(__file__).resolve().parents[1]


def doc_example():
    """The lap-joint MODEL.toml shown in docs/formats.md."""
    text = (REPO / "docs" / "formats.md").read_text(encoding="utf-8")
    m = re.search(r"```toml\n(# file: lap_joint.toml\n.*?)```", text, re.S)
    assert m, "docs/formats.md shows the lap joint model"
    return m.group(1)


@pytest.fixture
def lap(tmp_path):
    (tmp_path / "examples").symlink_to(REPO / "examples", target_is_directory=True)
    p = tmp_path / "lap_joint.toml"
    p.write_text(doc_example(), encoding="utf-8")
    return p


def write(tmp_path, text, name="MODEL.toml"):
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


def test_shipped_npz_is_the_documented_lap_joint():
    from lap_joint_model import lap_joint_matrices

    M, K, names = lap_joint_matrices()
    with np.load(REPO / "examples" / "lap_joint.npz") as z:
        assert np.array_equal(z["M"], M) and np.array_equal(z["K"], K)
        assert [str(s) for s in z["dof_names"]] == names


def test_documented_example_reads_and_solves(lap):
    spec = read_structure_model(lap)
    assert spec.M.shape == (44, 44) and spec.dof_names[:2] == ("A.w0", "A.r0")
    assert isinstance(spec.joints[0].law, Iwan4) and spec.joints[0].k_model == 2.0e3
    assert spec.predict["force_levels"] == [0.5, 2.0, 5.0]
    st, response = structure_from_spec(spec)
    f = st.modal.frequencies_hz
    assert f[0] == 0.0 and f[1] == 0.0  # free-free: two rigid-body modes
    assert f[2] == pytest.approx(84.19, abs=0.01)  # as the document says
    # at a tiny force the joint is stuck: the response is the linear model's
    p = st.solve(80.0, 1e-6, 5)
    X = st.response(p, response)["B.w10"]
    phi = st.modal.shapes[st.modal.index("B.w10")]
    lin = np.sum(phi * st.engine.receptance(p.omega) * st.engine.force_shape) * (-1j) * 1e-6
    assert abs(to_complex(X)[1] - lin) < 1e-6 * abs(lin)
    # at 2 N the joint slips: the response at 80 Hz differs from the linear one by more than 10 %
    q = st.solve(80.0, 2.0, 5)
    Xq = to_complex(st.response(q, response)["B.w10"])[1]
    assert abs(Xq - 2.0e6 * lin) > 0.1 * abs(2.0e6 * lin)


def test_matrix_market_and_mat_files_give_the_same_model(lap, tmp_path):
    with np.load(REPO / "examples" / "lap_joint.npz") as z:
        M, K, names = z["M"], z["K"], [str(s) for s in z["dof_names"]]
    scipy.io.mmwrite(str(tmp_path / "M.mtx"), scipy.sparse.coo_matrix(M))
    scipy.io.mmwrite(str(tmp_path / "K.mtx"), scipy.sparse.coo_matrix(K))
    scipy.io.savemat(tmp_path / "lap.mat", {"Mass": M, "Stiff": K})
    base = doc_example()
    names_line = "dof_names = [" + ", ".join(f'"{s}"' for s in names) + "]"
    mtx = base.replace('file = "examples/lap_joint.npz"', f'mass = "M.mtx"\nstiffness = "K.mtx"\n{names_line}')
    mat = base.replace('file = "examples/lap_joint.npz"',
                       f'file = "lap.mat"\nmass_key = "Mass"\nstiffness_key = "Stiff"\n{names_line}')
    ref = structure_from_spec(read_structure_model(lap))[0].modal.omega
    for text, name in ((mtx, "mtx.toml"), (mat, "mat.toml")):
        om = structure_from_spec(read_structure_model(write(tmp_path, text, name)))[0].modal.omega
        assert np.allclose(om, ref, rtol=1e-12, atol=1e-9)


def test_rayleigh_and_modal_data(tmp_path, lap):
    base = doc_example()
    text = base.replace("modal = 0.002 ", "rayleigh = [2.0, 1e-6] ")
    st = structure_from_spec(read_structure_model(write(tmp_path, text)))[0]
    om = st.modal.omega[2]
    assert st.modal.zeta[2] == pytest.approx(2.0 / (2 * om) + 1e-6 * om / 2, rel=1e-12)
    assert st.modal.zeta[0] == 0.0
    modal = """
[modal]
frequencies_hz = [20.0, 60.0]
damping_ratios = [0.01, 0.02]
dof_names = ["a", "b", "tip"]
shapes = [[0.1, 0.3], [0.4, -0.2], [1.0, 0.5]]
[[joint]]
dofs = ["a", "b"]
law = "jenkins"
parameters = { kt = 1e4, Fs = 1.0 }
k_model = "stuck"
[force]
dofs = { tip = 1.0 }
[response]
dofs = ["tip"]
"""
    spec = read_structure_model(write(tmp_path, modal, "modal.toml"))
    st = structure_from_spec(spec)[0]
    assert np.allclose(st.engine.joint_shapes, [[0.3, -0.5]]) and spec.joints[0].k_model == 1e4
    assert st.solve(19.0, 0.5, 5).residual_norm < 1e-10


@pytest.mark.parametrize("old,new,error,match", [
    ('[damping]', '[dampin]', ManifestError, "dampin.*did you mean 'damping'"),
    ('modal = 0.002 ', 'modal = -0.1 ', ManifestError, "damping.modal.*non-negative"),
    ('file = "examples/lap_joint.npz"', 'file = "examples/nothing.npz"', RecordFileNotFoundError,
     "matrices.file.*nothing.npz"),
    ('mass_key = "M"', 'mass_key = "Mass"', ManifestError, "no array 'Mass'"),
    ('dofs = ["A.r10", "B.r0"]', 'dofs = ["A.r10", "B.r00"]', ManifestError, r"joint\[0\].dofs.*'B.r00'.*did you mean"),
    ('law = "iwan4"', 'law = "iwan"', ManifestError, r"joint\[0\].law.*did you mean 'iwan4'"),
    ('chi = -0.5', 'chi = -1.5', ManifestError, r"joint\[0\].parameters.*chi"),
    ('F_S = 2.0,', 'F_S = 2.0, mu = 3,', ManifestError, r"joint\[0\].parameters.*mu"),
    ('dofs = { "B.w10" = 1.0 }', 'dofs = { "B.w10" = "one" }', ManifestError, "force.dofs.B.w10"),
    ('n_modes = 12', 'n_modes = 100', ManifestError, "model.n_modes"),
    ('force_levels = [0.5, 2.0, 5.0]', 'force_levels = [0.5, 0.0]', ManifestError, r"predict.force_levels\[1\]"),
    ('motion = "rotation"', 'motion = "spin"', ManifestError, r"joint\[0\].motion.*translation.*rotation"),
    ('dofs = ["A.w0", "B.w10"] ', 'dofs = ["A.w0", "B.w10"]\nunits = { "B.r0" = "rad" } ', ManifestError,
     r"response.units.B.r0.*not one of the response DOFs"),
    ('dofs = ["A.w0", "B.w10"] ', 'dofs = ["A.w0", "B.w10"]\nunits = { "A.w0" = 3 } ', ManifestError,
     r"response.units.*DOF name -> unit"),
])
def test_bad_model_files_name_the_file_and_key(lap, old, new, error, match):
    text = lap.read_text(encoding="utf-8")
    if old == 'mass_key = "M"':
        old, new = 'file = "examples/lap_joint.npz"', 'file = "examples/lap_joint.npz"\nmass_key = "Mass"'
    assert old in text
    lap.write_text(text.replace(old, new, 1), encoding="utf-8")
    with pytest.raises(error, match=match) as info:
        read_structure_model(lap)
    assert str(lap) in str(info.value)


def test_bad_matrices_and_mechanisms(tmp_path):
    head = """
[matrices]
file = "m.npz"
[damping]
modal = 0.01
[[joint]]
dofs = ["a", "b"]
law = "jenkins"
parameters = { kt = 1e4, Fs = 1.0 }
[force]
dofs = { a = 1.0 }
[response]
dofs = ["b"]
"""
    p = write(tmp_path, head)
    np.savez(tmp_path / "m.npz", M=np.eye(2), K=np.array([[1.0, 2.0], [0.0, 1.0]]), dof_names=np.array(["a", "b"]))
    with pytest.raises(ManifestError, match=f"{re.escape(str(p))}.*'K' is not symmetric"):
        read_structure_model(p)
    np.savez(tmp_path / "m.npz", M=np.eye(2), K=np.array([[1.0, np.nan], [np.nan, 1.0]]), dof_names=np.array(["a", "b"]))
    with pytest.raises(ManifestError, match="NaN"):
        read_structure_model(p)
    # the joint's stiffness left out of K of two free masses: the joint is a mechanism
    np.savez(tmp_path / "m.npz", M=np.eye(2), K=np.zeros((2, 2)), dof_names=np.array(["a", "b"]))
    spec = read_structure_model(p)
    with pytest.raises(StructureError, match=f"{re.escape(str(p))}.*mechanism"):
        structure_from_spec(spec)
    np.savez(tmp_path / "m.npz", M=np.eye(2), K=-np.eye(2), dof_names=np.array(["a", "b"]))
    with pytest.raises(StructureError, match="positive semi-definite"):
        structure_from_spec(read_structure_model(p))
    (tmp_path / "m.npz").write_bytes(b"not a zip file")
    with pytest.raises(ManifestError, match="cannot read m.npz"):
        read_structure_model(p)


def test_predict_command_on_the_documented_model(lap, tmp_path, capsys):
    import json

    from jointid.cli import EXIT_OK, main

    out = tmp_path / "lap-out"
    assert main(["predict", str(lap), "--force-levels", "0.5,5", "--frequency-range", "72", "88", "--harmonics", "3",
                 "--out", str(out), "--quiet"]) == EXIT_OK
    res = json.loads((out / "results.json").read_text())
    assert [p["force_level"] for p in res["predictions"]] == [0.5, 5.0]
    assert (out / "figures" / "structure_frf.png").is_file() and (out / "report.txt").is_file()
    lo, hi = (p["peaks"]["B.w10"] for p in res["predictions"])
    assert res["model"]["response_units"] == {"A.w0": "m", "B.w10": "m"}  # translations unless declared
    # the lap joint is a rotation: its Iwan law's slip force is a moment, its stiffness per radian
    assert res["model"]["joints"][0]["units"] == {"F_S": "N m", "K_T": "N m/rad", "chi": "1", "beta": "1"}
    # the joint slips more at 5 N: the peak moves down from the stuck joint's 84.19 Hz, and further at 5 N
    assert 72 < hi["peak_frequency_hz"] < lo["peak_frequency_hz"] < 84.19
    for p in res["predictions"]:
        assert p["max_residual"] < 1e-8 and p["error"] == ""
        f = np.array(p["curve"]["frequency_hz"])
        assert f[0] == pytest.approx(72.0) and f[-1] == pytest.approx(88.0)
        # the located peak is at least the largest continued point
        assert p["peaks"]["B.w10"]["peak_amplitude"] >= max(p["curve"]["amplitude"]["B.w10"]) * (1 - 1e-12)


def test_motion_units_read_a_translation_law_for_a_rotation():
    from jointid.io.structure_model import motion_units

    assert [motion_units(u, "rotation") for u in ("N", "N/m", "1", "1/m", "N/m^3", "N s/m")] == [
        "N m", "N m/rad", "1", "1/rad", "N m/rad^3", "N m s/rad"]
    assert motion_units("N/m", "translation") == "N/m"
