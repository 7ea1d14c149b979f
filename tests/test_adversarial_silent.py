"""Issue 24: bad inputs that were accepted silently (exit 0, no word) and now are refused or flagged.

``simulate`` onto an earlier campaign, a simulation model that is not physical (negative damping, a
softening term that leaves no well), overlapping ``modal --bands``, and import records that are dead,
without their force, with a garbage ``[structure]`` or with logical MAT channels.  The import cases of
the description itself are rows of tests/test_adversarial_corpus.py; here are the ones that need more
than one row: the controls that the same input, made whole, is accepted, and the partial imports.
"""

from __future__ import annotations

import numpy as np
import pytest

from jointid.cli import main
from jointid.io.outputset import MARKER, read_marker

SIM = ('[campaign]\nname = "x"\n[[model]]\npreload = "p"\nterms = "{terms}"\nomega1 = 170.0\n'
       'coefficients = {{ {coefficients} }}\n{laws}[excitation]\nforce_levels = [{levels}]\n'
       'omega_start = 165.0\nomega_stop = 175.0\nn_frequencies = {n}\n[acquisition]\nfs = 2000.0\nperiods = 5.0\n')


def _sim(folder, name="s.toml", coefficients="k3 = 5e6, c = 0.08", laws="", levels="1.0", n=2,
         terms="q + -q^3 + q'"):
    (folder / name).write_text(SIM.format(coefficients=coefficients, laws=laws, levels=levels, n=n, terms=terms))
    return folder / name


def _run(argv, capsys):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    assert "Traceback" not in err and "internal error" not in err, err
    return code, out, err


def _tree(folder):
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


# ------------------------------------------------------------------------------ 1. simulate onto a campaign
def test_simulate_replaces_its_own_earlier_campaign_as_a_whole(tmp_path, capsys):
    """A second run with fewer frequencies left the first run's third record beside the new ones."""
    from jointid.io.campaign import load_campaign

    out = tmp_path / "camp"
    assert _run(["simulate", _sim(tmp_path, "a.toml", n=3), "--out", out, "--quiet"], capsys)[0] == 0
    assert len(list((out / "records").iterdir())) == 3
    assert _run(["simulate", _sim(tmp_path, "b.toml", n=2), "--out", out, "--quiet"], capsys)[0] == 0
    assert sorted(p.name for p in (out / "records").iterdir()) == ["0000.csv", "0001.csv"]
    assert len(load_campaign(out).records) == 2
    marker = read_marker(out)
    assert marker["kind"] == "simulate" and sorted(marker["files"]) == ["campaign.toml", "records/0000.csv",
                                                                         "records/0001.csv"]
    assert not list(tmp_path.glob(".camp.*"))  # no temporary set left


@pytest.mark.parametrize("what", ["results_inside", "user_campaign", "config_inside"])
def test_simulate_never_deletes_what_it_did_not_create(tmp_path, capsys, what):
    out = tmp_path / "camp"
    assert _run(["simulate", _sim(tmp_path, n=2), "--out", out, "--quiet"], capsys)[0] == 0
    config = _sim(tmp_path, "b.toml", n=3)
    if what == "results_inside":  # identify's output set inside the campaign folder
        (out / "results").mkdir()
        (out / "results" / "results.json").write_text("{}")
        pattern = "did not write"
    elif what == "user_campaign":  # a campaign without jointid's marker: written by hand, or by an older version
        (out / MARKER).unlink()
        pattern = "did not write as an output set"
    else:
        config = _sim(out, "b.toml", n=3)
        pattern = "did not write (b.toml)"
    before = _tree(out)
    code, _, err = _run(["simulate", config, "--out", out, "--quiet"], capsys)
    assert code == 2 and pattern in err and len(err.strip().splitlines()) == 1, err
    assert _tree(out) == before


# ------------------------------------------------------------------------------ 2. a model that is not physical
@pytest.mark.parametrize("coefficients, laws, pattern", [
    ("k3 = 5e6, c = -0.08", "", "[model] coefficients.c: the damping coefficient c of term \"q'\" is -0.08"),
    ("k3 = 5e6, c = 0.08, c_cubic = -1.0", "", "coefficients.c_cubic: the damping coefficient c_cubic"),
    ("k3 = 5e30, c = 0.08", "", "coefficients.k3 = 5e+30"),
    # so softening that harmonic balance finds no solution of its equations at all
    ("k3 = 1e300, c = 0.08", "", "harmonic balance found no steady state at force level 1; the restoring force "
                                 "stops pulling back to rest by |q| = "),
    # the law is positive at rest but negative at the amplitudes reached near resonance
    ("k3 = 5e6", "amplitude_laws = { c = [0.08, -1000.0] }\n", "[model] amplitude_laws.c: the damping coefficient"),
], ids=["negative_c", "negative_cubic_damping", "softening_k3_5e30", "softening_k3_1e300", "damping_law_negative"])
def test_simulate_refuses_a_model_that_is_not_physical(tmp_path, capsys, coefficients, laws, pattern):
    terms = "q + -q^3 + q' + q'^3"
    code, _, err = _run(["simulate", _sim(tmp_path, coefficients=coefficients, laws=laws, n=3, terms=terms), "--out",
                         tmp_path / "out", "--quiet"], capsys)
    assert code == 2 and pattern in err and "s.toml" in err, err
    assert len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "out").exists()


def test_well_edge_of_a_softening_cubic_is_its_closed_form():
    """omega1^2 q - k3 q^3 stops pulling back at q = omega1 / sqrt(k3); a hardening one never does."""
    from jointid.app.synthesis import _well_edge
    from jointid.simulate.model import SingleModeModel

    for k3 in (5e6, 5e12, 5e30):
        m = SingleModeModel("q + -q^3 + q'", (170.0**2, k3, 0.1))
        exact = 170.0 / np.sqrt(k3)
        assert _well_edge(m, m.coefficients, 2 * exact) == pytest.approx(exact, rel=3e-3)
        assert _well_edge(m, m.coefficients, 0.99 * exact) is None
    hard = SingleModeModel("q + -q^3 + q'", (170.0**2, -5e30, 0.1))
    assert _well_edge(hard, hard.coefficients, 1.0) is None
    asym = SingleModeModel("q + q^2 + q'", (170.0**2, 1e6, 0.1))  # the well opens on the negative side only
    assert _well_edge(asym, asym.coefficients, 0.05) == pytest.approx(170.0**2 / 1e6, rel=3e-3)


def test_physical_models_near_their_limits_are_still_simulated(tmp_path, capsys):
    """Controls: a strongly softening model inside its well, a very stiff hardening one and zero damping
    of the cubic term are accepted; the hardening one has the amplitude of its cubic spring."""
    from jointid.app.synthesis import load_simulation_config, simulate_steady_states

    cfg = load_simulation_config(_sim(tmp_path, coefficients="k3 = 5e12, c = 0.08, c_cubic = 0.0", n=3,
                                      terms="q + -q^3 + q' + q'^3"))
    (_, _, frf), = simulate_steady_states(cfg)
    assert all(s.q_max < 170.0 / np.sqrt(5e12) for s in frf.states)
    cfg = load_simulation_config(_sim(tmp_path, "h.toml", coefficients="k3 = -5e30, c = 0.08", n=2))
    (_, _, frf), = simulate_steady_states(cfg)
    # q'' + 5e30 q^3 ~ sin: the one-harmonic balance (3/4) k A^3 = F within the higher harmonics' share
    assert all(s.amplitude == pytest.approx((4 / 3 / 5e30) ** (1 / 3), rel=0.1) for s in frf.states)


# ------------------------------------------------------------------------------ 3. modal --bands
@pytest.mark.parametrize("bands, pattern", [
    ("24-29,24-29", "band 1 (24-29 Hz) is given twice"),
    ("140-175,24-29,27-35", "band 2 (24-29 Hz) overlaps band 3 (27-35 Hz)"),
    ("24-inf", "expected finite 0 < LO < HI"),
])
def test_modal_bands_repeated_or_overlapping_are_refused(tmp_path, capsys, bands, pattern):
    from test_frf_modal_cli import STRUCTURE

    (tmp_path / "s.toml").write_text(STRUCTURE.format(x_f=0.05))
    code, _, err = _run(["modal", tmp_path / "s.toml", "--frf", tmp_path / "r.csv", "--response", "accel_42",
                         "--bands", bands, "--out", tmp_path / "out"], capsys)
    assert code == 2 and pattern in err and len(err.strip().splitlines()) == 1, err


def test_check_bands_accepts_touching_bands_and_refuses_overlap_given_as_pairs():
    from jointid.app.modal_workflow import check_bands, parse_bands
    from jointid.errors import IdentificationError

    assert parse_bands("24-29,29-35") == [(24.0, 29.0), (29.0, 35.0)]
    with pytest.raises(IdentificationError, match="overlaps"):
        check_bands([(140.0, 175.0), (150.0, 160.0)])


# ------------------------------------------------------------------------------ 4.-7. import
T = np.arange(4096) / 1024.0
F = np.sin(2 * np.pi * 20 * T)
A = -((2 * np.pi * 20) ** 2) * 1e-3 * np.sin(2 * np.pi * 20 * T - 0.3)


def _csv(folder, name, force=F, accel=A):
    np.savetxt(folder / name, np.column_stack([T, force, accel]), delimiter=",", header="time,F,A", comments="")


def test_import_leaves_out_a_dead_record_named_and_writes_the_others(tmp_path, capsys):
    from jointid.io.campaign import load_campaign

    _csv(tmp_path, "good.csv")
    _csv(tmp_path, "dead.csv", force=np.zeros(T.size))
    (tmp_path / "d.toml").write_text('[import]\nfs = 1024.0\nchannels = { force = "F", accel = "A" }\n'
                                     '[[record]]\nfile = "good.csv"\n[[record]]\nfile = "dead.csv"\n')
    code, out, _ = _run(["import", tmp_path / "d.toml", "--out", tmp_path / "c"], capsys)
    assert code == 1 and "1 records written" in out, out
    assert "record 1: dead.csv [record 1, channel 'force']: zero at every sample" in out, out
    assert len(load_campaign(tmp_path / "c").records) == 1


def test_import_of_ringdown_needs_no_force_and_a_valid_structure_is_imported(tmp_path, capsys):
    """Controls of the import rows: a free decay has no force column; a physical campaign with a
    checked [structure] table is imported, and identify reads the same table."""
    from jointid.io.campaign import load_campaign

    _csv(tmp_path, "d.csv")
    _csv(tmp_path, "decay.csv", force=np.zeros(T.size))  # the shaker's force channel recorded while detached
    (tmp_path / "d.toml").write_text(
        '[campaign]\ncoordinates = "physical"\n[structure]\nforce_column = "force"\n'
        'mode_shape = { force = 0.02, accel = 2.0 }\n[import]\nfs = 1024.0\n'
        '[[record]]\nfile = "d.csv"\nchannels = { force = "F", accel = "A" }\n'
        '[[record]]\nfile = "d.csv"\nchannels = { accel = "A" }\nexcitation = "ringdown"\n'
        '[[record]]\nfile = "decay.csv"\nchannels = { force = "F", accel = "A" }\nexcitation = "ringdown"\n')
    code, out, err = _run(["import", tmp_path / "d.toml", "--out", tmp_path / "c"], capsys)
    assert code == 0 and "3 records written" in out, (out, err)
    camp = load_campaign(tmp_path / "c")
    assert camp.coordinates == "physical" and camp.structure["mode_shape"] == {"force": 0.02, "accel": 2.0}


def test_mat_logical_is_refused_where_the_same_samples_as_numbers_are_read(tmp_path):
    from scipy.io import savemat

    from jointid.errors import RecordError
    from jointid.io.firsth import read_first_harmonic_source
    from jointid.io.matlab import read_mat

    savemat(tmp_path / "a.mat", {"trig": F > 0, "num": (F > 0).astype(float), "s": {"flag": F > 0}})
    assert np.array_equal(read_mat(tmp_path / "a.mat", {"x": "num"}, fs=1024.0)["x"], (F > 0).astype(float))
    for ref in ("trig", "s.flag"):
        with pytest.raises(RecordError, match=r"\[channel 'x'\]: '" + ref.replace(".", r"\.") + "' is a MATLAB logical"):
            read_mat(tmp_path / "a.mat", {"x": ref}, fs=1024.0)
    with pytest.raises(RecordError, match=r"'trig' holds logical values; expected numbers"):
        read_first_harmonic_source(tmp_path / "a.mat", {"force": "trig"})
