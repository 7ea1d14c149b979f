"""Adversarial campaign folders, caught when the campaign is loaded or a record read (audit 2).

Repeated data under another name (hard link, copy), preload / force level written as a number in one
record and as a text in another, control characters in a label, unit labels inside HDF5 / UFF record
files, and numbers printed plainly in time-base errors.
"""

import os
import shutil

import numpy as np
import pytest

from jointid.errors import ManifestError, RecordError
from jointid.io.campaign import load_campaign, read_record, write_campaign, write_csv_record
from jointid.io.channels import Channels


def _signal(seed=0, n=400, fs=1000.0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / fs
    force = np.sin(2 * np.pi * 25 * t) + 0.01 * rng.standard_normal(n)
    accel = 3.0 * np.sin(2 * np.pi * 25 * t + 0.3) + 0.01 * rng.standard_normal(n)
    return t, force, accel


def _csv_campaign(folder, n=3, **keys):
    (folder / "records").mkdir(parents=True, exist_ok=True)
    recs = []
    for i in range(n):
        t, f, a = _signal(i)
        rel = f"records/{i:04d}.csv"
        write_csv_record(folder / rel, t, {"force": f, "accel": a})
        recs.append({"file": rel, "force_level": 1.0, "preload": 120, **keys})
    return recs


# 1. the same data under another name ------------------------------------------------------------

def test_hard_link_fails_the_later_record(tmp_path):
    recs = _csv_campaign(tmp_path, 2)
    for k in range(3):
        os.link(tmp_path / "records/0000.csv", tmp_path / f"records/h{k}.csv")
        recs.append({"file": f"records/h{k}.csv", "force_level": 1.0, "preload": 120})
    write_campaign(tmp_path, "c", recs)
    camp = load_campaign(tmp_path)
    assert camp.records[0].error is None and camp.records[1].error is None
    for spec in camp.records[2:]:
        assert "same file as record 0" in spec.error and "records/0000.csv" in spec.error
        assert f"records/{spec.file.split('/')[-1]}" in spec.error
        with pytest.raises(ManifestError, match="record 0"):
            read_record(spec)
    read_record(camp.records[0])  # the first one is read


def test_copied_file_fails_as_same_data(tmp_path):
    recs = _csv_campaign(tmp_path, 3)
    shutil.copyfile(tmp_path / "records/0001.csv", tmp_path / "records/copy.csv")
    recs.append({"file": "records/copy.csv", "force_level": 2.0, "preload": 120})
    text = (tmp_path / "records/0000.csv").read_text()
    other = text.replace("0.", "1.", 1)  # one digit changed, same size: another measurement, kept
    assert len(other) == len(text) and other != text
    (tmp_path / "records/other.csv").write_text(other)
    recs.append({"file": "records/other.csv", "force_level": 1.0, "preload": 120})
    write_campaign(tmp_path, "c", recs)
    camp = load_campaign(tmp_path)
    assert [s.error is None for s in camp.records] == [True, True, True, False, True]
    err = camp.records[3].error
    assert "records/copy.csv [record 3]" in err and "same data as record 1 (records/0001.csv)" in err


# 2. a grouping value written as a number and as a text ---------------------------------------------

@pytest.mark.parametrize("key, number, text", [("preload", 120, "120"), ("force_level", 1.0, "1.0")])
def test_number_and_text_label_refused(tmp_path, key, number, text):
    recs = _csv_campaign(tmp_path, 4)
    for r in recs:
        r[key] = number
    recs[2][key] = text
    write_campaign(tmp_path, "c", recs)
    with pytest.raises(ManifestError) as exc:
        load_campaign(tmp_path)
    msg = str(exc.value)
    assert "campaign.toml" in msg and key in msg
    assert "record 0" in msg and "record 2" in msg and "(a number)" in msg and "(text)" in msg
    recs[2][key] = "other"  # another text label is another group: fine
    write_campaign(tmp_path, "c", recs)
    assert all(s.error is None for s in load_campaign(tmp_path).records)


# 3. control characters in a label --------------------------------------------------------------------

@pytest.mark.parametrize("label", ["a\nb\0c", "tab\there", "zero\u200bwidth"])
def test_control_characters_in_label_fail_the_record(tmp_path, label):
    recs = _csv_campaign(tmp_path, 3)
    recs[1]["preload"] = label
    write_campaign(tmp_path, "c", recs)
    camp = load_campaign(tmp_path)
    assert camp.records[0].error is None and camp.records[2].error is None
    err = camp.records[1].error
    assert "records/0001.csv [record 1]" in err and "preload" in err and "character" in err


# 4. units written inside HDF5 / UFF record files ---------------------------------------------------------

def _one_file_campaign(folder, name, units, writer):
    t, f, a = _signal(0)
    (folder / "records").mkdir(parents=True, exist_ok=True)
    rec = Channels.from_arrays({"force": f, "accel": a}, time=t, units=units)
    writer(folder / "records" / name, rec)
    write_campaign(folder, "c", [{"file": f"records/{name}", "force_level": 1.0, "preload": 120}])
    return load_campaign(folder).records[0], t, f, a


def _h5(path, rec):
    from jointid.io.hdf5 import write_hdf5

    write_hdf5(path, rec)


def _uff(path, rec):
    from jointid.io.uff import write_uff

    write_uff(path, rec, binary=True)


@pytest.mark.parametrize("writer, name", [(_h5, "r.h5"), (_uff, "r.uff")])
def test_record_file_units_converted_to_si(tmp_path, writer, name):
    spec, t, f, a = _one_file_campaign(tmp_path, name, {"force": "mN", "accel": "g"}, writer)
    rec = read_record(spec)
    np.testing.assert_allclose(rec.channels["force"], 1e-3 * f, rtol=1e-12)
    np.testing.assert_allclose(rec.channels["accel"], 9.80665 * a, rtol=1e-12)
    np.testing.assert_allclose(rec.time, t, rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("unit", ["furlong", "MN", "m/s^2"])
def test_hdf5_unknown_or_wrong_unit_refused(tmp_path, unit):
    spec, *_ = _one_file_campaign(tmp_path, "r.h5", {"force": unit, "accel": "m/s^2"}, _h5)
    with pytest.raises(RecordError) as exc:
        read_record(spec)
    msg = str(exc.value)
    assert "records/r.h5 [record 0, channel 'force']" in msg and repr(unit) in msg


def test_a_channel_not_read_by_its_name_keeps_an_unknown_unit(tmp_path):
    """A record file's extra channel (a temperature, a shaker current) in a unit outside the table does not fail
    the record: only the channels jointid reads by their kind are converted or refused."""
    t, f, a = _signal(0)
    (tmp_path / "records").mkdir()
    rec = Channels.from_arrays({"force": f, "accel": a, "temperature": 20 + 0 * t}, time=t,
                               units={"force": "N", "accel": "m/s^2", "temperature": "degC"})
    _h5(tmp_path / "records" / "r.h5", rec)
    write_campaign(tmp_path, "c", [{"file": "records/r.h5", "force_level": 1.0, "preload": 120}])
    got = read_record(load_campaign(tmp_path).records[0])
    np.testing.assert_allclose(got.channels["force"], f, rtol=1e-12)
    np.testing.assert_allclose(got.channels["temperature"], 20.0)


def test_hdf5_time_in_ms_converted_and_unknown_refused(tmp_path):
    import h5py

    spec, t, f, a = _one_file_campaign(tmp_path, "r.h5", {"force": "N", "accel": "m/s^2"}, _h5)
    with h5py.File(spec.path, "r+") as h5:
        h5["time"][...] = t * 1e3
        h5["time"].attrs["units"] = "ms"
    np.testing.assert_allclose(read_record(spec).time, t, rtol=1e-12, atol=1e-15)
    with h5py.File(spec.path, "r+") as h5:
        h5["time"].attrs["units"] = "min"
    with pytest.raises(RecordError, match=r"\[record 0, channel 'time'\].*'min'"):
        read_record(spec)


# 5. numbers printed plainly ---------------------------------------------------------------------------------

def test_time_restart_message_without_numpy_repr(tmp_path):
    recs = _csv_campaign(tmp_path, 1)
    t, f, a = _signal(0)
    t = t.copy()
    t[200:] -= t[200]
    write_csv_record(tmp_path / "records/0000.csv", t, {"force": f, "accel": a})
    write_campaign(tmp_path, "c", recs)
    with pytest.raises(RecordError) as exc:
        read_record(load_campaign(tmp_path).records[0])
    msg = str(exc.value)
    assert "np.float64" not in msg and "t[200] = 0 s after t[199] = 0.199 s" in msg
