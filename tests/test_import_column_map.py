"""Import column map: any column names, a time column or a sampling rate, units and scales, generic HDF5."""

from __future__ import annotations

import h5py
import numpy as np
import pytest

from jointid.errors import ManifestError
from jointid.io.campaign import load_campaign, read_record
from jointid.io.importer import import_campaign

FS = 512.0


def _signals(n=2048):
    t = np.arange(n) / FS
    return t, np.sin(2 * np.pi * 20 * t), 0.5 * np.cos(2 * np.pi * 20 * t)


def _read(folder):
    camp = load_campaign(folder)
    return camp, read_record(camp.records[0])


def test_csv_with_own_names_time_column_units_and_scale(tmp_path):
    t, F, a = _signals()
    rows = np.column_stack([t, F / 4.4482216152605, a / 9.80665, 2 * a])
    np.savetxt(tmp_path / "lab.csv", rows, delimiter=",", header="t [s],Load,Acc (g),Half accel", comments="")
    (tmp_path / "d.toml").write_text(
        '[import]\ntime = "t [s]"\n'
        'channels = { force = { channel = "Load", unit = "lbf" }, accel = { channel = "Acc (g)", unit = "g" }, '
        'accel_b = { channel = "Half accel", scale = 0.5 } }\n'
        '[[record]]\nfile = "lab.csv"\nfrequency_hz = 20.0\n')
    import_campaign(tmp_path / "d.toml", tmp_path / "c")
    _, rec = _read(tmp_path / "c")
    assert np.allclose(rec.channels["force"], F, atol=1e-12)
    assert np.allclose(rec.channels["accel"], a, atol=1e-12)
    assert np.allclose(rec.channels["accel_b"], a, atol=1e-12)
    assert np.allclose(rec.time, t)


def test_csv_without_time_takes_fs_and_a_window(tmp_path):
    t, F, a = _signals()
    np.savetxt(tmp_path / "raw.csv", np.column_stack([F, a]), delimiter=",", header="ch1,ch2", comments="")
    (tmp_path / "d.toml").write_text(
        '[import]\nfs = 512.0\nwindow_s = [1.0, 3.0]\nchannels = { force = "ch1", accel = "ch2" }\n'
        '[[record]]\nfile = "raw.csv"\n')
    import_campaign(tmp_path / "d.toml", tmp_path / "c")
    _, rec = _read(tmp_path / "c")
    keep = (t >= 1.0) & (t < 3.0)
    assert rec.time.size == np.count_nonzero(keep)
    assert np.allclose(rec.channels["accel"], a[keep], atol=1e-12)
    assert rec.time[0] == pytest.approx(1.0)


def test_generic_hdf5_by_dataset_path(tmp_path):
    t, F, a = _signals()
    with h5py.File(tmp_path / "daq.h5", "w") as h5:
        h5["run1/daq/ai0"] = F
        h5["run1/daq/ai1"] = a * 1e3  # mm/s^2
        h5["run1/clock"] = t
    for time_key in ('time = "run1/clock"', "fs = 512.0"):
        (tmp_path / "d.toml").write_text(
            f'[import]\n{time_key}\n'
            'channels = { force = "/run1/daq/ai0", accel = { channel = "/run1/daq/ai1", unit = "mm/s^2" } }\n'
            '[[record]]\nfile = "daq.h5"\n')
        import_campaign(tmp_path / "d.toml", tmp_path / "c")
        _, rec = _read(tmp_path / "c")
        assert np.allclose(rec.channels["accel"], a, atol=1e-9) and np.allclose(rec.time, t)
    # a dataset that is not there fails its record, naming the file and the column
    (tmp_path / "d.toml").write_text('[import]\nfs = 512.0\nchannels = { force = "/run1/daq/ai0", accel = "/nope" }\n'
                                     '[[record]]\nfile = "daq.h5"\n[[record]]\nfile = "daq.h5"\n'
                                     'channels = { force = "/run1/daq/ai0", accel = "/run1/daq/ai1" }\n')
    res = import_campaign(tmp_path / "d.toml", tmp_path / "c2")
    assert len(res.written) == 1 and "daq.h5" in res.failed[0][1] and "/nope" in res.failed[0][1]


def test_column_map_errors_name_the_column(tmp_path):
    t, F, a = _signals()
    np.savetxt(tmp_path / "x.csv", np.column_stack([t, F, a]), delimiter=",", header="tt,f,a", comments="")
    (tmp_path / "d.toml").write_text('[import]\nchannels = { force = { channel = "f", unit = "furlong" } }\n'
                                     '[[record]]\nfile = "x.csv"\n')
    with pytest.raises(ManifestError, match="force.*furlong"):
        import_campaign(tmp_path / "d.toml", tmp_path / "c")
    (tmp_path / "d.toml").write_text('[import]\nwindow_s = [3.0, 1.0]\nchannels = { force = "f", accel = "a" }\n'
                                     '[[record]]\nfile = "x.csv"\n')
    with pytest.raises(ManifestError, match="window_s"):
        import_campaign(tmp_path / "d.toml", tmp_path / "c")
    (tmp_path / "d.toml").write_text('[import]\nchannels = { force = "f", accel = "a" }\n[[record]]\nfile = "x.csv"\n')
    res_err = None
    try:
        import_campaign(tmp_path / "d.toml", tmp_path / "c")
    except Exception as exc:  # no time column and no fs: the only record fails, the message says what to give
        res_err = str(exc)
    assert res_err is not None and "time" in res_err and "fs" in res_err
