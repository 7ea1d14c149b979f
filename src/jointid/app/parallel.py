"""Parallel work on dask.distributed: records of a campaign, campaigns of a study.

One engine for all parallel work.  :func:`map_tasks` calls a function on a list of
argument tuples and returns the results in the order of the list:

* ``jobs=1`` and no ``scheduler`` (the default): in this process, one after the other;
  dask is not even imported;
* ``jobs=N`` (``0``: one per core): a ``distributed.LocalCluster`` of ``N`` single-threaded
  worker processes on the loopback interface, started for the call and closed after it;
* ``scheduler="tcp://host:8786"``: the workers of an existing cluster (``dask scheduler``
  and ``dask worker``, or any cluster manager that gives a scheduler address).

A task receives plain arguments (paths, record specifications, settings, arrays) and
returns plain data; nothing is written to disk between the steps.  Results are placed
by their index, so they do not depend on the number of workers or on the order in which
the tasks finish.  Every task runs with single-threaded BLAS (see :mod:`jointid._blas`),
in a worker as in this process, so the floating-point results are bit-identical.

A worker that dies is replaced (the nanny restarts it) and its tasks run again on the
others: a task may be lost with ``ALLOWED_FAILURES`` workers before the run gives up.
A lost scheduler (the cluster's head killed or unreachable) is different: the tasks not yet
finished cannot be completed, and :func:`map_tasks` raises
:class:`~jointid.errors.ClusterLostError` with the number of tasks done, after the results
received so far were handed to ``on_result``.
"""

from __future__ import annotations

import logging
import os
import re
import sys
import time
from contextlib import contextmanager

from .._blas import single_threaded
from ..errors import ClusterLostError, SchedulerError

__all__ = ["map_tasks", "dask_client", "local_cluster", "progress_bar", "resolve_jobs", "check_scheduler",
           "parse_scheduler_address", "ALLOWED_FAILURES"]

#: Workers a task may lose (killed, out of memory) before the run stops with an error.
ALLOWED_FAILURES = 3

_INSTALL = "parallel work needs dask.distributed: pip install 'distributed>=2024.1'"


# ----------------------------------------------------------------------------------------------------------
# scheduler addresses: checked before any work, and before any output folder is made

#: Address schemes of dask.distributed's communication layer.
SCHEDULER_SCHEMES = ("tcp", "tls", "inproc", "ucx", "ws", "wss")

#: Seconds to resolve, connect to and hear the handshake of a scheduler (each step shares this budget).
PROBE_TIMEOUT = 8.0

_HOST = re.compile(r"^(?:\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9_](?:[A-Za-z0-9_.-]{0,251}[A-Za-z0-9_])?)$")


def parse_scheduler_address(address):
    """``(scheme, host, port)`` of a dask scheduler address, or :class:`~jointid.errors.SchedulerError`.

    ``tcp://host:port`` (``host:port`` alone is read as tcp; the port defaults to dask's 8786),
    ``tls://host:port``, ``ucx://``, ``ws://``, ``wss://`` and ``inproc://`` (a scheduler in
    this process).  The host is a name or an IP address (IPv6 in brackets); the port is 1 to 65535.
    """
    if not isinstance(address, str) or not address.strip():
        raise SchedulerError(f"scheduler address {address!r} is empty; give one like tcp://10.0.0.5:8786")
    text = address.strip()
    scheme, sep, rest = text.partition("://")
    if not sep:
        scheme, rest = "tcp", text
    scheme = scheme.lower()
    example = "tcp://10.0.0.5:8786"
    if scheme not in SCHEDULER_SCHEMES:
        raise SchedulerError(f"scheduler address {address!r}: scheme {scheme!r} is not one of dask's "
                             f"({', '.join(SCHEDULER_SCHEMES)}); give one like {example}")
    if scheme == "inproc":
        if not rest:
            raise SchedulerError(f"scheduler address {address!r}: inproc:// needs the scheduler's name in this process")
        return scheme, rest, None
    if "/" in rest or "?" in rest or "#" in rest:
        raise SchedulerError(f"scheduler address {address!r}: a scheduler address is scheme://host:port, without a "
                             f"path; give one like {example}")
    if rest.startswith("["):
        host, _, tail = rest.partition("]")
        host += "]"
        port_text = tail[1:] if tail.startswith(":") else (None if not tail else "?" + tail)
    elif rest.count(":") == 1:
        host, port_text = rest.split(":")
    elif ":" in rest:
        raise SchedulerError(f"scheduler address {address!r}: an IPv6 host goes in brackets, e.g. tcp://[::1]:8786")
    else:
        host, port_text = rest, None
    if not host or not _HOST.match(host):
        raise SchedulerError(f"scheduler address {address!r}: {host!r} is not a host name or IP address; give one "
                             f"like {example}")
    if port_text is None:
        port = 8786
    else:
        if not port_text.isdigit() or not 1 <= int(port_text) <= 65535:
            raise SchedulerError(f"scheduler address {address!r}: port {port_text!r} is not a number from 1 to 65535")
        port = int(port_text)
    return scheme, host, port


def _tls_context(address):
    from distributed.security import Security

    ctx = Security().get_connection_args("client").get("ssl_context")
    if ctx is None:
        raise SchedulerError(f"scheduler address {address!r}: tls:// needs the cluster's certificates in the dask "
                             f"configuration (distributed.comm.tls.ca-file, .client.cert and .client.key); none are set")
    return ctx


def _resolve(host, port, deadline, address):
    """``getaddrinfo`` with a deadline (it can block much longer on a name no DNS server answers for)."""
    import socket
    import threading

    box = {}

    def look_up():
        try:
            box["info"] = socket.getaddrinfo(host.strip("[]"), port, type=socket.SOCK_STREAM)
        except OSError as exc:
            box["error"] = exc

    t = threading.Thread(target=look_up, daemon=True)
    t.start()
    t.join(max(0.1, deadline - time.monotonic()))
    if "info" in box and box["info"]:
        return box["info"]
    why = f"({box['error']})" if "error" in box else "(no answer from the name service)"
    raise SchedulerError(f"cannot reach the dask scheduler at {address!r}: host name {host!r} cannot be resolved {why}")


def _recv_exact(sock, n, deadline):
    data = b""
    while len(data) < n:
        sock.settimeout(max(0.05, deadline - time.monotonic()))
        chunk = sock.recv(min(n - len(data), 65536))
        if not chunk:
            break
        data += chunk
    return data


def _probe(scheme, host, port, address, timeout):
    """Connect to a tcp or tls scheduler address and read the handshake a dask scheduler sends first.

    A dask comm frames every message as its length (8 bytes, little-endian), the number of
    frames, their lengths and the frames; the handshake is a small msgpack map with the keys
    ``compression``, ``python`` and ``pickle-protocol``.  Anything else (an HTTP service that
    waits for a request, a silent listener, other bytes) is not a dask scheduler.
    """
    import socket
    import struct

    deadline = time.monotonic() + timeout
    infos = _resolve(host, port, deadline, address)
    sock, error = None, None
    for family, kind, proto, _, sockaddr in infos:
        try:
            sock = socket.socket(family, kind, proto)
            sock.settimeout(max(0.05, deadline - time.monotonic()))
            sock.connect(sockaddr)
            break
        except OSError as exc:
            error = exc
            sock.close()
            sock = None
    if sock is None:
        why = "no answer" if isinstance(error, socket.timeout) else str(error)
        raise SchedulerError(f"cannot reach the dask scheduler at {address!r}: {why}; is the scheduler running and "
                             f"is its port open from here?")
    def not_dask(what="it answers with something else"):
        return SchedulerError(f"{address!r} is not a dask scheduler: something listens there but {what} (a dashboard "
                              f"or other HTTP port? a scheduler prints its address as 'Scheduler at:' when it starts)")

    try:
        if scheme == "tls":
            ctx = _tls_context(address)
            sock = ctx.wrap_socket(sock, server_hostname=host.strip("[]") if ctx.check_hostname else None)
        head = _recv_exact(sock, 8, deadline)
        if len(head) < 8:
            raise not_dask()
        (n,) = struct.unpack("<Q", head)
        if not 24 <= n <= 65536:
            raise not_dask()
        body = _recv_exact(sock, n, deadline)
        (n_frames,) = struct.unpack("<Q", body[:8]) if len(body) == n else (0,)
        if not 1 <= n_frames <= 16 or b"pickle-protocol" not in body:
            raise not_dask()
    except socket.timeout:
        raise not_dask(f"sent no dask handshake within {timeout:g} s") from None
    except OSError as exc:
        if isinstance(exc, SchedulerError):
            raise
        raise not_dask(f"the connection failed before a dask handshake ({exc})") from None
    finally:
        sock.close()


def check_scheduler(address, timeout=None):
    """Check a scheduler address before any work: its form, and that a dask scheduler answers there.

    tcp and tls addresses are probed: the host name resolved, a connection opened and the
    handshake a dask scheduler sends first read, all within ``timeout`` seconds (default
    :data:`PROBE_TIMEOUT`).  Other
    schemes are checked for form and for their communication backend.

    Returns
    -------
    str
        The address as dask takes it (``host:port`` gets ``tcp://``).

    Raises
    ------
    jointid.errors.SchedulerError
        With one line saying what is wrong.
    """
    scheme, host, port = parse_scheduler_address(address)
    timeout = PROBE_TIMEOUT if timeout is None else float(timeout)
    if scheme in ("tcp", "tls"):
        if scheme == "tls":
            _tls_context(address)
        _probe(scheme, host, port, address, timeout)
    elif scheme != "inproc":
        try:
            from distributed.comm.registry import get_backend

            get_backend(scheme)
        except Exception as exc:  # noqa: BLE001 - a missing optional backend (ucx-py, websockets)
            raise SchedulerError(f"scheduler address {address!r}: dask cannot speak {scheme}:// here ({exc})") from None
    return f"{scheme}://{host}" + ("" if port is None else f":{port}")


def resolve_jobs(jobs) -> int:
    """Number of workers for ``jobs`` (``0`` or negative: one per core)."""
    jobs = int(jobs)
    return jobs if jobs > 0 else (os.cpu_count() or 1)


class _LogProgress:
    """Progress as plain lines (every tenth of the work and at the end) for logs that are no terminal."""

    def __init__(self, total, desc, file):
        self.total, self.desc, self.file = total, desc, file
        self.n, self._next, self._t0 = 0, 0, time.perf_counter()

    def update(self, n=1):
        self.n += n
        if self.n >= self._next or self.n == self.total:
            elapsed = time.perf_counter() - self._t0
            pct = 100.0 * self.n / self.total if self.total else 100.0
            print(f"{self.desc}: {self.n}/{self.total} ({pct:.0f} %), {elapsed:.1f} s", file=self.file, flush=True)
            self._next = self.n + max(1, self.total // 10)

    def close(self):
        pass


class _NoProgress:
    def update(self, n=1):
        pass

    def close(self):
        pass


def progress_bar(total, desc, enabled=True, file=None):
    """A tqdm bar on a terminal, a line every tenth of the work otherwise, nothing when disabled."""
    file = sys.stderr if file is None else file
    if not enabled:
        return _NoProgress()
    if getattr(file, "isatty", lambda: False)():
        from tqdm.auto import tqdm

        return tqdm(total=total, desc=desc, file=file)
    return _LogProgress(total, desc, file)


@contextmanager
def dask_client(jobs=1, scheduler=None, timeout="20s"):
    """A ``distributed.Client``: on the cluster at ``scheduler``, or on a new local cluster.

    Parameters
    ----------
    jobs : int
        Worker processes of the local cluster (``0``: one per core); ignored with ``scheduler``.
    scheduler : str, optional
        Address of an existing scheduler, e.g. ``"tcp://10.0.0.5:8786"``.
    timeout : str or float, default "20s"
        How long to try to reach the scheduler.

    Raises
    ------
    jointid.errors.SchedulerError
        When the scheduler cannot be reached.
    ImportError
        When dask.distributed is not installed (with the install command).
    """
    try:
        from distributed import Client
    except ImportError as exc:  # pragma: no cover - distributed is a declared dependency
        raise ImportError(_INSTALL) from exc
    if scheduler:
        address = check_scheduler(scheduler)
        try:
            client = Client(address, timeout=timeout)
        except (OSError, TimeoutError) as exc:
            raise SchedulerError(f"cannot reach the dask scheduler at {scheduler!r}: {exc}") from exc
        except Exception as exc:  # noqa: BLE001 - whatever answers there, it is no usable scheduler
            raise SchedulerError(f"cannot use the dask scheduler at {scheduler!r}: {type(exc).__name__}: {exc}") from None
        lost = False
        try:
            yield client
        except ClusterLostError:
            lost = True
            raise
        finally:
            _close(client, quiet=lost)
        return
    with local_cluster(resolve_jobs(jobs)) as cluster, Client(cluster) as client:
        yield client


def _close(client, quiet=False):
    """Close a client; after a lost scheduler without the client's log of its reconnection attempts
    (a traceback on stderr that says nothing more than the ClusterLostError)."""
    log = logging.getLogger("distributed.client")
    disabled = log.disabled
    log.disabled = disabled or quiet
    try:
        if quiet:
            client.close(timeout=10)
        else:
            client.close()
    except Exception:  # noqa: BLE001 - closing a client of a lost cluster may fail in many ways
        if not quiet:
            raise
    finally:
        log.disabled = disabled


def local_cluster(n_workers: int, allowed_failures: int = ALLOWED_FAILURES):
    """A ``distributed.LocalCluster`` of single-threaded worker processes on the loopback interface.

    No dashboard; the scheduler's small HTTP server (health checks) takes a free loopback port.
    A task may take ``allowed_failures`` workers down with it and still be run again.

    The workers run without dask's statistical profiler (:data:`WORKER_CONFIG`): it samples the
    stack of the running task every 10 ms, CPU time taken from the numerical work. They also keep
    the C library's own heap policy: dask sets ``MALLOC_TRIM_THRESHOLD_=65536`` in a worker's
    environment, which switches glibc's adaptive mmap threshold off, so every array above
    128 KiB is mapped afresh and its pages faulted in again (about 9,000 page faults and 20 ms of
    system time per campaign of ``benchmarks/bench_study.py``, none in this process).
    """
    import logging

    import dask
    from distributed import LocalCluster

    with dask.config.set(WORKER_CONFIG):  # the nannies hand this configuration to their workers
        return LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True, host="127.0.0.1",
                            dashboard_address=None,
                            scheduler_kwargs={"dashboard_address": "127.0.0.1:0", "allowed_failures": allowed_failures},
                            silence_logs=logging.ERROR)


#: dask configuration of :func:`local_cluster`: its scheduler and nannies (threads of this process)
#: and its workers (on an existing cluster, set ``DASK_DISTRIBUTED__WORKER__PROFILE__ENABLED=False``,
#: ``DASK_DISTRIBUTED__ADMIN__TICK__INTERVAL=1s``, ``DASK_DISTRIBUTED__ADMIN__SYSTEM_MONITOR__INTERVAL=5s``
#: and ``DASK_DISTRIBUTED__WORKER__MEMORY__MONITOR_INTERVAL=500ms`` where the workers start, and start
#: them without ``MALLOC_TRIM_THRESHOLD_`` in their environment, e.g. ``dask worker`` without a nanny).
#:
#: The three intervals are dask's periodic callbacks, which wake a server's event loop thread and take
#: the GIL from the task: the event loop health check (every 20 ms by default, one per scheduler,
#: nanny and worker), the system monitor (500 ms, psutil) and the memory monitor (100 ms, in each
#: worker and its nanny).  With dask's defaults a two-worker local cluster spends about 45 ms of CPU
#: per second in this process (scheduler and nannies) and 17 ms per second in each worker's event loop,
#: idle or busy; with these, about 9 and 4.  The nanny still restarts a worker that runs out of memory
#: (checked every 500 ms), and an event loop blocked for more than 3 s is still reported.
WORKER_CONFIG = {"distributed.worker.profile.enabled": False,
                 "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,
                 "distributed.admin.tick.interval": "1s",
                 "distributed.admin.system-monitor.interval": "5s",
                 "distributed.worker.memory.monitor-interval": "500ms"}


#: What the last :func:`map_tasks` call of this process ran on (set when it returns):
#: ``executor`` ("in-process", "local cluster" or the scheduler's address), ``workers`` and
#: ``worker_cpu_s`` (CPU seconds the workers' processes spent during the tasks).
LAST_RUN: dict = {}


def _worker_cpu():
    return time.process_time()


def _cpu_of_workers(client):
    try:
        return client.run(_worker_cpu)
    except Exception:  # noqa: BLE001 - the times are information, never a reason to fail
        return {}


def _call(fn, args):
    return single_threaded(fn)(*args)


def map_tasks(fn, arglist, *, jobs=1, scheduler=None, client=None, progress=False, desc="tasks", on_result=None,
              on_lost=None, cleanup=None, files=None, chunk_size=None, min_items=2):
    """``[fn(*args) for args in arglist]``, in this process or on dask workers.

    Parameters
    ----------
    fn : callable
        A module-level function (workers import it by name); it should return plain data
        and report its own failures in it rather than raise.
    arglist : sequence of tuple
        Arguments of each call.
    jobs : int, default 1
        ``1``: in this process, without dask; ``N > 1``: a local cluster of ``N`` workers;
        ``0``: one worker per core.
    scheduler : str, optional
        Address of an existing dask scheduler (overrides ``jobs``).
    client : distributed.Client, optional
        An open client to use (overrides ``jobs`` and ``scheduler``).
    progress : bool
        Show the progress (a bar on a terminal, plain lines in a log).
    desc : str
        Label of the progress display.
    on_result : callable, optional
        ``on_result(index, result)`` as each call finishes (in the order they finish).
    on_lost : callable, optional
        ``on_lost(index, message)`` gives the result of a task that could not be completed on
        the workers (it took ``ALLOWED_FAILURES`` workers down with it, or raised); without it
        the run stops with that error.  ``on_result`` is not called for such a task.
    cleanup : callable, optional
        Called without arguments on every worker once the tasks are done (e.g. to remove what
        workers killed during the run left on their machines); a failure of it is ignored.
    files : sequence of path, optional
        Files the tasks read.  On an existing cluster (``scheduler`` or ``client``) every
        worker is asked first whether it sees them, with the sizes they have here
        (:func:`check_worker_files`): a worker on another machine without the shared folder
        stops the run before any task, not with every task failing at the end.
    chunk_size : int, optional
        Calls per dask task (default: :data:`CHUNKS_PER_WORKER` tasks per worker).  A task
        carries its calls' arguments once and returns their results together, so its fixed
        cost is shared; a task that fails is run again one call per task.
    min_items : int, default 2
        A local cluster (``jobs``) is started only for this many calls or more: fewer are run
        in this process, where they finish sooner than a cluster starts (same results).

    Returns
    -------
    list
        The results in the order of ``arglist``.
    """
    arglist = list(arglist)
    results = [None] * len(arglist)
    bar = progress_bar(len(arglist), desc, enabled=progress)
    try:
        if client is None and scheduler is None and (resolve_jobs(jobs) == 1 or len(arglist) < max(2, min_items)):
            for i, args in enumerate(arglist):
                results[i] = _call(fn, args)
                if on_result is not None:
                    on_result(i, results[i])
                bar.update()
            LAST_RUN.clear()
            LAST_RUN.update(executor="in-process", workers=1, worker_cpu_s=0.0)
            return results
        if client is not None:
            if files is not None:
                check_worker_files(client, files)
            _on_cluster(client, "client", fn, arglist, results, bar, on_result, on_lost, cleanup, chunk_size)
        else:
            with dask_client(min(resolve_jobs(jobs), len(arglist)), scheduler) as cl:
                if files is not None and scheduler is not None:
                    check_worker_files(cl, files)
                _on_cluster(cl, scheduler or "local cluster", fn, arglist, results, bar, on_result, on_lost, cleanup,
                            chunk_size)
        return results
    finally:
        bar.close()


def _file_sizes(paths):
    """Size of each file (``None``: not a readable file) as this process sees it."""
    out = []
    for p in paths:
        try:
            out.append(os.stat(p).st_size if os.path.isfile(p) and os.access(p, os.R_OK) else None)
        except OSError:
            out.append(None)
    return out


def check_worker_files(client, paths):
    """Refuse to start when a worker does not see ``paths`` as this process does.

    Every connected worker stats the files (by the same path, relative ones from its own
    working folder); a file missing there or of another size means the worker reads
    another folder than this process (no shared file system, another mount point).  A
    cluster without workers yet is not checked.

    Raises
    ------
    jointid.errors.RecordFileNotFoundError
        Naming the worker, the first file and how many files differ.
    """
    from ..errors import RecordFileNotFoundError

    paths = [str(p) for p in paths]
    if not paths:
        return
    here = _file_sizes(paths)
    try:
        views = client.run(_file_sizes, paths)
    except Exception as exc:  # noqa: BLE001 - a worker that cannot even answer
        raise SchedulerError(f"cannot ask the dask workers whether they see the input files: "
                             f"{type(exc).__name__}: {exc}") from None
    for worker, there in sorted(views.items()):
        bad = [i for i, (a, b) in enumerate(zip(here, there)) if a != b]
        if bad:
            i = bad[0]
            what = "does not exist there" if there[i] is None else f"has {there[i]} bytes there, {here[i]} here"
            raise RecordFileNotFoundError(
                f"the dask worker {worker} does not see the input files as this machine does: {paths[i]} {what} "
                f"({len(bad)} of {len(paths)} files differ); the workers read the files by the same path, so put the "
                f"folder on a file system shared at the same path on every worker, or run without --scheduler; "
                f"nothing was run")


def _on_cluster(client, executor, fn, arglist, results, bar, on_result, on_lost, cleanup, chunk_size=None):
    before = _cpu_of_workers(client)
    _gather(client, fn, arglist, results, bar, on_result, on_lost, chunk_size)
    after = _cpu_of_workers(client)
    _run_on_workers(client, cleanup)
    if executor == "client":
        executor = getattr(getattr(client, "scheduler", None), "address", None) or "dask client"
    LAST_RUN.clear()
    LAST_RUN.update(executor=executor, workers=len(after),
                    worker_cpu_s=float(sum(max(0.0, t - before.get(w, 0.0)) for w, t in after.items())))


def _run_on_workers(client, fn):
    if fn is None:
        return
    try:
        client.run(fn)
    except Exception:  # noqa: BLE001 - a cleanup never fails the run
        pass


def _scheduler_lost(client, exc) -> bool:
    """Whether a task failed because the client lost its scheduler (not because of the task)."""
    from concurrent.futures import CancelledError

    return isinstance(exc, CancelledError) or getattr(client, "status", "running") not in ("running", "newly-created")


#: Chunks per worker: enough for the last ones to balance the load, few enough that a task's
#: fixed cost (scheduling, transfer, a result's round trip) is small against its work.
CHUNKS_PER_WORKER = 8


def chunk_indices(n, workers, chunk_size=None, taper=False):
    """Consecutive index ranges covering ``range(n)``: ``chunk_size`` each, or ``CHUNKS_PER_WORKER``
    chunks per worker (at least one item each).

    With ``taper``, the chunks shrink towards the end of the list: none holds more than a share
    ``1 / (2 workers)`` of the items after it begins, down to one item.  The workers then finish
    together (the last chunks are short) instead of one waiting for the other's last full chunk,
    half a chunk on average: 2 s of a 35 s run of ``benchmarks/bench_study.py`` on two workers.
    """
    if n <= 0:
        return []
    if chunk_size is None:
        chunk_size = -(-n // max(1, min(n, CHUNKS_PER_WORKER * max(1, workers))))
    chunk_size = max(1, int(chunk_size))
    if not taper:
        return [list(range(a, min(n, a + chunk_size))) for a in range(0, n, chunk_size)]
    out, a = [], 0
    while a < n:
        size = min(chunk_size, max(1, -(-(n - a) // (2 * max(1, workers)))))
        out.append(list(range(a, a + size)))
        a += size
    return out


def _call_chunk(fn, chunk):
    """``[fn(*args) for args in chunk]`` with single-threaded BLAS set once for the chunk."""
    return single_threaded(lambda: [fn(*args) for args in chunk])()


def _gather(client, fn, arglist, results, bar, on_result, on_lost, chunk_size=None):
    """Run the calls in chunks; a chunk whose task failed (it took its workers down) is run again
    one call per task, so only the call that fails is lost."""
    from distributed import as_completed

    try:
        workers = len(client.scheduler_info().get("workers", {})) or 1
    except Exception:  # noqa: BLE001 - the number of workers only sets the chunk size
        workers = 1
    index = {}

    def submit(idx):
        fut = client.submit(_call_chunk, fn, [arglist[i] for i in idx], pure=False)
        index[fut.key] = idx
        return fut

    queue = as_completed([submit(idx) for idx in chunk_indices(len(arglist), workers, chunk_size,
                                                               taper=chunk_size is None and workers > 1)])
    n_done = 0
    for fut in queue:
        idx = index.pop(fut.key)
        try:
            out = fut.result()
        except Exception as exc:  # noqa: BLE001 - a lost task must not lose the others
            if _scheduler_lost(client, exc):
                address = getattr(getattr(client, "scheduler", None), "address", None) or "?"
                raise ClusterLostError(f"the dask cluster was lost (no answer from its scheduler at {address}) after "
                                       f"{n_done} of {len(arglist)} tasks; nothing was written: run the same command "
                                       f"again", n_done, len(arglist)) from None
            if len(idx) > 1:  # find the call that failed: each one alone
                for i in idx:
                    queue.add(submit([i]))
                continue
            if on_lost is None:
                raise
            out = None
            results[idx[0]] = on_lost(idx[0], f"{type(exc).__name__}: {exc}")
        else:
            for i, r in zip(idx, out):
                results[i] = r
                if on_result is not None:
                    on_result(i, r)
        finally:
            fut.release()
        n_done += len(idx)
        bar.update(len(idx))
