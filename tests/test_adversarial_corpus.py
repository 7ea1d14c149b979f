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
    assert "d.toml" in err
    assert not (tmp_path / "out").exists()


def test_the_corpus_bases_import(tmp_path, capsys):
    """The sources the import cases break are imported when left whole."""
    _csv(tmp_path)
    _fh_csv(tmp_path)
    (tmp_path / "d.toml").write_text(IMPORT.format(channels=MAP, file="d.csv", extra="frequency_hz = 20.0") +
                                     '[[record]]\nfile = "fh.csv"\n' + FH + f"channels = {FH_MAP}\n")
    code, out, _ = _run(["import", tmp_path / "d.toml", "--out", tmp_path / "out"], capsys)
    assert code == 0 and "2 records written" in out
