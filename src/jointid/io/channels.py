"""The common in-memory form of a measured or simulated record: :class:`Channels`.

Every reader in :mod:`jointid.io` (UFF 58, MAT, HDF5 and the loaders of the public
data sets) returns a :class:`Channels`: one uniform time base shared by a set of
named 1-D signals, their units, the file they came from and free metadata.

A :class:`Channels` is validated when it is made (see :func:`validate_channels`), so a
record that exists is always usable: every channel is 1-D, finite and as long as the
time vector, and the time vector is strictly increasing and uniform.  The arrays are
stored as read-only ``float64`` copies (an array that is already read-only ``float64`` and
owns its data, as the readers return, is kept as it is: a long record is not held twice),
so a record cannot be changed in place; build a new one with :meth:`Channels.select`, :meth:`Channels.rename`, :meth:`Channels.with_channel`
or :func:`dataclasses.replace`.

Examples
--------
>>> import numpy as np
>>> from jointid.io.channels import Channels
>>> rec = Channels.from_arrays({"force": np.ones(4), "acc": np.zeros(4)}, fs=100.0,
...                            units={"force": "N", "acc": "m/s^2"})
>>> rec.names, rec.fs, rec.n_samples
(('force', 'acc'), 100.0, 4)
>>> rec["force"]
array([1., 1., 1., 1.])
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from jointid.errors import RecordError, where

__all__ = ["Channels", "merge_channels", "validate_channels", "TIME_RTOL", "MAX_SAMPLES"]

#: Largest allowed deviation of a time step from the mean step, relative to the mean step.
TIME_RTOL = 1e-6
#: Largest number of samples of one record (every reader checks it before loading the values).
MAX_SAMPLES = 20_000_000


#: Samples per block of the checks of :func:`validate_channels` (no temporary as long as the record).
BLOCK = 1 << 18


def _blocks(n: int, size: int = BLOCK):
    for start in range(0, n, size):
        yield slice(start, min(n, start + size))


def _readonly_float(values: Any) -> np.ndarray:
    if (isinstance(values, np.ndarray) and values.dtype == np.float64 and values.flags.owndata
            and not values.flags.writeable):
        return values  # already a read-only float64 array of its own: a copy would only double a long record
    arr = np.array(values, dtype=np.float64, copy=True)
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True, eq=False)
class Channels:
    """Named signals sampled on one uniform time base.

    Parameters
    ----------
    time : numpy.ndarray
        1-D time vector in seconds, strictly increasing and uniform (every step within
        ``TIME_RTOL`` = 1e-6 of the mean step).  At least two samples.
    data : dict of str to numpy.ndarray
        Channel name -> 1-D array with the same length as `time`.  The insertion order
        is the channel order.
    units : dict of str to str, optional
        Channel name -> unit string (SI, e.g. ``"m/s^2"``, ``"N"``, ``"V"``).  Channels
        without an entry get ``""`` (unknown).  Keys that are not channels are an error.
    source : str, optional
        The file (or folder) the record was read from, used in error messages.
    meta : dict, optional
        Free, preferably JSON-safe, metadata (data-set name, excitation, level...).

    Raises
    ------
    jointid.errors.RecordError
        If the record is not valid (see :func:`validate_channels`).

    Notes
    -----
    Arrays are copied to read-only ``float64``; equality is identity (``eq=False``),
    compare arrays explicitly.
    """

    time: np.ndarray
    data: dict[str, np.ndarray]
    units: dict[str, str] = field(default_factory=dict)
    source: str = ""
    meta: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        src = str(self.source)
        if not isinstance(self.data, Mapping):
            raise RecordError(
                f"{where(src)}expected the channel data as a mapping name -> array, "
                f"got {type(self.data).__name__}"
            )
        data: dict[str, np.ndarray] = {}
        for name, values in self.data.items():
            if not isinstance(name, str) or not name:
                raise RecordError(
                    f"{where(src)}expected channel names to be non-empty strings, got {name!r}"
                )
            if np.iscomplexobj(values):
                raise RecordError(
                    f"{where(src, channel=name)}expected real numbers, got complex values"
                )
            try:
                data[name] = _readonly_float(values)
            except (TypeError, ValueError) as exc:
                raise RecordError(
                    f"{where(src, channel=name)}expected real numbers, got values that "
                    f"cannot be converted to float64 ({exc})"
                ) from exc
        try:
            time = _readonly_float(self.time)
        except (TypeError, ValueError) as exc:
            raise RecordError(
                f"{where(src, channel='time')}expected real numbers, got values that "
                f"cannot be converted to float64 ({exc})"
            ) from exc
        units = {}
        for name, unit in dict(self.units or {}).items():
            if name not in data:
                raise RecordError(
                    f"{where(src, channel=name)}a unit was given for a channel that is not "
                    f"in the record; channels are {list(data)}"
                )
            units[name] = str(unit)
        for name in data:
            units.setdefault(name, "")
        object.__setattr__(self, "time", time)
        object.__setattr__(self, "data", data)
        object.__setattr__(self, "units", units)
        object.__setattr__(self, "source", src)
        object.__setattr__(self, "meta", dict(self.meta or {}))
        validate_channels(time, data, source=src)

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_arrays(
        cls,
        data: Mapping[str, Any],
        *,
        fs: float | None = None,
        time: Any | None = None,
        t0: float = 0.0,
        units: Mapping[str, str] | None = None,
        source: str = "",
        meta: Mapping[str, Any] | None = None,
    ) -> "Channels":
        """Build a record from arrays and either a sampling rate or a time vector.

        Parameters
        ----------
        data : mapping of str to array_like
            Channel name -> 1-D samples.
        fs : float, optional
            Sampling rate in Hz; the time vector is ``t0 + arange(n) / fs``.
        time : array_like, optional
            Explicit time vector in seconds (give `fs` or `time`, not both).
        t0 : float, optional
            Start time when `fs` is given.  Default 0.
        units, source, meta
            As in :class:`Channels`.

        Returns
        -------
        Channels

        Raises
        ------
        jointid.errors.RecordError
            If neither or both of `fs` and `time` are given, `fs` is not positive and
            finite, or the record is invalid.
        """
        if (fs is None) == (time is None):
            raise RecordError(
                f"{where(source or None)}expected exactly one of fs= or time=, got "
                f"{'both' if fs is not None else 'neither'}"
            )
        if time is None:
            fs_f = float(fs)  # type: ignore[arg-type]
            if not np.isfinite(fs_f) or fs_f <= 0:
                raise RecordError(
                    f"{where(source or None)}expected a positive finite sampling rate, got fs={fs!r}"
                )
            lengths = {np.size(v) for v in data.values()}
            n = lengths.pop() if len(lengths) == 1 else None
            if n is None:
                # let validation produce the detailed message
                first = next(iter(data.values()), np.empty(0))
                n = np.size(first)
            time = t0 + np.arange(n) / fs_f
        return cls(
            time=np.asarray(time),
            data=dict(data),
            units=dict(units or {}),
            source=source,
            meta=dict(meta or {}),
        )

    # ------------------------------------------------------------------ properties
    @property
    def names(self) -> tuple[str, ...]:
        """Channel names in order."""
        return tuple(self.data)

    @property
    def n_samples(self) -> int:
        """Number of samples per channel."""
        return int(self.time.size)

    @property
    def dt(self) -> float:
        """Mean time step in seconds, ``(t[-1] - t[0]) / (n - 1)``."""
        return float((self.time[-1] - self.time[0]) / (self.time.size - 1))

    @property
    def fs(self) -> float:
        """Sampling rate in Hz, ``1 / dt``."""
        return 1.0 / self.dt

    @property
    def t0(self) -> float:
        """Time of the first sample in seconds."""
        return float(self.time[0])

    @property
    def duration(self) -> float:
        """Record length ``n * dt`` in seconds."""
        return self.n_samples * self.dt

    # ------------------------------------------------------------------ access
    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self.data[name]
        except KeyError:
            raise KeyError(
                f"{where(self.source or None, channel=name)}no such channel; "
                f"channels are {list(self.data)}"
            ) from None

    def __contains__(self, name: object) -> bool:
        return name in self.data

    def __iter__(self) -> Iterator[str]:
        return iter(self.data)

    def __len__(self) -> int:
        return len(self.data)

    def __repr__(self) -> str:
        chans = ", ".join(
            f"{n}[{u}]" if u else n for n, u in ((n, self.units.get(n, "")) for n in self.data)
        )
        return (
            f"Channels({chans}; n={self.n_samples}, fs={self.fs:.6g} Hz, "
            f"source={self.source!r})"
        )

    def as_array(self, names: Iterable[str] | None = None) -> np.ndarray:
        """Stack channels into an array of shape ``(n_channels, n_samples)`` (time last).

        Parameters
        ----------
        names : iterable of str, optional
            Channels to stack, in order; default all.

        Returns
        -------
        numpy.ndarray
        """
        names = self.names if names is None else tuple(names)
        return np.vstack([self[n] for n in names]) if names else np.empty((0, self.n_samples))

    # ------------------------------------------------------------------ derived records
    def select(self, names: Iterable[str]) -> "Channels":
        """Return a record with only the given channels, in the given order."""
        names = list(names)
        for n in names:
            self[n]  # raises a KeyError naming the file and channel
        return dataclasses.replace(
            self,
            data={n: self.data[n] for n in names},
            units={n: self.units[n] for n in names},
        )

    def rename(self, mapping: Mapping[str, str]) -> "Channels":
        """Return a record with channels renamed by ``mapping`` (old -> new)."""
        for old in mapping:
            self[old]
        new_names = [mapping.get(n, n) for n in self.data]
        if len(set(new_names)) != len(new_names):
            raise RecordError(
                f"{where(self.source or None)}renaming would give duplicate channel names "
                f"{new_names}"
            )
        return dataclasses.replace(
            self,
            data={mapping.get(n, n): v for n, v in self.data.items()},
            units={mapping.get(n, n): u for n, u in self.units.items()},
        )

    def with_channel(self, name: str, values: Any, unit: str = "") -> "Channels":
        """Return a record with channel `name` added (or replaced)."""
        data = dict(self.data)
        data[name] = values
        units = dict(self.units)
        units[name] = unit
        return dataclasses.replace(self, data=data, units=units)

    def slice(self, start: int | None = None, stop: int | None = None) -> "Channels":
        """Return the samples ``start:stop`` (sample indices, like Python slicing)."""
        sl = slice(start, stop)
        return dataclasses.replace(
            self, time=self.time[sl], data={n: v[sl] for n, v in self.data.items()}
        )


def validate_channels(time: Any, data: Mapping[str, Any], *, source: str | None = None,
                      time_rtol: float = TIME_RTOL) -> None:
    """Check that a time vector and channels form a usable record.

    Checks, in order: the time vector is 1-D with at least two finite samples; it is
    strictly increasing and uniform (every step within ``TIME_RTOL`` = 1e-6 of the mean
    step, relative); every channel is 1-D, as long as the time vector and finite.

    Parameters
    ----------
    time : array_like
        Time vector in seconds.
    data : mapping of str to array_like
        Channel name -> samples.
    source : str, optional
        File the record came from, named in error messages.

    Raises
    ------
    jointid.errors.RecordError
        Naming the file and channel, what was expected and what came.

    Examples
    --------
    >>> import numpy as np
    >>> validate_channels(np.arange(3) * 0.1, {"x": [1.0, float("nan"), 2.0]}, source="a.csv")
    Traceback (most recent call last):
    ...
    jointid.errors.RecordError: a.csv [channel 'x']: expected finite values, got 1 non-finite value(s), first at sample 1 (nan)
    """
    src = source or None
    t = np.asarray(time, dtype=float)
    if t.ndim != 1:
        raise RecordError(
            f"{where(src, channel='time')}expected a 1-D time vector, got shape {t.shape}"
        )
    n = t.size
    if n < 2:
        raise RecordError(
            f"{where(src, channel='time')}expected at least 2 samples, got {n}"
        )
    if not _all_finite(t):
        bad = ~np.isfinite(t)
        i = int(np.flatnonzero(bad)[0])
        raise RecordError(
            f"{where(src, channel='time')}expected finite times, got {int(bad.sum())} "
            f"non-finite value(s), first at sample {i} ({t[i]})"
        )
    dt = (t[-1] - t[0]) / (n - 1)
    worst, worst_dev = 0, -1.0
    for sl in _blocks(n - 1):  # the steps block by block: no temporary as long as the record
        steps = t[sl.start + 1 : sl.stop + 1] - t[sl]
        if np.any(steps <= 0):
            i = sl.start + int(np.flatnonzero(steps <= 0)[0])
            raise RecordError(
                f"{where(src, channel='time')}expected strictly increasing times, got "
                f"t[{i + 1}] = {float(t[i + 1]):.9g} s after t[{i}] = {float(t[i]):.9g} s"
            )
        dev = np.abs(steps - dt)
        j = int(np.argmax(dev))
        if dev[j] > worst_dev:
            worst, worst_dev = sl.start + j, float(dev[j])
    if worst_dev > time_rtol * dt:
        step = t[worst + 1] - t[worst]
        raise RecordError(
            f"{where(src, channel='time')}expected a uniform time step (within "
            f"{time_rtol:g} of dt = {dt:.9g} s), got step {step:.9g} s between "
            f"samples {worst} and {worst + 1}"
        )
    for name, values in data.items():
        v = np.asarray(values)
        if v.ndim != 1:
            raise RecordError(
                f"{where(src, channel=name)}expected a 1-D array of {n} samples, "
                f"got shape {v.shape}"
            )
        if v.size != n:
            raise RecordError(
                f"{where(src, channel=name)}expected {n} samples (length of the time "
                f"vector), got {v.size}"
            )
        if not np.issubdtype(v.dtype, np.number) or np.iscomplexobj(v):
            raise RecordError(
                f"{where(src, channel=name)}expected real numbers, got dtype {v.dtype}"
            )
        if not _all_finite(v):
            bad = ~np.isfinite(v)
            i = int(np.flatnonzero(bad)[0])
            raise RecordError(
                f"{where(src, channel=name)}expected finite values, got {int(bad.sum())} "
                f"non-finite value(s), first at sample {i} ({v[i]})"
            )


def _all_finite(x: np.ndarray) -> bool:
    """Whether every value is finite, block by block (no mask as long as the record)."""
    return all(bool(np.isfinite(x[sl]).all()) for sl in _blocks(x.size))


def merge_channels(records: Iterable[Channels], *, source: str | None = None) -> Channels:
    """Join records sampled on the same time base into one record.

    Parameters
    ----------
    records : iterable of Channels
        Records with the same number of samples and the same time vector (within
        ``TIME_RTOL`` of the time step); channel names must not repeat.
    source : str, optional
        ``source`` of the result; default the sources of the inputs joined by ``" + "``.

    Returns
    -------
    Channels
        Channels in input order, the time vector of the first record, and ``meta``
        merged left to right (later keys win).

    Raises
    ------
    jointid.errors.RecordError
        If the records differ in length or time, or a channel name repeats.
    """
    records = list(records)
    if not records:
        raise RecordError("expected at least one record to merge, got none")
    first = records[0]
    data: dict[str, np.ndarray] = {}
    units: dict[str, str] = {}
    meta: dict[str, Any] = {}
    for rec in records:
        if rec.n_samples != first.n_samples:
            raise RecordError(
                f"{where(rec.source or None)}expected {first.n_samples} samples like "
                f"{first.source!r}, got {rec.n_samples}"
            )
        dev = float(np.max(np.abs(rec.time - first.time)))
        if dev > TIME_RTOL * first.dt:
            raise RecordError(
                f"{where(rec.source or None, channel='time')}expected the time vector of "
                f"{first.source!r}, got one that differs by up to {dev:.3g} s"
            )
        for name in rec.names:
            if name in data:
                raise RecordError(
                    f"{where(rec.source or None, channel=name)}channel name already used by "
                    f"an earlier record"
                )
            data[name] = rec.data[name]
            units[name] = rec.units[name]
        meta.update(rec.meta)
    if source is None:
        source = " + ".join(dict.fromkeys(r.source for r in records if r.source))
    return Channels(time=first.time, data=data, units=units, source=source, meta=meta)
