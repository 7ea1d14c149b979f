"""`jointid import`: lab exports to a campaign folder, then identification on it."""

import warnings

import numpy as np
import pytest

from jointid.cli import main
from jointid.io.campaign import load_campaign, read_record
from jointid.io.channels import Channels
from jointid.io.importer import import_campaign
from jointid.io.uff import write_uff
from jointid.app.workflow import identify_campaign


def test_import_unesp_test_lab_sine_dwells_and_identify(shared_data, tmp_path):
    base = shared_data / "unesp_bolted_beam" / "T5Nm" / "Sine"
    lines = [f'[campaign]\nname = "UNESP <dwells>"\ncoordinates = "modal"\n[import]\ndata_folder = "{base}"\n']
    for f in (17, 18, 19, 20):
        lines.append(f"""
[[record]]
frequency_hz = {f}.0
force_level = 0.15
preload = 5
[[record.source]]
file = "Sine_{f}Hz/Time.mat"
channels = {{ accel = "Signal[0]" }}
[[record.source]]
file = "Sine_{f}Hz/TimeShaker.mat"
channels = {{ force = "Time_Shaker__X" }}
""")
    lines.append("""
[[record]]
frequency_hz = 16.0
[[record.source]]
file = "Sine_16Hz/TimeShaker.mat"
channels = { force = "Time_Shaker__X" }
""")
    desc = tmp_path / "import.toml"
    desc.write_text("".join(lines))
    res = import_campaign(desc, tmp_path / "camp")
    assert len(res.written) == 4 and len(res.failed) == 1
    assert "Sine_16Hz" in res.failed[0][1]
    camp = load_campaign(tmp_path / "camp")
    rec = read_record(camp.records[1])
    assert rec.time.size == 65536 and rec.time[1] - rec.time[0] == pytest.approx(1 / 1024)
    assert np.sqrt(np.mean(rec.channels["accel"] ** 2)) == pytest.approx(70.2, rel=0.01)  # SOURCE.md
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = identify_campaign(camp, n_harmonics=3, keep_flagged=True)
    assert not out.failed
    # the drive is switched off before each record ends: the records are not steady, and say so
    assert all("transient" in [f.name for f in r.flags] for r in out.records)
    f1 = [r.fit.omega1 / (2 * np.pi) for r in out.records]
    assert all(15.0 < f < 22.0 for f in f1), f1  # mode 1 near 18.7 Hz (voltage, not force, as input)


def test_import_uff_roundtrip_and_cli(tmp_path):
    t = np.arange(4000) / 1000.0
    ch = Channels(t, {"F": np.sin(2 * np.pi * 20 * t), "A1": np.cos(2 * np.pi * 20 * t)}, {"F": "N", "A1": "m/s^2"})
    write_uff(tmp_path / "r.uff", ch, binary=True)
    (tmp_path / "d.toml").write_text('[import]\nchannels = { force = "F", accel = "A1" }\n'
                                     '[[record]]\nfile = "r.uff"\nforce_level = 1\npreload = 1\n')
    assert main(["import", str(tmp_path / "d.toml"), "--out", str(tmp_path / "c")]) == 0
    rec = read_record(load_campaign(tmp_path / "c").records[0])
    assert np.array_equal(rec.channels["force"], ch.data["F"]) and np.array_equal(rec.channels["accel"], ch.data["A1"])
    assert np.allclose(rec.time, t, rtol=0, atol=1e-15)


def test_import_description_errors(tmp_path):
    (tmp_path / "d.toml").write_text("[[record]]\nforce_level = 1\n")
    assert main(["import", str(tmp_path / "d.toml"), "--out", str(tmp_path / "c")]) == 2
    (tmp_path / "d.toml").write_text('[[record]]\nfile = "nope.mat"\nchannels = { force = "x" }\n')
    assert main(["import", str(tmp_path / "d.toml"), "--out", str(tmp_path / "c")]) == 2


def test_public_data_command(shared_data, tmp_path, capsys):
    assert main(["public-data", "--only", "f16", "--out", str(tmp_path)]) == 0
    assert "softening" in capsys.readouterr().out
    assert (tmp_path / "results.json").is_file()
