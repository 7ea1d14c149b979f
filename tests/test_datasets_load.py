"""The loaders of the public data sets read the real files in ../shared/data.

Expected values come from the files themselves and from each folder's SOURCE.md.
The whole module is skipped when ../shared/data is not beside the repository.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from jointid.errors import RecordFileNotFoundError
from jointid.io import datasets as ds

SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "data"

pytestmark = pytest.mark.skipif(
    not SHARED.is_dir(), reason=f"shared data folder {SHARED} not found beside the repository"
)


@pytest.fixture(autouse=True)
def _point_at_shared_data(monkeypatch):
    monkeypatch.setenv(ds.ENV_VAR, str(SHARED))


def rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(x))))


UNESP_CHANNELS = ("voltage", "acc1", "acc2", "acc3", "acc4", "laser_velocity")
UNESP_UNITS = {"voltage": "V", "acc1": "m/s^2", "acc2": "m/s^2", "acc3": "m/s^2",
               "acc4": "m/s^2", "laser_velocity": "m/s"}


# ------------------------------------------------------------------------ location
def test_shared_data_dir_found_beside_repository(monkeypatch):
    monkeypatch.delenv(ds.ENV_VAR)
    assert ds.shared_data_dir().resolve() == SHARED.resolve()


def test_shared_data_dir_env_var_missing_folder(monkeypatch, tmp_path):
    monkeypatch.setenv(ds.ENV_VAR, str(tmp_path / "absent"))
    with pytest.raises(RecordFileNotFoundError, match="JOINTID_SHARED_DATA"):
        ds.shared_data_dir()


# ------------------------------------------------------------------------ UNESP
def test_unesp_sine_frequencies():
    assert ds.unesp_sine_frequencies() == (
        5, 5.5, 6, 6.5, 6.75, 8, 8.5, 9, 9.5, 9.75, 16, 17, 18, 19, 20
    )


def test_unesp_sine_18hz():
    rec = ds.load_unesp_sine(18)
    assert rec.names == UNESP_CHANNELS
    assert rec.units == UNESP_UNITS
    assert rec.n_samples == 65536
    assert rec.fs == 1024.0 and rec.t0 == 0.0
    assert rec.meta["frequency_hz"] == 18.0 and rec.meta["input"] == "voltage"
    # SOURCE.md: Acc1 RMS 70.2 m/s^2 ~ 2 pi 18 x 0.625 m/s (laser): values are SI
    assert rms(rec["acc1"]) == pytest.approx(70.2, abs=0.05)
    assert rms(rec["laser_velocity"]) == pytest.approx(0.625, abs=0.001)
    assert rms(rec["acc1"]) == pytest.approx(2 * np.pi * 18 * rms(rec["laser_velocity"]), rel=0.01)
    # 0.15 V sine setting: the recorded amplifier voltage is ~0.094 V RMS
    assert rms(rec["voltage"]) == pytest.approx(0.0943, abs=5e-4)
    assert rec.meta["labels"]["acc1"] == "Time Acc1:+X"
    assert rec.meta["run_name"] == "Round01_Sine0p15_18Hz_1"


def test_unesp_sine_fractional_frequency():
    rec = ds.load_unesp_sine(6.75)
    assert rec.n_samples == 65536 and rec.meta["frequency_hz"] == 6.75
    assert rec.source.endswith("Sine_06p75Hz")


def test_unesp_sine_16hz_has_no_voltage():
    with pytest.raises(RecordFileNotFoundError, match=r"Sine_16Hz/TimeShaker\.mat.*voltage=False"):
        ds.load_unesp_sine(16)
    with pytest.raises(FileNotFoundError):
        ds.load_unesp_sine(16)
    rec = ds.load_unesp_sine(16, voltage=False)
    assert rec.names == UNESP_CHANNELS[1:]
    assert rec.meta["input"] is None
    assert rms(rec["acc1"]) == pytest.approx(12.46, abs=0.01)


def test_unesp_sine_unknown_frequency():
    with pytest.raises(ValueError, match=r"15.*available frequencies.*18\.0"):
        ds.load_unesp_sine(15)


def test_unesp_random():
    assert ds.unesp_random_levels() == (0.05, 0.1, 0.15, 0.2, 0.25, 0.3)
    low, high = ds.load_unesp_random(0.05), ds.load_unesp_random("0p30")
    for rec in (low, high):
        assert rec.names == UNESP_CHANNELS and rec.units == UNESP_UNITS
        assert rec.n_samples == 16384 and rec.fs == 1024.0
        assert rec.meta["excitation"] == "random"
    # SOURCE.md: the shaker-channel RMS is only 0.53-3.1 mV
    assert rms(low["voltage"]) == pytest.approx(0.53e-3, abs=0.05e-3)
    assert rms(high["voltage"]) == pytest.approx(3.1e-3, abs=0.05e-3)
    assert high.meta["level"] == 0.3
    with pytest.raises(ValueError, match="levels are"):
        ds.load_unesp_random(0.4)


def test_unesp_chirp():
    runs = ds.unesp_chirp_runs()
    assert set(runs) == {"0to40Hz", "0to110Hz", "70to110Hz"}
    assert runs["0to110Hz"] == (0.05, 0.1, 0.15, 0.25, 0.3)  # 0p20 missing (SOURCE.md)
    assert runs["0to40Hz"] == runs["70to110Hz"] == (0.05, 0.1, 0.15, 0.2, 0.25, 0.3)
    rec = ds.load_unesp_chirp((0, 40), 0.2)
    assert rec.names == UNESP_CHANNELS
    assert rec.n_samples == 16384 and rec.fs == 1024.0
    assert rec.meta["band_hz"] == [0.0, 40.0] and rec.meta["level"] == 0.2
    assert rms(rec["voltage"]) == pytest.approx(0.0981, abs=5e-4)
    assert ds.load_unesp_chirp("70-110", "0p05").meta["band_hz"] == [70.0, 110.0]
    with pytest.raises(ValueError, match="levels are"):
        ds.load_unesp_chirp("0to110Hz", 0.2)
    with pytest.raises(ValueError, match="bands are"):
        ds.load_unesp_chirp("5to10Hz", 0.2)


# ------------------------------------------------------------------------ Silverbox
@pytest.mark.parametrize(
    ("level", "u_std_mv", "y_std_mv"),
    [(5, 5.3, 10.6), (20, 19.3, 37.6), (50, 48.3, 89.3), (100, 96.8, 162.0), (150, 145.2, 224.0)],
)
def test_silverbox_multilevel(level, u_std_mv, y_std_mv):
    rec = ds.load_silverbox_multilevel(level)
    assert rec.names == ("u", "y") and rec.units == {"u": "V", "y": "V"}
    assert rec.fs == pytest.approx(1e7 / 2**12, rel=1e-12)  # 2441.40625 Hz from the file
    assert rec.n_samples == 245760
    assert rec.meta["periods"] == 30 and rec.meta["samples_per_period"] == 8192
    assert rec.meta["excited_bins"] == list(range(1, 1008))
    # SOURCE.md gives these as "RMS"; they are standard deviations (u has a ~15 mV offset)
    assert np.std(rec["u"]) * 1e3 == pytest.approx(u_std_mv, abs=0.1)
    assert np.std(rec["y"]) * 1e3 == pytest.approx(y_std_mv, abs=0.6)


def test_silverbox_multilevel_excited_lines():
    rec = ds.load_silverbox_multilevel(50)
    spectrum = np.abs(np.fft.rfft(rec["u"][-8192:]))
    excited = spectrum[rec.meta["excited_bins"]]
    assert excited.min() > 100 * spectrum[1010:4000].max()


def test_silverbox_multilevel_unknown_level():
    with pytest.raises(ValueError, match="levels are"):
        ds.load_silverbox_multilevel(80)


def test_silverbox_snls80mv():
    rec = ds.load_silverbox_snls80mv()
    assert rec.names == ("u", "y")
    assert rec.fs == 610.3515625 and rec.n_samples == 131072
    assert rec.duration == pytest.approx(214.7, abs=0.05)
    assert np.mean(rec["u"]) == pytest.approx(6.2e-3, abs=0.05e-3)
    assert rec["u"].min() == pytest.approx(-0.123, abs=1e-3)
    assert rec["u"].max() == pytest.approx(0.149, abs=1e-3)
    assert rec["y"].min() == pytest.approx(-0.300, abs=1e-3)
    assert rec["y"].max() == pytest.approx(0.276, abs=1e-3)
    assert rec.meta["ovld1"] == 0 and rec.meta["ovld2"] == 0


# ------------------------------------------------------------------------ F-16
def test_f16_sinesweep():
    rec = ds.load_f16_sinesweep()
    assert rec.names == ("force", "acc_ms", "acc_ws")
    assert rec.units == {"force": "N", "acc_ms": "m/s^2", "acc_ws": "m/s^2"}
    assert rec.fs == pytest.approx(400.0, rel=1e-12) and rec.n_samples == 108477
    assert rec.t0 == pytest.approx(0.08489, abs=1e-5)
    assert rec.meta["labels"] == {
        "force": "3:DP_RIGHT:+Z",
        "acc_ms": "70:RMIS MS:1004:+Z",
        "acc_ws": "108:RMIS WS:1004:+Z",
    }
    assert rms(rec["force"]) == pytest.approx(47.0, abs=0.5)  # SOURCE.md: ~47 N RMS
    assert 67 < np.max(np.abs(rec["force"])) < 74
    assert rms(rec["acc_ms"]) == pytest.approx(0.974, abs=0.001)
    assert rms(rec["acc_ws"]) == pytest.approx(0.881, abs=0.001)


def test_f16_plain_file_is_identical():
    a = ds.load_f16_sinesweep()
    b = ds.load_f16_sinesweep(file="f16.mat")
    for name in a.names:
        assert np.array_equal(a[name], b[name])
    assert b.fs == 400.0 and b.t0 == 0.0
    with pytest.raises(ValueError, match="F16_Data.mat"):
        ds.load_f16_sinesweep(file="other.mat")


# ------------------------------------------------------------------------ Bouc-Wen
def test_bouc_wen_parts():
    train = ds.load_bouc_wen()
    assert train.names == ("force", "displacement")
    assert train.units == {"force": "N", "displacement": "m"}
    assert train.fs == 750.0 and train.n_samples == 40960
    assert train.meta["measured"] is False
    u = train["force"]
    assert np.array_equal(u[:8192], u[8192:16384])  # 5 periods of one multisine
    assert rms(u) == pytest.approx(50.0, abs=0.01)
    ms = ds.load_bouc_wen("multisine")
    assert ms.n_samples == 8192 and rms(ms["force"]) == pytest.approx(50.0, abs=0.01)
    sw = ds.load_bouc_wen("sinesweep")
    assert sw.n_samples == 153000 and np.std(sw["force"]) == pytest.approx(28.28, abs=0.01)
    with pytest.raises(ValueError, match="part must be"):
        ds.load_bouc_wen("test")
