"""Campaign folders: ``campaign.toml`` plus record files (the campaign contract).

A campaign is a folder with a manifest::

    [campaign]
    name = "free text"
    coordinates = "modal"        # force column is Q(t), acceleration column is q''(t)

    [[record]]
    file = "records/0000.csv"    # relative to the campaign folder
    frequency_hz = 26.48         # optional: estimated from the force when absent
    force_level = 1.5            # grouping key
    preload = 120                # grouping key

A CSV record has one header row: ``time`` [s], ``force``, then the acceleration
column(s) (``accel`` in a modal campaign).  Other record formats (UFF 58, HDF5, MAT) are
read by extension (UFF 58, HDF5); other exports are converted with ``jointid import``.

Nothing is guessed silently: a path leaving the folder (that record is refused), a missing file, a missing
column, values that are not finite, columns of different lengths and a time base that is
not uniform are refused with an error naming the file, the record and the channel.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ManifestError, RecordError, RecordFileNotFoundError, where
from .channels import validate_channels

__all__ = ["RecordSpec", "Campaign", "read_toml", "load_campaign", "read_record", "RecordData", "write_campaign", "write_csv_record"]

COORDINATES = ("modal", "physical")
#: Allowed deviation of a time step from the mean step, as a fraction of it.
CSV_TIME_RTOL = 1e-2


@dataclass(frozen=True)
class RecordSpec:
    """One ``[[record]]`` entry of a manifest."""

    index: int
    file: str
    path: Path
    frequency_hz: float | None
    force_level: Any
    preload: Any
    extra: dict = field(default_factory=dict)
    error: str | None = None

    @property
    def group(self) -> tuple:
        return (self.preload, self.force_level)


@dataclass(frozen=True)
class Campaign:
    """A parsed, validated campaign manifest."""

    root: Path
    name: str
    coordinates: str
    records: tuple
    structure: dict | None = None
    manifest: dict = field(default_factory=dict, repr=False)


@dataclass(frozen=True)
class RecordData:
    """The columns of one record file."""

    spec: RecordSpec
    time: np.ndarray
    channels: dict


def _number(value, key, ctx):
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ManifestError(f"{ctx}{key} must be a number, got {value!r}")
    if not math.isfinite(value):
        raise ManifestError(f"{ctx}{key} must be finite, got {value!r}")
    return float(value)


def read_toml(path, what="file") -> dict:
    """Parse a TOML file; a missing file or invalid TOML is an error naming the file.

    Raises
    ------
    RecordFileNotFoundError
        When ``path`` is not a file (``what`` says which file was expected).
    ManifestError
        When the file is not valid TOML.
    """
    path = Path(path)
    if not path.is_file():
        raise RecordFileNotFoundError(f"{path}: {what} not found")
    try:
        with open(path, "rb") as fh:
            return tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise ManifestError(f"{path}: not valid TOML ({exc})") from exc


def load_campaign(folder) -> Campaign:
    """Read and validate ``folder/campaign.toml``.

    Raises
    ------
    ManifestError
        Malformed TOML, missing keys, a record path leaving the folder, bad types.
    RecordFileNotFoundError
        When the campaign folder or its manifest does not exist.
    """
    root = Path(folder)
    manifest_path = root / "campaign.toml"
    data = read_toml(manifest_path, "campaign manifest")
    head = data.get("campaign", {})
    if not isinstance(head, dict):
        raise ManifestError(f"{manifest_path}: [campaign] must be a table")
    coordinates = head.get("coordinates", "modal")
    if coordinates not in COORDINATES:
        raise ManifestError(f"{manifest_path}: coordinates must be one of {COORDINATES}, got {coordinates!r}")
    entries = data.get("record", [])
    if not isinstance(entries, list) or not entries:
        raise ManifestError(f"{manifest_path}: expected at least one [[record]] entry")
    root_resolved = root.resolve()
    records = []
    for i, entry in enumerate(entries):
        ctx = f"{manifest_path} [record {i}]: "
        if not isinstance(entry, dict) or "file" not in entry:
            raise ManifestError(f"{ctx}each [[record]] needs a 'file' key")
        rel = entry["file"]
        if not isinstance(rel, str) or not rel:
            raise ManifestError(f"{ctx}'file' must be a non-empty string, got {rel!r}")
        # problems of a single entry fail that record only; the others still run
        error = None
        p = (root / rel).resolve()
        if Path(rel).is_absolute() or not p.is_relative_to(root_resolved):
            error = f"{where(rel, i)}record path leaves the campaign folder {root}; it is refused"
        try:
            freq = _number(entry.get("frequency_hz"), "frequency_hz", "")
            if freq is not None and freq <= 0:
                raise ManifestError(f"frequency_hz must be positive, got {freq!r}")
        except ManifestError as exc:
            freq, error = None, error or f"{where(rel, i)}manifest entry: {exc}"
        known = {"file", "frequency_hz", "force_level", "preload"}
        records.append(
            RecordSpec(
                index=i,
                file=rel,
                path=p,
                frequency_hz=freq,
                force_level=entry.get("force_level"),
                preload=entry.get("preload"),
                extra={k: v for k, v in entry.items() if k not in known},
                error=error,
            )
        )
    structure = data.get("structure")
    if coordinates == "physical" and structure is None:
        raise ManifestError(f"{manifest_path}: a physical campaign needs a [structure] section")
    return Campaign(root, str(head.get("name", root.name)), coordinates, tuple(records), structure, data)


def _read_csv(path: Path, spec: RecordSpec):
    with open(path, "r", encoding="utf-8-sig") as fh:
        header = fh.readline()
    names = [h.strip() for h in header.strip().split(",")]
    if not names or names == [""]:
        raise RecordError(f"{where(path, spec.index)}empty file; expected a header row 'time,force,...'")
    if len(set(names)) != len(names):
        raise RecordError(f"{where(path, spec.index)}duplicate column names in header {names}")
    try:
        rows = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2, dtype=float)
    except ValueError as exc:
        msg = str(exc)
        raise RecordError(
            f"{where(path, spec.index)}columns of different lengths or non-numeric values ({msg}); "
            f"expected {len(names)} numeric columns {names} on every row"
        ) from exc
    if rows.shape[1] != len(names):
        raise RecordError(f"{where(path, spec.index)}header names {len(names)} columns but rows have {rows.shape[1]}")
    return {n: rows[:, j] for j, n in enumerate(names)}


def read_record(spec: RecordSpec, required=("time", "force", "accel")) -> RecordData:
    """Read one record file and check that the required columns exist and are finite.

    Raises
    ------
    RecordFileNotFoundError, RecordError
        Naming the file, the record index and the channel.
    """
    path = spec.path
    if spec.error:
        raise ManifestError(spec.error)
    if not path.is_file():
        raise RecordFileNotFoundError(f"{where(spec.file, spec.index)}record file not found ({path})")
    suffix = path.suffix.lower()
    if suffix in (".csv", ".txt"):
        cols = _read_csv(path, spec)
    else:
        cols = _read_other(path, spec)
    missing = [c for c in required if c not in cols]
    if missing:
        raise RecordError(
            f"{where(spec.file, spec.index, missing[0])}missing column; expected {list(required)}, found {sorted(cols)}"
        )
    # CSV time stamps are often printed with few digits: allow 1 % jitter of the step
    validate_channels(cols["time"], {k: v for k, v in cols.items() if k != "time"},
                      source=where(spec.file, spec.index)[:-2], time_rtol=CSV_TIME_RTOL)
    time = cols.pop("time")
    return RecordData(spec, time, cols)


def _read_other(path: Path, spec: RecordSpec) -> dict:
    """Records in UFF 58 / HDF5 / MAT files, through the format readers."""
    suffix = path.suffix.lower()
    try:
        if suffix in (".uff", ".unv", ".uff58"):
            from .uff import read_uff as reader
        elif suffix in (".h5", ".hdf5"):
            from .hdf5 import read_hdf5 as reader
        else:
            raise RecordError(
                f"{where(spec.file, spec.index)}unknown record format {suffix!r}; expected .csv, .uff or .h5 "
                f"(MAT files and other exports: convert them with 'jointid import')"
            )
    except ImportError as exc:  # pragma: no cover - format reader not installed
        raise RecordError(f"{where(spec.file, spec.index)}cannot read {suffix} files: {exc}") from exc
    ch = reader(path)
    cols = {"time": np.asarray(ch.time, float)}
    cols.update({k: np.asarray(v, float) for k, v in ch.data.items()})
    return cols


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        return repr(float(v))
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{_toml_key(k)} = {_toml_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def _toml_key(k: str) -> str:
    return k if k.replace("_", "").replace("-", "").isalnum() else _toml_value(k)


def toml_dumps(data: dict, _prefix: str = "") -> str:
    """Minimal TOML writer for manifests (tables, arrays of tables, scalars, lists)."""
    lines = []
    for k, v in data.items():
        if not isinstance(v, dict) and not _is_table_list(v):
            lines.append(f"{_toml_key(k)} = {_toml_value(v)}")
    for k, v in data.items():
        name = f"{_prefix}{_toml_key(k)}"
        if isinstance(v, dict):
            lines += ["", f"[{name}]", toml_dumps(v, name + ".").strip()]
        elif _is_table_list(v):
            for item in v:
                lines += ["", f"[[{name}]]", toml_dumps(item, name + ".").strip()]
    return "\n".join(lines).strip() + "\n"


def _is_table_list(v) -> bool:
    return isinstance(v, list) and bool(v) and all(isinstance(x, dict) for x in v)


def write_csv_record(path, time, columns: dict) -> None:
    """Write a record CSV (``time`` first, full double precision), atomically."""
    from .results import atomic_write

    names = ["time"] + list(columns)
    data = np.column_stack([np.asarray(time, float)] + [np.asarray(columns[n], float) for n in columns])
    import io as _io

    buf = _io.StringIO()
    np.savetxt(buf, data, delimiter=",", fmt="%.17g", header=",".join(names), comments="")
    atomic_write(path, buf.getvalue())


def write_campaign(folder, name, records, coordinates="modal", structure=None, extra=None) -> Path:
    """Write ``campaign.toml`` for record entries (dicts with ``file`` and keys), atomically."""
    from .results import atomic_write

    folder = Path(folder)
    head = {"name": name, "coordinates": coordinates}
    if extra:
        head.update(extra)
    data = {"campaign": head}
    if structure is not None:
        data["structure"] = structure
    data["record"] = [{k: v for k, v in r.items() if v is not None} for r in records]
    atomic_write(folder / "campaign.toml", toml_dumps(data))
    return folder
