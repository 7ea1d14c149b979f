"""Turn lab exports (UFF 58, MAT incl. LMS Test.Lab, HDF5, CSV) into a campaign folder.

An import description (TOML) names the source files of every record and which of their
channels become which campaign columns::

    [campaign]
    name = "UNESP sine dwells"
    coordinates = "modal"           # or "physical", with a [structure] table copied as is

    [import]                        # defaults for every source
    fs = 1024.0                     # for plain MAT arrays without a time vector
    channels = { force = "Time_Shaker__X", accel = "Time_Laser__X" }
    data_folder = "../data/unesp"   # optional: where the source files are (default: the
                                    # description's folder); relative to the description, or
                                    # "shared:unesp_bolted_beam/T5Nm": below the shared data
                                    # folder ($JOINTID_SHARED_DATA, jointid.io.datasets)

    [[record]]
    frequency_hz = 17.0             # optional, as in a campaign
    force_level = 0.15
    preload = 5
    [[record.source]]               # one or more files, merged on their common time base
    file = "Sine/Sine_17Hz/Time.mat"          # relative to the description file
    channels = { accel = "Time_Laser__X" }    # column -> channel in that file
    [[record.source]]
    file = "Sine/Sine_17Hz/TimeShaker.mat"
    channels = { force = "Time_Shaker__X" }

A record with a single source may give ``file = ...`` directly.  The channel given for a
column is: for MAT a variable or struct path (``"Signal[0]"``, ``"data.force"``), for UFF a
dataset label (id line or LMS node:direction), for HDF5 a dataset name of a jointid record
or, in any other HDF5 file, a dataset path (``"/run1/daq/ai0"``), for CSV a column name.

Column map
    A column may also be a table ``{ channel = "Ch 3", unit = "g", scale = 0.5 }``: the values
    are multiplied by ``scale`` and converted from ``unit`` to SI (:data:`UNIT_FACTORS`:
    ``g``, ``mm``, ``mm/s``, ``mV``, ``kN`` ...).  ``time = "t [s]"`` names the time column of
    a CSV file (or the time dataset of an HDF5 file) when it is not ``time``; a CSV or HDF5
    source without a time column takes ``fs`` (sampling rate [Hz]) instead.
Time window
    ``window_s = [t0, t1]`` (in ``[import]`` or a record) keeps the samples with
    ``t0 <= t < t1`` (e.g. the steady state of a dwell whose drive stops before the end of
    the record).  The records are written as ``records/NNNN.csv`` with ``time`` first; a record that
cannot be read is reported and left out, the others are written.

First-harmonic records
    A record with ``excitation = "first-harmonic"`` (optionally ``control = "force"``,
    ``"response"`` or ``"phase-resonance"``) holds one line per frequency of a stepped-sine
    controller's export; its columns are ``frequency_hz``, ``force`` (amplitude),
    ``force_phase`` (optional), ``accel`` (amplitude at the driving point) and
    ``accel_phase``, or a complex ``frf`` (``frf_real`` and ``frf_imag``) with ``force``
    (see :mod:`jointid.io.firsth`).  A MAT reference may index struct arrays anywhere
    (``"FRdata.ForceControl[2].amplitude"``); units ``deg`` and ``hz`` convert phases and
    frequencies.  It is written as ``records/NNNN.csv`` with the columns of
    :data:`jointid.io.firsth.FH_COLUMNS`.

The description is validated before any file is read, like a campaign manifest: UTF-8 text,
known keys (the nearest valid name is suggested), types and values; a source path that
leaves the data folder (``..``, an absolute path) fails its record.  CSV time stamps get the
campaign's tolerance (:data:`jointid.io.campaign.CSV_TIME_RTOL`) and are written uniform.
A ``[structure]`` table is checked as the campaign loader reads it (known keys, or tables keyed
by the records' preloads), and its values by the command (:mod:`jointid.modal.structure`).
A record fails, named, when its column map lacks what its excitation is identified from (the
force, but for a ring-down; the response in modal coordinates) or when a channel is constant
or zero throughout (a dead sensor); MAT logical arrays are refused, not read as 0/1 samples.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..conventions import STRUCTURE_KEYS
from ..errors import JointidError, ManifestError, RecordError, RecordFileNotFoundError, unknown_key_message, where
from .campaign import (
    COORDINATES,
    CSV_TIME_RTOL,
    MAX_RECORDS,
    _decode,
    _excitation,
    _label,
    _number,
    _same_label,
    check_keys,
    check_regular_file,
    read_toml,
    write_campaign,
    write_csv_record,
)
from .channels import Channels, merge_channels, validate_channels
from .outputset import output_set
from .units import UNITS, check_column_unit

#: Keys of an import description, of its ``[import]`` table, of a record and of a source.
DESCRIPTION_KEYS = ("campaign", "import", "record", "structure")
#: ``[import] data_folder`` starting with this is below the shared data folder.
SHARED_PREFIX = "shared:"
IMPORT_KEYS = ("fs", "channels", "data_folder", "time", "window_s")
RECORD_KEYS = ("file", "source", "channels", "fs", "frequency_hz", "force_level", "preload", "excitation",
               "period_s", "time", "window_s", "control")
SOURCE_KEYS = ("file", "channels", "time", "fs")
#: Record keys about a time history, which a first-harmonic record does not have.
FH_TIME_KEYS = ("frequency_hz", "period_s", "time", "fs", "window_s")
#: Keys of a column of the column map given as a table.
COLUMN_KEYS = ("channel", "unit", "scale")
#: Factors from the units a column map may name to SI (:data:`jointid.io.units.UNITS` holds their dimensions).
UNIT_FACTORS = {u: f for u, (f, _) in UNITS.items()}
#: Response columns of a record in modal coordinates: what its excitation is identified from
#: (stepped sines and ring-downs by the acceleration; multisine and random records by any of them).
MODAL_RESPONSES = {"stepped-sine": ("accel",), "ringdown": ("accel",),
                   "multisine": ("accel", "velocity", "displacement"), "random": ("accel", "velocity", "displacement")}

__all__ = ["ImportResult", "import_campaign", "read_source"]


@dataclass(frozen=True)
class ImportResult:
    """What an import wrote and what it could not."""

    folder: Path
    written: tuple  # (index, file) of each written record
    failed: tuple  # (index, message)

    def report(self) -> str:
        lines = [f"{len(self.written)} records written to {self.folder}, {len(self.failed)} failed"]
        lines += [f"  record {i}: {msg}" for i, msg in self.failed]
        return "\n".join(lines)


def _uniform_time(n: int, fs, path, what) -> np.ndarray:
    if fs is None:
        raise RecordError(f"{path}: {what}; give the time column (time = \"...\") or the sampling rate fs")
    return np.arange(n) / float(fs)


def _read_hdf5_datasets(path: Path, channels: dict, fs=None, time=None) -> Channels:
    """Channels from any HDF5 file by dataset path; time from a dataset or ``fs``."""
    import h5py

    data = {}
    from .hdf5 import check_dataset, check_no_external_link

    try:
        with h5py.File(path, "r") as h5:
            for out, src in channels.items():
                check_no_external_link(h5, src, path, out)  # before the link is followed
                node = h5.get(src)
                if not isinstance(node, h5py.Dataset):
                    raise RecordError(f"{path} [channel {out!r}]: no dataset {src!r} in the file")
                check_dataset(node, path, out, src)  # real numbers within the record limit, before reading
                x = np.asarray(node[()], dtype=float)
                if x.ndim != 1:
                    x = np.squeeze(x)
                if x.ndim != 1:
                    raise RecordError(f"{path} [channel {out!r}]: dataset {src!r} has shape {node.shape}, "
                                      "expected one dimension")
                data[out] = x
            lengths = {out: x.size for out, x in data.items()}
            o1, n1 = next(iter(lengths.items()), (None, None))
            other = [(o, n) for o, n in lengths.items() if n != n1]
            if other:
                o2, n2 = other[0]
                base = (f"the time dataset {time!r}" if time is not None else
                        f"fs = {fs!r} Hz" if fs is not None else "no time base")
                raise RecordError(f"{path} [channel {o2!r}]: dataset {channels[o2]!r} has {n2} samples, but "
                                  f"dataset {channels[o1]!r} (channel {o1!r}) has {n1}; the channels of a record "
                                  f"are sampled together, one length for all (time base: {base})")
            if time is not None:
                check_no_external_link(h5, time, path, "time")
                node = h5.get(time)
                if not isinstance(node, h5py.Dataset):
                    raise RecordError(f"{path} [channel 'time']: no dataset {time!r} in the file")
                check_dataset(node, path, "time", time)
                t = np.asarray(node[()], dtype=float).ravel()
            else:
                t = _uniform_time(next(iter(data.values())).size, fs, path, "no time dataset")
    except OSError as exc:
        raise RecordError(f"{path}: not a readable HDF5 file ({exc})") from None
    validate_channels(t, data, source=str(path), time_rtol=CSV_TIME_RTOL)
    return Channels(t, data, source=str(path))


def read_source(path: Path, channels: dict, fs=None, time=None) -> Channels:
    """Read ``channels`` (column -> source channel) from one file, by its extension.

    ``time`` names a CSV time column (default ``"time"``) or an HDF5 time dataset; without
    one, ``fs`` gives the sampling rate.
    """
    check_regular_file(path, "source file")  # a folder or device is said to be one, not "not found"
    suffix = path.suffix.lower()
    if suffix == ".mat":
        from .matlab import read_mat

        return read_mat(path, channels, fs=fs if time is None else None, time=time)
    if suffix in (".uff", ".unv", ".uff58"):
        from .uff import read_uff

        return read_uff(path, channels)
    if suffix in (".h5", ".hdf5"):
        import h5py

        try:
            with h5py.File(path, "r") as h5:
                jointid_layout = "channels" in h5 and time is None
        except OSError as exc:
            raise RecordError(f"{path}: not a readable HDF5 file ({exc})") from None
        if not jointid_layout:
            return _read_hdf5_datasets(path, channels, fs=fs, time=time)
        from .hdf5 import read_hdf5

        ch = read_hdf5(path, list(channels.values()))
        return Channels(ch.time, {out: ch.data[src] for out, src in channels.items()},
                        {out: ch.units.get(src, "") for out, src in channels.items()}, source=str(path))
    if suffix in (".csv", ".txt"):
        with open(path, "rb") as fh:
            head = fh.read(4096)
        try:
            text = _decode(head, path, "CSV file")
        except ManifestError as exc:
            raise RecordError(str(exc)) from None
        header = [h.strip() for h in (text.splitlines() or [""])[0].split(",")]
        try:
            with warnings.catch_warnings():  # an empty file is said below, not by numpy's warning
                warnings.simplefilter("ignore", UserWarning)
                rows = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2, encoding="utf-8")
        except UnicodeDecodeError:
            raise RecordError(f"{path}: CSV file must be UTF-8 text; it holds bytes that are not") from None
        except ValueError as exc:
            raise RecordError(f"{path}: not a numeric CSV with header {header} ({exc})") from exc
        tname = "time" if time is None else time
        if tname not in header and (time is not None or fs is None):
            raise RecordError(f"{path} [channel {tname!r}]: missing time column; found {header} "
                              "(name it with time = \"...\" or give the sampling rate fs)")
        missing = [src for src in channels.values() if src not in header]
        if missing:
            raise RecordError(f"{path} [channel {missing[0]!r}]: missing column; found {header}")
        if rows.shape[1] != len(header):
            raise RecordError(f"{path}: header names {len(header)} columns but rows have {rows.shape[1]}")
        twice = sorted({h for h in header if header.count(h) > 1} & ({tname} | set(channels.values())))
        if twice:
            raise RecordError(f"{path} [channel {twice[0]!r}]: the header names column {twice[0]!r} more than "
                              "once; which one is meant cannot be told: rename one")
        t = rows[:, header.index(tname)] if tname in header else _uniform_time(rows.shape[0], fs, path, "")
        data = {out: rows[:, header.index(src)] for out, src in channels.items()}
        # time stamps written as text: the campaign's tolerance, then the uniform grid they stand for
        validate_channels(t, data, source=str(path), time_rtol=CSV_TIME_RTOL)
        t = t[0] + (t[-1] - t[0]) / (t.size - 1) * np.arange(t.size)
        return Channels(t, data, source=str(path))
    raise RecordError(f"{path}: unknown format {suffix!r}; expected .mat, .uff, .unv, .h5 or .csv")


def _channel_map(value, ctx) -> dict:
    """A ``column -> source channel`` table (texts, or ``{channel, unit, scale}`` tables), else a ManifestError."""
    if not isinstance(value, dict):
        raise ManifestError(f"{ctx}channels must be a table column -> channel, e.g. "
                            f"{{ force = \"F\", accel = \"A1\" }}, got {value!r}")
    for k, v in value.items():
        if str(k).strip().lower() == "time":  # the time base is not a channel: it would be written twice
            raise ManifestError(f"{ctx}channels.{k}: the time column is not a channel of the column map; name it "
                                f"with time = \"{v if isinstance(v, str) else '...'}\" (in [import], the record or "
                                "the source) or give the sampling rate fs")
        if isinstance(v, dict):
            check_keys(v, COLUMN_KEYS, f"{ctx}channels.{k}: ")
            if not isinstance(v.get("channel"), str) or not v["channel"]:
                raise ManifestError(f"{ctx}channels.{k} needs channel = \"<name in the file>\", got {v!r}")
            unit = v.get("unit", "")
            if not isinstance(unit, str):
                raise ManifestError(f"{ctx}channels.{k}: unit must be text, got {unit!r}")
            check_column_unit(k, unit, ctx)  # known, and of the column's dimension
            scale = _number(v.get("scale", 1.0), "scale", f"{ctx}channels.{k}: ")
            if scale is None or scale == 0:
                raise ManifestError(f"{ctx}channels.{k}: scale must be a finite non-zero number, got {v.get('scale')!r}")
        elif not isinstance(v, str) or not v:
            raise ManifestError(f"{ctx}channels.{k} must be a channel name (text) or a table "
                                f"{{ channel = \"...\", unit = \"g\", scale = 1.0 }}, got {v!r}")
    seen = {}
    for k, v in value.items():
        name = v["channel"] if isinstance(v, dict) else v
        if name in seen:
            raise ManifestError(f"{ctx}channels.{seen[name]} and channels.{k} both name channel {name!r}; "
                                "each column of the record comes from its own channel")
        seen[name] = k
    return dict(value)


def _split_map(channels: dict):
    """``(column -> source channel, column -> factor to SI)`` of a column map."""
    names, factors = {}, {}
    for k, v in channels.items():
        if isinstance(v, dict):
            names[k] = v["channel"]
            factors[k] = float(v.get("scale", 1.0)) * UNIT_FACTORS[v.get("unit", "").strip()]
        else:
            names[k] = v
    return names, factors


def _window(value, ctx):
    """``[t0, t1]`` with ``t0 < t1``, or None."""
    if value is None:
        return None
    if (not isinstance(value, list) or len(value) != 2
            or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in value)
            or not value[0] < value[1]):
        raise ManifestError(f"{ctx}window_s must be [t0, t1] in seconds with t0 < t1, got {value!r}")
    return float(value[0]), float(value[1])


def _sources(entry, i, defaults, ctx):
    rctx = f"{ctx}[record {i}]: "
    if "source" in entry and ("file" in entry or "channels" in entry):
        raise ManifestError(f"{rctx}give 'file' (with 'channels') or [[record.source]] tables, not both "
                            f"(found {', '.join(k for k in ('file', 'channels') if k in entry)} beside 'source')")
    if "source" in entry:
        srcs = entry["source"]
        if not isinstance(srcs, list) or not srcs or not all(isinstance(s, dict) for s in srcs):
            raise ManifestError(f"{rctx}'source' must be a list of [[record.source]] tables")
    elif "file" in entry:
        srcs = [{"file": entry["file"], "channels": entry.get("channels", defaults)}]
    else:
        raise ManifestError(f"{rctx}needs 'file' or [[record.source]] tables")
    out = []
    for s in srcs:
        check_keys(s, SOURCE_KEYS, f"{rctx}source: ")
        if "file" not in s:
            raise ManifestError(f"{rctx}every source needs a 'file'")
        if not isinstance(s["file"], str) or not s["file"]:
            raise ManifestError(f"{rctx}'file' must be a non-empty file name, got {s['file']!r}")
        ch = _channel_map(s.get("channels", defaults), rctx)
        if not ch:
            raise ManifestError(f"{rctx}no channels for {s['file']!r} (give channels or [import].channels)")
        if "time" in s and (not isinstance(s["time"], str) or not s["time"]):
            raise ManifestError(f"{rctx}'time' must be the name of a time column or dataset, got {s['time']!r}")
        out.append((s["file"], ch, s.get("time"), s.get("fs")))
    return out


def _validate(d: dict, desc: Path):
    """Check a whole description before any file is read; returns (head, imp, defaults, records, data folder)."""
    ctx = f"{desc} "
    check_keys(d, DESCRIPTION_KEYS, f"{desc}: ", "table")
    head, imp = d.get("campaign", {}), d.get("import", {})
    for name, table in (("campaign", head), ("import", imp)):
        if not isinstance(table, dict):
            raise ManifestError(f"{desc}: [{name}] must be a table, got {table!r}")
    check_keys(imp, IMPORT_KEYS, f"{desc}: [import] ")
    if head.get("coordinates", "modal") not in COORDINATES:
        raise ManifestError(f"{desc}: [campaign] coordinates must be one of {COORDINATES}, "
                            f"got {head.get('coordinates')!r}")
    if head.get("coordinates", "modal") == "physical" and not isinstance(d.get("structure"), dict):
        raise ManifestError(f"{desc}: [campaign] coordinates = \"physical\" needs a [structure] table (the "
                            "beam model and the sensor positions, copied into the campaign); got "
                            f"{'none' if 'structure' not in d else repr(d['structure'])}")
    structures = _check_structure(d.get("structure"), desc)
    if not isinstance(head.get("name", ""), str):
        raise ManifestError(f"{desc}: [campaign] name must be a text, got {head.get('name')!r}")
    defaults = _channel_map(imp.get("channels", {}), f"{desc}: [import] ")
    fs = _number(imp.get("fs"), "fs", f"{desc}: [import] ")
    if fs is not None and fs <= 0:
        raise ManifestError(f"{desc}: [import] fs must be a positive sampling rate in Hz, got {fs!r}")
    folder = imp.get("data_folder", ".")
    if not isinstance(folder, str) or not folder:
        raise ManifestError(f"{desc}: [import] data_folder must be a folder name, got {folder!r}")
    if folder.startswith(SHARED_PREFIX):  # below the shared public data (jointid.io.datasets)
        from .datasets import shared_data_dir

        try:
            data_folder = (shared_data_dir() / folder[len(SHARED_PREFIX):]).resolve()
        except RecordFileNotFoundError as exc:
            raise ManifestError(f"{desc}: [import] data_folder {folder!r}: {exc}") from None
    else:
        data_folder = (desc.parent / folder).resolve()
    if not data_folder.is_dir():
        raise ManifestError(f"{desc}: [import] data_folder {str(data_folder)!r} is not a folder")
    records = d.get("record", [])
    if not isinstance(records, list) or not records or not all(isinstance(e, dict) for e in records):
        raise ManifestError(f"{desc}: expected at least one [[record]] table")
    if len(records) > MAX_RECORDS:
        raise ManifestError(f"{desc}: {len(records)} records exceed the limit of {MAX_RECORDS}")
    for i, entry in enumerate(records):
        rctx = f"{desc} [record {i}]: "
        check_keys(entry, RECORD_KEYS, rctx)
        if structures is not None and "" not in structures and \
                not any(_same_label(label, entry.get("preload")) for label in structures):
            raise ManifestError(f"{rctx}no [structure.{entry.get('preload')}] table for preload "
                                f"{entry.get('preload')!r}; structures are given for {list(structures)}")
        _sources(entry, i, defaults, ctx)
        f = _number(entry.get("frequency_hz"), "frequency_hz", rctx)
        if f is not None and f <= 0:
            raise ManifestError(f"{rctx}frequency_hz must be positive, got {f!r}")
        r = _number(entry.get("fs"), "fs", rctx)
        if r is not None and r <= 0:
            raise ManifestError(f"{rctx}fs must be a positive sampling rate in Hz, got {r!r}")
        _label(entry.get("force_level"), "force_level", rctx)
        _label(entry.get("preload"), "preload", rctx)
        _excitation(entry, rctx)
        _window(entry.get("window_s", imp.get("window_s")), rctx)
        if entry.get("excitation") == "first-harmonic":
            timed = [k for k in FH_TIME_KEYS if k in entry]
            if timed:
                raise ManifestError(f"{rctx}{', '.join(timed)}: no meaning on a first-harmonic record (one line "
                                    "per frequency, no time history); remove "
                                    f"{'it' if len(timed) == 1 else 'them'}")
        if "time" in entry and (not isinstance(entry["time"], str) or not entry["time"]):
            raise ManifestError(f"{rctx}'time' must be the name of a time column or dataset, got {entry['time']!r}")
    if "time" in imp and (not isinstance(imp["time"], str) or not imp["time"]):
        raise ManifestError(f"{desc}: [import] time must be the name of a time column or dataset, got {imp['time']!r}")
    return head, imp, defaults, records, data_folder, structures


def _check_structure(structure, desc: Path):
    """The ``[structure]`` tables of a description (``{"": table}`` or ``{preload: table}``), or None.

    Checked like the campaign loader reads them (:func:`jointid.io.campaign.load_campaign`): one
    table of known keys for every preload, or tables keyed by preload; a table given by file name
    is refused, since the import copies the tables into the campaign and not the files.  The
    values are checked by the ``check_structure`` of :func:`import_campaign`.
    """
    if structure is None:
        return None
    if not isinstance(structure, dict):
        raise ManifestError(f"{desc}: [structure] must be a table, got {structure!r}"[:300])
    if not structure:
        raise ManifestError(f"{desc}: [structure] is empty; give the structure's keys "
                            f"({', '.join(sorted(STRUCTURE_KEYS))}) or remove the table")
    if set(structure) & STRUCTURE_KEYS:
        for k in structure:
            if k not in STRUCTURE_KEYS:
                raise ManifestError(f"{desc}: [structure] {unknown_key_message(k, STRUCTURE_KEYS)}")
        return {"": structure}
    for label, table in structure.items():
        ctx = f"{desc}: [structure.{label}] "
        if not isinstance(table, dict):
            raise ManifestError(f"{desc}: [structure] {unknown_key_message(label, STRUCTURE_KEYS)}; or a "
                                f"per-preload table [structure.<preload>], got {label} = {table!r}"[:400])
        if "file" in table:
            raise ManifestError(f"{ctx}file: an import copies the [structure] tables into the campaign, not the "
                                f"files they name; give the structure's keys in the table itself")
        if not table:
            raise ManifestError(f"{ctx}is empty; give the structure's keys ({', '.join(sorted(STRUCTURE_KEYS))})")
        for k in table:
            if k not in STRUCTURE_KEYS:
                raise ManifestError(f"{ctx}{unknown_key_message(k, STRUCTURE_KEYS)}")
    return {str(label): table for label, table in structure.items()}


def _force_column(structures, entry) -> str:
    """The force column of a record: the structure's ``force_column`` (physical campaigns), else ``force``."""
    if not structures:
        return "force"
    table = structures.get("")
    if table is None:
        table = next((t for label, t in structures.items() if _same_label(label, entry.get("preload"))), {})
    col = table.get("force_column", "force")
    return col if isinstance(col, str) and col else "force"


def _check_columns(entry, i, sources, coordinates, structures) -> None:
    """A record's column map holds what its excitation is identified from: the force (all but a
    ring-down) and, in modal coordinates, the response; else the record fails, named."""
    kind = entry.get("excitation", "stepped-sine")
    mapped = [k for _, ch, _, _ in sources for k in ch]
    first = sources[0][0]
    force = _force_column(structures, entry) if coordinates == "physical" else "force"
    if kind != "ringdown" and force not in mapped:
        raise RecordError(f"{where(first, i, force)}a {kind} record needs its force column {force!r} (the "
                          f"excitation); the column map gives {mapped}; map it, e.g. channels = {{ {force} = "
                          f"\"<channel>\", ... }}, or mark a free decay with excitation = \"ringdown\"")
    responses = MODAL_RESPONSES.get(kind, ()) if coordinates == "modal" else ()
    if responses and not any(r in mapped for r in responses):
        raise RecordError(f"{where(first, i, responses[0])}a {kind} record needs a response column "
                          f"({' or '.join(repr(r) for r in responses)}); the column map gives {mapped}")


def _check_live(rec: Channels, files: dict, i: int, skip=()) -> None:
    """Every channel varies: a constant or all-zero channel is a dead or unconnected sensor (the record fails).

    ``skip``: columns not used (the force of a free decay, which may well be zero throughout).

    The rule of the identification's check (:func:`jointid.signal.checks.check_live`, a floor
    above this module), here before the record is written, naming the source file and channel.
    """
    for k in rec.names:
        if k in skip:
            continue
        x = rec.data[k]
        lo, hi = float(np.min(x)), float(np.max(x))
        if hi - lo <= 1e-12 * max(abs(lo), abs(hi)):
            value = float(np.median(x))
            what = "zero at every sample" if value == 0 else f"constant ({value:.6g} at every sample)"
            raise RecordError(f"{where(files.get(k, str(rec.source)), i, k)}{what}; a dead, stuck or unconnected "
                              f"channel carries no signal, so the record is not imported")


def _source_path(data_folder: Path, rel: str, i: int) -> Path:
    """A source file inside the data folder; a path leaving it fails the record."""
    p = (data_folder / rel).resolve()
    if Path(rel).is_absolute() or not p.is_relative_to(data_folder):
        raise RecordError(f"{where(rel, i)}source path leaves the data folder {data_folder}; it is refused "
                          f"(set [import] data_folder to the folder that holds the files)")
    return p


def _import_first_harmonic(entry, i, defaults, ctx, data_folder: Path, target: Path) -> None:
    """Read the columns of a first-harmonic record from its sources, check them, write the campaign CSV."""
    from .firsth import first_harmonic_from_columns, read_first_harmonic_source, write_first_harmonic_csv

    cols, files = {}, []
    for f, ch, _t, _fs in _sources(entry, i, defaults, ctx):
        names, factors = _split_map(ch)
        got = read_first_harmonic_source(_source_path(data_folder, f, i), names)
        for k, v in got.items():
            v = np.asarray(v) * factors.get(k, 1.0)
            if k == "frequency_hz" and k in cols:
                same = np.shape(v) == np.shape(cols[k]) and np.allclose(v, cols[k], rtol=1e-9, atol=0)
                if not same:
                    raise RecordError(f"{where(f, i, k)}the sources of a record are on different frequency lines")
                continue
            if k in cols:
                raise RecordError(f"{where(f, i, k)}column given by two sources of the record")
            cols[k] = v
        files.append(f)
    rec = first_harmonic_from_columns(cols, " + ".join(files), i, entry.get("control", "force"))
    write_first_harmonic_csv(target, rec)


#: Relative disagreement between a given ``fs`` and the sampling rate of a file's own time base
#: that is refused (time stamps rounded as text stay far within it over a record).
FS_RTOL = 1e-3


def _check_fs_agrees(part: Channels, fs, fs_key, i: int) -> None:
    """A sampling rate ``fs`` given for a source whose file has its own time base (a time column or
    dataset, a jointid HDF5 record, UFF abscissas) must agree with it; a conflict fails the record,
    naming the key to drop, instead of one of the two being ignored."""
    if fs is None or isinstance(fs, bool) or not isinstance(fs, (int, float)) or part.time.size < 2:
        return
    span = float(part.time[-1] - part.time[0])
    if not span > 0:
        return  # said by the checks of the time base
    fs_file = (part.time.size - 1) / span
    if abs(fs_file - float(fs)) > FS_RTOL * float(fs):
        raise RecordError(f"{where(part.source, i, 'time')}{fs_key} = {float(fs):g} Hz disagrees with the time "
                          f"base of the file ({fs_file:.6g} Hz from its time stamps); drop {fs_key} (the file's "
                          f"time base is used; fs is for sources without one) or correct it")


def _check_time_span(rec: Channels, entry: dict, i: int) -> None:
    """The record resolves its stated frequency and holds one period of it (or of its multisine)."""
    n = rec.time.size
    dt = (rec.time[-1] - rec.time[0]) / (n - 1)
    span = n * dt
    loc = where(str(rec.source), i)
    f = entry.get("frequency_hz")
    if f is not None:
        if f >= 0.5 / dt:
            raise RecordError(f"{loc}frequency_hz {f:g} is at or above the Nyquist frequency {0.5 / dt:.6g} Hz "
                              f"of the record (sampling rate {1 / dt:.6g} Hz)")
        if span * f < 1.0:
            raise RecordError(f"{loc}the record holds {span:.6g} s, less than one period of frequency_hz "
                              f"{f:g} ({1 / f:.6g} s)")
    period = entry.get("period_s")
    if entry.get("excitation") == "multisine" and period is not None and period > span * (1 + 1e-9):
        raise RecordError(f"{loc}period_s {period:g} is longer than the record ({span:.6g} s); a multisine "
                          "record holds at least one whole period")


def import_campaign(description, out_dir, *, check_structure=None) -> ImportResult:
    """Write the campaign described by ``description`` (a TOML file) into ``out_dir``.

    The campaign is written as one output set of kind ``import``
    (:func:`jointid.io.outputset.output_set`): it replaces an earlier import into ``out_dir``
    as a whole (no stale records), and a folder holding anything else (a campaign written by
    hand, the data folder, the description) is refused before any file is read.

    ``check_structure(table, source)``, when given, checks each ``[structure]`` table before
    any file is read (the command passes :meth:`jointid.modal.structure.Structure.from_mapping`,
    a floor above this module); it raises a :class:`~jointid.errors.JointidError` naming the key.
    """
    desc = Path(description)
    d = read_toml(desc, "import description")
    head, imp, defaults, records, data_folder, structures = _validate(d, desc)
    if check_structure is not None and structures:
        for label, table in structures.items():
            check_structure(table, f"{desc} [structure{'.' + label if label else ''}]")
    final = Path(out_dir)
    with output_set(final, kind="import", inputs=(desc, data_folder)) as out:
        written, failed = _import_records(d, desc, head, imp, defaults, records, data_folder, out, structures)
    return ImportResult(final, tuple(written), tuple(failed))


def _import_records(d, desc, head, imp, defaults, records, data_folder, out, structures=None):
    """Read the sources and write the records and ``campaign.toml`` into ``out``."""
    ctx = f"{desc} "
    entries, written, failed = [], [], []
    for i, entry in enumerate(records):
        if entry.get("excitation") == "first-harmonic":
            try:
                rel = f"records/{len(written):04d}.csv"
                _import_first_harmonic(entry, i, defaults, ctx, data_folder, out / rel)
            except ManifestError:
                raise
            except JointidError as exc:
                failed.append((i, str(exc)))
                continue
            keys = {k: v for k, v in entry.items() if k in ("force_level", "preload", "excitation", "control")}
            entries.append({"file": rel, **keys})
            written.append((i, rel))
            continue
        try:
            parts, files = [], {}
            sources = _sources(entry, i, defaults, ctx)
            _check_columns(entry, i, sources, head.get("coordinates", "modal"), structures)
            for f, ch, t_name, s_fs in sources:
                names, factors = _split_map(ch)
                files.update((k, f) for k in names)
                fs_key = ("source fs" if s_fs is not None else "record fs" if "fs" in entry else
                          "[import] fs" if "fs" in imp else None)
                fs = s_fs if s_fs is not None else entry.get("fs", imp.get("fs"))
                part = read_source(_source_path(data_folder, f, i), names, fs=fs,
                                   time=t_name if t_name is not None else entry.get("time", imp.get("time")))
                _check_fs_agrees(part, fs, fs_key, i)
                if factors:
                    part = Channels(part.time, {k: part.data[k] * factors.get(k, 1.0) for k in part.names},
                                    {k: ("SI" if k in factors else part.units.get(k, "")) for k in part.names},
                                    source=part.source)
                parts.append(part)
            rec = parts[0] if len(parts) == 1 else merge_channels(parts, source=f"record {i}")
            win = _window(entry.get("window_s", imp.get("window_s")), f"{desc} [record {i}]: ")
            if win is not None:
                keep = (rec.time >= win[0]) & (rec.time < win[1])
                if np.count_nonzero(keep) < 2:
                    raise RecordError(f"{where(str(rec.source), i)}window_s {list(win)} holds "
                                      f"{np.count_nonzero(keep)} samples of the record "
                                      f"({rec.time[0]:.6g} .. {rec.time[-1]:.6g} s)")
                rec = Channels(rec.time[keep], {k: rec.data[k][keep] for k in rec.names},
                               dict(rec.units), source=rec.source)
            _check_time_span(rec, entry, i)
            physical = head.get("coordinates", "modal") == "physical"
            force = _force_column(structures, entry) if physical else "force"
            _check_live(rec, files, i, skip=(force,) if entry.get("excitation") == "ringdown" else ())
            rel = f"records/{len(written):04d}.csv"
            write_csv_record(out / rel, rec.time, {k: rec.data[k] for k in rec.names})
        except ManifestError:
            raise
        except JointidError as exc:
            failed.append((i, str(exc)))
            continue
        keys = {k: v for k, v in entry.items() if k in ("frequency_hz", "force_level", "preload", "excitation",
                                                        "period_s")}
        entries.append({"file": rel, **keys})
        written.append((i, rel))
    if not entries:
        if len(failed) == 1:  # one line, as every refusal of the command
            raise RecordError(f"{desc}: no record could be imported: {failed[0][1]}")
        raise RecordError(f"{desc}: no record could be imported:\n  " + "\n  ".join(m for _, m in failed))
    write_campaign(out, str(head.get("name", desc.stem)), entries, coordinates=head.get("coordinates", "modal"),
                   structure=d.get("structure"))
    return written, failed
