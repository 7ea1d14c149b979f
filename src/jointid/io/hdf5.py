"""Store records (:class:`~jointid.io.channels.Channels`) in HDF5 files.

Layout (``format = "jointid.channels"``, ``format_version = 1``)
------------------------------------------------------------------
::

    <group>                      the file root "/" by default, or a named group
      attrs  format          "jointid.channels"
             format_version  1
             fs              sampling rate [Hz]
             t0              time of the first sample [s]
             n_samples       samples per channel
             channel_names   JSON list: the channel order
             source          the file the record was first read from
             meta            JSON object: Channels.meta
      time                   float64 (n_samples,), attrs units="s"
      channels/              group
        <name>               float64 (n_samples,), attrs units, fs

The file root also carries ``format`` and ``format_version`` when records are stored in
named groups.  Channel values and the time vector are stored as float64, so a round trip
is bit-exact; ``units`` and ``meta`` come back unchanged (JSON-safe values; numpy
scalars and arrays are converted to numbers and lists).  The record read back has the
HDF5 file as ``source``; the stored ``source`` is in ``meta["original_source"]``.

Files written by hand or by other programs are read too if they follow the layout; only
``channels/<name>`` datasets are required.  Without a ``time`` dataset the time vector
is ``t0 + arange(n) / fs`` from the ``fs`` attribute of the group (or, failing that, the
``fs`` attribute of the channel datasets, which must agree) and ``t0`` (default 0).
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from jointid.errors import RecordError, RecordFileNotFoundError, where
from jointid.io.channels import MAX_SAMPLES, TIME_RTOL, Channels

__all__ = ["read_hdf5", "write_hdf5", "FORMAT_NAME", "FORMAT_VERSION"]

#: Value of the ``format`` attribute of a jointid record.
FORMAT_NAME = "jointid.channels"
#: Layout version written; files with a higher version are refused.
FORMAT_VERSION = 1


def _h5py():
    try:
        import h5py
    except ImportError as exc:  # pragma: no cover - h5py is a hard dependency
        raise ImportError("HDF5 files need h5py: pip install 'h5py>=3.9'") from exc
    return h5py


def _json_default(obj: Any) -> Any:
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, (Path, os.PathLike)):
        return os.fspath(obj)
    raise TypeError(f"{type(obj).__name__} is not JSON serialisable")


def _attr_str(value: Any) -> str:
    if isinstance(value, bytes):
        return value.decode("utf-8")
    return str(value)


def check_no_external_link(h5, name: str, path, channel: str) -> None:
    """Raise a :class:`RecordError` when a group or the dataset on the path ``name`` in the open file
    ``h5`` is an HDF5 external link: it would be followed into another file (anywhere on the disk,
    outside the data folder), so it is refused, checked before the link is followed."""
    h5py = _h5py()
    parts = [p for p in str(name).split("/") if p]
    node, prefix = h5, ""
    for part in parts:
        prefix = f"{prefix}/{part}"
        if not isinstance(node, h5py.Group) or part not in node:
            return  # missing: said by the caller
        link = node.get(part, getlink=True)
        if isinstance(link, h5py.ExternalLink):
            raise RecordError(
                f"{where(path, channel=channel)}dataset {name!r}"
                f"{'' if prefix == '/' + '/'.join(parts) else f': {prefix!r}'} is an HDF5 external link to "
                f"{link.path!r} in file {link.filename!r}; external links are not followed (the data must "
                f"be in the file itself: copy the dataset in)"
            )
        node = node.get(part)


def check_dataset(ds, path, channel: str, name: str | None = None) -> None:
    """Raise a :class:`RecordError` unless ``ds`` holds real numbers (not text, compound or complex
    values) within the record limit (:data:`jointid.io.channels.MAX_SAMPLES` values), checked on
    its type and shape before a byte is read (a compressed dataset may inflate far beyond its file),
    and lies in the file ``path`` itself (not reached through an external link)."""
    name = ds.name if name is None else name
    try:
        same_file = Path(ds.file.filename).resolve() == Path(path).resolve()
    except (OSError, ValueError):  # pragma: no cover - an in-memory file has no path to compare
        same_file = True
    if not same_file:
        raise RecordError(f"{where(path, channel=channel)}dataset {name!r} is reached through an HDF5 external "
                          f"link into file {ds.file.filename!r}; external links are not followed (the data "
                          f"must be in the file itself)")
    dt = ds.dtype
    if _h5py().check_enum_dtype(dt) is not None:  # integer codes of named states, not measured values
        raise RecordError(f"{where(path, channel=channel)}expected real numbers in dataset {name!r}, got an "
                          f"enumeration of {sorted(_h5py().check_enum_dtype(dt))} (dtype {dt})")
    if dt.names is not None or dt.kind not in "iuf":
        text = dt.kind in "SU" or _h5py().check_string_dtype(dt) is not None
        what = ("compound records" if dt.names is not None else "text" if text else
                "variable-length or object values" if dt.kind == "O" else
                "complex numbers" if dt.kind == "c" else "booleans" if dt.kind == "b" else f"dtype {dt}")
        raise RecordError(f"{where(path, channel=channel)}expected real numbers in dataset {name!r}, got {what} "
                          f"(dtype {dt})")
    if ds.shape is None:
        raise RecordError(f"{where(path, channel=channel)}dataset {name!r} is empty (no dataspace)")
    size = int(np.prod(ds.shape, dtype=np.int64))
    if size > MAX_SAMPLES:
        raise RecordError(f"{where(path, channel=channel)}dataset {name!r} holds {size} values (shape {ds.shape}), "
                          f"more than the limit of {MAX_SAMPLES} samples of a record")


def write_hdf5(
    path: str | os.PathLike,
    channels: Channels,
    *,
    group: str = "/",
    mode: str = "w",
) -> Path:
    """Write a record to an HDF5 file in the jointid layout.

    Parameters
    ----------
    path : str or os.PathLike
        HDF5 file.
    channels : Channels
        The record.  Channel names must not contain ``/`` or be ``.``.
    group : str, optional
        Group to write the record into; ``"/"`` (default) is the file root.
    mode : {"w", "a"}, optional
        ``"w"`` creates or truncates the file (default); ``"a"`` adds the record to an
        existing file, in a group that must not exist yet.

    Returns
    -------
    pathlib.Path
        The file written.

    Raises
    ------
    jointid.errors.RecordError
        If a channel name cannot be a dataset name, ``meta`` is not JSON-safe, or the
        group already exists in ``"a"`` mode.

    See Also
    --------
    read_hdf5
    """
    h5py = _h5py()
    path = Path(path)
    if not isinstance(channels, Channels):
        raise RecordError(
            f"{where(path)}expected a jointid.io.Channels record, got {type(channels).__name__}"
        )
    if mode not in ("w", "a"):
        raise ValueError(f"mode must be 'w' or 'a', got {mode!r}")
    for name in channels.names:
        if "/" in name or name in (".", ""):
            raise RecordError(
                f"{where(path, channel=name)}expected a channel name usable as an HDF5 "
                f"dataset name (no '/'), got {name!r}"
            )
    try:
        meta_json = json.dumps(channels.meta, default=_json_default, allow_nan=True)
    except (TypeError, ValueError) as exc:
        raise RecordError(
            f"{where(path)}expected JSON-safe metadata to store in HDF5, got {exc}"
        ) from exc
    with h5py.File(path, mode) as f:
        f.attrs["format"] = FORMAT_NAME
        f.attrs["format_version"] = FORMAT_VERSION
        if group in ("/", ""):
            g = f["/"]
        else:
            if group in f:
                raise RecordError(
                    f"{where(path)}expected a new group {group!r} for the record, it exists"
                )
            g = f.create_group(group)
        fs = channels.fs
        g.attrs["format"] = FORMAT_NAME
        g.attrs["format_version"] = FORMAT_VERSION
        g.attrs["fs"] = fs
        g.attrs["t0"] = channels.t0
        g.attrs["n_samples"] = channels.n_samples
        g.attrs["channel_names"] = json.dumps(list(channels.names))
        g.attrs["source"] = channels.source
        g.attrs["meta"] = meta_json
        t = g.create_dataset("time", data=np.asarray(channels.time, dtype=np.float64))
        t.attrs["units"] = "s"
        cg = g.create_group("channels")
        for name, values in channels.data.items():
            ds = cg.create_dataset(name, data=np.asarray(values, dtype=np.float64))
            ds.attrs["units"] = channels.units.get(name, "")
            ds.attrs["fs"] = fs
    return path


def read_hdf5(
    path: str | os.PathLike,
    channels: Sequence[str] | None = None,
    *,
    group: str = "/",
) -> Channels:
    """Read a record written by :func:`write_hdf5` (or following its layout).

    Parameters
    ----------
    path : str or os.PathLike
        HDF5 file.
    channels : sequence of str, optional
        Channels to read, in this order; default all, in the stored order.
    group : str, optional
        Group holding the record; default the file root.

    Returns
    -------
    Channels
        ``source`` is the HDF5 file; the stored ``source`` attribute is in
        ``meta["original_source"]`` (unless ``meta`` already has that key).

    Raises
    ------
    jointid.errors.RecordFileNotFoundError
        If the file does not exist.
    jointid.errors.RecordError
        If the file is not HDF5, the group or a channel is missing, the format version is
        newer than this reader, or a dataset has the wrong shape or length (the message
        names the file and dataset).

    Examples
    --------
    >>> import numpy as np, tempfile, os
    >>> rec = Channels.from_arrays({"x": np.arange(5.0)}, fs=50.0, units={"x": "m"},
    ...                            meta={"level": 3})
    >>> with tempfile.TemporaryDirectory() as d:
    ...     back = read_hdf5(write_hdf5(os.path.join(d, "r.h5"), rec))
    >>> back.fs, back.units, back.meta["level"], np.array_equal(back["x"], rec["x"])
    (50.0, {'x': 'm'}, 3, True)
    """
    h5py = _h5py()
    path = Path(path)
    if not path.is_file():
        raise RecordFileNotFoundError(f"{where(path)}HDF5 file not found")
    try:
        f = h5py.File(path, "r")
    except OSError as exc:
        raise RecordError(f"{where(path)}cannot open as an HDF5 file: {exc}") from exc
    with f:
        gname = group if group not in ("", "/") else "/"
        if gname not in f:
            raise RecordError(
                f"{where(path)}expected group {gname!r}, not in the file; top-level items are "
                f"{sorted(f.keys())}"
            )
        g = f[gname]
        fmt = g.attrs.get("format", f.attrs.get("format"))
        if fmt is not None and _attr_str(fmt) != FORMAT_NAME:
            raise RecordError(
                f"{where(path)}expected format attribute {FORMAT_NAME!r}, got {_attr_str(fmt)!r}"
            )
        version = g.attrs.get("format_version", f.attrs.get("format_version", FORMAT_VERSION))
        if int(version) > FORMAT_VERSION:
            raise RecordError(
                f"{where(path)}expected format_version <= {FORMAT_VERSION}, got {int(version)}; "
                f"update jointid"
            )
        if "channels" not in g or not isinstance(g["channels"], h5py.Group):
            raise RecordError(
                f"{where(path)}expected a group 'channels' in {gname!r} holding one dataset "
                f"per channel, missing; {gname!r} has {sorted(g.keys())}"
            )
        cg = g["channels"]
        stored = list(cg.keys())
        if "channel_names" in g.attrs:
            order = json.loads(_attr_str(g.attrs["channel_names"]))
            stored = [n for n in order if n in cg] + [n for n in stored if n not in order]
        wanted = stored if channels is None else [str(c) for c in channels]
        if not wanted:
            raise RecordError(f"{where(path)}expected at least one channel dataset, got none")
        data: dict[str, np.ndarray] = {}
        units: dict[str, str] = {}
        fs_attrs: dict[str, float] = {}
        n_ref: tuple[str, int] | None = None
        for name in wanted:
            dpath = f"{cg.name.rstrip('/')}/{name}"
            check_no_external_link(f, dpath, path, name)
            if name not in cg:
                raise RecordError(
                    f"{where(path, channel=name)}expected dataset {dpath!r}, missing; "
                    f"channels are {stored}"
                )
            ds = cg[name]
            if not isinstance(ds, h5py.Dataset):
                raise RecordError(
                    f"{where(path, channel=name)}expected {dpath!r} to be a dataset, got a group"
                )
            if ds.ndim != 1:
                raise RecordError(
                    f"{where(path, channel=name)}expected dataset {dpath!r} to be 1-D "
                    f"(n_samples,), got shape {ds.shape}"
                )
            check_dataset(ds, path, name, dpath)
            if n_ref is None:
                n_ref = (dpath, ds.shape[0])
            elif ds.shape[0] != n_ref[1]:
                raise RecordError(
                    f"{where(path, channel=name)}expected dataset {dpath!r} to have {n_ref[1]} "
                    f"samples like {n_ref[0]!r}, got {ds.shape[0]}"
                )
            data[name] = np.asarray(ds[()], dtype=np.float64)
            units[name] = _attr_str(ds.attrs.get("units", ""))
            if "fs" in ds.attrs:
                fs_attrs[name] = float(ds.attrs["fs"])
        assert n_ref is not None
        n = n_ref[1]
        if "n_samples" in g.attrs and int(g.attrs["n_samples"]) != n:
            raise RecordError(
                f"{where(path)}expected {int(g.attrs['n_samples'])} samples (attribute "
                f"n_samples of {gname!r}), got {n} in {n_ref[0]!r}"
            )
        if "time" in g:
            check_no_external_link(f, f"{g.name.rstrip('/')}/time", path, "time")
            tds = g["time"]
            tpath = tds.name
            if not isinstance(tds, h5py.Dataset) or tds.ndim != 1 or tds.shape[0] != n:
                shape = tds.shape if isinstance(tds, h5py.Dataset) else "a group"
                raise RecordError(
                    f"{where(path, channel='time')}expected dataset {tpath!r} of shape ({n},), "
                    f"got {shape}"
                )
            check_dataset(tds, path, "time", tpath)
            time = np.asarray(tds[()], dtype=np.float64)
        else:
            if "fs" in g.attrs:
                fs = float(g.attrs["fs"])
            elif fs_attrs:
                fs = next(iter(fs_attrs.values()))
            else:
                raise RecordError(
                    f"{where(path)}expected a 'time' dataset or an 'fs' attribute on {gname!r} "
                    f"or on the channel datasets, found neither"
                )
            for name, f_ch in fs_attrs.items():
                if abs(f_ch - fs) > TIME_RTOL * fs:
                    raise RecordError(
                        f"{where(path, channel=name)}expected fs = {fs!r} Hz like the record, "
                        f"got fs = {f_ch!r} Hz on dataset {cg.name}/{name}"
                    )
            if not (np.isfinite(fs) and fs > 0):
                raise RecordError(f"{where(path)}expected a positive fs attribute, got {fs!r}")
            t0 = float(g.attrs.get("t0", 0.0))
            time = t0 + np.arange(n) / fs
        meta: dict[str, Any] = {}
        if "meta" in g.attrs:
            try:
                meta = json.loads(_attr_str(g.attrs["meta"]))
            except json.JSONDecodeError as exc:
                raise RecordError(
                    f"{where(path)}expected the 'meta' attribute of {gname!r} to be JSON, got "
                    f"invalid text ({exc})"
                ) from exc
            if not isinstance(meta, dict):
                raise RecordError(
                    f"{where(path)}expected the 'meta' attribute to be a JSON object, got "
                    f"{type(meta).__name__}"
                )
        if "source" in g.attrs:
            meta.setdefault("original_source", _attr_str(g.attrs["source"]))
        # the unit label of the time dataset as written (a time from fs is in s); read by the campaign reader
        meta["time_units"] = _attr_str(g["time"].attrs.get("units", "")) if "time" in g else "s"
    return Channels(time=time, data=data, units=units, source=str(path), meta=meta)
