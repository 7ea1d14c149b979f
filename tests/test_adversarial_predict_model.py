"""``jointid predict MODEL.toml`` on adversarial model files: bad input refused naming the file and key,
implausible results flagged (exit 1), no hang (the audit of the structure model file)."""

import functools
import json
import signal

import numpy as np
import pytest
import scipy.io
import scipy.sparse

import two_mass_backbone as tb

from jointid.app.structure_predict import predict_structure
from jointid.cli import main
from jointid.errors import ConvergenceError, ManifestError, StructureError
from jointid.io.structure_model import read_structure_model
from jointid.simulate.structure import structure_from_spec
from jointid.simulate.structure_hb import CondensedHB
from jointid.simulate.structure_timeint import integrate_structure

# two masses, a Jenkins joint from x1 to the ground, the force at x2 (modes 22.5 and 45 Hz): the model file
# of docs/formats.md
TWO_MASS = tb.MODEL_TOML
JENKINS = 'law = "jenkins"\nparameters = { kt = 2.5e3, Fs = 1.25 }'


def model(tmp_path, *changes, extra="", name="MODEL.toml"):
    """TWO_MASS with ``(old, new)`` replacements and ``extra`` text appended, written to ``tmp_path``."""
    text = TWO_MASS
    for old, new in changes:
        assert old in text
        text = text.replace(old, new)
    p = tmp_path / name
    p.write_text(text + extra, encoding="utf-8")
    return p


@pytest.fixture
def deadline():
    """A test that would hang fails after 30 s instead."""
    def boom(*_):
        raise TimeoutError("the run did not end within 30 s")

    old = signal.signal(signal.SIGALRM, boom)
    signal.alarm(30)
    yield
    signal.alarm(0)
    signal.signal(signal.SIGALRM, old)


# --- 1. Iwan n_sliders ----------------------------------------------------------------------------
@pytest.mark.parametrize("value", ["inf", "nan", '"sixty"', "20001", "true"])
def test_iwan_slider_count_is_an_integer_within_its_bound(tmp_path, value):
    law = f'law = "iwan4"\nparameters = {{ F_S = 1.25, K_T = 2.5e3, chi = -0.5, beta = 0.1, n_sliders = {value} }}'
    p = model(tmp_path, (JENKINS, law))
    with pytest.raises(ManifestError, match=r"MODEL\.toml: joint\[0\]\.parameters.*n_sliders.*(10000|a number)"):
        read_structure_model(p)


# --- 2. Matrix Market files -----------------------------------------------------------------------
def _chain(tmp_path, mass_text):
    K = np.array([[2.0, -1.0, 0.0], [-1.0, 2.0, -1.0], [0.0, -1.0, 1.0]]) * 1e4
    scipy.io.mmwrite(str(tmp_path / "K.mtx"), scipy.sparse.coo_matrix(K))
    (tmp_path / "M.mtx").write_text(mass_text)
    p = tmp_path / "chain.toml"
    p.write_text('[matrices]\nmass = "M.mtx"\nstiffness = "K.mtx"\ndof_names = ["x1", "x2", "x3"]\n'
                 '[damping]\nmodal = 0.002\n[[joint]]\ndofs = ["x1", "x2"]\nlaw = "jenkins"\n'
                 'parameters = { kt = 5e3, Fs = 1.0 }\n[force]\ndofs = { "x3" = 1.0 }\n[response]\ndofs = ["x3"]\n')
    return p


def test_a_huge_matrix_market_file_is_refused_before_it_is_made_dense(tmp_path):
    p = _chain(tmp_path, "%%MatrixMarket matrix coordinate real symmetric\n200000 200000 1\n1 1 1.0\n")
    with pytest.raises(ManifestError, match=r"chain\.toml: matrices\.mass: M\.mtx: .*200000 x 200000.*5000 DOFs"):
        read_structure_model(p)


def test_a_matrix_market_pattern_file_is_no_matrix_of_values(tmp_path):
    p = _chain(tmp_path, "%%MatrixMarket matrix coordinate pattern symmetric\n3 3 3\n1 1\n2 2\n3 3\n")
    with pytest.raises(ManifestError, match=r"matrices\.mass: M\.mtx: .*pattern"):
        read_structure_model(p)


# --- 3, 8. the time check is bounded; one that is not done is said, not a failure (the harmonic balance is
# not in doubt: an explicit integrator cannot afford the model's highest mode) -----------------------------
def test_a_time_check_on_an_absurdly_stiff_mode_is_not_done_and_says_how_to_do_it(tmp_path, deadline):
    p = model(tmp_path, ("frequencies_hz = [22.507907903927652, 45.015815807855304]",
                         "frequencies_hz = [22.507907903927652, 1e8]"))
    lines = []
    res = predict_structure(p, force_levels=[0.5], frequency_range=(18.0, 30.0), time_check=1, progress=lines.append)
    (c,) = res.time_checks
    assert "not done" in c["not_done"] and "n_modes" in c["not_done"] and "--time-check 0" in c["not_done"]
    assert not c["error"] and c["relative_difference"] is None
    assert not res.failed and not res.levels[0].flagged
    assert "1 not done" in lines[-1] and "within" not in lines[-1] and "FAILED" not in lines[-1]
    assert any("not done" in line for line in res.lines())


def test_the_time_integration_stops_at_its_step_bound(tmp_path, deadline):
    st, _ = structure_from_spec(read_structure_model(model(tmp_path)))
    p = st.solve(22.0, 0.5, 3)
    with pytest.raises(ConvergenceError, match="stopped after 80 steps"):
        integrate_structure(st, p, dofs=["x2"], n_periods=10, max_steps=80)


# --- 4. a peak at the edge of the band is no peak ----------------------------------------------------
def test_a_curve_largest_at_the_band_edge_has_no_peak_and_exits_1(tmp_path, capsys):
    p = model(tmp_path)
    rc = main(["predict", str(p), "--force-levels", "0.5", "--frequency-range", "1", "5", "--time-check", "0",
               "--harmonics", "2", "--out", str(tmp_path / "out"), "--quiet"])
    assert rc == 1
    assert "x2 no peak in 1-5 Hz" in capsys.readouterr().err
    pk = json.loads((tmp_path / "out" / "results.json").read_text())["predictions"][0]["peaks"]["x2"]
    assert pk["located"] == "no peak" and pk["peak_frequency_hz"] is None and pk["largest_at_hz"] == 5.0


# --- 5. a continuation that stopped early; zero damping -------------------------------------------------
def test_a_partial_curve_and_an_undamped_mode_are_flagged(tmp_path, monkeypatch):
    monkeypatch.setattr(CondensedHB, "continuation", functools.partialmethod(CondensedHB.continuation, max_steps=8))
    p = model(tmp_path, ("damping_ratios = [0.002, 0.002]", "damping_ratios = [0.0, 0.0]"))
    res = predict_structure(p, force_levels=[0.5], frequency_range=(18.0, 30.0), n_harmonics=2, time_check=0)
    (lv,) = res.levels
    assert lv.flagged and any("partial" in w for w in lv.warnings) and res.failed
    assert any("no damping at rest" in w for w in res.warnings)
    assert "F = 0.5 N: WARNING: continuation stopped after 8 steps" in res.report()


# --- 6. modal data listed out of order ----------------------------------------------------------------
def test_unsorted_modal_data_keep_the_lowest_mode_with_its_shape(tmp_path):
    p = model(tmp_path, ("[model]\n", "[model]\nn_modes = 1\n"),
              ("frequencies_hz = [22.507907903927652, 45.015815807855304]",
               "frequencies_hz = [45.015815807855304, 22.507907903927652]"),
              ("damping_ratios = [0.002, 0.002]", "damping_ratios = [0.003, 0.001]"),
              ("shapes = [[0.5773502691896258, 0.816496580927726], [1.1547005383792517, -0.816496580927726]]",
               "shapes = [[0.816496580927726, 0.5773502691896258], [-0.816496580927726, 1.1547005383792517]]"))
    st, _ = structure_from_spec(read_structure_model(p))
    assert st.modal.frequencies_hz == pytest.approx([22.507907903927652])
    assert st.modal.zeta == pytest.approx([0.001])
    assert st.modal.shapes[:, 0] == pytest.approx([0.5773502691896258, 1.1547005383792517])


# --- 7. no force, an inert joint ----------------------------------------------------------------------
def test_a_force_of_zero_weight_and_an_inert_joint_are_refused(tmp_path):
    p = model(tmp_path, ('dofs = { "x2" = 1.0 }', 'dofs = { "x2" = 0.0 }'))
    with pytest.raises(ManifestError, match=r"MODEL\.toml: force\.dofs: every weight is 0"):
        read_structure_model(p)
    p = model(tmp_path, ("[[0.5773502691896258, 0.816496580927726]", "[[0.0, 0.0]"))
    with pytest.raises(StructureError, match=r"MODEL\.toml: joint\[0\]\.dofs: joint 'slip' .*inert"):
        structure_from_spec(read_structure_model(p))


# --- 9. negative damping, a statically unstable joint -------------------------------------------------
@pytest.mark.parametrize("params,flag", [('{ "q" = 1e3, "q\'" = -5.0 }', "negative damping at rest"),
                                         ('{ "q" = -1e6 }', "statically unstable")])
def test_negative_damping_and_a_statically_unstable_joint_are_flagged(tmp_path, params, flag):
    p = model(tmp_path, (JENKINS, f'law = "polynomial"\nparameters = {params}'))
    res = predict_structure(p, force_levels=[0.5], frequency_range=(18.0, 30.0), n_harmonics=2, time_check=0)
    assert any(flag in w for w in res.warnings) and res.failed
    assert f"WARNING: {flag}" in res.report()


# --- 10, 11. units and types ------------------------------------------------------------------------------
def test_a_response_unit_that_is_no_length_or_angle_is_refused(tmp_path):
    p = model(tmp_path, extra='units = { "x2" = "kg" }\n')
    with pytest.raises(ManifestError, match=r"MODEL\.toml: response\.units\.x2: 'kg' is not a unit of length or angle"):
        read_structure_model(p)
    assert read_structure_model(model(tmp_path, extra='units = { "x2" = "mm" }\n')).response_units == {"x2": "mm"}


@pytest.mark.parametrize("law,key", [("parameters = { kt = true, Fs = 1.25 }", "kt"),
                                     ('parameters = { kt = "2.5e3", Fs = 1.25 }', "kt"),
                                     ('law = "discrete_iwan"\nparameters = { stiffness = "1e3", slip_force = "1" }',
                                      "stiffness"),
                                     ('law = "discrete_iwan"\nparameters = { stiffness = [1e3, "2"], slip_force = '
                                      '[1.0, 2.0] }', r"stiffness\[1\]")])
def test_law_parameters_are_toml_numbers(tmp_path, law, key):
    new = law if law.startswith("law") else f'law = "jenkins"\n{law}'
    p = model(tmp_path, (JENKINS, new))
    with pytest.raises(ManifestError, match=rf"MODEL\.toml: joint\[0\]\.parameters\.{key}: expected a number"):
        read_structure_model(p)


# --- 12. [predict] n_harmonics and n_time -------------------------------------------------------------
def test_the_files_harmonics_apply_unless_the_option_is_given(tmp_path):
    p = model(tmp_path, extra="[predict]\nn_harmonics = 3\nfrequency_range_hz = [18.0, 30.0]\n")
    for opts, H in (([], 3), (["--harmonics", "2"], 2)):
        out = tmp_path / f"out{H}"
        assert main(["predict", str(p), "--force-levels", "0.5", "--time-check", "0", "--out", str(out),
                     "--quiet", *opts]) == 0
        assert json.loads((out / "results.json").read_text())["settings"]["n_harmonics"] == H



def test_a_results_folder_is_predicted_with_five_harmonics_by_default(tmp_path, monkeypatch):
    import jointid.app.predict as predict

    seen = {}

    def fake(file, levels, **kw):
        seen.update(kw)
        raise KeyboardInterrupt  # stop here: only the arguments are checked

    monkeypatch.setattr(predict, "load_results", lambda path: ({}, tmp_path / "results.json"))
    monkeypatch.setattr(predict, "predict_from_results", fake)
    for opts, H in (([], 5), (["--harmonics", "3"], 3)):
        assert main(["predict", str(tmp_path / "res"), "--force-levels", "1", "--out", str(tmp_path / "o"),
                     *opts]) == 130
        assert seen["n_harmonics"] == H


def test_too_few_time_samples_in_the_file_name_the_key(tmp_path):
    p = model(tmp_path, extra="[predict]\nn_time = 8\nfrequency_range_hz = [18.0, 30.0]\n")
    with pytest.raises(ManifestError, match=r"MODEL\.toml: predict\.n_time: 8 .*exceed 2 n_harmonics = 10"):
        predict_structure(p, force_levels=[0.5])


# --- 13. messages in the user's terms; two joints of one name -------------------------------------------
def test_stuck_of_a_negative_stiffness_says_what_the_user_wrote(tmp_path):
    p = model(tmp_path, (JENKINS, 'law = "polynomial"\nparameters = { "q" = -1e3, "-q^3" = 1e9 }\nk_model = "stuck"'))
    with pytest.raises(ManifestError, match=r'joint\[0\]\.k_model: "stuck" takes the law\'s stiffness at rest, '
                                            r'here -1000 \(its "q" term\)') as e:
        read_structure_model(p)
    assert "got -1000.0" not in str(e.value)


def test_a_missing_band_names_the_option(tmp_path):
    with pytest.raises(ManifestError, match=r"predict\.frequency_range_hz: missing.*--frequency-range"):
        predict_structure(model(tmp_path), force_levels=[0.5])


def test_two_joints_of_one_name_are_refused(tmp_path):
    p = model(tmp_path, extra='[[joint]]\nname = "slip"\ndofs = ["x2"]\nlaw = "jenkins"\n'
                              'parameters = { kt = 2.5e3, Fs = 1.25 }\n')
    with pytest.raises(ManifestError, match=r"MODEL\.toml: joint\[1\]\.name: joint name 'slip' appears twice"):
        read_structure_model(p)


def test_a_folder_given_as_the_model_is_said_to_be_one(tmp_path):
    folder = tmp_path / "MODEL.toml"
    folder.mkdir()
    with pytest.raises(ManifestError, match=r"MODEL\.toml: structure model is a folder, not a file"):
        read_structure_model(folder)
