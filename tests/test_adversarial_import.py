"""`jointid import` refuses, with the file, dataset/column and key named (exit 2), what it used to
accept silently: complex MAT variables, units in the wrong case, an fs that contradicts the time
column, HDF5 external links; and its messages about v7.3 MAT files and HDF5 lengths say what to do."""

from __future__ import annotations

import warnings

import h5py
import numpy as np
import pytest

from jointid.cli import main
from jointid.errors import ManifestError, RecordError
from jointid.io.units import check_column_unit, unit_factor

FS = 512.0


def _signals(n=2048, fs=FS):
    t = np.arange(n) / fs
    return t, np.sin(2 * np.pi * 20 * t), 0.5 * np.cos(2 * np.pi * 20 * t)


def _run(argv, capsys):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    assert "Traceback" not in err and "internal error" not in err, err
    return code, out, err


def _describe(tmp_path, file, imp="", record=""):
    (tmp_path / "d.toml").write_text(f"[import]\n{imp}\n[[record]]\nfile = \"{file}\"\nfrequency_hz = 20.0\n{record}")
    return tmp_path / "d.toml"


def test_complex_mat_variable_is_refused_not_reduced_to_its_real_part(tmp_path, capsys):
    from scipy.io import savemat

    _, F, a = _signals()
    savemat(tmp_path / "r.mat", {"F": (F + 0.3j * a)[None, :], "A": a[None, :]})
    desc = _describe(tmp_path, "r.mat", f'fs = {FS}\nchannels = {{ force = "F", accel = "A" }}')
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no ComplexWarning from scipy either
        code, _, err = _run(["import", desc, "--out", tmp_path / "c"], capsys)
    assert code == 2, err
    line = err.strip().splitlines()[-1]
    assert "r.mat" in line and "'force'" in line and "'F'" in line and "complex" in line, err
    assert "ComplexWarning" not in err and not (tmp_path / "c").exists()
    savemat(tmp_path / "r.mat", {"F": F[None, :], "A": a[None, :]})  # real variables are still read
    code, _, err = _run(["import", desc, "--out", tmp_path / "c"], capsys)
    assert code == 0, err


# a capital M is a mega prefix: never "corrected" to milli (a factor 1e9 from what was written)
@pytest.mark.parametrize("unit, hint", [("MN", "M mega)"), ("KN", "'kN'"), ("n", "'N'"), ("MV", "M mega)")])
def test_units_are_case_sensitive(tmp_path, capsys, unit, hint):
    with pytest.raises(ManifestError) as info:
        check_column_unit("force", unit, "d.toml: ")
    msg = str(info.value)
    assert "channels.force" in msg and repr(unit) in msg and "case-sensitive" in msg and hint in msg
    assert "known:" in msg and "kN" in msg
    documented = {"mN": 1e-3, "kN": 1e3, "N": 1.0, "mV": 1e-3, "V": 1.0, "hz": 1.0, "Hz": 1.0, "g": 9.80665,
                  "mm": 1e-3, "mm/s": 1e-3, "m/s^2": 1.0, "lbf": 4.4482216152605, "deg": np.pi / 180, "ms": 1e-3}
    for name, factor in documented.items():  # the spellings the docs list are kept
        assert unit_factor(name) == pytest.approx(factor), name


def test_mega_newton_spelling_fails_the_import(tmp_path, capsys):
    t, F, a = _signals()
    np.savetxt(tmp_path / "r.csv", np.column_stack([t, F, a]), delimiter=",", header="time,F,A", comments="")
    desc = _describe(tmp_path, "r.csv", 'channels = { force = { channel = "F", unit = "MN" }, accel = "A" }')
    code, _, err = _run(["import", desc, "--out", tmp_path / "c"], capsys)
    assert code == 2 and "d.toml" in err and "channels.force" in err and "'MN'" in err, err
    assert not (tmp_path / "c").exists()


def test_fs_contradicting_the_time_column_is_refused(tmp_path, capsys):
    t, F, a = _signals(fs=2000.0)
    np.savetxt(tmp_path / "r.csv", np.column_stack([t, F, a]), delimiter=",", header="time,F,A", comments="",
               fmt="%.6g")
    desc = _describe(tmp_path, "r.csv", 'fs = 1000.0\nchannels = { force = "F", accel = "A" }')
    code, _, err = _run(["import", desc, "--out", tmp_path / "c"], capsys)
    assert code == 2, err
    assert "r.csv" in err and "[import] fs" in err and "1000" in err and "2000" in err and "drop" in err, err
    desc.write_text(desc.read_text().replace("fs = 1000.0", "fs = 2000.0"))  # agreeing within rounding
    code, _, err = _run(["import", desc, "--out", tmp_path / "c"], capsys)
    assert code == 0, err


def test_hdf5_external_link_is_refused(tmp_path, capsys):
    t, F, a = _signals()
    outside = tmp_path / "elsewhere"
    outside.mkdir()
    with h5py.File(outside / "other.h5", "w") as h5:
        h5["x"] = a
    data = tmp_path / "data"
    data.mkdir()
    with h5py.File(data / "r.h5", "w") as h5:
        h5["F"] = F
        h5["A"] = h5py.ExternalLink(str(outside / "other.h5"), "/x")
    desc = _describe(tmp_path, "r.h5", f'data_folder = "data"\nfs = {FS}\nchannels = {{ force = "F", accel = "A" }}')
    code, _, err = _run(["import", desc, "--out", tmp_path / "c"], capsys)
    assert code == 2, err
    assert "r.h5" in err and "'accel'" in err and "'A'" in err and "external link" in err, err


def test_hdf5_external_link_is_refused_in_a_jointid_record(tmp_path):
    from jointid.io.hdf5 import read_hdf5

    t, F, a = _signals()
    with h5py.File(tmp_path / "other.h5", "w") as h5:
        h5["x"] = a
    with h5py.File(tmp_path / "r.h5", "w") as h5:
        h5.attrs["fs"] = FS
        h5["channels/F"] = F
        h5["channels/A"] = h5py.ExternalLink("other.h5", "/x")
    with pytest.raises(RecordError, match="external link"):
        read_hdf5(tmp_path / "r.h5")


def test_v73_mat_message_says_what_to_do_without_internal_names(tmp_path, capsys):
    t, F, a = _signals()
    with h5py.File(tmp_path / "r.mat", "w", userblock_size=512) as h5:
        h5["F"], h5["A"] = F[:, None], a[:, None]
    with open(tmp_path / "r.mat", "r+b") as fh:
        fh.write(b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Jan  1 00:00:00 2024 HDF5 schema 1.00 .")
    desc = _describe(tmp_path, "r.mat", f'fs = {FS}\nchannels = {{ force = "F", accel = "A" }}')
    code, _, err = _run(["import", desc, "--out", tmp_path / "c"], capsys)
    assert code == 2 and "r.mat" in err and "v7.3" in err, err
    assert "read_mat" not in err and "h5py" not in err, err
    assert "-v7" in err and "HDF5" in err, err


def test_hdf5_lengths_differ_with_fs_names_both_datasets_not_a_time_vector(tmp_path, capsys):
    t, F, a = _signals()
    with h5py.File(tmp_path / "r.h5", "w") as h5:
        h5["F"], h5["A"] = F, a[:-100]
    desc = _describe(tmp_path, "r.h5", f'fs = {FS}\nchannels = {{ force = "F", accel = "A" }}')
    code, _, err = _run(["import", desc, "--out", tmp_path / "c"], capsys)
    assert code == 2, err
    assert "time vector" not in err and "'A'" in err and "'F'" in err and "1948" in err and "2048" in err, err
    assert "fs = 512.0 Hz" in err, err


def test_a_csv_column_named_twice_is_refused(tmp_path, capsys):
    t, F, a = _signals(fs=2000.0)
    np.savetxt(tmp_path / "r.csv", np.column_stack([t, F, 2 * F, a]), delimiter=",", header="time,F,F,A",
               comments="", fmt="%.6g")
    desc = _describe(tmp_path, "r.csv", 'channels = { force = "F", accel = "A" }')
    code, _, err = _run(["import", desc, "--out", tmp_path / "c"], capsys)
    assert code == 2 and "r.csv" in err and "'F'" in err and "more than once" in err, err
    assert not (tmp_path / "c").exists()
