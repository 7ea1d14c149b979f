"""Read time records from MATLAB MAT files (v4/v5/v7): plain arrays and LMS Test.Lab structs.

:func:`read_mat` takes a *spec*, a mapping from the channel names wanted to references
into the file:

``"V1"``
    a variable; a row or column vector, or an array with one singleton dimension.
``"Signal[2]"``
    column 2 (0-based) along the channel axis of a 2-D array.  The time axis of a 2-D
    array is the axis whose length equals the record length when that is known (from a
    time vector, a Test.Lab struct or another channel), else the longer axis.
``"Signal[Acc1:+X]"``
    for a Test.Lab struct, the channel whose ``function_record.name`` or
    ``function_record.primary_channel.label`` is ``Acc1:+X`` (ignoring case and repeated
    blanks; quotes around the label are allowed).
``"s.a.b"``
    a field of a (nested) MATLAB struct; may be followed by an index.

LMS Test.Lab exports
--------------------
A Test.Lab "Signal" struct (loaded with ``squeeze_me=True, struct_as_record=False``) holds
its samples in ``y_values.values`` (``(N,)`` or ``(N, n_channels)``), its time base in
``x_values.start_value``, ``x_values.increment`` and ``x_values.number_of_values``, and its
channel names in ``function_record.name``.  :func:`read_mat` reads such a struct directly:
the time base comes from ``x_values`` and the unit from ``y_values.quantity``.  When the
quantity says ``"Data saved by Test.Lab in MKS"`` the values are SI whatever the display
label (an acceleration labelled ``'g'`` with factor 0.10197 is in m/s²), so the unit is
built from the SI dimension exponents in ``quantity.quantity_terms`` (``m/s^2``, ``m/s``,
``N``, ``V``...).

MATLAB v7.3 files
-----------------
v7.3 MAT files are HDF5 files.  None of the shared data sets uses v7.3, so they are not
read here: :func:`read_mat` raises a :class:`~jointid.errors.RecordError` that says so
(save them with ``-v7``, or read them as HDF5 files by dataset path).

Complex variables are refused (not reduced to their real part).
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from jointid.errors import RecordError, RecordFileNotFoundError, where
from jointid.io.channels import TIME_RTOL, Channels
from jointid.io.units import SI_NAMES

__all__ = ["read_mat", "mat_variables", "testlab_unit"]

_REF = re.compile(r"^\s*(?P<path>[A-Za-z]\w*(?:\.[A-Za-z]\w*)*)\s*(?:\[(?P<index>.*)\])?\s*$")

_SI_SYMBOL = {
    "MASS": "kg",
    "LENGTH": "m",
    "TIME": "s",
    "CURRENT": "A",
    "TEMPERATURE": "K",
    "ANGLE": "rad",
    "LIGHT": "cd",
    "MOLCULAR_AMOUNT": "mol",
    "MOLECULAR_AMOUNT": "mol",
}
# SI dimension exponents (kg, m, s, A) -> usual unit name (the one table of units: jointid.io.units)
_NAMED_UNITS = SI_NAMES


def _is_struct(obj: Any) -> bool:
    return hasattr(obj, "_fieldnames")


def _fields(obj: Any) -> list[str]:
    return list(getattr(obj, "_fieldnames", []))


def _is_testlab(obj: Any) -> bool:
    return (
        _is_struct(obj)
        and {"x_values", "y_values"} <= set(_fields(obj))
        and "values" in _fields(obj.y_values)
    )


def _strings(obj: Any) -> list[str]:
    if obj is None:
        return []
    arr = np.atleast_1d(np.asarray(obj, dtype=object))
    return [str(x) for x in arr.ravel()]


def _norm(label: str) -> str:
    return " ".join(str(label).split()).casefold()


def mat_variables(path: str | os.PathLike) -> dict[str, tuple[tuple[int, ...], str]]:
    """List the variables of a MAT file without loading them.

    Parameters
    ----------
    path : str or os.PathLike
        MAT file (v4, v5 or v7).

    Returns
    -------
    dict
        Variable name -> (shape, MATLAB class), as :func:`scipy.io.whosmat` reports them.

    Raises
    ------
    jointid.errors.RecordFileNotFoundError
        If the file does not exist.
    jointid.errors.RecordError
        If the file is not a readable MAT file (or is v7.3).
    """
    from scipy.io import whosmat

    path = _check_path(path)
    try:
        return {name: (tuple(shape), cls) for name, shape, cls in whosmat(str(path))}
    except Exception as exc:
        raise RecordError(f"{where(path)}cannot read the MAT file: {exc}") from exc


def testlab_unit(quantity: Any) -> str:
    """Unit of a Test.Lab ``quantity`` struct, in SI when the data were saved in MKS.

    Parameters
    ----------
    quantity : scipy.io.matlab.mat_struct
        ``x_values.quantity`` or ``y_values.quantity`` of a Test.Lab struct.

    Returns
    -------
    str
        The display label when it is an SI label (factor 1, offset 0) or the data were
        not saved in MKS; otherwise the SI unit built from ``quantity_terms``.
    """
    if not _is_struct(quantity):
        return ""
    label = str(getattr(quantity, "label", "") or "")
    info = str(getattr(quantity, "info", "") or "")
    tr = getattr(quantity, "unit_transformation", None)
    factor = float(getattr(tr, "factor", 1.0)) if tr is not None else 1.0
    offset = float(getattr(tr, "offset", 0.0)) if tr is not None else 0.0
    if (factor == 1.0 and offset == 0.0) or "MKS" not in info.upper():
        return label
    terms = np.atleast_1d(getattr(quantity, "quantity_terms", np.array([], dtype=object)))
    exps: dict[str, float] = {}
    for t in terms.ravel():
        if not _is_struct(t):
            continue
        num, den = float(getattr(t, "num", 0)), float(getattr(t, "den", 1) or 1)
        if num:
            exps[str(t.quantity).upper()] = num / den
    base = ("MASS", "LENGTH", "TIME", "CURRENT")
    if set(exps) <= set(base) and all(float(e).is_integer() for e in exps.values()):
        key = tuple(int(exps.get(q, 0)) for q in base)
        if key in _NAMED_UNITS:
            return _NAMED_UNITS[key]
    parts = []
    for q, e in exps.items():
        sym = _SI_SYMBOL.get(q, q.lower())
        parts.append(sym if e == 1 else f"{sym}^{e:g}")
    return " ".join(parts)


def _check_path(path: str | os.PathLike) -> Path:
    path = Path(path)
    if not path.is_file():
        raise RecordFileNotFoundError(f"{where(path)}MAT file not found")
    with open(path, "rb") as fh:
        head = fh.read(128)
    if head.startswith(b"MATLAB 7.3") or head[:4] == b"\x89HDF" or b"MATLAB 7.3" in head[:116]:
        raise RecordError(
            f"{where(path)}this is a MATLAB v7.3 (HDF5) MAT file, which is not read as a MAT file; "
            f"re-save it in MATLAB with save(..., '-v7'), or read it as an HDF5 file (name it .h5 and "
            f"give each channel as a dataset path, e.g. \"/force\")"
        )
    return path


def _load(path: Path, names: list[str]) -> dict[str, Any]:
    """Load the variables ``names`` in MATLAB's own classes (a logical array reads as bool, not as
    uint8 0/1 samples).  A complex variable is returned as stored, complex: with ``mat_dtype=True``
    scipy would cast it to its class ``double`` and keep only the real part (a ComplexWarning), so
    such variables are read again without that cast; the callers refuse or use the complex values.
    """
    import warnings

    from scipy.io import loadmat

    complex_warning = getattr(getattr(np, "exceptions", np), "ComplexWarning")
    kwargs = dict(squeeze_me=True, struct_as_record=False)

    def load(variables, mat_dtype):
        with warnings.catch_warnings():
            warnings.simplefilter("error", complex_warning)
            return loadmat(str(path), mat_dtype=mat_dtype, variable_names=variables, **kwargs)

    try:
        try:
            return load(names, True)
        except complex_warning:
            pass
        loaded: dict[str, Any] = {}
        for name in names:  # which variables are complex
            try:
                loaded.update(load([name], True))
            except complex_warning:
                loaded.update(load([name], False))
        return loaded
    except Exception as exc:
        raise RecordError(f"{where(path)}cannot read the MAT file: {exc}") from exc


def _walk(path: Path, loaded: Mapping[str, Any], ref: str, channel: str) -> tuple[Any, str | None]:
    m = _REF.match(ref)
    if m is None:
        raise RecordError(
            f"{where(path, channel=channel)}expected a reference like 'name', 'name[3]', "
            f"'name[label]' or 'struct.field', got {ref!r}"
        )
    parts = m.group("path").split(".")
    top = parts[0]
    if top not in loaded:
        available = sorted(k for k in loaded if not k.startswith("__"))
        raise RecordError(
            f"{where(path, channel=channel)}expected variable {top!r}, not in the file; "
            f"variables are {available}"
        )
    obj = loaded[top]
    walked = top
    for field in parts[1:]:
        if not _is_struct(obj) or field not in _fields(obj):
            have = _fields(obj) if _is_struct(obj) else f"a {type(obj).__name__}, not a struct"
            raise RecordError(
                f"{where(path, channel=channel)}expected field {field!r} in {walked!r}, "
                f"missing; {walked!r} has {have}"
            )
        obj = getattr(obj, field)
        walked = f"{walked}.{field}"
    index = m.group("index")
    return obj, (index.strip().strip("'\"") if index is not None else None)


def _testlab_labels(obj: Any) -> list[list[str]]:
    """Per channel, the labels it can be selected by."""
    fr = getattr(obj, "function_record", None)
    names = _strings(getattr(fr, "name", None)) if fr is not None else []
    pc = getattr(fr, "primary_channel", None) if fr is not None else None
    plabels = _strings(getattr(pc, "label", None)) if pc is not None else []
    n = max(len(names), len(plabels))
    out = []
    for k in range(n):
        labs = []
        if k < len(names):
            labs.append(names[k])
        if k < len(plabels):
            labs.append(plabels[k])
        out.append(labs)
    return out


def _testlab_time(path: Path, obj: Any, channel: str) -> tuple[float, float, int]:
    xv = obj.x_values
    missing = [f for f in ("start_value", "increment", "number_of_values") if f not in _fields(xv)]
    if missing:
        raise RecordError(
            f"{where(path, channel=channel)}expected fields {missing} in the Test.Lab "
            f"x_values struct, missing; x_values has {_fields(xv)}"
        )
    return float(xv.start_value), float(xv.increment), int(xv.number_of_values)


def _orient(
    path: Path, arr: np.ndarray, index: str | None, n: int | None, channel: str, ref: str,
    labels: list[list[str]] | None,
) -> np.ndarray:
    if arr.dtype == bool:
        raise RecordError(
            f"{where(path, channel=channel)}{ref!r} is a MATLAB logical (true/false) array, not samples "
            f"of a signal; it is not converted to 0/1 values (save the measured channel as a numeric array)"
        )
    if arr.dtype == object or not np.issubdtype(arr.dtype, np.number):
        raise RecordError(
            f"{where(path, channel=channel)}expected a numeric array for {ref!r}, got "
            f"{'a struct or cell array' if arr.dtype == object else f'dtype {arr.dtype}'}"
        )
    if arr.ndim == 2 and 1 in arr.shape:
        arr = arr.ravel()
    if arr.ndim == 0:
        raise RecordError(
            f"{where(path, channel=channel)}expected a vector of samples for {ref!r}, got a scalar"
        )
    if arr.ndim == 1:
        if index is not None:
            if labels and len(labels) == 1 and _label_index(labels, index) == 0:
                return arr
            if index == "0":
                return arr
            raise RecordError(
                f"{where(path, channel=channel)}{ref!r} is a single vector of {arr.size} "
                f"samples; no column {index!r} to select"
            )
        return arr
    if arr.ndim != 2:
        raise RecordError(
            f"{where(path, channel=channel)}expected a vector or a 2-D array for {ref!r}, "
            f"got shape {arr.shape}"
        )
    if n is not None and (arr.shape[0] == n) != (arr.shape[1] == n):
        time_axis = 0 if arr.shape[0] == n else 1
    elif arr.shape[0] != arr.shape[1]:
        time_axis = 0 if arr.shape[0] > arr.shape[1] else 1
    else:
        raise RecordError(
            f"{where(path, channel=channel)}cannot tell the time axis of {ref!r} with shape "
            f"{arr.shape}"
        )
    n_chan = arr.shape[1 - time_axis]
    if index is None:
        raise RecordError(
            f"{where(path, channel=channel)}{ref!r} has shape {arr.shape} ({n_chan} channels); "
            f"expected a channel index such as '{ref}[0]'"
            + (f" or a label such as '{ref}[{labels[0][-1]}]'" if labels else "")
        )
    k = _label_index(labels, index) if labels else None
    if k is None:
        try:
            k = int(index)
        except ValueError:
            have = [lab[-1] for lab in labels] if labels else []
            raise RecordError(
                f"{where(path, channel=channel)}expected a channel labelled {index!r} in "
                f"{ref.split('[')[0]!r}, not found"
                + (f"; labels are {have}" if have else "; it has no channel labels, use an index")
            ) from None
    if not -n_chan <= k < n_chan:
        raise RecordError(
            f"{where(path, channel=channel)}expected a channel index below {n_chan} for "
            f"{ref!r} (shape {arr.shape}), got {k}"
        )
    return arr[:, k] if time_axis == 0 else arr[k, :]


def _label_index(labels: list[list[str]] | None, index: str) -> int | None:
    if not labels:
        return None
    key = _norm(index)
    hits = [k for k, labs in enumerate(labels) if key in {_norm(x) for x in labs}]
    return hits[0] if len(hits) == 1 else None


def read_mat(
    path: str | os.PathLike,
    spec: Mapping[str, str],
    *,
    fs: float | str | None = None,
    time: Any = None,
    t0: float = 0.0,
    units: Mapping[str, str] | None = None,
    meta: Mapping[str, Any] | None = None,
) -> Channels:
    """Read channels from a MAT file (plain arrays or LMS Test.Lab structs).

    Parameters
    ----------
    path : str or os.PathLike
        MAT file, version 4, 5 or 7 (not 7.3).
    spec : mapping of str to str
        Channel name -> reference into the file (see the module documentation), e.g.
        ``{"u": "V1", "y": "V2"}`` or ``{"acc1": "Signal[Acc1:+X]"}``.
    fs : float or str, optional
        Sampling rate in Hz, or the name of a scalar variable holding it (e.g. ``"fs"``).
    time : array_like or str, optional
        Time vector in seconds, or a reference to one in the file.
    t0 : float, optional
        Start time when `fs` is given.  Default 0.
    units : mapping of str to str, optional
        Units per channel; override those read from Test.Lab structs.
    meta : mapping, optional
        Extra metadata for the record.

    Returns
    -------
    Channels
        ``meta`` holds ``format`` (``"mat"``), ``references`` (the spec) and, for Test.Lab
        channels, ``labels`` (their Test.Lab channel names) and ``run_name``.

    Raises
    ------
    jointid.errors.RecordFileNotFoundError
        If the file does not exist.
    jointid.errors.RecordError
        If the file cannot be read, a variable, field or channel label is missing (the
        message names it and lists what is there), there is no time base (give `fs` or
        `time` for plain arrays), or the channels disagree in length or time base.

    Notes
    -----
    Time base, in order of precedence: `time`, then `fs` (with `t0`), then the
    ``x_values`` of the Test.Lab structs read (all must agree).

    Examples
    --------
    >>> import numpy as np, tempfile, os
    >>> from scipy.io import savemat
    >>> with tempfile.TemporaryDirectory() as d:
    ...     f = os.path.join(d, "r.mat")
    ...     savemat(f, {"V1": np.arange(4.0)[None, :], "fs": 10.0})
    ...     rec = read_mat(f, {"u": "V1"}, fs="fs", units={"u": "V"})
    >>> rec.names, rec.fs, rec["u"]
    (('u',), 10.0, array([0., 1., 2., 3.]))
    """
    path = _check_path(path)
    if not isinstance(spec, Mapping) or not spec:
        raise RecordError(
            f"{where(path)}expected a non-empty mapping channel name -> variable reference, "
            f"got {spec!r}"
        )
    available = mat_variables(path)

    def top_name(ref: str) -> str:
        return re.split(r"[.\[]", str(ref).strip(), maxsplit=1)[0].strip()

    needed = {top_name(r) for r in spec.values()}
    if isinstance(time, str):
        needed.add(top_name(time))
    if isinstance(fs, str):
        needed.add(top_name(fs))
    for name in sorted(needed):
        if name not in available:
            raise RecordError(
                f"{where(path)}expected variable {name!r}, not in the file; variables are "
                + ", ".join(f"{k} {v[0]} {v[1]}" for k, v in available.items())
            )
    loaded = _load(path, sorted(needed))

    # explicit time base
    n_expected: int | None = None
    time_vec: np.ndarray | None = None
    if time is not None and fs is not None:
        raise RecordError(f"{where(path)}expected fs= or time=, got both")
    if time is not None:
        if isinstance(time, str):
            obj, idx = _walk(path, loaded, time, "time")
            if _is_testlab(obj):
                obj = obj.y_values.values
            time_vec = _orient(path, np.asarray(obj), idx, None, "time", time, None)
            if np.iscomplexobj(time_vec):
                raise RecordError(f"{where(path, channel='time')}expected real time stamps in {time!r}, got "
                                  f"complex values")
        else:
            time_vec = np.asarray(time, dtype=float)
        n_expected = int(time_vec.size)
    fs_val: float | None = None
    if fs is not None:
        if isinstance(fs, str):
            obj, _ = _walk(path, loaded, fs, "fs")
            arr = np.asarray(obj)
            if arr.size != 1 or not np.issubdtype(arr.dtype, np.number) or np.iscomplexobj(arr):
                raise RecordError(
                    f"{where(path)}expected {fs!r} to hold a scalar sampling rate, got "
                    f"shape {arr.shape} dtype {arr.dtype}"
                )
            fs_val = float(arr.ravel()[0])
        else:
            fs_val = float(fs)
        if not (np.isfinite(fs_val) and fs_val > 0):
            raise RecordError(f"{where(path)}expected a positive sampling rate, got fs={fs_val!r}")

    # channels
    data: dict[str, np.ndarray] = {}
    unit_of: dict[str, str] = {}
    labels_of: dict[str, str] = {}
    testlab_bases: dict[str, tuple[float, float, int]] = {}
    run_names: set[str] = set()
    for name, ref in spec.items():
        obj, index = _walk(path, loaded, str(ref), name)
        labels = None
        if _is_testlab(obj):
            start, inc, nval = _testlab_time(path, obj, name)
            testlab_bases[name] = (start, inc, nval)
            labels = _testlab_labels(obj)
            values = np.asarray(obj.y_values.values)
            unit_of[name] = testlab_unit(getattr(obj.y_values, "quantity", None))
            n_hint = n_expected if n_expected is not None else nval
            vec = _orient(path, values, index, n_hint, name, str(ref), labels)
            k = None
            if index is not None and labels:
                k = _label_index(labels, index)
                if k is None:
                    try:
                        k = int(index)
                    except ValueError:
                        k = None
            if k is None and labels and len(labels) == 1:
                k = 0
            if k is not None and -len(labels) <= k < len(labels):
                labels_of[name] = labels[k][0]
            fr = getattr(obj, "function_record", None)
            ann = getattr(fr, "TL_export_properties_annotation", None) if fr is not None else None
            run_names.update(_strings(getattr(ann, "run_name", None)) if ann is not None else [])
        else:
            if _is_struct(obj):
                have = _fields(obj)
                missing = [f for f in ("x_values", "y_values") if f not in have]
                if not missing and "values" not in _fields(obj.y_values):
                    missing = ["y_values.values"]
                raise RecordError(
                    f"{where(path, channel=name)}expected {str(ref)!r} to be a numeric array "
                    f"or a Test.Lab signal struct, got a struct missing field(s) {missing}; "
                    f"its fields are {have}"
                )
            n_hint = n_expected
            if n_hint is None and data:
                n_hint = next(iter(data.values())).size
            vec = _orient(path, np.asarray(obj), index, n_hint, name, str(ref), None)
        if np.iscomplexobj(vec):
            raise RecordError(
                f"{where(path, channel=name)}expected real samples in {str(ref)!r}, got complex values; they "
                f"are not reduced to their real part (save the real signal, or its real and imaginary parts "
                f"as two real variables)"
            )
        data[name] = np.asarray(vec, dtype=np.float64)

    # time base
    if time_vec is None:
        n = next(iter(data.values())).size
        if fs_val is not None:
            time_vec = t0 + np.arange(n) / fs_val
        elif testlab_bases:
            (ref_name, (start, inc, nval)), *rest = testlab_bases.items()
            for other, (s2, i2, n2) in rest:
                if n2 != nval or abs(i2 - inc) > TIME_RTOL * inc or abs(s2 - start) > TIME_RTOL * inc:
                    raise RecordError(
                        f"{where(path, channel=other)}expected the Test.Lab time base of "
                        f"channel {ref_name!r} (start {start!r} s, increment {inc!r} s, "
                        f"{nval} values), got start {s2!r} s, increment {i2!r} s, {n2} values"
                    )
            if not (np.isfinite(inc) and inc > 0):
                raise RecordError(
                    f"{where(path, channel=ref_name)}expected a positive x_values.increment, "
                    f"got {inc!r}"
                )
            time_vec = start + np.arange(nval) * inc
        else:
            raise RecordError(
                f"{where(path)}expected a time base: the channels are plain arrays, so give "
                f"fs= (a number or the name of a variable) or time="
            )
    for name, (start, inc, nval) in testlab_bases.items():
        if data[name].size != nval:
            raise RecordError(
                f"{where(path, channel=name)}expected {nval} samples (x_values.number_of_values), "
                f"got {data[name].size}"
            )
    unit_of.update(dict(units or {}))
    meta_out: dict[str, Any] = {"format": "mat", "references": {k: str(v) for k, v in spec.items()}}
    if labels_of:
        meta_out["labels"] = labels_of
    if run_names:
        meta_out["run_name"] = sorted(run_names)[0] if len(run_names) == 1 else sorted(run_names)
    meta_out.update(dict(meta or {}))
    return Channels(
        time=time_vec,
        data=data,
        units=unit_of,
        source=str(path),
        meta=meta_out,
    )
