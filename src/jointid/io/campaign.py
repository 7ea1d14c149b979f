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
    excitation = "stepped-sine"  # optional: "stepped-sine" (default), "multisine" (with period_s),
                                 # "random", "ringdown" or "first-harmonic" (jointid.io.firsth:
                                 # one line per frequency, with control = "force", "response"
                                 # or "phase-resonance")

A physical campaign has a ``[structure]`` table (see :mod:`jointid.modal.structure`), or one per
preload: ``[structure.120]`` tables keyed by the preload label, each a structure table or
``{ file = "structure_120.toml" }`` (a TOML file in the campaign folder with a ``[structure]``
table); :meth:`Campaign.structure_for` returns the table of a preload.

A CSV record has one header row: ``time`` [s], ``force``, then the acceleration
column(s) (``accel`` in a modal campaign).  Other record formats (UFF 58, HDF5, MAT) are
read by extension (UFF 58, HDF5); other exports are converted with ``jointid import``.

Nothing is guessed silently: a path leaving the folder (that record is refused), a missing file, a missing
column, values that are not finite, columns of different lengths and a time base that is
not uniform are refused with an error naming the file, the record and the channel.  The
manifest itself is checked before any work: UTF-8 text, known keys (an unknown key names the
nearest valid one), types, finite values, bounded sizes; a problem of one entry (a bad value,
a duplicated file) fails that record only.  A record whose file is another record's file (a hard link) or
holds the same bytes, at the same preload, fails as a repeated measurement; a preload or force level
written as a number in one record and as the same value in text in another refuses the manifest; a label
with control characters fails its record.  Unit labels inside HDF5 / UFF record files are converted to SI
(jointid.io.units); an unknown label or one of another kind is refused.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
import tomllib
import unicodedata
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..conventions import STRUCTURE_KEYS
from ..errors import ManifestError, RecordError, RecordFileNotFoundError, unknown_key_message, where
from .channels import MAX_SAMPLES, validate_channels

__all__ = ["RecordSpec", "Campaign", "read_toml", "read_text", "load_campaign", "read_record", "RecordData",
           "write_campaign", "write_csv_record", "EXCITATIONS", "RECORD_KEYS"]

COORDINATES = ("modal", "physical")
#: Allowed deviation of a time step from the mean step, as a fraction of it (time stamps written
#: as text with few digits); the same tolerance for ``jointid import`` and ``jointid identify``.
CSV_TIME_RTOL = 1e-2
#: Kinds of excitation a record may declare (``excitation`` key); the first is the default.
EXCITATIONS = ("stepped-sine", "multisine", "random", "ringdown", "first-harmonic")
#: Keys of a ``[[record]]`` entry; anything else is an error naming the nearest of these.
RECORD_KEYS = ("file", "frequency_hz", "force_level", "preload", "excitation", "period_s", "settled", "control")
#: How a first-harmonic record's test was controlled (``control`` key; jointid.io.firsth).
CONTROLS = ("force", "response", "phase-resonance")
#: Top-level tables of a manifest.
MANIFEST_KEYS = ("campaign", "record", "structure")
#: Size bounds: records per campaign, samples per record (MAX_SAMPLES, from io.channels), bytes of a manifest
#: or record file.
MAX_RECORDS = 100_000
MAX_MANIFEST_BYTES = 64 * 2**20
MAX_RECORD_BYTES = 4 * 2**30


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
    excitation: str = "stepped-sine"
    period_s: float | None = None

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
    structures: dict | None = None  # per-preload [structure.<preload>] tables (label -> table), else None

    def structure_for(self, preload) -> dict | None:
        """The ``[structure]`` table of a preload: the per-preload one when given, else the common one.

        Raises
        ------
        ManifestError
            When per-preload structures are given but none for this preload.
        """
        if self.structures is None:
            return self.structure
        for label, table in self.structures.items():
            if _same_label(label, preload):
                return table
        raise ManifestError(
            f"{self.root / 'campaign.toml'}: no [structure.{preload}] table for preload {preload!r}; "
            f"structures are given for {list(self.structures)}"
        )


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


def _same_label(label, value) -> bool:
    """Whether a TOML table key (always text) names a grouping value (``"120"`` ~ ``120`` ~ ``120.0``)."""
    if str(label) == str(value):
        return True
    try:
        return float(label) == float(value)
    except (TypeError, ValueError):
        return False


def check_regular_file(path, what="file", error=RecordFileNotFoundError, max_bytes=None) -> Path:
    """``path`` as a :class:`~pathlib.Path` when it is an existing regular file (not a folder or device).

    Raises
    ------
    RecordFileNotFoundError
        (or ``error``) when it does not exist, is a folder or is not a regular file.
    ManifestError
        When it is larger than ``max_bytes``.
    """
    path = Path(path)
    if not path.exists():
        raise error(f"{path}: {what} not found")
    if path.is_dir():
        raise error(f"{path}: {what} expected, got a folder")
    if not path.is_file():
        raise error(f"{path}: {what} expected, got a device or special file")
    if max_bytes is not None and path.stat().st_size > max_bytes:
        raise ManifestError(f"{path}: {what} of {path.stat().st_size} bytes exceeds the limit of {max_bytes} bytes")
    return path


def _decode(raw: bytes, path, what) -> str:
    if raw[:2] in (b"\xff\xfe", b"\xfe\xff") or (raw and raw.count(0) > len(raw) // 8):
        kind = "UTF-16 text" if raw[:2] in (b"\xff\xfe", b"\xfe\xff") or raw[1::2].count(0) > len(raw) // 4 else "binary data"
        raise ManifestError(f"{path}: {what} must be UTF-8 text, got {kind}; save it as UTF-8")
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        raise ManifestError(
            f"{path}: {what} must be UTF-8 text, got byte 0x{raw[exc.start]:02x} on line {line} "
            f"(another encoding or binary data); save it as UTF-8"
        ) from None


def read_text(path, what="file", max_bytes=MAX_MANIFEST_BYTES) -> str:
    """The text of a UTF-8 file; a folder, device, oversize, UTF-16 or binary file is a clear error.

    Raises
    ------
    RecordFileNotFoundError
        When ``path`` is not an existing regular file.
    ManifestError
        When the file is too large or not UTF-8 text.
    """
    path = check_regular_file(path, what, max_bytes=max_bytes)
    return _decode(path.read_bytes(), path, what)


def read_toml(path, what="file") -> dict:
    """Parse a TOML file; a missing file, a file that is not UTF-8 text or invalid TOML is an
    error naming the file.

    Raises
    ------
    RecordFileNotFoundError
        When ``path`` is not a file (``what`` says which file was expected).
    ManifestError
        When the file is not UTF-8 text or not valid TOML.
    """
    text = read_text(path, what)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ManifestError(f"{path}: not valid TOML ({exc})") from exc


def check_keys(table: dict, valid, ctx: str, what="key") -> None:
    """A :class:`ManifestError` for the first key of ``table`` not in ``valid``, naming the nearest valid one."""
    for key in table:
        if key not in valid:
            raise ManifestError(f"{ctx}{unknown_key_message(key, valid, what)}")


def _label(value, key, ctx):
    """A grouping value (preload, force level): a finite number or a short text, else a ManifestError."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        raise ManifestError(f"{ctx}{key} must be a number or a text label, got {type(value).__name__} {value!r}")
    if isinstance(value, float) and not math.isfinite(value):
        raise ManifestError(f"{ctx}{key} must be finite, got {value!r}")
    if isinstance(value, str) and not (0 < len(value.strip()) <= 200):
        raise ManifestError(f"{ctx}{key} must be a text of 1 to 200 characters, got {len(value)} characters")
    if isinstance(value, str):
        bad = [c for c in value if unicodedata.category(c) in ("Cc", "Cf", "Cs", "Co", "Cn", "Zl", "Zp")]
        if bad:
            raise ManifestError(f"{ctx}{key} {value!r} holds a control or invisible character "
                                f"(U+{ord(bad[0]):04X}); a label must be printable text")
    return value


def _excitation(entry, ctx):
    kind = entry.get("excitation", EXCITATIONS[0])
    if kind not in EXCITATIONS:
        raise ManifestError(f"{ctx}excitation must be one of {list(EXCITATIONS)}, got {kind!r}")
    period = _number(entry.get("period_s"), "period_s", ctx)
    if kind == "multisine" and period is None:
        raise ManifestError(f"{ctx}a multisine record needs period_s (the period of the multisine in s)")
    if period is not None and (kind != "multisine" or period <= 0):
        raise ManifestError(f"{ctx}period_s must be a positive period of a multisine record, got {period!r} "
                            f"with excitation {kind!r}")
    control = entry.get("control")
    if control is not None and (kind != "first-harmonic" or control not in CONTROLS):
        raise ManifestError(f"{ctx}control must be one of {list(CONTROLS)} on a first-harmonic record, got "
                            f"{control!r} with excitation {kind!r}")
    return kind, period


def _structures(structure, root: Path, manifest_path: Path):
    """Per-preload structure tables when ``[structure]`` holds tables keyed by preload, else ``None``."""
    if structure is None:
        return None
    if not isinstance(structure, dict):
        raise ManifestError(f"{manifest_path}: [structure] must be a table, got {structure!r}")
    if not structure or set(structure) & STRUCTURE_KEYS:
        return None  # one structure for every preload (validated by jointid.modal.structure)
    out = {}
    for label, table in structure.items():
        ctx = f"{manifest_path} [structure.{label}]: "
        if not isinstance(table, dict):
            raise ManifestError(f"{ctx}{unknown_key_message(label, STRUCTURE_KEYS)}; or a per-preload table")
        if "file" in table:
            if set(table) != {"file"} or not isinstance(table["file"], str) or not table["file"]:
                raise ManifestError(f"{ctx}expected only file = \"structure.toml\" (a file name), got {table!r}")
            p = (root / table["file"]).resolve()
            if Path(table["file"]).is_absolute() or not p.is_relative_to(root.resolve()):
                raise ManifestError(f"{ctx}structure file {table['file']!r} leaves the campaign folder {root}")
            data = read_toml(p, "structure file")
            table = data.get("structure", data)
            if not isinstance(table, dict):
                raise ManifestError(f"{p}: [structure] must be a table")
        out[str(label)] = table
    return out


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
    if root.exists() and not root.is_dir():
        raise ManifestError(f"{root}: expected a campaign folder (with campaign.toml), got a file")
    manifest_path = root / "campaign.toml"
    data = read_toml(manifest_path, "campaign manifest")
    check_keys(data, MANIFEST_KEYS, f"{manifest_path}: ", "table")
    head = data.get("campaign", {})
    if not isinstance(head, dict):
        raise ManifestError(f"{manifest_path}: [campaign] must be a table")
    coordinates = head.get("coordinates", "modal")
    if coordinates not in COORDINATES:
        raise ManifestError(f"{manifest_path}: coordinates must be one of {COORDINATES}, got {coordinates!r}")
    import difflib

    for key in head:  # free metadata, but a near miss of a meaningful key is a typo
        close = difflib.get_close_matches(key, ("name", "coordinates"), n=1, cutoff=0.75)
        if close and close[0] != key:
            raise ManifestError(f"{manifest_path}: [campaign] {unknown_key_message(key, ('name', 'coordinates'))}")
    name = head.get("name", root.name)
    if not isinstance(name, str):
        raise ManifestError(f"{manifest_path}: [campaign] name must be a text, got {name!r}")
    entries = data.get("record", [])
    if not isinstance(entries, list) or not entries:
        raise ManifestError(f"{manifest_path}: expected at least one [[record]] entry")
    if len(entries) > MAX_RECORDS:
        raise ManifestError(f"{manifest_path}: {len(entries)} records exceed the limit of {MAX_RECORDS} per campaign; "
                            f"split the campaign")
    root_resolved = root.resolve()
    records, seen = [], {}
    for i, entry in enumerate(entries):
        ctx = f"{manifest_path} [record {i}]: "
        if not isinstance(entry, dict) or "file" not in entry:
            raise ManifestError(f"{ctx}each [[record]] needs a 'file' key")
        check_keys(entry, RECORD_KEYS, ctx)
        rel = entry["file"]
        if not isinstance(rel, str) or not rel:
            raise ManifestError(f"{ctx}'file' must be a non-empty string, got {rel!r}")
        # problems of a single entry fail that record only; the others still run
        error = None
        p = (root / rel).resolve()
        if Path(rel).is_absolute() or not p.is_relative_to(root_resolved):
            error = f"{where(rel, i)}record path leaves the campaign folder {root}; it is refused"
        elif p in seen:
            error = f"{where(rel, i)}the same file as record {seen[p]}; a record is counted once"
        seen.setdefault(p, i)
        values = {}
        for key, check in (("frequency_hz", _number), ("force_level", _label), ("preload", _label)):
            try:
                values[key] = check(entry.get(key), key, "")
                if key == "frequency_hz" and values[key] is not None and values[key] <= 0:
                    raise ManifestError(f"frequency_hz must be positive, got {values[key]!r}")
            except ManifestError as exc:
                values[key] = None
                error = error or f"{where(rel, i)}manifest entry: {exc}"
        try:
            kind, period = _excitation(entry, "")
        except ManifestError as exc:
            kind, period = EXCITATIONS[0], None
            error = error or f"{where(rel, i)}manifest entry: {exc}"
        known = {"file", "frequency_hz", "force_level", "preload", "excitation", "period_s"}
        records.append(
            RecordSpec(
                index=i,
                file=rel,
                path=p,
                frequency_hz=values["frequency_hz"],
                force_level=values["force_level"],
                preload=values["preload"],
                extra={k: v for k, v in entry.items() if k not in known},
                error=error,
                excitation=kind,
                period_s=period,
            )
        )
    _check_label_types(records, manifest_path)
    records = _refuse_repeated_data(records)
    structure = data.get("structure")
    if coordinates == "physical" and structure is None:
        raise ManifestError(f"{manifest_path}: a physical campaign needs a [structure] section")
    structures = _structures(structure, root, manifest_path)
    return Campaign(root, name, coordinates, tuple(records), structure, data, structures)


def _check_label_types(records, manifest_path) -> None:
    """A ManifestError when a preload or force level is a number in one record and the same value as a
    text in another (``120`` and ``"120"``): they would make two groups that print alike."""
    for key in ("preload", "force_level"):
        first = {}  # value as a float -> (record index, value) of its first number / first text
        for spec in records:
            value = getattr(spec, key)
            if value is None:
                continue
            is_text = isinstance(value, str)
            try:
                number = float(value.strip()) if is_text else float(value)
            except ValueError:
                continue
            if not math.isfinite(number):
                continue
            seen = first.setdefault(number, {})
            seen.setdefault(is_text, (spec.index, value))
            if len(seen) == 2:
                (i_num, v_num), (i_txt, v_txt) = seen[False], seen[True]
                raise ManifestError(
                    f"{manifest_path}: {key} {v_num!r} (a number) in record {i_num} and {v_txt!r} (text) in "
                    f"record {i_txt}: write them alike (both numbers or both texts); as written they make "
                    f"two groups that print the same"
                )


def _file_digest(path: Path) -> str:
    h = hashlib.blake2b(digest_size=20)
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _refuse_repeated_data(records: list) -> list:
    """Fail each record whose file is the file (hard link) or holds the bytes of an earlier record's file
    at the same preload (whose records make one regression): a repeated measurement would count twice."""
    candidates = []  # (spec, stat) of the records whose file is a readable regular file
    for spec in records:
        if spec.error:
            continue
        try:
            st = os.stat(spec.path)
        except OSError:
            continue  # reported when the record is read
        if not os.path.isfile(spec.path) or st.st_size > MAX_RECORD_BYTES:
            continue
        candidates.append((spec, st))
    errors, by_inode, by_size = {}, {}, {}
    for spec, st in candidates:
        # st_ino is unique only when non-zero (some network and FUSE file systems give 0): then the hash decides
        first = by_inode.setdefault((spec.preload, st.st_dev, st.st_ino), spec) if st.st_ino else spec
        if first is not spec:
            errors[spec.index] = (f"{where(spec.file, spec.index)}the same file as record {first.index} "
                                  f"({first.file}, a hard link or alias); a repeated measurement would count "
                                  f"twice, so this record is refused")
        else:
            by_size.setdefault((spec.preload, st.st_size), []).append(spec)
    for same_size in by_size.values():  # hash only files whose size another file shares
        if len(same_size) < 2:
            continue
        by_hash = {}
        for spec in same_size:
            try:
                digest = _file_digest(spec.path)
            except OSError:
                continue
            first = by_hash.setdefault(digest, spec)
            if first is not spec:
                errors[spec.index] = (f"{where(spec.file, spec.index)}same data as record {first.index} "
                                      f"({first.file}): the files are byte for byte identical; a repeated "
                                      f"measurement would count twice, so this record is refused")
    if not errors:
        return records
    return [dataclasses.replace(r, error=errors[r.index]) if r.index in errors else r for r in records]


def _read_csv(path: Path, spec: RecordSpec):
    with open(path, "rb") as fh:
        head = fh.read(4096)
    try:
        _decode(head, where(spec.file, spec.index)[:-2], "record file")
    except ManifestError as exc:
        raise RecordError(str(exc)) from None
    header = head.decode("utf-8-sig", errors="replace").splitlines()[0] if head else ""
    names = [h.strip() for h in header.strip().split(",")]
    if not names or names == [""]:
        raise RecordError(f"{where(spec.file, spec.index)}empty file; expected a header row 'time,force,...'")
    if len(set(names)) != len(names):
        raise RecordError(f"{where(spec.file, spec.index)}duplicate column names in header {names}")
    try:
        with warnings.catch_warnings():  # no data rows: reported below as too few samples
            warnings.simplefilter("ignore", UserWarning)
            rows = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2, dtype=float, encoding="utf-8")
    except UnicodeDecodeError:
        raise RecordError(f"{where(spec.file, spec.index)}record file must be UTF-8 text; it holds bytes that are "
                          f"not (another encoding or binary data); save it as UTF-8") from None
    except ValueError as exc:
        msg = str(exc)
        raise RecordError(
            f"{where(spec.file, spec.index)}columns of different lengths or non-numeric values ({msg}); "
            f"expected {len(names)} numeric columns {names} on every row"
        ) from exc
    if rows.shape[0] == 0:
        raise RecordError(f"{where(spec.file, spec.index)}no data rows below the header {names}; expected samples")
    if rows.shape[1] != len(names):
        raise RecordError(f"{where(spec.file, spec.index)}header names {len(names)} columns but rows have {rows.shape[1]}")
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
    loc = where(spec.file, spec.index)
    if not path.exists():
        raise RecordFileNotFoundError(f"{loc}record file not found ({path})")
    if not path.is_file():
        kind = "a folder" if path.is_dir() else "a device or special file"
        raise RecordError(f"{loc}expected a record file, got {kind} ({path})")
    if path.stat().st_size > MAX_RECORD_BYTES:
        raise RecordError(f"{loc}file of {path.stat().st_size} bytes exceeds the limit of {MAX_RECORD_BYTES} bytes")
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
    n = np.size(cols["time"])
    if n > MAX_SAMPLES:
        raise RecordError(f"{where(spec.file, spec.index, 'time')}{n} samples exceed the limit of {MAX_SAMPLES} "
                          f"per record; split or decimate the record")
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
    time_unit = str(ch.meta.get("time_units", "") or "").strip()
    # spellings of the second outside the table of units, then the table (s, ms; another unit is refused)
    time_factor = 1.0 if time_unit.lower() in ("s", "sec", "secs", "second", "seconds") else \
        _si_factor("time", time_unit, spec)
    cols = {"time": np.asarray(ch.time, float) * time_factor}
    for name, values in ch.data.items():
        factor = _si_factor(name, ch.units.get(name, ""), spec)
        values = np.asarray(values, float)
        cols[name] = values * factor if factor != 1.0 else values
    return cols


def _si_factor(name: str, unit, spec: RecordSpec) -> float:
    """Factor from the unit label a record file gives a channel to SI (:func:`jointid.io.units.unit_problem`:
    an unknown label or one of another kind than the channel, ``accel`` in ``N``, is refused); a label
    outside the table on a channel not read by its kind (a temperature, a current) is left as it is."""
    from .units import UNITS, column_kind, unit_problem

    label = str(unit or "").strip()
    if label not in UNITS and column_kind(name) is None:
        return 1.0
    problem = unit_problem(name, label)
    if problem:
        raise RecordError(f"{where(spec.file, spec.index, name)}{problem} (the unit label in the record file; "
                          "convert the record with 'jointid import' and a unit or scale)")
    return float(UNITS[label][0])


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        return repr(float(v))
    if isinstance(v, str):  # a JSON string is a valid TOML basic string (same escapes)
        return json.dumps(v, ensure_ascii=False)
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
