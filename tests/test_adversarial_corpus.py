"""Adversarial corpus of every command and input format: the cases that were accepted silently
or ended in a traceback before, one row per case.

Each bad input ends in exit 2 (or a failed, flagged record, exit 1) with a message naming the
file, the record or key and the cause; no traceback, no warning printed by a library, no output
folder left behind.
"""

from __future__ import annotations

import numpy as np
import pytest

from jointid.cli import main

T = np.arange(4096) / 1024.0
F = np.sin(2 * np.pi * 20 * T)
A = -((2 * np.pi * 20) ** 2) * 1e-3 * np.sin(2 * np.pi * 20 * T - 0.3)


def _run(argv, capsys):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    assert "Traceback" not in err and "internal error" not in err, err
    assert "Warning" not in err, err  # a library's warning is not a message of jointid
    return code, out, err


# ------------------------------------------------------------------------------ import: sources
def _csv(folder, name="d.csv", text=None):
    if text is None:
        np.savetxt(folder / name, np.column_stack([T, F, A]), delimiter=",", header="time,F,A", comments="")
    else:
        (folder / name).write_text(text)


def _fh_csv(folder, name="fh.csv", phase=None):
    f = np.linspace(18, 22, 21)
    w, w0 = 2 * np.pi * f, 2 * np.pi * 20
    H = -(w**2) / (w0**2 - w**2 + 2j * 0.02 * w0 * w)
    p = np.angle(H) if phase is None else np.full(f.size, phase)
    np.savetxt(folder / name, np.column_stack([f, np.ones_like(f), np.abs(H), p]), delimiter=",",
               header="f,F,A,P", comments="")


def _mat_text(folder):
    from scipy.io import savemat

    savemat(folder / "d.mat", {"f": "abc", "F": np.ones(3), "A": np.ones(3), "P": np.ones(3)})


def _h5_enum(folder):
    import h5py

    with h5py.File(folder / "d.h5", "w") as h5:
        h5.create_dataset("F", data=np.zeros(T.size, "i1"), dtype=h5py.enum_dtype({"off": 0, "on": 1}, basetype="i1"))
        h5["A"] = A


IMPORT = '[import]\nfs = 1024.0\nchannels = {channels}\n[[record]]\nfile = "{file}"\n{extra}\n'


def _csv_dead(folder, value):
    np.savetxt(folder / "d.csv", np.column_stack([T, F, np.full(T.size, value)]), delimiter=",", header="time,F,A",
               comments="")


def _mat_logical(folder):
    from scipy.io import savemat

    savemat(folder / "d.mat", {"F": F > 0, "A": A})


STRUCT = 'force_column = "force"\nmode_shape = { force = 0.02, accel = 2.0 }\n'
PHYSICAL = '[campaign]\ncoordinates = "physical"\n[structure]\n{structure}'

MAP = '{ force = "F", accel = "A" }'
FH_MAP = '{ frequency_hz = "f", force = "F", accel = "A", accel_phase = "P" }'
FH = 'excitation = "first-harmonic"\n'

# name: (write the sources, description text, pattern the message must hold)
IMPORT_CASES = {
    # a MAT text variable as a first-harmonic column was a traceback (multiplying text by a unit factor)
    "fh_mat_text": (_mat_text, IMPORT.format(channels=FH_MAP, file="d.mat", extra=FH), r"'f' holds text"),
    # the acceleration phase was taken as 0 on every line when not mapped
    "fh_accel_without_phase": (_fh_csv, IMPORT.format(channels='{ frequency_hz = "f", force = "F", accel = "A" }',
                                                      file="fh.csv", extra=FH), r"accel_phase'\]: missing"),
    "fh_phase_not_radians": (lambda d: _fh_csv(d, phase=1e300), IMPORT.format(channels=FH_MAP, file="fh.csv",
                                                                              extra=FH), "not a phase in radians"),
    "fh_window_on_record": (_fh_csv, IMPORT.format(channels=FH_MAP, file="fh.csv", extra=FH + "window_s = [0.0, 1.0]"),
                            "window_s: no meaning on a first-harmonic record"),
    "fh_frequency_on_record": (_fh_csv, IMPORT.format(channels=FH_MAP, file="fh.csv", extra=FH + "frequency_hz = 20.0"),
                               "frequency_hz: no meaning on a first-harmonic record"),
    # the record's file was used and its sources silently ignored
    "file_and_source": (_csv, IMPORT.format(channels=MAP, file="d.csv", extra='[[record.source]]\nfile = "d.csv"\n'
                                            'channels = { force = "A" }'), "not both"),
    "physical_without_structure": (_csv, '[campaign]\ncoordinates = "physical"\n' + IMPORT.format(
        channels=MAP, file="d.csv", extra=""), r"needs a \[structure\] table"),
    "same_channel_twice": (_csv, IMPORT.format(channels='{ force = "F", accel = "F" }', file="d.csv", extra=""),
                           "channels.force and channels.accel both name channel 'F'"),
    "frequency_above_nyquist": (_csv, IMPORT.format(channels=MAP, file="d.csv", extra="frequency_hz = 2000.0"),
                                "at or above the Nyquist frequency 512 Hz"),
    "window_shorter_than_a_period": (_csv, IMPORT.format(channels=MAP, file="d.csv",
                                                         extra="frequency_hz = 20.0\nwindow_s = [1.0, 1.001]"),
                                     "less than one period of frequency_hz 20"),
    "multisine_period_beyond_record": (_csv, IMPORT.format(channels=MAP, file="d.csv",
                                                           extra='excitation = "multisine"\nperiod_s = 100.0'),
                                       "period_s 100 is longer than the record"),
    "hdf5_enum": (_h5_enum, IMPORT.format(channels=MAP, file="d.h5", extra=""), "got an enumeration"),
    # issue 24: accepted silently before
    "dead_channel_zero": (lambda d: _csv_dead(d, 0.0), IMPORT.format(channels=MAP, file="d.csv", extra=""),
                          r"d.csv \[record 0, channel 'accel'\]: zero at every sample"),
    "dead_channel_constant": (lambda d: _csv_dead(d, 9.81), IMPORT.format(channels=MAP, file="d.csv", extra=""),
                              r"d.csv \[record 0, channel 'accel'\]: constant \(9.81 at every sample\)"),
    "stepped_sine_without_force": (_csv, IMPORT.format(channels='{ accel = "A" }', file="d.csv", extra=""),
                                   r"d.csv \[record 0, channel 'force'\]: a stepped-sine record needs its force"),
    "multisine_without_force": (_csv, IMPORT.format(channels='{ accel = "A" }', file="d.csv",
                                                    extra='excitation = "multisine"\nperiod_s = 1.0'),
                                r"channel 'force'\]: a multisine record needs its force column"),
    "stepped_sine_without_response": (_csv, IMPORT.format(channels='{ force = "F" }', file="d.csv", extra=""),
                                      r"channel 'accel'\]: a stepped-sine record needs a response column"),
    "structure_unknown_key": (_csv, PHYSICAL.format(structure=STRUCT + "stifness = 3\n") +
                              IMPORT.format(channels=MAP, file="d.csv", extra=""),
                              r"\[structure\] unknown key 'stifness'"),
    "structure_garbage_value": (_csv, PHYSICAL.format(structure='beam = "steel"\n') +
                                IMPORT.format(channels=MAP, file="d.csv", extra=""), r"structure.beam"),
    "structure_not_a_table": (_csv, 'structure = 3\n' + IMPORT.format(channels=MAP, file="d.csv", extra=""),
                              r"\[structure\] must be a table, got 3"),
    "structure_per_preload_missing": (_csv, PHYSICAL.format(structure="") + "[structure.5]\n" + STRUCT +
                                      IMPORT.format(channels=MAP, file="d.csv", extra="preload = 7"),
                                      r"\[record 0\]: no \[structure.7\] table for preload 7"),
    "structure_file_reference": (_csv, PHYSICAL.format(structure="") + '[structure.5]\nfile = "s.toml"\n' +
                                 IMPORT.format(channels=MAP, file="d.csv", extra="preload = 5"),
                                 r"\[structure.5\] file: an import copies the \[structure\] tables"),
    "mat_logical_channel": (_mat_logical, IMPORT.format(channels=MAP, file="d.mat", extra=""),
                            r"d.mat \[channel 'force'\]: 'F' is a MATLAB logical \(true/false\) array"),
    # numpy's "input contained no data" warning was printed above jointid's own message
    "csv_empty": (lambda d: _csv(d, text=""), IMPORT.format(channels=MAP, file="d.csv", extra=""),
                  r"d.csv \[channel 'F'\]: missing column"),
}


@pytest.mark.parametrize("name", list(IMPORT_CASES))
def test_import_corpus(tmp_path, capsys, name):
    write, text, pattern = IMPORT_CASES[name]
    write(tmp_path)
    (tmp_path / "d.toml").write_text(text)
    code, _, err = _run(["import", tmp_path / "d.toml", "--out", tmp_path / "out"], capsys)
    assert code == 2 and len(__import__("re").findall(pattern, err)) >= 1, err
    assert "d.toml" in err and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "out").exists()


def test_the_corpus_bases_import(tmp_path, capsys):
    """The sources the import cases break are imported when left whole."""
    _csv(tmp_path)
    _fh_csv(tmp_path)
    (tmp_path / "d.toml").write_text(IMPORT.format(channels=MAP, file="d.csv", extra="frequency_hz = 20.0") +
                                     '[[record]]\nfile = "fh.csv"\n' + FH + f"channels = {FH_MAP}\n")
    code, out, _ = _run(["import", tmp_path / "d.toml", "--out", tmp_path / "out"], capsys)
    assert code == 0 and "2 records written" in out


# ------------------------------------------------------------------------------ --out symlink loops
def _sim_toml(folder):
    text = ('[campaign]\nname = "x"\n[[model]]\npreload = "p"\nterms = "q + -q^3 + q\'"\nomega1 = 170.0\n'
            'coefficients = { k3 = 5e6 }\namplitude_laws = { c = [0.08] }\n[excitation]\nforce_levels = [1.0]\n'
            'omega_start = 165.0\nomega_stop = 175.0\nn_frequencies = 2\n[acquisition]\nfs = 2000.0\nperiods = 5.0\n')
    (folder / "s.toml").write_text(text)
    return folder / "s.toml"


# a --out that is a link to itself was a traceback (FileExistsError / too many levels of links) in these
# commands; each must refuse it before any work
@pytest.mark.parametrize("argv", [
    lambda d: ["simulate", _sim_toml(d), "--out", d / "out", "--quiet"],
    lambda d: ["example", "--out", d / "out"],
    lambda d: ["example", "--copy", "all", "--to", d / "out"],
    lambda d: ["backbone", d / "results.json", "--out", d / "out"],
    lambda d: ["modal", _sim_toml(d), "--out", d / "out"],
], ids=["simulate", "example", "example_copy", "backbone", "modal"])
def test_out_symlink_loop_is_refused(tmp_path, capsys, argv):
    import os

    (tmp_path / "results.json").write_text("{}")
    os.symlink(tmp_path / "out", tmp_path / "out")
    code, _, err = _run(argv(tmp_path), capsys)
    assert code == 2 and "symbolic link to nothing (or a loop of links)" in err, err


# ------------------------------------------------------------------------------ first-harmonic lines of noise
def _fh_campaign(folder, noisy_level):
    rng = np.random.default_rng(4)
    folder.mkdir()
    f = np.linspace(18, 22, 21)
    w, w0 = 2 * np.pi * f, 2 * np.pi * 20
    lines = ['[campaign]\nname = "fh"\n']
    for i, level in enumerate((1.0, 2.0)):
        H = -(w**2) / (w0**2 - w**2 + 2j * 0.02 * w0 * w)
        if i == noisy_level:
            H = np.abs(rng.standard_normal(f.size)) * np.exp(1j * rng.uniform(-3, 3, f.size))
        np.savetxt(folder / f"fh{i}.csv", np.column_stack([f, np.full(f.size, level), level * np.abs(H),
                                                           np.angle(H)]),
                   delimiter=",", header="frequency_hz,force,accel,accel_phase", comments="")
        lines.append(f'[[record]]\nfile = "fh{i}.csv"\npreload = "p"\nforce_level = {level}\n'
                     'excitation = "first-harmonic"\n')
    (folder / "campaign.toml").write_text("".join(lines))
    return folder


def test_first_harmonic_lines_of_noise_are_not_identified(tmp_path, capsys):
    """A level of noise was fitted for minutes (every candidate law at its evaluation limit) and the run
    ended with exit 0 and no word; now the preload is refused at once and the run says so (exit 1)."""
    import json
    import time

    t0 = time.perf_counter()
    code, _, err = _run(["identify", _fh_campaign(tmp_path / "c", 0), "--out", tmp_path / "r", "--no-figures",
                         "--quiet"], capsys)
    assert time.perf_counter() - t0 < 30
    assert code == 1 and "preload p: not identified" in err and "level 1.0 scatter by" in err, err
    (p,) = json.loads((tmp_path / "r" / "results.json").read_text())["first_harmonic"]
    assert p["fit"] is None and "no resonance of one mode" in p["errors"]["fit"]


def test_linear_mode_scatter_separates_a_resonance_from_noise():
    from jointid.app.firstharmonic_campaign import MAX_LINEAR_SCATTER, linear_mode_scatter
    from jointid.identify.firstharmonic import FirstHarmonicLevel
    from jointid.io.campaign import load_campaign
    from jointid.io.firsth import read_first_harmonic_record

    import tempfile
    from pathlib import Path

    with tempfile.TemporaryDirectory() as d:
        camp = load_campaign(_fh_campaign(Path(d) / "c", 0))
        noise, clean = (linear_mode_scatter(FirstHarmonicLevel.from_record(read_first_harmonic_record(s), "x"))
                        for s in camp.records)
    assert clean < 1e-6 and noise > 1.5 * MAX_LINEAR_SCATTER


# ------------------------------------------------------------------------------ public-data on damaged files
def test_public_data_with_a_damaged_mat_file_names_it(tmp_path, capsys, monkeypatch):
    """A damaged data file was a traceback; now it fails its example, named, and the others still run."""
    import shutil
    from pathlib import Path

    from jointid.io.datasets import shared_data_dir

    real = shared_data_dir()
    sh = tmp_path / "sh"
    (sh / "silverbox_multilevel_noel").mkdir(parents=True)
    for f in Path(real / "silverbox_multilevel_noel").glob("*.mat"):
        (sh / "silverbox_multilevel_noel" / f.name).write_bytes(b"MATLAB 5.0 MAT-file" + bytes(200))
    shutil.copytree(real / "silverbox", sh / "silverbox")
    monkeypatch.setenv("JOINTID_SHARED_DATA", str(sh))
    code, _, err = _run(["public-data", "--only", "silverbox", "--out", tmp_path / "out"], capsys)
    assert code == 2 and "silverbox: failed:" in err and "SNJP_" in err and "no example could be run" in err, err
    assert not (tmp_path / "out").exists()


# ------------------------------------------------------------------------------ modal --frf
def test_modal_nperseg_beyond_half_the_record_is_refused(tmp_path, capsys, monkeypatch):
    """--nperseg 1e9 was clipped to one segment (coherence 1 whatever the data) and the fit ran past minutes."""
    from test_frf_modal_cli import STRUCTURE

    from jointid.io.campaign import write_csv_record

    monkeypatch.chdir(tmp_path)
    rng = np.random.default_rng(3)
    n = 4096
    (tmp_path / "s.toml").write_text(STRUCTURE.format(x_f=0.05))
    write_csv_record(tmp_path / "r.csv", np.arange(n) / 1024.0,
                     {"force": rng.standard_normal(n), "accel_42": rng.standard_normal(n)})
    code, _, err = _run(["modal", tmp_path / "s.toml", "--frf", tmp_path / "r.csv", "--response", "accel_42",
                         "--nperseg", "1000000000", "--out", tmp_path / "out"], capsys)
    assert code == 2 and "r.csv: --nperseg 1000000000 leaves fewer than two averages" in err and "2048" in err, err


# ------------------------------------------------------------------------------ ring-down of absurd amplitude
def test_a_ringdown_whose_fit_breaks_fails_alone(tmp_path, capsys):
    """A ring-down of amplitude 1e300 broke the decay fit (LinAlgError) and took every backbone of the
    campaign with it, exit 0; now it fails itself, named, and the run says so (exit 1)."""
    import json

    from jointid.app.synthesis import load_simulation_config, simulate_campaign
    from jointid.io.campaign import write_csv_record

    cfg = {"campaign": {"name": "rd"},
           "model": [{"preload": "p", "terms": "q + -q^3 + q'", "omega1": 170.0, "coefficients": {"k3": 5e6},
                      "amplitude_laws": {"c": [0.08, 70.0, 1e4]}}],
           "excitation": {"force_levels": [1.0], "omega_start": 165.0, "omega_stop": 175.0, "n_frequencies": 4},
           "acquisition": {"fs": 2000.0, "periods": 10.0, "noise": 0.01, "seed": 1}}
    camp = simulate_campaign(load_simulation_config(cfg), tmp_path / "c")
    t = np.arange(8000) / 2000.0
    write_csv_record(camp / "rd_huge.csv", t, {"accel": 1e300 * np.exp(-t) * np.sin(170.0 * t)})
    with open(camp / "campaign.toml", "a", encoding="utf-8") as fh:
        fh.write('\n[[record]]\nfile = "rd_huge.csv"\npreload = "p"\nforce_level = 1.0\nexcitation = "ringdown"\n')
    code, _, err = _run(["identify", camp, "--out", tmp_path / "r", "--no-figures", "--no-reprediction", "--quiet"],
                        capsys)
    assert code == 1 and "rd_huge.csv" in err and "not a usable free decay" in err, err
    bb = json.loads((tmp_path / "r" / "results.json").read_text())["backbones"]
    assert bb["error"] is None and len(bb["preloads"]) == 1
    assert bb["preloads"][0]["model"] is not None  # the model's backbone is kept
