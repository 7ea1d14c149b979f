"""Read and write time records as Universal File Format dataset 58 (ASCII and binary 58b).

One dataset 58 holds one channel.  :func:`write_uff` writes one dataset per channel of a
:class:`~jointid.io.channels.Channels`; :func:`read_uff` reads the time-response datasets
of a file back into one :class:`~jointid.io.channels.Channels`.  The UFF parsing itself
is done by `pyuff <https://github.com/ladisk/pyuff>`_.

How jointid fills a dataset 58
------------------------------
=====================  ================================================================
field                  value
=====================  ================================================================
ID line 1              channel name (the key :func:`read_uff` matches first)
ID line 2              ``jointid record <source file name>`` (run identification)
ID line 3              creation date ``DD-MMM-YY HH:MM:SS`` (UTC)
ID line 4              ``jointid dt=<repr> t0=<repr>``: the exact time step and start
ID line 5              ``NONE``
function type          1 (time response), load case 0
response node / dir    channel index + 1 / 0 (scalar)
ordinate data type     4 (real, double precision)
abscissa               even spacing, minimum t0, increment dt, specific type 17 (time),
                       units label ``s``
ordinate               units label = channel unit (at most 20 characters), specific
                       data type from the unit (12 acceleration for ``m/s^2``, 11
                       velocity for ``m/s``, 8 displacement for ``m``, 13 excitation
                       force for ``N``, else 0 unknown)
=====================  ================================================================

Precision of a round trip
-------------------------
* **Binary (58b)**: the ordinates are stored as IEEE float64, so values read back are
  bit-for-bit equal to the values written.
* **ASCII (58)**: pyuff writes double-precision ordinates in ``E20.11`` format, that is
  12 significant digits; values read back differ from the written ones by at most
  ``5e-12`` relative to each value (float64 is *not* reproduced exactly).
* **Time base**: the record header stores the abscissa minimum and increment in
  ``E13.5`` format (6 significant digits), which is not enough for a sampling rate such
  as 1024 Hz over 65536 samples.  jointid therefore also writes the exact ``dt`` and
  ``t0`` in ID line 4 and uses them when they agree with the header; for files written
  by other programs the time base is only as exact as their header (6 digits).
* Metadata (``Channels.meta``) is not stored in UFF; use HDF5 for that.

Reading files from other programs
---------------------------------
Time responses are datasets 58 with function type 1 (or type 0 with a time abscissa,
specific data type 17); other datasets are skipped (listed in ``meta["skipped"]``).
A requested channel name is matched, ignoring case and repeated blanks, first against
ID line 1, then against ID lines 2-5, the response entity name, and the response
node/direction written as ``"<entity>:<node>:<dir>"``, ``"<node>:<dir>"`` and
``"<node><dir>"`` (``dir`` as ``+X``, ``-Z``, ``+RX``... or ``S`` for scalar), which
covers LMS Test.Lab exports.  Without a selection every time response is read and named
by ID line 1 when those are unique, else by ``"<entity>:<node>:<dir>"``, else ``ch<i>``.

Damaged files
-------------
A file that does not end with the delimiter ``    -1``, a dataset whose number of
values differs from the count in its record 7, or a dataset pyuff cannot parse raises a
:class:`~jointid.errors.RecordError` naming the file.  A file cut exactly between two
datasets is a valid, shorter UFF file and cannot be told apart from a complete one.

pyuff 2.4-2.5 quirks worked around here: in ``"overwrite"`` mode pyuff truncates the
header of a binary dataset it has just written, so :func:`write_uff` empties the file
and appends; pyuff writes binary ordinates as float64 even when the header says single
precision, so :func:`write_uff` always writes double precision.
"""

from __future__ import annotations

import datetime as _dt
import os
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from jointid.errors import RecordError, RecordFileNotFoundError, where
from jointid.io.channels import TIME_RTOL, Channels

__all__ = ["read_uff", "write_uff"]

_JOINTID_TIME_TAG = "jointid"
_DIR_LABELS = {
    0: "S",
    1: "+X", -1: "-X", 2: "+Y", -2: "-Y", 3: "+Z", -3: "-Z",
    4: "+RX", -4: "-RX", 5: "+RY", -5: "-RY", 6: "+RZ", -6: "-RZ",
}
_SPEC_DATA_TYPE = {"m/s^2": 12, "m/s2": 12, "m/s**2": 12, "m/s": 11, "m": 8, "n": 13}
_TIME_SPEC_DATA_TYPE = 17
_PRINTABLE = re.compile(r"^[\x20-\x7e]*$")


def _pyuff():
    try:
        import pyuff
    except ImportError as exc:  # pragma: no cover - pyuff is a hard dependency
        raise ImportError(
            "reading and writing UFF files needs pyuff: pip install 'pyuff>=2.4'"
        ) from exc
    return pyuff


def _norm(label: str) -> str:
    return " ".join(str(label).split()).casefold()


def _is_none(label: Any) -> bool:
    s = str(label).strip() if label is not None else ""
    return s == "" or s.upper() == "NONE"


# ---------------------------------------------------------------------------- write
def write_uff(path: str | os.PathLike, channels: Channels, binary: bool = False) -> Path:
    """Write every channel of a record as one UFF dataset 58 (time response).

    Parameters
    ----------
    path : str or os.PathLike
        File to write (overwritten if it exists).  The usual extension is ``.uff``.
    channels : Channels
        The record.  Channel names must be printable ASCII, at most 80 characters, without
        leading or trailing blanks and not ``NONE``; units at most 20 characters.
    binary : bool, optional
        Write binary 58b datasets (float64 ordinates, bit-exact round trip) instead of
        ASCII 58 (12 significant digits).  Default False.

    Returns
    -------
    pathlib.Path
        The file written.

    Raises
    ------
    jointid.errors.RecordError
        If a channel name or unit cannot be stored, or pyuff fails to write.

    See Also
    --------
    read_uff

    Notes
    -----
    See the module documentation for the fields used and the precision of a round trip.
    """
    pyuff = _pyuff()
    path = Path(path)
    if not isinstance(channels, Channels):
        raise RecordError(
            f"{where(path)}expected a jointid.io.Channels record, got {type(channels).__name__}"
        )
    if len(channels) == 0:
        raise RecordError(f"{where(path)}expected at least one channel to write, got none")
    dt = channels.dt
    t0 = channels.t0
    created = _dt.datetime.now(_dt.timezone.utc).strftime("%d-%b-%y %H:%M:%S")
    run = f"jointid record {Path(channels.source).name}" if channels.source else "jointid record"
    time_line = f"{_JOINTID_TIME_TAG} dt={dt!r} t0={t0!r}"
    dsets = []
    for i, (name, values) in enumerate(channels.data.items()):
        unit = channels.units.get(name, "")
        if (
            not _PRINTABLE.match(name)
            or len(name) > 80
            or name != name.strip()
            or _is_none(name)
        ):
            raise RecordError(
                f"{where(path, channel=name)}expected a channel name of at most 80 printable "
                f"ASCII characters without leading/trailing blanks and not 'NONE' (UFF ID "
                f"line), got {name!r}"
            )
        if not _PRINTABLE.match(unit) or len(unit) > 20 or unit != unit.strip():
            raise RecordError(
                f"{where(path, channel=name)}expected a unit of at most 20 printable ASCII "
                f"characters (UFF axis units label), got {unit!r}"
            )
        dsets.append(
            {
                "type": 58,
                "binary": 1 if binary else 0,
                "id1": name,
                "id2": run[:80],
                "id3": created,
                "id4": time_line,
                "id5": "NONE",
                "func_type": 1,
                "func_id": i + 1,
                "ver_num": 0,
                "load_case_id": 0,
                "rsp_ent_name": "NONE",
                "rsp_node": i + 1,
                "rsp_dir": 0,
                "ref_ent_name": "NONE",
                "ref_node": 0,
                "ref_dir": 0,
                "abscissa_spacing": 1,
                "abscissa_spec_data_type": _TIME_SPEC_DATA_TYPE,
                "abscissa_axis_lab": "Time",
                "abscissa_axis_units_lab": "s",
                "ordinate_spec_data_type": _SPEC_DATA_TYPE.get(unit.casefold(), 0),
                "ordinate_axis_lab": name[:20],
                "ordinate_axis_units_lab": unit if unit else "NONE",
                "orddenom_spec_data_type": 0,
                "z_axis_spec_data_type": 0,
                "data": np.array(values, dtype=np.float64),
                "x": np.array(channels.time, dtype=np.float64),
            }
        )
    try:
        # pyuff's 'overwrite' mode truncates the header of a binary dataset it has just
        # written (it reopens the file with 'wb' for the data), so clear the file
        # ourselves and append every dataset.
        path.write_bytes(b"")
        pyuff.UFF(str(path)).write_sets(dsets, mode="add", force_double=True)
    except Exception as exc:  # pyuff raises bare Exception
        raise RecordError(f"{where(path)}pyuff could not write the UFF file: {exc}") from exc
    return path


# ---------------------------------------------------------------------------- read
def _candidates(dset: Mapping[str, Any]) -> list[str]:
    """Labels under which a dataset can be selected, most specific first."""
    out = []
    for key in ("id1", "id2", "id3", "id4", "id5"):
        v = dset.get(key, "")
        if not _is_none(v):
            out.append(str(v).strip())
    ent = str(dset.get("rsp_ent_name", "")).strip()
    node = dset.get("rsp_node")
    direction = _DIR_LABELS.get(dset.get("rsp_dir"), str(dset.get("rsp_dir")))
    if not _is_none(ent):
        out.append(ent)
        if node is not None:
            out.append(f"{ent}:{node}:{direction}")
    if node is not None:
        out.append(f"{node}:{direction}")
        out.append(f"{node}{direction}")
    return out


def _auto_names(dsets: Sequence[Mapping[str, Any]]) -> list[str]:
    def unique(names):
        return all(names) and len(set(map(_norm, names))) == len(names)

    by_id1 = ["" if _is_none(d.get("id1")) else str(d["id1"]).strip() for d in dsets]
    if unique(by_id1):
        return by_id1
    by_node = []
    for d in dsets:
        ent = str(d.get("rsp_ent_name", "")).strip()
        direction = _DIR_LABELS.get(d.get("rsp_dir"), str(d.get("rsp_dir")))
        node = d.get("rsp_node")
        by_node.append(
            f"{node}:{direction}" if _is_none(ent) else f"{ent}:{node}:{direction}"
        )
    if unique(by_node):
        return by_node
    return [f"ch{i}" for i in range(len(dsets))]


def _check_file_end(path: Path) -> None:
    size = path.stat().st_size
    if size == 0:
        raise RecordError(f"{where(path)}expected a UFF file with dataset 58, got an empty file")
    with open(path, "rb") as fh:
        fh.seek(max(0, size - 256))
        tail = fh.read()
    # ASCII files end with a line '    -1'; binary 58b puts it right after the data
    if not tail.rstrip(b" \r\n").endswith(b"    -1"):
        raise RecordError(
            f"{where(path)}expected the file to end with the UFF delimiter '    -1', got "
            f"{tail.rstrip()[-40:]!r}; the file is truncated or not a UFF file"
        )


def _read_time_base(path: Path, dset: Mapping[str, Any], label: str) -> tuple[float, float]:
    """Return (t0, dt) for an evenly spaced dataset, preferring jointid's exact ID line 4."""
    t0_h = float(dset.get("abscissa_min", 0.0))
    dt_h = float(dset.get("abscissa_inc", 0.0))
    text = str(dset.get("id4", ""))
    m = re.match(rf"^\s*{_JOINTID_TIME_TAG} dt=(\S+) t0=(\S+)\s*$", text)
    if m:
        try:
            dt_x, t0_x = float(m.group(1)), float(m.group(2))
        except ValueError:
            dt_x = t0_x = float("nan")
        # the header holds 6 significant digits (E13.5)
        if (
            np.isfinite(dt_x)
            and dt_x > 0
            and abs(dt_x - dt_h) <= 1e-5 * dt_x
            and abs(t0_x - t0_h) <= 1e-5 * max(abs(t0_x), dt_x)
        ):
            return t0_x, dt_x
    if not (np.isfinite(dt_h) and dt_h > 0):
        raise RecordError(
            f"{where(path, channel=label)}expected a positive abscissa increment in record 7 "
            f"of dataset 58, got {dt_h!r}"
        )
    return t0_h, dt_h


def _uneven_time(path: Path, x: np.ndarray, label: str) -> tuple[float, float]:
    """Return (t0, dt) for an unevenly stored but uniform abscissa."""
    x = np.asarray(x, dtype=float)
    if x.size < 2:
        raise RecordError(f"{where(path, channel=label)}expected at least 2 samples, got {x.size}")
    dt = (x[-1] - x[0]) / (x.size - 1)
    # uneven abscissae are stored as E13.5 (6 significant digits): allow that rounding
    tol = max(TIME_RTOL * dt, 5e-6 * float(np.max(np.abs(x))))
    dev = np.abs(x - (x[0] + np.arange(x.size) * dt))
    if not dt > 0 or dev.max() > tol:
        k = int(np.argmax(dev))
        raise RecordError(
            f"{where(path, channel=label)}expected a uniform time abscissa, got sample {k} at "
            f"{float(x[k]):.9g} s, {dev[k]:.3g} s away from the uniform grid (dt = {dt:.9g} s)"
        )
    return float(x[0]), float(dt)


def open_uff(path: Path):
    """``(pyuff.UFF, dataset types)`` of a UFF file, checked to exist and to end whole."""
    pyuff = _pyuff()
    if not path.is_file():
        raise RecordFileNotFoundError(f"{where(path)}UFF file not found")
    _check_file_end(path)
    try:
        uff = pyuff.UFF(str(path))
        return uff, [int(t) for t in uff.get_set_types()]
    except Exception as exc:
        raise RecordError(f"{where(path)}cannot parse the UFF file: {exc}") from exc


def read_uff(
    path: str | os.PathLike,
    channels: Sequence[str] | Mapping[str, str] | None = None,
) -> Channels:
    """Read the time-response datasets 58 of a UFF file into one record.

    Parameters
    ----------
    path : str or os.PathLike
        UFF file, ASCII or binary (58b), single or double precision.
    channels : sequence of str or mapping of str to str, optional
        Channels to read.  A sequence of names selects datasets by those names (see the
        module documentation for how a name is matched, including LMS Test.Lab labels);
        a mapping ``{output_name: label_in_file}`` selects and renames.  Default: every
        time-response dataset of the file.

    Returns
    -------
    Channels
        ``source`` is the file path; ``meta`` holds ``format`` (``"uff58"`` or
        ``"uff58b"``), ``labels`` (the ID line 1 of each channel) and ``skipped`` (the
        datasets that are not time responses, as ``"<index>: type <n>"``).

    Raises
    ------
    jointid.errors.RecordFileNotFoundError
        If `path` does not exist.
    jointid.errors.RecordError
        If the file is empty, truncated or corrupt, holds no time-response dataset 58,
        a requested channel is missing or ambiguous, or the channels do not share one time
        base.  The message names the file and what was missing.

    See Also
    --------
    write_uff

    Examples
    --------
    >>> import numpy as np, tempfile, os
    >>> from jointid.io.channels import Channels
    >>> rec = Channels.from_arrays({"force": np.sin(np.arange(8.0))}, fs=1024.0,
    ...                            units={"force": "N"})
    >>> with tempfile.TemporaryDirectory() as d:
    ...     f = write_uff(os.path.join(d, "r.uff"), rec, binary=True)
    ...     back = read_uff(f)
    >>> back.names, back.fs, back.units["force"], np.array_equal(back["force"], rec["force"])
    (('force',), 1024.0, 'N', True)
    """
    path = Path(path)
    uff, types = open_uff(path)
    if not types:
        raise RecordError(
            f"{where(path)}expected UFF datasets delimited by '    -1' lines, found none; the "
            f"file is corrupt or not a UFF file"
        )
    idx58 = [i for i, t in enumerate(types) if t == 58]
    if not idx58:
        raise RecordError(
            f"{where(path)}expected at least one dataset 58 (function at nodal DOF), got "
            f"dataset types {sorted(set(types))}"
        )
    dsets = []
    for i in idx58:
        try:
            d = uff.read_sets(i)
        except Exception as exc:
            raise RecordError(
                f"{where(path, record=i)}cannot read dataset 58 (corrupt or truncated): {exc}"
            ) from exc
        if isinstance(d, dict) and int(d.get("abscissa_spacing", 1)) == 1:
            d.pop("x", None)  # an even abscissa is t0 + n dt: its array would only double a long record
        dsets.append((i, d))

    skipped = [f"{i}: type {t}" for i, t in enumerate(types) if t != 58]
    time_sets = []
    for i, d in dsets:
        ftype = int(d.get("func_type", -1))
        abscissa_type = int(d.get("abscissa_spec_data_type", 0))
        if ftype == 1 or (ftype == 0 and abscissa_type == _TIME_SPEC_DATA_TYPE):
            time_sets.append((i, d))
        else:
            skipped.append(f"{i}: type 58, function type {ftype}")
    if not time_sets:
        ftypes = sorted({int(d.get("func_type", -1)) for _, d in dsets})
        raise RecordError(
            f"{where(path)}expected a dataset 58 time response (function type 1), got only "
            f"function types {ftypes}"
        )

    # check every dataset is complete
    for i, d in time_sets:
        label = f"dataset {i}" if _is_none(d.get("id1")) else str(d["id1"]).strip()
        values = d.get("data")
        if values is None or np.iscomplexobj(values):
            raise RecordError(
                f"{where(path, record=i, channel=label)}expected real time-response ordinates, "
                f"got {'none' if values is None else 'complex values'}"
            )
        n_header = int(d.get("num_pts", -1))
        if np.size(values) != n_header:
            raise RecordError(
                f"{where(path, record=i, channel=label)}expected {n_header} values (record 7 "
                f"of dataset 58), got {np.size(values)}; the file is truncated or corrupt"
            )

    # select
    auto = _auto_names([d for _, d in time_sets])
    if channels is None:
        chosen = list(zip(auto, time_sets))
    else:
        if isinstance(channels, str):
            mapping = {channels: channels}
        elif isinstance(channels, Mapping):
            mapping = {str(k): str(v) for k, v in channels.items()}
        else:
            mapping = {str(c): str(c) for c in channels}
        chosen = []
        for out_name, label in mapping.items():
            key = _norm(label)
            hits = [k for k, (_, d) in enumerate(time_sets) if key == _norm(d.get("id1", ""))]
            if not hits:
                hits = [
                    k
                    for k, (_, d) in enumerate(time_sets)
                    if key in {_norm(c) for c in _candidates(d)}
                ]
            if not hits:
                raise RecordError(
                    f"{where(path, channel=out_name)}expected a dataset 58 time response "
                    f"labelled {label!r}, not found; the file has {auto}"
                )
            if len(hits) > 1:
                raise RecordError(
                    f"{where(path, channel=out_name)}label {label!r} matches {len(hits)} "
                    f"datasets ({[auto[k] for k in hits]}); select by a unique label"
                )
            chosen.append((out_name, time_sets[hits[0]]))

    # common time base
    data: dict[str, np.ndarray] = {}
    units: dict[str, str] = {}
    labels: dict[str, str] = {}
    ref = None
    binary_any = False
    for name, (i, d) in chosen:
        values = np.asarray(d["data"], dtype=np.float64)
        if values.flags.owndata:
            values.setflags(write=False)  # our own array: the record keeps it without a copy
        if int(d.get("abscissa_spacing", 1)) == 1:
            t0, dt = _read_time_base(path, d, name)
        else:
            t0, dt = _uneven_time(path, d["x"], name)
        if ref is None:
            ref = (name, t0, dt, values.size)
            time_units = str(d.get("abscissa_axis_units_lab", "")).strip()
            time_units = "" if _is_none(time_units) else time_units
        else:
            rname, rt0, rdt, rn = ref
            if values.size != rn:
                raise RecordError(
                    f"{where(path, record=i, channel=name)}expected {rn} samples like channel "
                    f"{rname!r}, got {values.size}"
                )
            if abs(dt - rdt) > TIME_RTOL * rdt or abs(t0 - rt0) > TIME_RTOL * rdt:
                raise RecordError(
                    f"{where(path, record=i, channel=name)}expected the time base of channel "
                    f"{rname!r} (t0 = {rt0!r} s, dt = {rdt!r} s), got t0 = {t0!r} s, "
                    f"dt = {dt!r} s"
                )
        if name in data:
            raise RecordError(f"{where(path, channel=name)}channel requested twice")
        data[name] = values
        unit = str(d.get("ordinate_axis_units_lab", "")).strip()
        units[name] = "" if _is_none(unit) else unit
        labels[name] = str(d.get("id1", "")).strip()
        binary_any = binary_any or bool(d.get("binary", 0))
    assert ref is not None
    _, t0, dt, n = ref
    time = t0 + np.arange(n) * dt
    time.setflags(write=False)  # kept by the record without a copy
    return Channels(
        time=time,
        data=data,
        units=units,
        source=str(path),
        meta={
            "format": "uff58b" if binary_any else "uff58",
            "labels": labels,
            "skipped": skipped,
            "time_units": time_units,
        },
    )
