"""First-harmonic records: what stepped-sine controllers export (one line per frequency).

A commercial stepped-sine controller (force-, response- or phase-resonance-controlled)
keeps, for every line it dwells on, the first harmonic of the force and of the
response: amplitude and phase.  Such a record has no time history.  In a campaign it is a
CSV file with one row per line::

    frequency_hz,force,force_phase,accel,accel_phase
    79.2,0.195,0.0,2.80,-0.0995
    ...

``frequency_hz`` [Hz]; ``force`` [N] and ``accel`` [m/s^2] are first-harmonic amplitudes
(positive); ``force_phase`` and ``accel_phase`` [rad] are their phases on a common
reference (only the difference matters).  ``accel`` is the acceleration at the driving
point.  The manifest entry says ``excitation = "first-harmonic"`` and may say how the test
was controlled, ``control = "force"`` (default), ``"response"`` or ``"phase-resonance"``;
tests of the three kinds may be mixed in one campaign.

:func:`read_first_harmonic_source` reads the columns of a lab export (MAT with any struct
layout, CSV, UFF 58 FRF datasets), :func:`first_harmonic_from_columns` checks them and
forms the record, :func:`write_first_harmonic_csv` and :func:`read_first_harmonic_record`
write and read the campaign file.  Every problem is a
:class:`~jointid.errors.RecordError` naming the file, the record and the column (and the
line where one value is at fault).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import RecordError, RecordFileNotFoundError, where

__all__ = ["FirstHarmonicRecord", "FH_COLUMNS", "FH_SOURCE_COLUMNS", "CONTROLS", "first_harmonic_from_columns",
           "read_first_harmonic_source", "read_first_harmonic_record", "write_first_harmonic_csv"]

#: Columns of a first-harmonic record file in a campaign.
FH_COLUMNS = ("frequency_hz", "force", "force_phase", "accel", "accel_phase")
#: Columns an import may map: the record's, or a complex FRF (``frf``, or ``frf_real`` and
#: ``frf_imag``: acceleration over force) with the force amplitude.
FH_SOURCE_COLUMNS = FH_COLUMNS + ("frf", "frf_real", "frf_imag")
#: Largest magnitude of a phase [rad] taken as a phase (unwrapped phases of a sweep stay far below it;
#: a larger value is a unit mistake or garbage, and its sine and cosine would be noise).
MAX_PHASE_RAD = 1e3
#: How a stepped-sine test was controlled (manifest key ``control``).
CONTROLS = ("force", "response", "phase-resonance")
#: Most lines in one record.
MAX_LINES = 1_000_000


@dataclass(frozen=True)
class FirstHarmonicRecord:
    """The lines of one first-harmonic record (one level of a stepped-sine test)."""

    frequency_hz: np.ndarray
    force: np.ndarray
    force_phase: np.ndarray
    accel: np.ndarray
    accel_phase: np.ndarray
    source: str = ""
    control: str = "force"

    def __len__(self):
        return int(self.frequency_hz.size)

    @property
    def frf(self) -> np.ndarray:
        """Accelerance ``A = accel / force`` of every line (complex, phase relative to the force)."""
        return self.accel / self.force * np.exp(1j * (self.accel_phase - self.force_phase))

    def columns(self) -> dict:
        return {k: getattr(self, k) for k in FH_COLUMNS}


def _vector(values, L, column) -> np.ndarray:
    x = np.asarray(values)
    if x.dtype == object or not np.issubdtype(x.dtype, np.number):
        raise RecordError(f"{L(column)}expected numbers, got {x.dtype} values")
    x = np.squeeze(x)
    if x.ndim == 0:
        x = x.reshape(1)
    if x.ndim != 1:
        raise RecordError(f"{L(column)}expected one value per line (a vector), got shape {x.shape}")
    if x.size > MAX_LINES:
        raise RecordError(f"{L(column)}{x.size} lines exceed the limit of {MAX_LINES}")
    return x


def first_harmonic_from_columns(cols: dict, source="", record=None, control="force") -> FirstHarmonicRecord:
    """Check the columns of one record and form it.

    Parameters
    ----------
    cols : dict
        ``frequency_hz`` and ``force`` (amplitude), with either ``accel`` (amplitude) and
        optionally ``accel_phase``, or a complex ``frf`` (or ``frf_real`` and ``frf_imag``);
        ``force_phase`` is optional (0).  Phases in rad.  A scalar ``force`` is the same
        force amplitude at every line (a nominal level).
    source : str
        File name, for messages.
    record : int, optional
        Record index, for messages.
    control : str
        One of :data:`CONTROLS`.

    Raises
    ------
    RecordError
        A missing column, values that are not finite, columns of different lengths, a
        frequency or an amplitude that is not positive; the message names the file, the
        record, the column and the first line at fault.
    """
    def L(column=None):
        return where(source or None, record, column)

    if control not in CONTROLS:
        raise RecordError(f"{L()}control must be one of {list(CONTROLS)}, got {control!r}")
    for need in ("frequency_hz", "force"):
        if need not in cols:
            raise RecordError(f"{L(need)}missing; a first-harmonic record needs frequency_hz, force "
                              f"and accel (with accel_phase) or frf; found {sorted(cols)}")
    has_accel = "accel" in cols
    has_frf = "frf" in cols or ("frf_real" in cols and "frf_imag" in cols)
    if has_accel == has_frf:
        raise RecordError(f"{L('accel')}give either accel (with accel_phase) or the complex FRF "
                          f"(frf, or frf_real and frf_imag), not {'both' if has_accel else 'neither'}; "
                          f"found {sorted(cols)}")
    if ("frf_real" in cols) != ("frf_imag" in cols):
        raise RecordError(f"{L('frf_imag')}frf_real and frf_imag come together; found {sorted(cols)}")
    f = _vector(cols["frequency_hz"], L, "frequency_hz").astype(float)
    n = f.size
    out = {"frequency_hz": f}

    def column(name, default=None, complex_ok=False):
        if name not in cols:
            return np.full(n, default, float)
        x = _vector(cols[name], L, name)
        if x.size == 1 and n > 1:
            x = np.full(n, x[0])
        if x.size != n:
            raise RecordError(f"{L(name)}has {x.size} values, frequency_hz has {n} lines")
        if np.iscomplexobj(x) and not complex_ok:
            raise RecordError(f"{L(name)}holds complex values; expected real numbers "
                              f"(a complex FRF goes in column 'frf')")
        return x

    force = column("force").astype(float)
    force_phase = column("force_phase", 0.0).astype(float)
    if has_accel:
        accel = column("accel").astype(float)
        accel_phase = column("accel_phase", 0.0).astype(float)
    else:
        frf = column("frf", complex_ok=True) if "frf" in cols else (
            column("frf_real").astype(float) + 1j * column("frf_imag").astype(float))
        frf = np.asarray(frf, complex)
        bad = ~np.isfinite(frf)
        if bad.any():
            raise RecordError(f"{L('frf')}value at frequency line {int(np.argmax(bad))} (from 0) is not finite")
        accel = np.abs(frf) * force
        accel_phase = np.angle(frf) + force_phase
    for name, x in (("frequency_hz", f), ("force", force), ("force_phase", force_phase), ("accel", accel),
                    ("accel_phase", accel_phase)):
        bad = ~np.isfinite(x)
        if bad.any():
            raise RecordError(f"{L(name)}value {float(x[bad][0])!r} at frequency line {int(np.argmax(bad))} (from 0) "
                              f"is not finite")
    for name, x in (("frequency_hz", f), ("force", force), ("accel", accel)):
        bad = x <= 0
        if bad.any():
            what = "frequency" if name == "frequency_hz" else "first-harmonic amplitude"
            raise RecordError(f"{L(name)}{what} {float(x[bad][0])!r} at frequency line {int(np.argmax(bad))} (from 0); "
                              f"expected a positive value")
    if has_accel and "accel_phase" not in cols:  # a phase of 0 on every line would be a wrong damping
        raise RecordError(f"{L('accel_phase')}missing; the acceleration amplitude needs its phase "
                          f"(accel_phase, in rad on the force's reference), or give the complex FRF; "
                          f"found {sorted(cols)}")
    for name, x in (("force_phase", force_phase), ("accel_phase", accel_phase)):
        bad = np.abs(x) > MAX_PHASE_RAD
        if bad.any():
            raise RecordError(f"{L(name)}phase {float(x[bad][0])!r} rad at frequency line {int(np.argmax(bad))} "
                              f"(from 0) is not a phase in radians (|phase| <= {MAX_PHASE_RAD:g}); for degrees "
                              "give unit = \"deg\"")
    if n < 1:
        raise RecordError(f"{L('frequency_hz')}no lines")
    out = {"frequency_hz": f, "force": force, "force_phase": force_phase, "accel": accel, "accel_phase": accel_phase}
    arrays = {}
    for k, v in out.items():
        v = np.array(v, float)
        v.setflags(write=False)
        arrays[k] = v
    return FirstHarmonicRecord(**arrays, source=str(source), control=control)


# ---------------------------------------------------------------------------- sources
_TOKEN = re.compile(r"^(?P<name>[A-Za-z]\w*)(?:\[(?P<index>-?\d+)\])?$")


def _mat_value(path: Path, loaded: dict, ref: str, column: str):
    """The value at ``ref`` in a loaded MAT file: ``a.b[2].c`` (fields, struct-array indices anywhere)."""
    from .matlab import _fields, _is_struct

    loc = where(path, channel=column)
    parts = ref.strip().split(".")
    walked = ""
    obj = loaded
    for k, part in enumerate(parts):
        m = _TOKEN.match(part.strip())
        if m is None:
            raise RecordError(f"{loc}expected a reference like 'name', 'struct.field' or 'struct.array[2].field', "
                              f"got {ref!r}")
        name, index = m.group("name"), m.group("index")
        if k == 0:
            if name not in loaded:
                have = sorted(v for v in loaded if not v.startswith("__"))
                raise RecordError(f"{loc}expected variable {name!r}, not in the file; variables are {have}")
            obj = loaded[name]
        else:
            if not _is_struct(obj) or name not in _fields(obj):
                have = _fields(obj) if _is_struct(obj) else f"a {type(obj).__name__}, not a struct"
                raise RecordError(f"{loc}expected field {name!r} in {walked!r}; {walked!r} has {have}")
            obj = getattr(obj, name)
        walked = f"{walked}.{name}" if walked else name
        if index is not None:
            arr = np.atleast_1d(np.asarray(obj, dtype=object) if not isinstance(obj, np.ndarray) else obj)
            i = int(index)
            if not -arr.size <= i < arr.size:
                raise RecordError(f"{loc}{walked!r} has {arr.size} elements; index {i} is out of range")
            obj = arr.ravel()[i]
            walked = f"{walked}[{i}]"
    if _is_struct(obj):
        raise RecordError(f"{loc}{ref!r} is a struct with fields {_fields(obj)}; expected numbers")
    arr = np.asarray(obj)
    if arr.dtype == object or not np.issubdtype(arr.dtype, np.number):
        what = ("text" if arr.dtype.kind in "SU" else "a cell array" if arr.dtype == object else
                "logical values" if arr.dtype == bool else f"dtype {arr.dtype}")
        raise RecordError(f"{loc}{ref!r} holds {what}; expected numbers")
    return obj


def _read_mat_columns(path: Path, channels: dict) -> dict:
    from .matlab import _check_path, _load

    path = _check_path(path)
    tops = sorted({re.split(r"[.\[]", ref.strip(), maxsplit=1)[0] for ref in channels.values()})
    loaded = _load(path, tops)
    return {col: _mat_value(path, loaded, ref, col) for col, ref in channels.items()}


def _read_csv_columns(path: Path, channels: dict, name=None, record=None, optional=()) -> dict:
    from .campaign import _decode
    from ..errors import ManifestError

    def loc(channel=None):
        return where(name if name is not None else path, record, channel)

    raw = path.read_bytes()
    try:
        text = _decode(raw, loc()[:-2], "CSV file")
    except ManifestError as exc:
        raise RecordError(str(exc)) from None
    lines = [ln for ln in text.splitlines() if ln.strip()]
    if not lines:
        raise RecordError(f"{loc()}empty file; expected a header row naming the columns")
    header = [h.strip() for h in lines[0].split(",")]
    missing = [src for col, src in channels.items() if src not in header and col not in optional]
    if missing:
        raise RecordError(f"{loc(missing[0])}missing column; found {header}")
    channels = {c: s for c, s in channels.items() if s in header}
    rows = []
    for j, ln in enumerate(lines[1:], start=1):
        cells = [c.strip() for c in ln.split(",")]
        if len(cells) != len(header):
            raise RecordError(f"{loc()}file line {j + 1} has {len(cells)} values, the header names {len(header)} "
                              f"columns")
        rows.append(cells)
    if not rows:
        raise RecordError(f"{loc()}no data rows below the header {header}")
    out = {}
    for col, src in channels.items():
        k = header.index(src)
        vals = []
        for j, r in enumerate(rows):
            try:
                vals.append(complex(r[k].replace("i", "j")) if col == "frf" else float(r[k]))
            except ValueError:
                raise RecordError(f"{loc(src)}file line {j + 2}: {r[k]!r} is not a number") from None
        out[col] = np.array(vals)
    return out


def _read_uff_columns(path: Path, channels: dict) -> dict:
    """Columns from UFF 58 datasets: the abscissa of an FRF or spectrum dataset is ``frequency_hz``."""
    from .uff import _candidates, _norm, open_uff

    uff, types = open_uff(path)
    try:
        sets = [(i, uff.read_sets(i)) for i, t in enumerate(types) if t == 58]
    except Exception as exc:
        raise RecordError(f"{where(path)}cannot parse the UFF file: {exc}") from exc
    if not sets:
        raise RecordError(f"{where(path)}expected datasets 58 (FRF or spectrum functions), got types {sorted(set(types))}")
    out, freq = {}, None
    for col, label in channels.items():
        if col == "frequency_hz":
            continue
        hits = [(i, d) for i, d in sets if _norm(label) in {_norm(c) for c in _candidates(d)}]
        if len(hits) != 1:
            have = [str(d.get("id1", "")).strip() for _, d in sets]
            raise RecordError(f"{where(path, channel=col)}expected one dataset labelled {label!r}, found "
                              f"{len(hits)}; datasets are {have}")
        i, d = hits[0]
        ftype = int(d.get("func_type", -1))
        if ftype == 1:
            raise RecordError(f"{where(path, record=i, channel=col)}dataset {label!r} is a time response; a "
                              f"first-harmonic record needs FRF or spectrum datasets (function type 4, 12 ...)")
        y = np.asarray(d.get("data"))
        x = np.asarray(d.get("x"), float)
        if x.size != y.size:
            raise RecordError(f"{where(path, record=i, channel=col)}{y.size} values but {x.size} abscissa values")
        if freq is None:
            freq = x
        elif freq.size != x.size or not np.allclose(freq, x, rtol=1e-9, atol=0):
            raise RecordError(f"{where(path, record=i, channel=col)}dataset {label!r} is on other frequency lines "
                              f"than the first dataset read")
        if col == "frf":
            out[col] = y.astype(complex)
        elif np.iscomplexobj(y):
            out[col] = np.abs(y) if col in ("force", "accel") else np.angle(y)
        else:
            out[col] = y.astype(float)
    if "frequency_hz" in channels and channels["frequency_hz"] not in ("", "abscissa", "x"):
        raise RecordError(f"{where(path, channel='frequency_hz')}in a UFF file the frequency lines are the "
                          f"datasets' abscissa; write frequency_hz = \"abscissa\" or leave it out")
    if freq is None:
        raise RecordError(f"{where(path)}no dataset selected; map frf (or accel) and force to dataset labels")
    out["frequency_hz"] = freq
    return out


def read_first_harmonic_source(path, channels: dict) -> dict:
    """Columns ``column -> values`` of one lab export, by its extension.

    ``channels`` maps record columns (:data:`FH_SOURCE_COLUMNS`) to what the file calls
    them: for MAT a variable or struct path, with indices into struct arrays anywhere
    (``"FRdata.ForceControl[2].amplitude"``); for CSV a column name (``frf`` may hold
    complex numbers such as ``1.5-0.2j``); for UFF 58 a dataset label (ID line 1 or LMS
    ``node:direction``) of an FRF dataset (``frf``, complex) or a spectrum (``force``: its
    modulus); the frequency lines are the datasets' abscissa.
    """
    from .campaign import check_regular_file

    path = Path(path)
    unknown = [c for c in channels if c not in FH_SOURCE_COLUMNS]
    if unknown:
        raise RecordError(f"{where(path, channel=unknown[0])}not a first-harmonic column; expected "
                          f"{list(FH_SOURCE_COLUMNS)}")
    check_regular_file(path, "source file")
    suffix = path.suffix.lower()
    if suffix == ".mat":
        return _read_mat_columns(path, channels)
    if suffix in (".csv", ".txt"):
        return _read_csv_columns(path, channels)
    if suffix in (".uff", ".unv", ".uff58"):
        return _read_uff_columns(path, channels)
    raise RecordError(f"{where(path)}unknown format {suffix!r} for a first-harmonic record; expected .mat, .csv "
                      f"or .uff")


def write_first_harmonic_csv(path, record: FirstHarmonicRecord) -> None:
    """Write a record as a campaign CSV (:data:`FH_COLUMNS`, full precision), atomically."""
    import io as _io

    from .results import atomic_write

    data = np.column_stack([np.asarray(getattr(record, k), float) for k in FH_COLUMNS])
    buf = _io.StringIO()
    np.savetxt(buf, data, delimiter=",", fmt="%.17g", header=",".join(FH_COLUMNS), comments="")
    atomic_write(path, buf.getvalue())


def read_first_harmonic_record(spec) -> FirstHarmonicRecord:
    """Read the first-harmonic record of a manifest entry (``excitation = "first-harmonic"``).

    Raises
    ------
    ManifestError, RecordFileNotFoundError, RecordError
        Naming the file, the record and the column.
    """
    from ..errors import ManifestError

    if spec.error:
        raise ManifestError(spec.error)
    path = spec.path
    loc = where(spec.file, spec.index)
    if not path.exists():
        raise RecordFileNotFoundError(f"{loc}record file not found ({path})")
    if not path.is_file():
        raise RecordError(f"{loc}expected a record file, got a folder or special file ({path})")
    if path.suffix.lower() not in (".csv", ".txt"):
        raise RecordError(f"{loc}a first-harmonic record in a campaign is a CSV file with columns "
                          f"{list(FH_COLUMNS)}; convert other exports with 'jointid import'")
    cols = _read_csv_columns(path, {c: c for c in FH_COLUMNS}, name=spec.file, record=spec.index,
                             optional=("force_phase",))  # force_phase: 0 when absent
    return first_harmonic_from_columns(cols, spec.file, spec.index, spec.extra.get("control", "force"))
