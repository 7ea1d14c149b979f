"""Exception and warning classes of jointid.

Every error raised on bad input is a :class:`JointidError` and also subclasses the
built-in exception a caller would expect (``ValueError``, ``FileNotFoundError``...),
so ``except ValueError`` keeps working.  Messages say what was expected and what came,
and name the file, record and channel where there is one.
"""

from __future__ import annotations

__all__ = [
    "JointidError",
    "ManifestError",
    "RecordError",
    "RecordFileNotFoundError",
    "StructureError",
    "ConvergenceError",
    "IdentificationError",
    "OutputError",
    "SchedulerError",
    "ClusterLostError",
    "JointidWarning",
    "IllConditionedWarning",
    "ConvergenceWarning",
    "where",
    "unknown_key_message",
    "nearest_name",
]


def where(file=None, record=None, channel=None) -> str:
    """Format a location prefix such as ``"records/0003.csv [record 3, channel 'accel']: "``."""
    parts = []
    if record is not None:
        parts.append(f"record {record}")
    if channel is not None:
        parts.append(f"channel {channel!r}")
    head = str(file) if file is not None else ""
    if parts:
        head = f"{head} [{', '.join(parts)}]" if head else ", ".join(parts)
    return f"{head}: " if head else ""


def nearest_name(key, valid):
    """The valid name nearest to a misspelt ``key`` (:func:`difflib.get_close_matches`), or None."""
    import difflib

    close = difflib.get_close_matches(str(key), [str(v) for v in valid], n=1, cutoff=0.6)
    return close[0] if close else None


def unknown_key_message(key, valid, what="key") -> str:
    """``"unknown key 'frequncy_hz'; did you mean 'frequency_hz'? (valid: ...)"`` (:func:`nearest_name`)."""
    valid = sorted(str(v) for v in valid)
    close = nearest_name(key, valid)
    hint = f"; did you mean {close!r}?" if close else ""
    return f"unknown {what} {key!r}{hint} (valid: {', '.join(valid)})"


class JointidError(Exception):
    """Base class of every error raised by jointid."""


class ManifestError(JointidError, ValueError):
    """A campaign manifest (``campaign.toml``) or configuration file is invalid."""


class RecordError(JointidError, ValueError):
    """A measured or simulated record cannot be used (bad values, lengths, time base...)."""


class RecordFileNotFoundError(JointidError, FileNotFoundError):
    """A file named by a manifest does not exist."""


class StructureError(JointidError, ValueError):
    """A structural model (beam, joint, sensors, mode shapes) is invalid."""


class ConvergenceError(JointidError, RuntimeError):
    """An iterative solver (harmonic balance, shooting, updating) did not converge."""


class IdentificationError(JointidError, ValueError):
    """An identification step cannot be carried out with the data given."""


class OutputError(JointidError, OSError):
    """An output folder cannot be written (an existing file, below a file, read-only)."""


class SchedulerError(JointidError, ConnectionError):
    """The dask scheduler given for parallel work cannot be reached."""


class ClusterLostError(SchedulerError):
    """The dask cluster (its scheduler) was lost in the middle of the work: the run is incomplete.

    ``done`` and ``total`` count the tasks whose results were received.
    """

    def __init__(self, message, done=None, total=None):
        super().__init__(message)
        self.done, self.total = done, total


class JointidWarning(UserWarning):
    """Base class of jointid warnings."""


class IllConditionedWarning(JointidWarning):
    """A regression is too ill-conditioned to resolve some of its coefficients."""


class ExtrapolationWarning(JointidWarning):
    """A fitted law is used where the data do not support it (beyond its amplitudes, or unresolved)."""


class ConvergenceWarning(JointidWarning):
    """A solver stopped early but returned a usable result."""
