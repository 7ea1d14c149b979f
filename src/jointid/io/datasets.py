"""Loaders for the public vibration data sets kept beside the repository in ``../shared/data``.

The data are never copied into the project: :func:`shared_data_dir` finds the folder
(environment variable ``JOINTID_SHARED_DATA``, else ``shared/data`` next to the
repository root) and each loader reads the original files into a
:class:`~jointid.io.channels.Channels`.  Every record's ``meta`` has at least

``dataset``
    folder name of the data set;
``input`` / ``outputs``
    the excitation channel and the response channels (names in the record);
``licence``, ``citation``
    how the data may be used and whom to cite;
``measured``
    True for measured, False for simulated data.

=====================================  ==========================  =====  ==========  ======
loader                                 channels                    fs Hz  samples     source
=====================================  ==========================  =====  ==========  ======
:func:`load_unesp_sine`                voltage, acc1..acc4,        1024   65536       UNESP
                                       laser_velocity
:func:`load_unesp_random`              same                        1024   16384       UNESP
:func:`load_unesp_chirp`               same                        1024   16384       UNESP
:func:`load_silverbox_multilevel`      u, y                        2441.4 245760      VUB
:func:`load_silverbox_snls80mv`        u, y                        610.35 131072      VUB
:func:`load_f16_sinesweep`             force, acc_ms, acc_ws       400    108477      ULiège
:func:`load_bouc_wen`                  force, displacement         750    40960 ...   sim.
=====================================  ==========================  =====  ==========  ======

See ``SOURCE.md`` in each data folder for the origin of the files.
"""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any

import numpy as np

from jointid.errors import RecordError, RecordFileNotFoundError, where
from jointid.io.channels import Channels, merge_channels
from jointid.io.matlab import read_mat

__all__ = [
    "shared_data_dir",
    "unesp_sine_frequencies",
    "unesp_random_levels",
    "unesp_chirp_runs",
    "load_unesp_sine",
    "load_unesp_random",
    "load_unesp_chirp",
    "silverbox_multilevel_levels",
    "load_silverbox_multilevel",
    "load_silverbox_snls80mv",
    "load_f16_sinesweep",
    "load_bouc_wen",
]

ENV_VAR = "JOINTID_SHARED_DATA"

_UNESP = "unesp_bolted_beam"
_UNESP_ROOT = ("unesp_bolted_beam", "T5Nm")
_UNESP_META = {
    "dataset": _UNESP,
    "measured": True,
    "licence": "CC BY-NC-SA (non-commercial, share-alike); read only, do not redistribute",
    "citation": (
        "UNESP-BERT bolted beam, SHM Lab UNESP/Ilha Solteira (github shm-unesp/"
        "DATASET_BOLTEDBEAM); Teloli et al. MSSP 159 (2021) 107751"
    ),
    "torque_nm": 5.0,
    "input": "voltage",
    "outputs": ["acc1", "acc2", "acc3", "acc4", "laser_velocity"],
}
_UNESP_TIME_SPEC = {
    "acc1": "Signal[Acc1:+X]",
    "acc2": "Signal[Acc2:+X]",
    "acc3": "Signal[Acc3:+X]",
    "acc4": "Signal[Acc4:+X]",
    "laser_velocity": "Time_Laser__X",
}
_UNESP_SHAKER_SPEC = {"voltage": "Time_Shaker__X"}
_CHIRP_BANDS = ("0to40Hz", "0to110Hz", "70to110Hz")

_SILVERBOX_CITATION = (
    "T. Wigren & J. Schoukens, 'Three free data sets for development and benchmarking in "
    "nonlinear system identification', ECC 2013 (nonlinearbenchmark.org)"
)


# ---------------------------------------------------------------------------- location
def _repository_roots() -> list[Path]:
    roots = []
    for start in (Path(__file__).resolve().parent, Path.cwd().resolve()):
        for p in (start, *start.parents):
            if (p / "pyproject.toml").is_file() or (p / ".git").exists():
                roots.append(p)
                break
    return list(dict.fromkeys(roots))


def shared_data_dir() -> Path:
    """Folder holding the shared public data sets.

    Returns
    -------
    pathlib.Path
        ``$JOINTID_SHARED_DATA`` when that environment variable is set; otherwise
        ``<repository root>/../shared/data``, the repository root being the first folder
        above this module (or above the working directory) with a ``pyproject.toml`` or
        ``.git``.

    Raises
    ------
    jointid.errors.RecordFileNotFoundError
        If the variable names a missing folder, or no ``shared/data`` folder is found
        beside the repository.
    """
    env = os.environ.get(ENV_VAR)
    if env:
        p = Path(env).expanduser()
        if not p.is_dir():
            raise RecordFileNotFoundError(
                f"{where(p)}{ENV_VAR} names a folder that does not exist"
            )
        return p
    tried = []
    for root in _repository_roots():
        cand = root.parent / "shared" / "data"
        tried.append(str(cand))
        if cand.is_dir():
            return cand
    raise RecordFileNotFoundError(
        f"shared data folder not found (looked for {tried or 'a repository root'}); set "
        f"{ENV_VAR} to the folder holding the public data sets"
    )


def _file(*parts: str) -> Path:
    p = shared_data_dir().joinpath(*parts)
    if not p.exists():
        raise RecordFileNotFoundError(f"{where(p)}data file not found")
    return p


# ---------------------------------------------------------------------------- UNESP
def _unesp_dir(*parts: str) -> Path:
    return shared_data_dir().joinpath(*_UNESP_ROOT, *parts)


def _level_tag(level: float | str) -> str:
    """0.05 or '0p05' or '0.05' -> '0p05'."""
    if isinstance(level, str):
        s = level.strip().replace(".", "p")
        if not re.fullmatch(r"\d+p\d+", s):
            raise ValueError(f"expected a level such as 0.05 or '0p05', got {level!r}")
        return s
    return f"{float(level):.2f}".replace(".", "p")


def _tag_level(tag: str) -> float:
    return float(tag.replace("p", "."))


def _freq_from_folder(name: str) -> float | None:
    m = re.fullmatch(r"Sine_(\d+)(?:p(\d+))?Hz", name)
    if not m:
        return None
    return float(f"{int(m.group(1))}.{m.group(2) or '0'}")


def unesp_sine_frequencies() -> tuple[float, ...]:
    """Frequencies (Hz) of the UNESP sine-dwell tests present, ascending.

    Returns
    -------
    tuple of float
        5, 5.5, 6, 6.5, 6.75, 8, 8.5, 9, 9.5, 9.75, 16, 17, 18, 19, 20 in the shared
        copy.  16 Hz is listed but has no shaker-voltage file (see :func:`load_unesp_sine`).
    """
    folder = _unesp_dir("Sine")
    if not folder.is_dir():
        raise RecordFileNotFoundError(f"{where(folder)}UNESP sine folder not found")
    freqs = [_freq_from_folder(p.name) for p in folder.iterdir() if p.is_dir()]
    return tuple(sorted(f for f in freqs if f is not None))


def unesp_random_levels() -> tuple[float, ...]:
    """Relative levels of the UNESP random tests present (folder ``Rand0p05`` -> 0.05)."""
    folder = _unesp_dir("Rand")
    if not folder.is_dir():
        raise RecordFileNotFoundError(f"{where(folder)}UNESP random folder not found")
    tags = [p.name[4:] for p in folder.iterdir() if p.is_dir() and p.name.startswith("Rand")]
    return tuple(sorted(_tag_level(t) for t in tags))


def unesp_chirp_runs() -> dict[str, tuple[float, ...]]:
    """UNESP chirp tests present: frequency band -> relative levels.

    Returns
    -------
    dict
        ``{"0to40Hz": (0.05, ..., 0.3), "0to110Hz": (0.05, 0.1, 0.15, 0.25, 0.3),
        "70to110Hz": (0.05, ..., 0.3)}`` in the shared copy (``0to110Hz`` level 0.20 is
        missing).
    """
    out = {}
    for band in _CHIRP_BANDS:
        folder = _unesp_dir("Chirp", f"Chirp{band}")
        if folder.is_dir():
            tags = [
                p.name[5:] for p in folder.iterdir() if p.is_dir() and p.name.startswith("Chirp")
            ]
            out[band] = tuple(sorted(_tag_level(t) for t in tags))
    return out


def _load_unesp_run(folder: Path, meta: dict[str, Any], voltage: bool, what: str) -> Channels:
    if not folder.is_dir():
        raise RecordFileNotFoundError(f"{where(folder)}UNESP test folder not found ({what})")
    time_file = folder / "Time.mat"
    shaker_file = folder / "TimeShaker.mat"
    if not time_file.is_file():
        raise RecordFileNotFoundError(
            f"{where(time_file)}response file of the {what} is missing from the data set"
        )
    responses = read_mat(time_file, _UNESP_TIME_SPEC)
    records = [responses]
    if voltage:
        if not shaker_file.is_file():
            raise RecordFileNotFoundError(
                f"{where(shaker_file)}the shaker-voltage file of the {what} is missing from "
                f"the data set (it was not in the repository snapshot, see SOURCE.md); pass "
                f"voltage=False to load the responses only"
            )
        shaker = read_mat(shaker_file, _UNESP_SHAKER_SPEC)
        records.insert(0, shaker)
    labels = {}
    for r in records:
        labels.update(r.meta.get("labels", {}))
    rec = merge_channels(records, source=str(folder))
    full_meta = dict(_UNESP_META)
    if not voltage:
        full_meta["input"] = None
    full_meta.update(meta)
    full_meta.update(
        {
            "files": [r.source for r in records],
            "labels": labels,
            "run_name": responses.meta.get("run_name"),
        }
    )
    return Channels(time=rec.time, data=rec.data, units=rec.units, source=rec.source,
                    meta=full_meta)


def load_unesp_sine(freq_hz: float, *, voltage: bool = True) -> Channels:
    """One steady-state sine-dwell test of the UNESP bolted lap-joint beam (5 Nm torque).

    Two aluminium beams (270 x 25.4 x 6.35 mm) joined by a bolted lap joint, mounted as
    a cantilever, driven by a shaker 85 mm from the clamp with a 0.15 V sine (nominal
    generator amplitude; the recorded amplifier voltage is about 0.133 V peak, 0.094 V
    RMS).  Mode 1 is near 18.75 Hz; 16-20 Hz covers the primary resonance, 5-9.75 Hz
    the super-harmonic resonances.

    Parameters
    ----------
    freq_hz : float
        Excitation frequency, one of :func:`unesp_sine_frequencies`.
    voltage : bool, optional
        Include the shaker voltage (default True).  The 16 Hz test has no voltage file;
        load it with ``voltage=False``.

    Returns
    -------
    Channels
        fs = 1024 Hz (Test.Lab ``x_values.increment`` = 1/1024 s), 65536 samples (64 s),
        t0 = 0.  Channels:

        ``voltage`` [V]
            shaker-amplifier voltage, ``TimeShaker.mat`` ``Time_Shaker__X``
            (Test.Lab channel ``Shaker:-X``).  **Not a force**: no force transducer was used.
        ``acc1`` .. ``acc4`` [m/s^2]
            accelerometers ``Acc1:+X`` .. ``Acc4:+X``, columns 0-3 of ``Time.mat``
            ``Signal`` (N x 4).  SI values although Test.Lab labels them ``g`` (MKS export):
            at 18 Hz the RMS of acc1 is 70.2 m/s^2 = 2 pi 18 x 0.625 m/s.
        ``laser_velocity`` [m/s]
            laser vibrometer at the free end, ``Time.mat`` ``Time_Laser__X`` (``Laser:+X``).

        ``meta`` adds ``frequency_hz``, ``excitation`` (``"sine"``), ``files``, ``labels``
        and ``run_name``.

    Raises
    ------
    ValueError
        If no test exists at `freq_hz` (the message lists the frequencies).
    jointid.errors.RecordFileNotFoundError
        If a file is missing, in particular ``Sine_16Hz/TimeShaker.mat`` with
        ``voltage=True``.

    Notes
    -----
    Licence CC BY-NC-SA: read it, do not redistribute it.
    """
    freqs = unesp_sine_frequencies()
    match = [f for f in freqs if abs(f - float(freq_hz)) < 1e-9]
    if not match:
        raise ValueError(
            f"no UNESP sine test at {freq_hz!r} Hz; available frequencies are {list(freqs)}"
        )
    folder = next(
        p for p in _unesp_dir("Sine").iterdir() if _freq_from_folder(p.name) == match[0]
    )
    return _load_unesp_run(
        folder,
        {"excitation": "sine", "frequency_hz": match[0], "amplitude_v_nominal": 0.15},
        voltage,
        f"{match[0]:g} Hz sine test",
    )


def load_unesp_random(level: float | str, *, voltage: bool = True) -> Channels:
    """One random-excitation test (0-110 Hz) of the UNESP bolted beam.

    Parameters
    ----------
    level : float or str
        Relative level, one of :func:`unesp_random_levels` (0.05 ... 0.30), or the folder
        tag such as ``"0p05"``.  The recorded shaker voltage is only 0.5-3.1 mV RMS, so the
        level is a relative setting, not volts.
    voltage : bool, optional
        Include the shaker voltage (default True).

    Returns
    -------
    Channels
        Same channels and units as :func:`load_unesp_sine`; fs = 1024 Hz, 16384 samples
        (16 s).  ``meta`` adds ``excitation`` (``"random"``), ``band_hz`` (0, 110) and
        ``level``.

    Raises
    ------
    ValueError
        If there is no test at that level (the message lists them).
    jointid.errors.RecordFileNotFoundError
        If a file is missing.
    """
    tag = _level_tag(level)
    folder = _unesp_dir("Rand", f"Rand{tag}")
    if not folder.is_dir():
        raise ValueError(
            f"no UNESP random test at level {level!r}; levels are {list(unesp_random_levels())}"
        )
    return _load_unesp_run(
        folder,
        {"excitation": "random", "band_hz": [0.0, 110.0], "level": _tag_level(tag)},
        voltage,
        f"random test at level {_tag_level(tag):g}",
    )


def _band_tag(band: str | tuple[float, float]) -> str:
    if isinstance(band, str):
        s = band.strip().replace(" ", "").replace("-", "to")
        if not s.endswith("Hz"):
            s += "Hz"
    else:
        lo, hi = band
        s = f"{float(lo):g}to{float(hi):g}Hz"
    return s


def load_unesp_chirp(
    band: str | tuple[float, float], level: float | str, *, voltage: bool = True
) -> Channels:
    """One chirp test of the UNESP bolted beam.

    Parameters
    ----------
    band : str or (float, float)
        Frequency band: ``"0to40Hz"``, ``"0to110Hz"`` or ``"70to110Hz"`` (also ``(0, 40)``
        or ``"0-40"``).
    level : float or str
        Relative level (0.05 ... 0.30, or the folder tag ``"0p05"``); see
        :func:`unesp_chirp_runs` (``0to110Hz`` has no 0.20).  The recorded voltage RMS is
        about 0.49 x level V.
    voltage : bool, optional
        Include the shaker voltage (default True).

    Returns
    -------
    Channels
        Same channels and units as :func:`load_unesp_sine`; fs = 1024 Hz, 16384 samples.
        ``meta`` adds ``excitation`` (``"chirp"``), ``band_hz`` and ``level``.

    Raises
    ------
    ValueError
        If there is no such band or level (the message lists what there is).
    jointid.errors.RecordFileNotFoundError
        If a file is missing.
    """
    btag = _band_tag(band)
    runs = unesp_chirp_runs()
    if btag not in runs:
        raise ValueError(f"no UNESP chirp band {band!r}; bands are {list(runs)}")
    tag = _level_tag(level)
    folder = _unesp_dir("Chirp", f"Chirp{btag}", f"Chirp{tag}")
    if not folder.is_dir():
        raise ValueError(
            f"no UNESP chirp {btag} test at level {level!r}; levels are {list(runs[btag])}"
        )
    lo, hi = (float(x) for x in btag[:-2].split("to"))
    return _load_unesp_run(
        folder,
        {"excitation": "chirp", "band_hz": [lo, hi], "level": _tag_level(tag)},
        voltage,
        f"{btag} chirp test at level {_tag_level(tag):g}",
    )


# ---------------------------------------------------------------------------- Silverbox
_SILVERBOX_LEVELS = (5, 20, 50, 100, 150)


def silverbox_multilevel_levels() -> tuple[int, ...]:
    """Input levels (mV RMS, nominal) of the multilevel Silverbox records: 5, 20, 50, 100, 150."""
    return _SILVERBOX_LEVELS


def load_silverbox_multilevel(level_mv: int) -> Channels:
    """Silverbox (electronic Duffing oscillator) under a full-band multisine at one level.

    Files ``silverbox_multilevel_noel/SNJP_um_full_FNSI_<L>.mat`` (variables ``um``
    245760 x 1 input voltage, ``fs`` = 2441.40625, ``P`` = 30, ``flines`` 1 x 1007) and
    ``SNJP_ym_full_FNSI_<L>.mat`` (``ym`` 245760 x 1 output voltage), from J.P. Noël.

    Parameters
    ----------
    level_mv : int
        Nominal input RMS in mV: 5, 20, 50, 100 or 150.

    Returns
    -------
    Channels
        fs = 1e7 / 2**12 = 2441.40625 Hz (read from the file), 245760 samples = 30 periods
        of 8192.  Channels ``u`` (input voltage [V]; it has a DC offset of about 15-16 mV,
        its standard deviation is 5.3, 19.3, 48.3, 96.8, 145.2 mV) and ``y`` (output
        voltage [V], the displacement analogue).  ``meta`` adds ``level_mv``, ``periods``
        (30), ``samples_per_period`` (8192), ``excited_bins`` (the 1007 ``flines``:
        bins 1..1007 of a numpy FFT of one 8192-sample period, 0.3-300 Hz; checked on the
        data, the excited lines are exactly these indices) and ``transient_periods_hint``
        (5: the pyvib example drops the first 5 periods).  Reference low-level linear mode:
        68.58 Hz, damping ratio 4.68 %.

    Raises
    ------
    ValueError
        If `level_mv` is not one of the levels.
    jointid.errors.RecordFileNotFoundError
        If a file is missing.
    """
    if int(level_mv) not in _SILVERBOX_LEVELS or float(level_mv) != int(level_mv):
        raise ValueError(
            f"no multilevel Silverbox record at {level_mv!r} mV; levels are "
            f"{list(_SILVERBOX_LEVELS)}"
        )
    lv = int(level_mv)
    ufile = _file("silverbox_multilevel_noel", f"SNJP_um_full_FNSI_{lv}.mat")
    yfile = _file("silverbox_multilevel_noel", f"SNJP_ym_full_FNSI_{lv}.mat")
    urec = read_mat(ufile, {"u": "um"}, fs="fs", units={"u": "V"})
    yrec = read_mat(yfile, {"y": "ym"}, fs=urec.fs, units={"y": "V"})
    from scipy.io import loadmat

    extra = loadmat(str(ufile), variable_names=["P", "flines"], squeeze_me=True)
    periods = int(extra["P"])
    bins = [int(b) for b in np.atleast_1d(extra["flines"])]
    n = urec.n_samples
    if n % periods:
        raise RecordError(
            f"{where(ufile, channel='u')}expected a whole number of periods ({periods}), got "
            f"{n} samples"
        )
    rec = merge_channels([urec, yrec], source=str(ufile.parent))
    meta = {
        "dataset": "silverbox_multilevel_noel",
        "measured": True,
        "licence": "none stated; attribute to J.P. Noël & J. Schoukens (VUB / ULiège)",
        "citation": (
            "J.P. Noël & J. Schoukens, 'Grey-box state-space identification of nonlinear "
            "mechanical vibrations', Int. J. Control 2018"
        ),
        "input": "u",
        "outputs": ["y"],
        "excitation": "multisine",
        "level_mv": lv,
        "periods": periods,
        "samples_per_period": n // periods,
        "excited_bins": bins,
        "transient_periods_hint": 5,
        "files": [str(ufile), str(yfile)],
    }
    return Channels(time=rec.time, data=rec.data, units=rec.units, source=rec.source, meta=meta)


def load_silverbox_snls80mv() -> Channels:
    """The classic Silverbox benchmark record ``silverbox/SNLS80mV.mat``.

    Returns
    -------
    Channels
        fs = 1e7 / 2**14 = 610.3515625 Hz (not stored in the file), 131072 samples
        (214.7 s), t0 = 0.  Channels ``u`` = ``V1`` (input voltage [V], raw: mean 6.2 mV,
        subtract it if needed) and ``y`` = ``V2`` (output voltage [V]).  ``meta`` adds
        the overload flags ``ovld1``/``ovld2`` (both 0) and the layout described in
        SOURCE.md: ``arrow_samples_approx`` (about the first 40 700 samples are the
        "arrow", filtered noise of linearly rising amplitude, the usual test set),
        ``test_slice_hint`` ([86, 40086], the split of the pyvib example / Paduart et al.
        2010: 86 leading zero samples, then 40 000 test samples) and
        ``multisine_realisations`` (10 odd random-phase multisines of 8192 samples, with a
        few hundred transient samples between them, after the arrow).

    Raises
    ------
    jointid.errors.RecordFileNotFoundError
        If the file is missing.
    """
    f = _file("silverbox", "SNLS80mV.mat")
    rec = read_mat(f, {"u": "V1", "y": "V2"}, fs=1e7 / 2**14, units={"u": "V", "y": "V"})
    from scipy.io import loadmat

    flags = loadmat(str(f), variable_names=["Ovld1", "Ovld2"], squeeze_me=True)
    meta = {
        "dataset": "silverbox",
        "measured": True,
        "licence": "freely available for research; cite Wigren & Schoukens (2013)",
        "citation": _SILVERBOX_CITATION,
        "input": "u",
        "outputs": ["y"],
        "excitation": "arrow (rising filtered noise) + 10 odd random-phase multisines",
        "ovld1": int(flags.get("Ovld1", 0)),
        "ovld2": int(flags.get("Ovld2", 0)),
        "arrow_samples_approx": 40700,
        "test_slice_hint": [86, 40086],
        "multisine_realisations": 10,
        "samples_per_period": 8192,
    }
    return Channels(time=rec.time, data=rec.data, units=rec.units, source=str(f), meta=meta)


# ---------------------------------------------------------------------------- F-16
_F16_MS = "RMIS MS:1004:+Z"
_F16_WS = "RMIS WS:1004:+Z"
_F16_MS_COL = 66
_F16_WS_COL = 102


def load_f16_sinesweep(*, file: str = "F16_Data.mat", extra_channels: tuple[str, ...] = ()) -> Channels:
    """F-16 ground vibration test: a downward sine sweep at the right wing-payload joint.

    LMS Test.Lab export of run ``SWS_RS_down_14`` (project
    ``GVT_RandomSetup_ChangedChannels_for_Sine_without_Slave``, 2014-09-29), ULiège/VUB.
    Sweep from about 15 Hz down to about 2 Hz at about 0.05 Hz/s, force about 67-70 N
    peak (47 N RMS).

    Parameters
    ----------
    file : {"F16_Data.mat", "f16.mat"}, optional
        ``F16_Data.mat`` (default) holds Test.Lab structs: ``Signal_1`` (108477,) force at
        ``DP_RIGHT:+Z`` [N] and ``Signal_0`` (108477 x 115) accelerations with names in
        ``function_record.name`` and the time base in ``x_values`` (start 0.0849 s,
        increment 0.0025 s).  ``f16.mat`` holds the same numbers as plain arrays ``u``
        (1 x 108477) and ``y`` (108477 x 115) without names or time; it is read with
        fs = 400 Hz and t0 = 0.
    extra_channels : tuple of str, optional
        More acceleration channels of ``Signal_0`` by Test.Lab label (e.g.
        ``"RHTP:1093:+X"``), added under that label.  Only with ``F16_Data.mat``; all
        channels but the two joint channels are zero in this run.

    Returns
    -------
    Channels
        fs = 400 Hz, 108477 samples (271.2 s).  Channels ``force`` [N] (shaker force at
        the right-wing driving point), ``acc_ms`` [m/s^2] (``RMIS MS:1004:+Z``, column 66:
        missile/payload side of the interface) and ``acc_ws`` [m/s^2]
        (``RMIS WS:1004:+Z``, column 102: wing side).  Accelerations are SI although
        Test.Lab labels them ``g`` (MKS export).  The relative acceleration across the
        joint is ``acc_ws - acc_ms``.

    Raises
    ------
    ValueError
        If `file` is not one of the two files, or `extra_channels` is used with ``f16.mat``.
    jointid.errors.RecordFileNotFoundError
        If the file is missing.
    jointid.errors.RecordError
        If an extra channel label is not in the file.
    """
    meta = {
        "dataset": "f16_gvt_sinesweep_uliege",
        "measured": True,
        "licence": "none stated; attribute to the F-16 GVT team (ULiège / VUB)",
        "citation": (
            "J.P. Noël & M. Schoukens, 'F-16 aircraft benchmark based on ground vibration "
            "test data', Workshop on Nonlinear System Identification Benchmarks, 2017"
        ),
        "input": "force",
        "outputs": ["acc_ms", "acc_ws"],
        "excitation": "sine sweep, about 15 Hz down to 2 Hz",
        "run_name": "SWS_RS_down_14",
        "joint": "right wing - missile/payload interface; MS = missile side, WS = wing side",
    }
    if file == "F16_Data.mat":
        f = _file("f16_gvt_sinesweep_uliege", "F16_Data.mat")
        spec = {
            "force": "Signal_1",
            "acc_ms": f"Signal_0[{_F16_MS}]",
            "acc_ws": f"Signal_0[{_F16_WS}]",
        }
        for label in extra_channels:
            if label in spec:
                raise ValueError(f"extra channel {label!r} clashes with a channel name")
            spec[label] = f"Signal_0[{label}]"
        rec = read_mat(f, spec)
        meta["labels"] = rec.meta.get("labels", {})
    elif file == "f16.mat":
        if extra_channels:
            raise ValueError("extra_channels needs file='F16_Data.mat' (f16.mat has no labels)")
        f = _file("f16_gvt_sinesweep_uliege", "f16.mat")
        rec = read_mat(
            f,
            {"force": "u", "acc_ms": f"y[{_F16_MS_COL}]", "acc_ws": f"y[{_F16_WS_COL}]"},
            fs=400.0,
            units={"force": "N", "acc_ms": "m/s^2", "acc_ws": "m/s^2"},
        )
    else:
        raise ValueError(f"file must be 'F16_Data.mat' or 'f16.mat', got {file!r}")
    meta["file"] = file
    return Channels(time=rec.time, data=rec.data, units=rec.units, source=str(f), meta=meta)


# ---------------------------------------------------------------------------- Bouc-Wen
_BOUC_WEN_PARTS = {
    "train": ("u", "y", "one random-phase multisine repeated over 5 periods of 8192, RMS 50 N"),
    "multisine": ("uval_multisine", "yval_multisine", "official multisine validation, RMS 50 N"),
    "sinesweep": ("uval_sinesweep", "yval_sinesweep", "official sine-sweep validation, 40 N"),
}


def load_bouc_wen(part: str = "train") -> Channels:
    """Bouc-Wen hysteretic benchmark (SIMULATED), ``bouc_wen/bouc-wen.mat``.

    Benchmark of J.P. Noël & M. Schoukens (2016): ``m y'' + c y' + k y + z(y, y') = u``,
    ``z' = alpha y' - beta (gamma |y'| |z|^(nu-1) z + delta y' |z|^nu)`` with, per the
    benchmark description (quoted from memory in SOURCE.md), m = 2 kg, c = 10 N s/m,
    k = 5e4 N/m, alpha = 5e4 N/m, beta = 1e3 1/m, gamma = 0.8, delta = -1.1, nu = 1.

    Parameters
    ----------
    part : {"train", "multisine", "sinesweep"}, optional
        ``"train"``: ``u`` (40960 x 1) and ``y`` (1 x 40960), a multisine repeated over 5
        periods of 8192 samples, input RMS 50 N (probably generated by the EHH authors);
        ``"multisine"``: ``uval_multisine``/``yval_multisine`` (1 x 8192), official
        validation, RMS 50 N; ``"sinesweep"``: ``uval_sinesweep``/``yval_sinesweep``
        (1 x 153000), official validation, amplitude 40 N.

    Returns
    -------
    Channels
        fs = 750 Hz (benchmark value; not stored in the file), t0 = 0.  Channels
        ``force`` [N] (input u) and ``displacement`` [m] (output y).  ``meta`` adds
        ``part``, ``parameters`` and, for the multisines, ``samples_per_period`` (8192).

    Raises
    ------
    ValueError
        If `part` is unknown.
    jointid.errors.RecordFileNotFoundError
        If the file is missing.
    """
    if part not in _BOUC_WEN_PARTS:
        raise ValueError(f"part must be one of {list(_BOUC_WEN_PARTS)}, got {part!r}")
    uvar, yvar, desc = _BOUC_WEN_PARTS[part]
    f = _file("bouc_wen", "bouc-wen.mat")
    rec = read_mat(
        f,
        {"force": uvar, "displacement": yvar},
        fs=750.0,
        units={"force": "N", "displacement": "m"},
    )
    meta: dict[str, Any] = {
        "dataset": "bouc_wen",
        "measured": False,
        "licence": "none stated (EHH repository); benchmark by Noël & Schoukens",
        "citation": (
            "J.P. Noël & M. Schoukens, 'Hysteretic benchmark with a dynamic nonlinearity', "
            "Workshop on Nonlinear System Identification Benchmarks, 2016"
        ),
        "input": "force",
        "outputs": ["displacement"],
        "part": part,
        "excitation": desc,
        "parameters": {
            "m": 2.0, "c": 10.0, "k": 5e4, "alpha": 5e4, "beta": 1e3,
            "gamma": 0.8, "delta": -1.1, "nu": 1.0,
        },
    }
    if part in ("train", "multisine"):
        meta["samples_per_period"] = 8192
    return Channels(time=rec.time, data=rec.data, units=rec.units, source=str(f), meta=meta)
