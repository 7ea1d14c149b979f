"""Turn lab exports (UFF 58, MAT incl. LMS Test.Lab, HDF5, CSV) into a campaign folder.

An import description (TOML) names the source files of every record and which of their
channels become which campaign columns::

    [campaign]
    name = "UNESP sine dwells"
    coordinates = "modal"           # or "physical", with a [structure] table copied as is

    [import]                        # defaults for every source
    fs = 1024.0                     # for plain MAT arrays without a time vector
    channels = { force = "Time_Shaker__X", accel = "Time_Laser__X" }

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
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import JointidError, ManifestError, RecordError, RecordFileNotFoundError
from .campaign import read_toml, write_campaign, write_csv_record
from .channels import Channels, merge_channels

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
        with open(path, encoding="utf-8-sig") as fh:
            header = [h.strip() for h in fh.readline().split(",")]
        try:
            rows = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
        except ValueError as exc:
            raise RecordError(f"{path}: not a numeric CSV with header {header} ({exc})") from exc
        if "time" not in header:
            raise RecordError(f"{path} [channel 'time']: missing column; found {header}")
        missing = [src for src in channels.values() if src not in header]
        if missing:
            raise RecordError(f"{path} [channel {missing[0]!r}]: missing column; found {header}")
        return Channels(rows[:, header.index("time")],
                        {out: rows[:, header.index(src)] for out, src in channels.items()}, source=str(path))
    raise RecordError(f"{path}: unknown format {suffix!r}; expected .mat, .uff, .unv, .h5 or .csv")


def _sources(entry, i, defaults, ctx):
    if "source" in entry:
        srcs = entry["source"]
        if not isinstance(srcs, list) or not srcs:
            raise ManifestError(f"{ctx}[record {i}]: 'source' must be a list of tables")
    elif "file" in entry:
        srcs = [{"file": entry["file"], "channels": entry.get("channels", defaults)}]
    else:
        raise ManifestError(f"{ctx}[record {i}]: needs 'file' or [[record.source]] tables")
    out = []
    for s in srcs:
        if "file" not in s:
            raise ManifestError(f"{ctx}[record {i}]: every source needs a 'file'")
        ch = dict(s.get("channels", defaults))
        if not ch:
            raise ManifestError(f"{ctx}[record {i}]: no channels for {s['file']!r} (give channels or [import].channels)")
        out.append((s["file"], ch))
    return out


def import_campaign(description, out_dir) -> ImportResult:
    """Write the campaign described by ``description`` (a TOML file) into ``out_dir``."""
    desc = Path(description)
    d = read_toml(desc, "import description")
    ctx = f"{desc} "
    head = d.get("campaign", {})
    imp = d.get("import", {})
    defaults = dict(imp.get("channels", {}))
    records = d.get("record", [])
    if not records:
        raise ManifestError(f"{desc}: expected at least one [[record]]")
    out = Path(out_dir)
    entries, written, failed = [], [], []
    for i, entry in enumerate(records):
        try:
            parts = [read_source(desc.parent / f, ch, fs=entry.get("fs", imp.get("fs")))
                     for f, ch in _sources(entry, i, defaults, ctx)]
            rec = parts[0] if len(parts) == 1 else merge_channels(parts, source=f"record {i}")
            rel = f"records/{len(written):04d}.csv"
            write_csv_record(out / rel, rec.time, {k: rec.data[k] for k in rec.names})
        except ManifestError:
            raise
        except JointidError as exc:
            failed.append((i, str(exc)))
            continue
        keys = {k: v for k, v in entry.items() if k in ("frequency_hz", "force_level", "preload")}
        entries.append({"file": rel, **keys})
        written.append((i, rel))
    if not entries:
        raise RecordError(f"{desc}: no record could be imported:\n  " + "\n  ".join(m for _, m in failed))
    write_campaign(out, str(head.get("name", desc.stem)), entries, coordinates=head.get("coordinates", "modal"),
                   structure=d.get("structure"))
    return ImportResult(out, tuple(written), tuple(failed))
