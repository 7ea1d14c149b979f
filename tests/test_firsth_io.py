"""First-harmonic records: import from MAT (struct arrays), CSV and UFF 58 FRFs, campaign round trip, bad input."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.io import savemat

from jointid.errors import ManifestError, RecordError
from jointid.io.campaign import load_campaign
from jointid.io.firsth import FH_COLUMNS, first_harmonic_from_columns, read_first_harmonic_record
from jointid.io.importer import import_campaign


def _lines(level, n=11):
    f = np.linspace(79.0, 81.0, n)
    force = 0.2 * level * (1 - 0.1 * np.exp(-((f - 80) / 0.3) ** 2))
    H = -(2 * np.pi * f) ** 2 * 0.5 / ((2 * np.pi * 80) ** 2 - (2 * np.pi * f) ** 2 + 2j * 0.003 * (2 * np.pi) ** 2 * 80 * f)
    return f, force, np.abs(H) * force, np.angle(H), H


def _write(path, text):
    path.write_text(text, encoding="utf-8")
    return path


def test_mat_struct_array_any_layout_becomes_campaign_records(tmp_path):
    levels = [_lines(k) for k in (1, 2, 3)]
    dtype = [("frequency", "O"), ("force", "O"), ("amplitude", "O"), ("phase", "O")]
    arr = np.empty((1, 3), dtype=dtype)
    for k, (f, F, A, ph, _) in enumerate(levels):
        arr[0, k] = (f, F, A, np.degrees(ph))
    savemat(tmp_path / "fr.mat", {"FRdata": {"ForceControl": arr}})
    recs = "".join(
        f"""
[[record]]
file = "fr.mat"
excitation = "first-harmonic"
control = "{c}"
force_level = {k}
preload = "beam"
channels = {{ frequency_hz = "FRdata.ForceControl[{k}].frequency", force = "FRdata.ForceControl[{k}].force", accel = "FRdata.ForceControl[{k}].amplitude", accel_phase = {{ channel = "FRdata.ForceControl[{k}].phase", unit = "deg" }} }}
""" for k, c in zip(range(3), ("force", "response", "phase-resonance")))
    desc = _write(tmp_path / "imp.toml", '[campaign]\nname = "fh"\n' + recs)
    res = import_campaign(desc, tmp_path / "camp")
    assert len(res.written) == 3 and not res.failed
    camp = load_campaign(tmp_path / "camp")
    assert [r.excitation for r in camp.records] == ["first-harmonic"] * 3
    for k, spec in enumerate(camp.records):
        rec = read_first_harmonic_record(spec)
        f, F, A, ph, H = levels[k]
        assert rec.control == ("force", "response", "phase-resonance")[k]
        np.testing.assert_allclose(rec.frequency_hz, f, rtol=1e-15)
        np.testing.assert_allclose(rec.frf, H, rtol=1e-12)
        np.testing.assert_allclose(rec.force, F, rtol=1e-15)


def test_csv_with_complex_frf_and_uff58_frfs_at_several_levels(tmp_path):
    pyuff = pytest.importorskip("pyuff")
    f, F, A, ph, H = _lines(2)
    rows = "\n".join(f"{a},{b},{float(c.real)!r},{float(c.imag)!r}" for a, b, c in zip(f, F, H))
    _write(tmp_path / "fr.csv", "f [Hz],F [N],Re,Im\n" + rows + "\n")
    sets = []

    def dset(name, ftype, values, x, k):
        return {"type": 58, "binary": 0, "id1": name, "id2": "NONE", "id3": "NONE", "id4": "NONE", "id5": "NONE",
                "func_type": ftype, "func_id": k, "ver_num": 0, "load_case_id": 0, "rsp_ent_name": "NONE",
                "rsp_node": 3, "rsp_dir": 3, "ref_ent_name": "NONE", "ref_node": 3, "ref_dir": 3,
                "abscissa_spacing": 1, "abscissa_spec_data_type": 18, "abscissa_axis_lab": "Frequency",
                "abscissa_axis_units_lab": "Hz", "ordinate_spec_data_type": 12, "ordinate_axis_lab": name[:20],
                "ordinate_axis_units_lab": "m/s^2", "orddenom_spec_data_type": 13, "z_axis_spec_data_type": 0,
                "data": values, "x": x}

    for k in (1, 3):
        fk, Fk, Ak, phk, Hk = _lines(k)
        sets.append(dset(f"FRF level {k}", 4, Hk, fk, 2 * k))
        sets.append(dset(f"Force level {k}", 0, Fk.astype(complex), fk, 2 * k + 1))
    (tmp_path / "fr.uff").write_bytes(b"")
    pyuff.UFF(str(tmp_path / "fr.uff")).write_sets(sets, mode="add", force_double=True)
    desc = _write(tmp_path / "imp.toml", """
[campaign]
name = "mixed sources"
[[record]]
file = "fr.csv"
excitation = "first-harmonic"
force_level = 2
channels = { frequency_hz = "f [Hz]", force = "F [N]", frf_real = "Re", frf_imag = "Im" }
[[record]]
file = "fr.uff"
excitation = "first-harmonic"
force_level = 1
channels = { frf = "FRF level 1", force = "Force level 1" }
[[record]]
file = "fr.uff"
excitation = "first-harmonic"
force_level = 3
channels = { frf = "FRF level 3", force = "Force level 3" }
""")
    res = import_campaign(desc, tmp_path / "camp")
    assert not res.failed, res.report()
    camp = load_campaign(tmp_path / "camp")
    got = [read_first_harmonic_record(s) for s in camp.records]
    np.testing.assert_allclose(got[0].frf, H, rtol=1e-12)
    for rec, k in zip(got[1:], (1, 3)):
        fk, Fk, Ak, phk, Hk = _lines(k)
        np.testing.assert_allclose(rec.frequency_hz, fk, rtol=1e-5)  # UFF abscissa: as written by pyuff
        np.testing.assert_allclose(rec.frf, Hk, rtol=1e-9)
        np.testing.assert_allclose(rec.accel, Ak, rtol=1e-9)


def test_bad_lines_fail_their_record_only_with_file_record_and_column(tmp_path):
    f, F, A, ph, H = _lines(1)
    F_bad = F.copy()
    F_bad[4] = -0.1
    _write(tmp_path / "good.csv", "frequency_hz,force,accel,accel_phase\n"
           + "\n".join(f"{a},{b},{c},{d}" for a, b, c, d in zip(f, F, A, ph)) + "\n")
    _write(tmp_path / "bad.csv", "frequency_hz,force,accel,accel_phase\n"
           + "\n".join(f"{a},{b},{c},{d}" for a, b, c, d in zip(f, F_bad, A, ph)) + "\n")
    _write(tmp_path / "nocol.csv", "frequency_hz,force,accel\n" + "\n".join(
        f"{a},{b},{c}" for a, b, c in zip(f, F, A)) + "\n")
    desc = _write(tmp_path / "imp.toml", """
[campaign]
name = "bad lines"
[import]
channels = { frequency_hz = "frequency_hz", force = "force", accel = "accel", accel_phase = "accel_phase" }
[[record]]
file = "good.csv"
excitation = "first-harmonic"
[[record]]
file = "bad.csv"
excitation = "first-harmonic"
[[record]]
file = "nocol.csv"
excitation = "first-harmonic"
""")
    res = import_campaign(desc, tmp_path / "camp")
    assert [i for i, _ in res.written] == [0]
    msgs = dict(res.failed)
    assert "bad.csv" in msgs[1] and "record 1" in msgs[1] and "'force'" in msgs[1] and "frequency line 4" in msgs[1]
    assert "nocol.csv" in msgs[2] and "'accel_phase'" in msgs[2]


def test_manifest_control_is_checked_and_a_campaign_csv_is_validated(tmp_path):
    camp = tmp_path / "camp"
    (camp / "records").mkdir(parents=True)
    _write(camp / "campaign.toml", """
[campaign]
name = "x"
[[record]]
file = "records/0000.csv"
excitation = "first-harmonic"
control = "voltage"
""")
    with pytest.raises(ManifestError, match="control must be one of"):
        spec = load_campaign(camp).records[0]
        read_first_harmonic_record(spec)
    _write(camp / "campaign.toml", """
[campaign]
name = "x"
[[record]]
file = "records/0000.csv"
excitation = "first-harmonic"
""")
    _write(camp / "records" / "0000.csv", ",".join(FH_COLUMNS) + "\n80.0,0.1,0,nan,0\n")
    spec = load_campaign(camp).records[0]
    with pytest.raises(RecordError, match=r"records/0000.csv \[record 0, channel 'accel'\]: .*not finite"):
        read_first_harmonic_record(spec)


def test_columns_need_accel_or_frf_not_both():
    with pytest.raises(RecordError, match="either accel"):
        first_harmonic_from_columns({"frequency_hz": [80.0], "force": [1.0]}, "x.csv", 2)
    with pytest.raises(RecordError, match=r"x.csv \[record 2, channel 'frequency_hz'\]"):
        first_harmonic_from_columns({"frequency_hz": [-80.0], "force": [1.0], "accel": [1.0]}, "x.csv", 2)


def test_a_ringdown_without_force_is_imported_from_a_mat_struct_with_its_time_vector(tmp_path):
    from jointid.io.campaign import read_record

    t = -0.01 + np.arange(2000) / 1000.0
    acc = np.exp(-t) * np.sin(2 * np.pi * 80 * t)
    savemat(tmp_path / "hi.mat", {"HIdata": {"time": t, "acc3": acc, "acc1": 2 * acc}})
    desc = _write(tmp_path / "imp.toml", """
[campaign]
name = "impact"
[[record]]
file = "hi.mat"
excitation = "ringdown"
time = "HIdata.time"
channels = { accel = "HIdata.acc3" }
""")
    res = import_campaign(desc, tmp_path / "camp")
    assert not res.failed, res.report()
    spec = load_campaign(tmp_path / "camp").records[0]
    assert spec.excitation == "ringdown"
    data = read_record(spec, required=("time", "accel"))
    assert "force" not in data.channels
    np.testing.assert_allclose(data.time, t, atol=1e-12)
    np.testing.assert_allclose(data.channels["accel"], acc, rtol=1e-12)
