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
                                    # description's folder); relative to the description

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
dataset label (id line or LMS node:direction), for HDF5 a dataset name, for CSV a column
name.  The records are written as ``records/NNNN.csv`` with ``time`` first; a record that
cannot be read is reported and left out, the others are written.

The description is validated before any file is read, like a campaign manifest: UTF-8 text,
known keys (the nearest valid name is suggested), types and values; a source path that
leaves the data folder (``..``, an absolute path) fails its record.  CSV time stamps get the
campaign's tolerance (:data:`jointid.io.campaign.CSV_TIME_RTOL`) and are written uniform.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import JointidError, ManifestError, RecordError, RecordFileNotFoundError, where
from .campaign import (
    COORDINATES,
    CSV_TIME_RTOL,
    MAX_RECORDS,
    _decode,
    _excitation,
    _label,
    _number,
    check_keys,
    read_toml,
    write_campaign,
    write_csv_record,
)
from .channels import Channels, merge_channels, validate_channels

#: Keys of an import description, of its ``[import]`` table, of a record and of a source.
DESCRIPTION_KEYS = ("campaign", "import", "record", "structure")
IMPORT_KEYS = ("fs", "channels", "data_folder")
RECORD_KEYS = ("file", "source", "channels", "fs", "frequency_hz", "force_level", "preload", "excitation",
               "period_s")
SOURCE_KEYS = ("file", "channels")

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


def read_source(path: Path, channels: dict, fs=None) -> Channels:
    """Read ``channels`` (column -> source channel) from one file, by its extension."""
    if not path.is_file():
        raise RecordFileNotFoundError(f"{path}: source file not found")
    suffix = path.suffix.lower()
    if suffix == ".mat":
        from .matlab import read_mat

        return read_mat(path, channels, fs=fs)
    if suffix in (".uff", ".unv", ".uff58"):
        from .uff import read_uff

        return read_uff(path, channels)
    if suffix in (".h5", ".hdf5"):
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
            rows = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2, encoding="utf-8")
        except UnicodeDecodeError:
            raise RecordError(f"{path}: CSV file must be UTF-8 text; it holds bytes that are not") from None
        except ValueError as exc:
            raise RecordError(f"{path}: not a numeric CSV with header {header} ({exc})") from exc
        if "time" not in header:
            raise RecordError(f"{path} [channel 'time']: missing column; found {header}")
        missing = [src for src in channels.values() if src not in header]
        if missing:
            raise RecordError(f"{path} [channel {missing[0]!r}]: missing column; found {header}")
        if rows.shape[1] != len(header):
            raise RecordError(f"{path}: header names {len(header)} columns but rows have {rows.shape[1]}")
        t = rows[:, header.index("time")]
        data = {out: rows[:, header.index(src)] for out, src in channels.items()}
        # time stamps written as text: the campaign's tolerance, then the uniform grid they stand for
        validate_channels(t, data, source=str(path), time_rtol=CSV_TIME_RTOL)
        t = t[0] + (t[-1] - t[0]) / (t.size - 1) * np.arange(t.size)
        return Channels(t, data, source=str(path))
    raise RecordError(f"{path}: unknown format {suffix!r}; expected .mat, .uff, .unv, .h5 or .csv")


def _channel_map(value, ctx) -> dict:
    """A ``column -> source channel`` table of non-empty texts, else a ManifestError."""
    if not isinstance(value, dict):
        raise ManifestError(f"{ctx}channels must be a table column -> channel, e.g. "
                            f"{{ force = \"F\", accel = \"A1\" }}, got {value!r}")
    for k, v in value.items():
        if not isinstance(v, str) or not v:
            raise ManifestError(f"{ctx}channels.{k} must be a channel name (text), got {v!r}")
    return dict(value)


def _sources(entry, i, defaults, ctx):
    rctx = f"{ctx}[record {i}]: "
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
        out.append((s["file"], ch))
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
    if not isinstance(head.get("name", ""), str):
        raise ManifestError(f"{desc}: [campaign] name must be a text, got {head.get('name')!r}")
    defaults = _channel_map(imp.get("channels", {}), f"{desc}: [import] ")
    fs = _number(imp.get("fs"), "fs", f"{desc}: [import] ")
    if fs is not None and fs <= 0:
        raise ManifestError(f"{desc}: [import] fs must be a positive sampling rate in Hz, got {fs!r}")
    folder = imp.get("data_folder", ".")
    if not isinstance(folder, str) or not folder:
        raise ManifestError(f"{desc}: [import] data_folder must be a folder name, got {folder!r}")
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
    return head, imp, defaults, records, data_folder


def _source_path(data_folder: Path, rel: str, i: int) -> Path:
    """A source file inside the data folder; a path leaving it fails the record."""
    p = (data_folder / rel).resolve()
    if Path(rel).is_absolute() or not p.is_relative_to(data_folder):
        raise RecordError(f"{where(rel, i)}source path leaves the data folder {data_folder}; it is refused "
                          f"(set [import] data_folder to the folder that holds the files)")
    return p


def import_campaign(description, out_dir) -> ImportResult:
    """Write the campaign described by ``description`` (a TOML file) into ``out_dir``."""
    desc = Path(description)
    d = read_toml(desc, "import description")
    ctx = f"{desc} "
    head, imp, defaults, records, data_folder = _validate(d, desc)
    out = Path(out_dir)
    entries, written, failed = [], [], []
    for i, entry in enumerate(records):
        try:
            parts = [read_source(_source_path(data_folder, f, i), ch, fs=entry.get("fs", imp.get("fs")))
                     for f, ch in _sources(entry, i, defaults, ctx)]
            rec = parts[0] if len(parts) == 1 else merge_channels(parts, source=f"record {i}")
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
        raise RecordError(f"{desc}: no record could be imported:\n  " + "\n  ".join(m for _, m in failed))
    write_campaign(out, str(head.get("name", desc.stem)), entries, coordinates=head.get("coordinates", "modal"),
                   structure=d.get("structure"))
    return ImportResult(out, tuple(written), tuple(failed))
