"""Round trips and error cases of the record readers/writers (Channels, UFF 58, MAT, HDF5)."""

from __future__ import annotations

import h5py
import numpy as np
import pytest
from scipy.io import savemat

from jointid.errors import JointidError, RecordError, RecordFileNotFoundError
from jointid.io.channels import Channels, merge_channels, validate_channels
from jointid.io.hdf5 import FORMAT_NAME, FORMAT_VERSION, read_hdf5, write_hdf5
from jointid.io.matlab import mat_variables, read_mat
from jointid.io.uff import read_uff, write_uff

FS = 1024.0
N = 1500  # not a multiple of 4 or 6: exercises the last, partial data line of ASCII UFF


@pytest.fixture
def record() -> Channels:
    rng = np.random.default_rng(1)
    t = np.arange(N) / FS
    return Channels.from_arrays(
        {
            "voltage": 0.13 * np.sin(2 * np.pi * 18 * t),
            "acc1": 70.0 * rng.standard_normal(N),
            "laser velocity": rng.standard_normal(N) * 1e-3,
            "tiny": rng.standard_normal(N) * 1e-300,
        },
        fs=FS,
        t0=0.0849,
        units={"voltage": "V", "acc1": "m/s^2", "laser velocity": "m/s", "tiny": ""},
        source="/some/where/rec.mat",
        meta={"level": 0.15, "tags": ["a", "b"], "n": np.int64(3)},
    )


# ------------------------------------------------------------------------ Channels
class TestChannels:
    def test_properties(self, record):
        assert record.names == ("voltage", "acc1", "laser velocity", "tiny")
        assert record.n_samples == N
        assert record.fs == pytest.approx(FS, rel=1e-12)
        assert record.t0 == 0.0849
        assert record.units["acc1"] == "m/s^2"
        assert "acc1" in record and len(record) == 4
        assert record.as_array().shape == (4, N)

    def test_arrays_are_read_only_copies(self):
        x = np.arange(5.0)
        rec = Channels.from_arrays({"x": x}, fs=10.0)
        x[0] = 99.0
        assert rec["x"][0] == 0.0
        with pytest.raises(ValueError):
            rec["x"][0] = 1.0

    def test_select_rename_slice_merge(self, record):
        sub = record.select(["acc1", "voltage"])
        assert sub.names == ("acc1", "voltage") and sub.units["voltage"] == "V"
        ren = record.rename({"acc1": "a"})
        assert ren.names[1] == "a" and ren.units["a"] == "m/s^2"
        part = record.slice(10, 20)
        assert part.n_samples == 10 and part.t0 == record.time[10]
        extra = Channels.from_arrays({"f": np.ones(N)}, time=record.time, units={"f": "N"})
        both = merge_channels([record, extra])
        assert both.names[-1] == "f" and both.units["f"] == "N"
        with pytest.raises(RecordError, match="already used"):
            merge_channels([record, record])
        with pytest.raises(KeyError, match="nope"):
            record["nope"]

    def test_different_lengths(self):
        with pytest.raises(RecordError, match=r"rec\.csv \[channel 'b'\]: expected 4 samples.*got 3"):
            Channels(time=np.arange(4.0), data={"a": np.zeros(4), "b": np.zeros(3)},
                     source="rec.csv")

    def test_nan(self):
        x = np.zeros(6)
        x[4] = np.nan
        with pytest.raises(RecordError, match=r"rec\.csv \[channel 'x'\]: expected finite.*sample 4"):
            Channels(time=np.arange(6.0), data={"x": x}, source="rec.csv")
        with pytest.raises(RecordError, match="channel 'x'"):
            Channels.from_arrays({"x": [0.0, np.inf, 1.0]}, fs=1.0)

    def test_time_checks(self):
        with pytest.raises(RecordError, match="strictly increasing"):
            validate_channels([0.0, 1.0, 1.0, 2.0], {}, source="f")
        with pytest.raises(RecordError, match="uniform time step"):
            validate_channels([0.0, 1.0, 2.0, 3.1], {}, source="f")
        # a jitter of 1e-7 of dt is accepted, 1e-5 is not
        t = np.arange(10) * 1e-3
        t[5] += 1e-10
        validate_channels(t, {"x": np.zeros(10)})
        t[5] += 1e-8
        with pytest.raises(RecordError, match="channel 'time'"):
            validate_channels(t, {"x": np.zeros(10)})
        with pytest.raises(RecordError, match="at least 2 samples"):
            validate_channels([0.0], {})

    def test_shape_and_type_checks(self):
        with pytest.raises(RecordError, match=r"expected a 1-D array.*shape \(2, 3\)"):
            Channels(time=np.arange(3.0), data={"x": np.zeros((2, 3))})
        with pytest.raises(RecordError, match="complex"):
            Channels(time=np.arange(3.0), data={"x": np.zeros(3, complex)})
        with pytest.raises(RecordError, match="not in the record"):
            Channels(time=np.arange(3.0), data={"x": np.zeros(3)}, units={"y": "m"})
        with pytest.raises(RecordError, match="exactly one of fs= or time="):
            Channels.from_arrays({"x": np.zeros(3)})

    def test_errors_are_value_errors(self):
        with pytest.raises(ValueError):
            Channels(time=np.arange(3.0), data={"x": np.zeros(2)})
        assert issubclass(RecordError, JointidError)


# ------------------------------------------------------------------------ UFF 58
class TestUFF:
    def test_ascii_round_trip(self, record, tmp_path):
        f = write_uff(tmp_path / "r.uff", record, binary=False)
        back = read_uff(f)
        assert back.names == record.names
        assert back.units == record.units
        assert back.meta["format"] == "uff58"
        # ASCII double precision is E20.11: 12 significant digits
        for name in record.names:
            np.testing.assert_allclose(back[name], record[name], rtol=5e-12, atol=0)
            assert not np.array_equal(back[name], record[name]) or name == "tiny"
        # exact time base from ID line 4 (the header only has 6 digits)
        assert back.fs == pytest.approx(FS, rel=1e-13)
        assert back.t0 == record.t0
        np.testing.assert_allclose(back.time, record.time, rtol=0, atol=1e-12)
        assert back.source == str(f)

    def test_binary_round_trip_is_exact(self, record, tmp_path):
        f = write_uff(tmp_path / "r.uff", record, binary=True)
        back = read_uff(f)
        assert back.meta["format"] == "uff58b"
        for name in record.names:
            assert np.array_equal(back[name], record[name]), name
        assert back.units == record.units
        np.testing.assert_allclose(back.time, record.time, rtol=0, atol=1e-12)

    def test_fs_exact_with_t0_zero(self, tmp_path):
        rec = Channels.from_arrays({"x": np.arange(10.0)}, fs=FS)
        back = read_uff(write_uff(tmp_path / "r.uff", rec))
        assert back.fs == FS
        assert np.array_equal(back.time, rec.time)

    def test_select_and_rename(self, record, tmp_path):
        f = write_uff(tmp_path / "r.uff", record, binary=True)
        sub = read_uff(f, ["acc1", "VOLTAGE"])
        assert sub.names == ("acc1", "VOLTAGE")
        assert np.array_equal(sub["VOLTAGE"], record["voltage"])
        ren = read_uff(f, {"v": "voltage", "laser": "laser   velocity"})
        assert ren.names == ("v", "laser")
        assert ren.units["laser"] == "m/s"
        with pytest.raises(RecordError, match=r"r\.uff \[channel 'force'\].*labelled 'force'.*acc1"):
            read_uff(f, ["force"])

    @staticmethod
    def _lms_like_sets(n: int = 257) -> list[dict]:
        rng = np.random.default_rng(2)
        x = np.arange(n) / 512.0
        return [
            {
                "type": 58, "binary": 0, "id1": "NONE", "id2": "Run 7",
                "func_type": 1, "rsp_ent_name": ent, "rsp_node": node,
                "rsp_dir": direction, "ref_node": 0, "ref_dir": 0,
                "abscissa_spacing": 1, "abscissa_spec_data_type": 17,
                "ordinate_spec_data_type": 12, "ordinate_axis_units_lab": "m/s^2",
                "orddenom_spec_data_type": 0, "z_axis_spec_data_type": 0,
                "ord_data_type": 2, "data": rng.standard_normal(n), "x": x,
            }
            for node, direction, ent in [(1, 1, "Acc1"), (2, -3, "Acc2")]
        ]

    def test_lms_style_labels_ascii_single_precision(self, tmp_path):
        """Datasets without ID line names (as some Test.Lab exports) are found by node/dir."""
        import pyuff

        sets = self._lms_like_sets()
        f = tmp_path / "lms.uff"
        pyuff.UFF(str(f)).write_sets(sets, mode="overwrite", force_double=False)
        auto = read_uff(f)
        assert auto.names == ("Acc1:1:+X", "Acc2:2:-Z")
        # ASCII single precision is E13.5: 6 significant digits
        np.testing.assert_allclose(auto["Acc1:1:+X"], sets[0]["data"], rtol=5e-6, atol=0)
        assert auto.fs == pytest.approx(512.0, rel=1e-5)  # E13.5 header: 6 digits
        assert auto.units["Acc2:2:-Z"] == "m/s^2"
        by_node = read_uff(f, {"a": "1:+X", "b": "acc2", "c": "2-Z", "d": "Acc1:1:+X"})
        assert by_node.names == ("a", "b", "c", "d")
        assert np.array_equal(by_node["b"], by_node["c"])
        with pytest.raises(RecordError, match="matches 2 datasets"):
            read_uff(f, ["Run 7"])

    def test_binary_single_precision(self, tmp_path):
        """58b with float32 ordinates (pyuff cannot write these, so the bytes are built here)."""
        import pyuff

        sets = self._lms_like_sets(n=101)
        blocks = []
        for k, dset in enumerate(sets):
            one = tmp_path / f"d{k}.uff"
            d = dict(dset, binary=1)
            one.write_bytes(b"")  # pyuff truncates binary sets in "overwrite" mode
            pyuff.UFF(str(one)).write_sets([d], mode="add", force_double=True)
            raw = one.read_bytes()
            lines = raw.split(b"\n")
            head = lines[:13]
            n_bytes = 4 * len(dset["data"])
            head[1] = b"    58b%6i%6i%12i%12i%6i%6i%12i%12i" % (1, 2, 11, n_bytes, 0, 0, 0, 0)
            head[8] = b"%10i" % 2 + head[8][10:]
            blocks.append(
                b"\n".join(head) + b"\n"
                + dset["data"].astype("<f4").tobytes() + b"    -1\n"
            )
        f = tmp_path / "single.uff"
        f.write_bytes(b"".join(blocks))
        rec = read_uff(f)
        assert rec.meta["format"] == "uff58b"
        for name, dset in zip(rec.names, sets):
            # float32 precision: equal to the float32-rounded values
            assert np.array_equal(rec[name], dset["data"].astype(np.float32).astype(np.float64))

    def test_truncated_ascii(self, record, tmp_path):
        f = write_uff(tmp_path / "r.uff", record)
        raw = f.read_bytes()
        # (a cut exactly between two datasets leaves a valid, shorter UFF file: undetectable)
        for cut in (len(raw) // 2 + 37, len(raw) - 30, 200):
            bad = tmp_path / f"cut{cut}.uff"
            bad.write_bytes(raw[:cut])
            with pytest.raises(RecordError, match=rf"cut{cut}\.uff.*truncated"):
                read_uff(bad)

    def test_truncated_binary(self, record, tmp_path):
        f = write_uff(tmp_path / "r.uff", record, binary=True)
        raw = f.read_bytes()
        bad = tmp_path / "cut.uff"
        bad.write_bytes(raw[: len(raw) * 2 // 3])
        with pytest.raises(RecordError, match=r"cut\.uff.*truncated"):
            read_uff(bad)

    def test_lost_values_detected(self, record, tmp_path):
        """A data line removed inside a dataset: the count in record 7 no longer matches."""
        f = write_uff(tmp_path / "r.uff", record.select(["acc1"]))
        lines = f.read_text().splitlines(keepends=True)
        del lines[20]
        bad = tmp_path / "short.uff"
        bad.write_text("".join(lines))
        with pytest.raises(RecordError, match=rf"short\.uff.*expected {N} values.*got {N - 4}"):
            read_uff(bad)

    def test_corrupt(self, record, tmp_path):
        f = write_uff(tmp_path / "r.uff", record.select(["acc1"]))
        text = f.read_text()
        lines = text.splitlines(keepends=True)
        lines[20] = "  garbage-in-a-line-that-should-hold-numbers-garbage-garbage-garbage-garbage\n"
        bad = tmp_path / "corrupt.uff"
        bad.write_text("".join(lines))
        with pytest.raises(RecordError, match=r"corrupt\.uff"):
            read_uff(bad)
        # header record 7 (number of values) destroyed
        lines = text.splitlines(keepends=True)
        lines[8] = "         4     xxxxx         1  0.00000e+00  9.76562e-04  0.00000e+00\n"
        bad.write_text("".join(lines))
        with pytest.raises(RecordError, match=r"corrupt\.uff"):
            read_uff(bad)

    def test_not_uff(self, tmp_path):
        bad = tmp_path / "notes.uff"
        bad.write_text("this is not a universal file\n")
        with pytest.raises(RecordError, match=r"notes\.uff.*'    -1'"):
            read_uff(bad)
        empty = tmp_path / "empty.uff"
        empty.write_bytes(b"")
        with pytest.raises(RecordError, match=r"empty\.uff.*empty file"):
            read_uff(empty)

    def test_without_dataset_58(self, tmp_path):
        import pyuff

        f = tmp_path / "nodes.uff"
        pyuff.UFF(str(f)).write_sets(
            [{"type": 15, "node_nums": np.array([1, 2]), "def_cs": np.array([0, 0]),
              "disp_cs": np.array([0, 0]), "color": np.array([0, 0]),
              "x": np.array([0.0, 1.0]), "y": np.zeros(2), "z": np.zeros(2)}],
            mode="overwrite",
        )
        with pytest.raises(RecordError, match=r"nodes\.uff.*dataset 58.*\[15\]"):
            read_uff(f)

    def test_only_frf_datasets(self, tmp_path):
        import pyuff

        f = tmp_path / "frf.uff"
        pyuff.UFF(str(f)).write_sets(
            [{"type": 58, "binary": 0, "func_type": 4, "rsp_node": 1, "rsp_dir": 1,
              "ref_node": 1, "ref_dir": 1, "abscissa_spacing": 1,
              "orddenom_spec_data_type": 13, "data": np.ones(8) + 1j, "x": np.arange(8.0)}],
            mode="overwrite",
        )
        with pytest.raises(RecordError, match=r"frf\.uff.*time response.*\[4\]"):
            read_uff(f)

    def test_channels_with_different_lengths(self, tmp_path):
        a = Channels.from_arrays({"a": np.zeros(10)}, fs=100.0)
        b = Channels.from_arrays({"b": np.zeros(12)}, fs=100.0)
        fa, fb = write_uff(tmp_path / "a.uff", a), write_uff(tmp_path / "b.uff", b)
        both = tmp_path / "ab.uff"
        both.write_bytes(fa.read_bytes() + fb.read_bytes())
        with pytest.raises(RecordError, match=r"ab\.uff.*channel 'b'.*10 samples.*got 12"):
            read_uff(both)

    def test_missing_file(self, tmp_path):
        with pytest.raises(RecordFileNotFoundError, match="nope.uff"):
            read_uff(tmp_path / "nope.uff")
        with pytest.raises(FileNotFoundError):
            read_uff(tmp_path / "nope.uff")

    def test_unstorable_names(self, tmp_path):
        rec = Channels.from_arrays({"x" * 81: np.zeros(3)}, fs=1.0)
        with pytest.raises(RecordError, match="80 printable"):
            write_uff(tmp_path / "r.uff", rec)
        rec = Channels.from_arrays({"x": np.zeros(3)}, fs=1.0, units={"x": "u" * 21})
        with pytest.raises(RecordError, match="20 printable"):
            write_uff(tmp_path / "r.uff", rec)


# ------------------------------------------------------------------------ HDF5
class TestHDF5:
    def test_round_trip_exact(self, record, tmp_path):
        f = write_hdf5(tmp_path / "r.h5", record)
        back = read_hdf5(f)
        assert back.names == record.names
        for name in record.names:
            assert np.array_equal(back[name], record[name])
        assert np.array_equal(back.time, record.time)
        assert back.units == record.units
        assert back.meta["level"] == 0.15 and back.meta["tags"] == ["a", "b"]
        assert back.meta["n"] == 3
        assert back.meta["original_source"] == record.source
        with h5py.File(f, "r") as h:
            assert h.attrs["format"] == FORMAT_NAME
            assert h.attrs["format_version"] == FORMAT_VERSION
            assert h["channels/acc1"].attrs["units"] == "m/s^2"
            assert h["channels/acc1"].attrs["fs"] == pytest.approx(FS)

    def test_groups_and_selection(self, record, tmp_path):
        f = tmp_path / "many.h5"
        write_hdf5(f, record, group="run1")
        write_hdf5(f, record.select(["acc1"]), group="run2", mode="a")
        assert read_hdf5(f, group="run2").names == ("acc1",)
        sub = read_hdf5(f, ["acc1", "voltage"], group="run1")
        assert sub.names == ("acc1", "voltage")
        with pytest.raises(RecordError, match="exists"):
            write_hdf5(f, record, group="run1", mode="a")
        with pytest.raises(RecordError, match=r"many\.h5.*group 'run3'"):
            read_hdf5(f, group="run3")
        with pytest.raises(RecordError, match=r"many\.h5 \[channel 'force'\].*/run1/channels/force"):
            read_hdf5(f, ["force"], group="run1")

    def test_hand_written_without_time(self, tmp_path):
        f = tmp_path / "hand.h5"
        with h5py.File(f, "w") as h:
            h.attrs["fs"] = 200.0
            h.attrs["t0"] = 1.0
            h.create_dataset("channels/force", data=np.arange(6.0))
        rec = read_hdf5(f)
        assert rec.fs == pytest.approx(200.0) and rec.t0 == 1.0
        assert rec.units == {"force": ""}

    def test_wrong_shape(self, tmp_path):
        f = tmp_path / "bad.h5"
        with h5py.File(f, "w") as h:
            h.attrs["fs"] = 10.0
            h.create_dataset("channels/acc", data=np.zeros((5, 2)))
        with pytest.raises(RecordError, match=r"bad\.h5 \[channel 'acc'\].*/channels/acc.*1-D.*\(5, 2\)"):
            read_hdf5(f)

    def test_different_lengths(self, tmp_path):
        f = tmp_path / "len.h5"
        with h5py.File(f, "w") as h:
            h.attrs["fs"] = 10.0
            h.create_dataset("channels/a", data=np.zeros(5))
            h.create_dataset("channels/b", data=np.zeros(6))
        with pytest.raises(RecordError, match=r"len\.h5 \[channel 'b'\].*/channels/b.*5 samples.*got 6"):
            read_hdf5(f)

    def test_time_wrong_length(self, record, tmp_path):
        f = write_hdf5(tmp_path / "t.h5", record)
        with h5py.File(f, "a") as h:
            del h["time"]
            h["time"] = np.arange(3.0)
        with pytest.raises(RecordError, match=r"t\.h5 \[channel 'time'\].*/time"):
            read_hdf5(f)

    def test_nan_in_file(self, tmp_path):
        f = tmp_path / "nan.h5"
        with h5py.File(f, "w") as h:
            h.attrs["fs"] = 10.0
            h.create_dataset("channels/a", data=np.array([0.0, np.nan, 1.0]))
        with pytest.raises(RecordError, match=r"nan\.h5 \[channel 'a'\].*finite"):
            read_hdf5(f)

    def test_not_a_record(self, tmp_path):
        f = tmp_path / "other.h5"
        with h5py.File(f, "w") as h:
            h.create_dataset("x", data=np.zeros(3))
        with pytest.raises(RecordError, match=r"other\.h5.*'channels'.*\['x'\]"):
            read_hdf5(f)
        with h5py.File(f, "a") as h:
            h.attrs["format"] = "something.else"
        with pytest.raises(RecordError, match="format attribute"):
            read_hdf5(f)
        txt = tmp_path / "plain.h5"
        txt.write_text("hello")
        with pytest.raises(RecordError, match=r"plain\.h5.*HDF5"):
            read_hdf5(txt)
        with pytest.raises(RecordFileNotFoundError):
            read_hdf5(tmp_path / "missing.h5")

    def test_newer_version_refused(self, record, tmp_path):
        f = write_hdf5(tmp_path / "v.h5", record)
        with h5py.File(f, "a") as h:
            h.attrs["format_version"] = FORMAT_VERSION + 1
        with pytest.raises(RecordError, match="format_version"):
            read_hdf5(f)

    def test_unstorable(self, tmp_path):
        rec = Channels.from_arrays({"a/b": np.zeros(3)}, fs=1.0)
        with pytest.raises(RecordError, match="no '/'"):
            write_hdf5(tmp_path / "x.h5", rec)
        rec = Channels.from_arrays({"a": np.zeros(3)}, fs=1.0, meta={"obj": object()})
        with pytest.raises(RecordError, match="JSON"):
            write_hdf5(tmp_path / "x.h5", rec)


# ------------------------------------------------------------------------ MAT
def _testlab_struct(values: np.ndarray, names: list[str], inc: float, start: float = 0.0) -> dict:
    """A minimal LMS Test.Lab signal struct as savemat writes nested dicts."""
    n = values.shape[0]
    terms = np.array(
        [{"num": 1.0, "den": 1.0, "quantity": "LENGTH"},
         {"num": -2.0, "den": 1.0, "quantity": "TIME"}],
        dtype=object,
    )
    return {
        "x_values": {"start_value": start, "increment": inc, "number_of_values": float(n)},
        "y_values": {
            "values": values,
            "quantity": {
                "label": "g",
                "unit_transformation": {"offset": 0.0, "factor": 0.101971621297793,
                                        "log_reference": 1.0},
                "quantity_terms": terms,
                "info": "Data saved by Test.Lab in MKS",
            },
        },
        "function_record": {
            "name": np.array([f"Time {s}" for s in names], dtype=object),
            "primary_channel": {"label": np.array(names, dtype=object)},
        },
    }


class TestMAT:
    def test_plain_arrays_fs_variable(self, tmp_path):
        f = tmp_path / "plain.mat"
        u = np.arange(100.0)
        savemat(f, {"u": u[None, :], "y": (2 * u)[:, None], "fs": 50.0, "Y": np.ones((100, 3))})
        rec = read_mat(f, {"u": "u", "y": "y", "y2": "Y[2]"}, fs="fs", units={"u": "V"})
        assert rec.names == ("u", "y", "y2")
        assert rec.fs == 50.0 and rec.n_samples == 100
        assert np.array_equal(rec["y"], 2 * u)
        assert rec.units == {"u": "V", "y": "", "y2": ""}
        assert set(mat_variables(f)) == {"u", "y", "fs", "Y"}

    def test_time_vector_variable(self, tmp_path):
        f = tmp_path / "t.mat"
        savemat(f, {"t": np.arange(10) * 0.01 + 2.0, "x": np.ones(10)})
        rec = read_mat(f, {"x": "x"}, time="t")
        assert rec.t0 == 2.0 and rec.fs == pytest.approx(100.0)

    def test_testlab_struct(self, tmp_path):
        f = tmp_path / "tl.mat"
        vals = np.random.default_rng(0).standard_normal((64, 2))
        savemat(f, {"Signal": _testlab_struct(vals, ["A:+X", "B:+Y"], inc=1 / 256, start=0.5)})
        rec = read_mat(f, {"b": "Signal[B:+Y]", "a": "Signal[0]", "c": "Signal['Time A:+X']"})
        assert np.array_equal(rec["a"], vals[:, 0]) and np.array_equal(rec["b"], vals[:, 1])
        assert rec.units["a"] == "m/s^2"  # MKS export: SI although labelled g
        assert rec.fs == 256.0 and rec.t0 == 0.5 and rec.n_samples == 64
        assert rec.meta["labels"]["b"] == "Time B:+Y"

    def test_missing_fields(self, tmp_path):
        f = tmp_path / "tl.mat"
        s = _testlab_struct(np.zeros((8, 1)), ["A:+X"], inc=0.1)
        del s["x_values"]
        savemat(f, {"Signal": s, "other": 1.0})
        with pytest.raises(RecordError, match=r"tl\.mat \[channel 'a'\].*missing field\(s\) \['x_values'\].*y_values"):
            read_mat(f, {"a": "Signal"})
        with pytest.raises(RecordError, match=r"tl\.mat \[channel 'a'\]: expected field 'nope' in 'Signal.y_values'.*\['values', 'quantity'\]"):
            read_mat(f, {"a": "Signal.y_values.nope"})
        with pytest.raises(RecordError, match=r"tl\.mat: expected variable 'Sig'.*Signal.*other"):
            read_mat(f, {"a": "Sig"})

    def test_unknown_label_lists_labels(self, tmp_path):
        f = tmp_path / "tl.mat"
        savemat(f, {"S": _testlab_struct(np.zeros((8, 2)), ["A:+X", "B:+X"], inc=0.1)})
        with pytest.raises(RecordError, match=r"labelled 'C:\+X'.*\['A:\+X', 'B:\+X'\]"):
            read_mat(f, {"c": "S[C:+X]"})
        with pytest.raises(RecordError, match=r"channel index such as 'S\[0\]'"):
            read_mat(f, {"c": "S"})

    def test_no_time_base(self, tmp_path):
        f = tmp_path / "p.mat"
        savemat(f, {"x": np.ones(5)})
        with pytest.raises(RecordError, match=r"p\.mat: expected a time base.*fs="):
            read_mat(f, {"x": "x"})

    def test_nan_and_lengths(self, tmp_path):
        f = tmp_path / "p.mat"
        savemat(f, {"x": np.array([1.0, np.nan, 2.0]), "y": np.ones(4)})
        with pytest.raises(RecordError, match=r"p\.mat \[channel 'x'\].*finite"):
            read_mat(f, {"x": "x"}, fs=1.0)
        with pytest.raises(RecordError, match=r"p\.mat \[channel 'y'\].*3 samples.*got 4"):
            Channels.from_arrays({"y": np.ones(4)}, time=np.arange(3.0), source=str(f))

    def test_v73_and_corrupt(self, tmp_path):
        v73 = tmp_path / "v73.mat"
        header = b"MATLAB 7.3 MAT-file, Platform: GLNXA64".ljust(512, b" ")
        v73.write_bytes(header + b"\x89HDF\r\n\x1a\n")
        with pytest.raises(RecordError, match=r"v73\.mat.*v7\.3"):
            read_mat(v73, {"x": "x"}, fs=1.0)
        junk = tmp_path / "junk.mat"
        junk.write_bytes(b"\x00\x01garbage" * 30)
        with pytest.raises(RecordError, match=r"junk\.mat: cannot read"):
            read_mat(junk, {"x": "x"}, fs=1.0)
        with pytest.raises(RecordFileNotFoundError):
            read_mat(tmp_path / "none.mat", {"x": "x"}, fs=1.0)
