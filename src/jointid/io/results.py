"""Atomic writing of results (JSON, CSV, text, figures).

Every file is written to a temporary file in the destination folder and renamed over the
target (``os.replace``), so a reader never sees a half-written result and an interrupted
run leaves the previous result intact.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import tempfile
from pathlib import Path

import numpy as np

from ..errors import OutputError

__all__ = ["misfits", "atomic_write", "write_json", "write_csv", "to_jsonable", "atomic_savefig", "csv_safe",
           "check_output_folder", "MARKER"]

#: File that marks a folder as a jointid output set (holds the run id).
MARKER = ".jointid-run"


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write(path, data) -> Path:
    """Write ``data`` (str or bytes) to ``path`` atomically; parent folders are created.

    The file gets the permissions of an ordinary new file (``0666`` less the umask), not
    the private mode of the temporary file it is renamed from.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    binary = isinstance(data, (bytes, bytearray))
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb" if binary else "w", encoding=None if binary else "utf-8", newline=None if binary else "") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
    return path


def to_jsonable(obj):
    """Convert numpy scalars/arrays, tuples and non-finite floats to JSON-safe values (NaN -> None)."""
    if isinstance(obj, dict):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist())
    if isinstance(obj, (np.bool_, bool)):
        return bool(obj)
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        v = float(obj)
        return v if math.isfinite(v) else None
    if isinstance(obj, Path):
        return str(obj)
    return obj


def write_json(path, data) -> Path:
    return atomic_write(path, json.dumps(to_jsonable(data), indent=2, allow_nan=False) + "\n")


def write_csv(path, rows: list[dict], columns=None) -> Path:
    """Write a list of flat dicts as CSV (columns from the first row unless given)."""
    columns = list(columns or (rows[0].keys() if rows else []))
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=columns, extrasaction="ignore", lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: _cell(r.get(k)) for k in columns})
    return atomic_write(path, buf.getvalue())


def _cell(v):
    if v is None:
        return ""
    if isinstance(v, (float, np.floating)):
        return repr(float(v)) if math.isfinite(v) else ""
    if isinstance(v, str):
        return csv_safe(v)
    return v


def csv_safe(text: str) -> str:
    """A text cell a spreadsheet shows as text: a leading ``= + - @`` (or tab, CR) that would
    start a formula gets a ``'`` in front; numbers such as ``-5`` stay as they are.

    Examples
    --------
    >>> csv_safe("=HYPERLINK(1)"), csv_safe("-5"), csv_safe("preload 120")
    ("'=HYPERLINK(1)", '-5', 'preload 120')
    """
    if text[:1] in ("=", "+", "-", "@", "\t", "\r"):
        try:
            float(text)
            return text
        except ValueError:
            return "'" + text
    return text


def atomic_savefig(fig, path, **kw) -> Path:
    """Save a matplotlib figure atomically (format from the suffix)."""
    path = Path(path)
    buf = io.BytesIO()
    fig.savefig(buf, format=path.suffix.lstrip(".") or "png", **kw)
    return atomic_write(path, buf.getvalue())


def check_output_folder(out, *, replace_set=True) -> Path:
    """Refuse an output folder that cannot be written, before any work starts.

    Refused: an existing file, a path below a file, a folder without write permission
    (or whose parent cannot take the temporary set), and, when the set replaces the
    folder, an existing non-empty folder that is not a jointid output set (it would be
    replaced: a campaign folder given as ``--out`` by mistake).

    Raises
    ------
    OutputError
        Naming the path and what is wrong.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise OutputError(f"{out}: output folder expected, got an existing file")
    probe = out
    while not probe.exists():
        if probe.parent == probe:
            break
        probe = probe.parent
    if probe != out and not probe.is_dir():
        raise OutputError(f"{out}: cannot create the output folder below {probe}, which is a file")
    need = probe if probe != out else out.parent if replace_set else out
    if not os.access(need, os.W_OK | os.X_OK) or (out.exists() and not os.access(out, os.W_OK | os.X_OK)):
        raise OutputError(f"{out}: output folder is not writable (no write permission on {need})")
    if replace_set and out.is_dir() and any(out.iterdir()) and not (out / MARKER).exists():
        raise OutputError(f"{out}: exists and holds files that are not a jointid output set; the set replaces "
                          f"the whole folder, so give a new or empty folder (see jointid.io.outputset)")
    return out


def misfits(checks) -> list:
    """The entries of a ``results.json`` ``fit_checks`` list whose model does not fit its data
    (``fits`` false), apart from those of a polynomial stand-in beside a selected hysteretic law
    (``stand_in``): the rule behind identify's exit status and the report's misfit sentence."""
    return [c for c in checks or () if c.get("fits") is False and not c.get("stand_in")]
