"""Who ran what: versions, where the work ran, how long it took, which code and plan.

:func:`provenance` gives the ``provenance`` entry of ``results.json`` and ``study.json``.
:func:`code_fingerprint` is a hash of jointid's own source files, so two runs of different
code are told apart even when the version number did not change (a development checkout);
a study refuses to resume campaigns made by other code unless told to mix them.
"""

from __future__ import annotations

import hashlib
import os
import platform
import socket
import sys
import time
from functools import lru_cache
from pathlib import Path

from ..report.provenance_text import provenance_line  # noqa: F401 - re-exported

__all__ = ["code_fingerprint", "versions", "provenance", "RunClock", "attach_provenance"]


@lru_cache(maxsize=1)
def code_fingerprint() -> str:
    """16 hex digits of a SHA-256 over jointid's Python source files (relative names and bytes)."""
    root = Path(__file__).resolve().parents[1]
    h = hashlib.sha256()
    for p in sorted(root.rglob("*.py")):
        if "__pycache__" in p.parts:
            continue
        h.update(p.relative_to(root).as_posix().encode() + b"\0")
        h.update(p.read_bytes())
        h.update(b"\0")
    return h.hexdigest()[:16]


def _version(dist):
    from importlib import metadata

    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return None


def versions() -> dict:
    """Versions of jointid, numpy, scipy, dask, distributed and Python (``None``: not installed)."""
    from .. import __version__

    out = {"jointid": __version__}
    for dist in ("numpy", "scipy", "dask", "distributed"):
        out[dist] = _version(dist)
    out["python"] = platform.python_version()
    return out


class RunClock:
    """Wall and CPU time of this process since it was made (``stop()`` freezes them)."""

    def __init__(self):
        from .parallel import LAST_RUN

        LAST_RUN.clear()  # what map_tasks reports from now on belongs to this run
        self.wall0, self.cpu0 = time.perf_counter(), time.process_time()
        self.wall = self.cpu = None

    def stop(self):
        if self.wall is None:
            self.wall = time.perf_counter() - self.wall0
            self.cpu = time.process_time() - self.cpu0
        return self


def provenance(clock: RunClock, *, plan_fingerprint=None, run=None) -> dict:
    """The ``provenance`` entry: versions, host, where the work ran, times and fingerprints.

    ``run`` is what :func:`jointid.app.parallel.map_tasks` reports about its last call
    (``executor``: ``"in-process"``, ``"local cluster"`` or the scheduler's address;
    ``workers``; ``worker_cpu_s``: CPU seconds of the workers during the tasks).
    """
    from .parallel import LAST_RUN

    clock.stop()
    run = dict(LAST_RUN if run is None else run)
    worker_cpu = run.get("worker_cpu_s") or 0.0
    return {
        "versions": versions(),
        "code_fingerprint": code_fingerprint(),
        "plan_fingerprint": plan_fingerprint,
        "host": socket.gethostname(),
        "platform": platform.platform(),
        "pid": os.getpid(),
        "executor": run.get("executor", "in-process"),
        "workers": run.get("workers", 1),
        "wall_s": round(clock.wall, 3),
        "cpu_s": round(clock.cpu + worker_cpu, 3),
        "client_cpu_s": round(clock.cpu, 3),
        "worker_cpu_s": round(worker_cpu, 3),
        "started": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(time.time() - clock.wall)),
        "argv": list(sys.argv),
    }


def attach_provenance(result, clock: RunClock, **kw):
    """``result.provenance = provenance(clock, ...)``; not part of ``result.summary()`` (which
    holds the results only, the same on any machine); written into ``results.json`` /
    ``study.json`` by the writers."""
    try:
        object.__setattr__(result, "provenance", provenance(clock, **kw))
    except (AttributeError, TypeError):  # pragma: no cover - a result type without a __dict__
        pass
    return result
