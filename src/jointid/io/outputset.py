"""Output sets: the files of one run, put in place as a whole, and the rules for ``--out``.

An output folder holds one complete run, never a mix, and a run never deletes or rewrites
what it did not create:

* The files of a set are written into a hidden temporary folder beside the output folder
  and moved into place once all are complete (:func:`output_set`): a reader sees the
  previous set or the new one.  A set interrupted by SIGKILL leaves a hidden
  ``.<name>.new.<pid>-<run id>.tmp`` folder, removed by the next run on the same folder once
  its process is gone.
* Each set carries a marker file (:data:`MARKER`, ``.jointid-run``): the run id on its first
  line, then ``kind=...`` (``identify``, ``import``, ``study``...) and the files it wrote.
  Only an earlier set *of the same kind*, holding nothing but the files it wrote, is
  replaced; a folder holding anything else (the user's files, a campaign, another kind of
  set) is refused with :class:`~jointid.errors.OutputError` before any work
  (:func:`check_output_folder`).
* A set whose files record their own paths (the demo's campaigns) is written in place
  (:func:`output_set_in_place`): the previous set waits beside it as
  ``.<name>.prev.<pid>-<run id>.tmp`` and comes back if the run fails, is interrupted or is
  killed (the next run restores it); the marker says ``state=writing`` until the set is complete.
* The output folder is never an input (a campaign, a study plan, an import's data folder)
  nor a folder that holds one: replacing it would destroy the input.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import threading
import time
import uuid
from pathlib import Path

from ..errors import JointidError, OutputError
from .results import MARKER, atomic_write
from .results import check_output_folder as _check_writable

__all__ = ["MARKER", "new_run_id", "read_marker", "marker_text", "check_output_folder", "check_command_output",
           "output_set", "output_set_in_place", "deferred_interrupt", "pid_alive", "remove_leftovers", "KINDS"]

#: Kinds of output set (the ``kind=`` line of the marker).
KINDS = ("identify", "import", "study", "demo", "public-data", "predict", "simulate", "update", "backbone")

#: Commands whose output folder is an output set, and how: ``(kind, replaced as a whole)``.
_COMMANDS = {"identify": ("identify", True), "import": ("import", True), "study": ("study", False),
             "demo": ("demo", True), "public-data": ("public-data", True), "predict": ("predict", True),
             "simulate": ("simulate", True), "update": ("update", True), "backbone": ("backbone", True)}


def new_run_id() -> str:
    """A run id: UTC time and a random suffix (``20261122T184501Z-3f9a1c``)."""
    return time.strftime("%Y%m%dT%H%M%SZ", time.gmtime()) + "-" + uuid.uuid4().hex[:6]


def pid_alive(pid: int) -> bool:
    """Whether a process of this id runs on this machine."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError, ValueError):
        return pid > 0
    return True


def marker_text(run_id: str, kind: str, files=(), **info) -> str:
    """The marker of a set: the run id, ``kind=...``, ``key=value`` lines, then ``file=...`` lines."""
    lines = [run_id, f"kind={kind}"] + [f"{k}={v}" for k, v in info.items()]
    lines += [f"file={f}" for f in sorted(files)]
    return "\n".join(lines) + "\n"


def read_marker(folder) -> dict | None:
    """The marker of ``folder`` as a dict (``run_id``, ``kind``, ``files`` and other keys), or None.

    A marker of an earlier version holds only the run id: it was written by ``identify``.
    ``files`` is None when the marker does not list them.
    """
    path = Path(folder) / MARKER
    try:
        if not path.is_file():
            return None
        text = path.read_bytes()[:1 << 24].decode("utf-8", "replace")
    except OSError:
        return None
    lines = text.splitlines()
    if not lines or not lines[0].strip():
        return None
    out = {"run_id": lines[0].strip(), "kind": "identify", "files": None}
    files = []
    for line in lines[1:]:
        key, sep, value = line.partition("=")
        if not sep:
            continue
        if key == "file":
            files.append(value)
        else:
            out[key] = value
    if files or "kind" in {ln.partition("=")[0] for ln in lines[1:]}:
        out["files"] = files
    return out


def _resolved(p) -> Path:
    try:
        return Path(os.path.abspath(Path(p).expanduser())).resolve()
    except (OSError, RuntimeError) as exc:
        raise OutputError(f"{p}: cannot resolve the path ({exc})") from None


def _inside(a: Path, b: Path) -> bool:
    """Whether ``a`` is ``b`` or inside it."""
    return a == b or b in a.parents


def _check_inputs(out, inputs) -> None:
    """Refuse an output folder that is an input or holds one (the set would replace it)."""
    target = _resolved(out)
    for inp in inputs:
        if inp is None:
            continue
        p = _resolved(inp)
        if p == target:
            raise OutputError(f"{out}: is the input {inp} itself; the output would destroy it, so give another "
                              f"folder for --out")
        if _inside(p, target):
            raise OutputError(f"{out}: holds the input {inp}; the output would destroy it, so give a folder outside "
                              f"it for --out")
        if _inside(target, p) and p.is_dir() and target.is_dir():
            _check_campaign_files(out, target, p)


def _check_campaign_files(out, target: Path, folder: Path) -> None:
    """An output folder inside a campaign folder must not hold the campaign's own record files."""
    if not (folder / "campaign.toml").is_file():
        return
    try:
        from .campaign import load_campaign

        campaign = load_campaign(folder)
    except (JointidError, OSError):
        return  # the command itself reports a bad manifest
    for spec in campaign.records:
        path = getattr(spec, "path", None)
        if path is not None and _inside(_resolved(path), target):
            raise OutputError(f"{out}: holds the record file {spec.file} of the input campaign {folder}; the output "
                              f"would destroy it, so give another folder for --out")


def _check_content(out: Path, kind: str | None) -> None:
    """An existing non-empty folder may only be an earlier set of the same kind, holding only its own files."""
    if not out.is_dir():
        return
    try:
        entries = list(out.iterdir())
    except OSError as exc:
        raise OutputError(f"{out}: cannot list the output folder ({exc})") from None
    if not entries:
        return
    marker = read_marker(out)
    if marker is None:
        raise OutputError(f"{out}: exists and holds files that jointid did not write as an output set (no {MARKER} "
                          f"marker); the output set replaces the whole folder, so give a new or empty folder")
    if kind is not None and marker["kind"] != kind:
        raise OutputError(f"{out}: holds a jointid {marker['kind']} output set; a {kind} output never replaces or "
                          f"mixes with another kind, so give another folder")
    if marker["files"] is None:
        return  # a set of an earlier version: no list of its files
    own = set(marker["files"]) | {MARKER}
    extra = []
    for root, dirs, files in os.walk(out):
        rel = Path(root).relative_to(out)
        for name in files:
            f = (rel / name).as_posix()
            if f not in own:
                extra.append(f)
        if len(extra) > 5:
            break
    if extra:
        raise OutputError(f"{out}: holds files that its earlier {kind or marker['kind']} set did not write "
                          f"({', '.join(extra[:5])}{', ...' if len(extra) > 5 else ''}); the new set would delete "
                          f"them, so move them or give another folder")


def check_output_folder(out, kind: str | None = None, inputs=(), *, replace: bool = True) -> Path:
    """Refuse an output folder before any work starts.

    Parameters
    ----------
    out : path
        The output folder.
    kind : str, optional
        Kind of the set to be written (:data:`KINDS`); an existing set of another kind is refused.
    inputs : sequence of paths
        The run's inputs (campaign folder, plan, data folder): ``out`` may be none of them and
        hold none of them; inside a campaign folder it may not hold the campaign's records.
    replace : bool
        Whether the set replaces the whole folder (then an existing non-empty folder must be
        an earlier set of the same kind that holds only its own files).

    Raises
    ------
    OutputError
        Naming the path and what is wrong.
    """
    out = Path(out)
    if out.is_symlink() and not out.exists():
        raise OutputError(f"{out}: is a symbolic link to nothing (or a loop of links); give a real folder")
    _check_inputs(out, inputs)
    _check_writable(out, replace_set=False)
    if replace:
        parent = _resolved(out).parent
        if parent.exists() and not os.access(parent, os.W_OK | os.X_OK):
            raise OutputError(f"{out}: output folder is not writable (no write permission on {parent})")
        _check_content(out, kind)
    return out


def check_command_output(command: str, out, inputs=()) -> Path:
    """The check of ``jointid COMMAND ... --out OUT`` before the work (see :func:`check_output_folder`).

    ``identify`` and ``import`` write sets that replace the folder; ``study`` writes into a
    study folder (see :func:`jointid.app.study.check_study_folder`); any other command needs a
    writable folder that is not an output set.
    """
    if command not in _COMMANDS:  # writes into the folder: never into an output set (it would mix with it)
        if Path(out).is_symlink() and not Path(out).exists():
            raise OutputError(f"{out}: is a symbolic link to nothing (or a loop of links); give a real folder")
        _check_writable(out, replace_set=False)
        marker = read_marker(out) if Path(out).is_dir() else None
        if marker is not None:
            raise OutputError(f"{out}: holds a jointid {marker['kind']} output set; {command} would mix its files "
                              f"with it, so give another folder")
        return Path(out)
    kind, replace = _COMMANDS[command]
    if not replace:
        check_output_folder(out, kind, inputs, replace=False)
        return Path(out)
    return check_output_folder(out, kind, inputs, replace=True)


def remove_leftovers(out) -> None:
    """Temporary sets of earlier runs on ``out`` whose process is gone (killed mid-write)."""
    out = Path(out)
    dead = []
    for p in sorted(out.parent.glob(f".{out.name}.*-*.tmp")):
        try:
            stage, rest = p.name[len(out.name) + 2:].split(".", 2)[:2]
            pid = int(rest.split("-")[0])
        except (IndexError, ValueError):
            continue
        if not pid_alive(pid):
            dead.append((stage, p))
    writing = read_marker(out) if out.is_dir() else None
    if writing is not None and writing.get("state") == "writing" and not pid_alive(int(writing.get("pid", 0) or 0)):
        # an in-place set whose process is gone: incomplete, jointid's own; the previous set (if any) comes back
        shutil.rmtree(out, ignore_errors=True)
        for stage, p in dead:
            if stage == "prev" and not out.exists():
                os.replace(p, out)
    for stage, p in dead:
        if not p.exists():
            continue
        # killed between moving the old set aside and the new one in: the new set is complete
        # (its marker is written last), so it is put in place rather than lost with the old one
        if stage == "new" and not out.exists() and not out.is_symlink() and read_marker(p) is not None \
                and read_marker(p)["files"] is not None:
            os.replace(p, out)
            continue
        shutil.rmtree(p, ignore_errors=True)


@contextlib.contextmanager
def deferred_interrupt():
    """Hold back SIGINT (Ctrl-C) until the block ends, then raise KeyboardInterrupt.

    For the few renames that put a set in place: an interrupt then would leave a mix.
    Outside the main thread (where no handler can be set) the block runs as it is.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught = []
    previous = signal.signal(signal.SIGINT, lambda *a: caught.append(1))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
    if caught:
        raise KeyboardInterrupt


def _files_of(folder: Path) -> list:
    return sorted((Path(r).relative_to(folder) / f).as_posix() for r, _, fs in os.walk(folder) for f in fs
                  if not (r == str(folder) and f == MARKER))


@contextlib.contextmanager
def output_set(out, run_id=None, kind="identify", inputs=()):
    """Write a set of files into a temporary folder, then put it in place of ``out``.

    Yields the temporary folder.  ``out`` is checked first (:func:`check_output_folder` with
    ``kind`` and ``inputs``).  On success the marker (run id, kind, the files written) is
    added, the previous ``out`` (if any) is moved aside and removed, and the new set renamed
    to ``out``; on any error or interrupt the temporary folder is removed and ``out`` is left
    as it was.
    """
    out = Path(out)
    run_id = run_id or new_run_id()
    check_output_folder(out, kind, inputs)
    out.parent.mkdir(parents=True, exist_ok=True)
    remove_leftovers(out)
    tmp = out.parent / f".{out.name}.new.{os.getpid()}-{run_id}.tmp"
    tmp.mkdir()
    try:
        yield tmp
        atomic_write(tmp / MARKER, marker_text(run_id, kind, _files_of(tmp)))
        _check_content(out, kind)  # nothing else arrived in ``out`` while the set was written
        old = out.parent / f".{out.name}.old.{os.getpid()}-{run_id}.tmp"
        swapped = False
        try:
            with deferred_interrupt():
                if out.exists():
                    os.replace(out, old)
                os.replace(tmp, out)
                swapped = True
        except KeyboardInterrupt:
            if not swapped:
                raise
            shutil.rmtree(old, ignore_errors=True)
            raise KeyboardInterrupt(f"the new output set was complete and is in {out} (run id {run_id})") from None
        shutil.rmtree(old, ignore_errors=True)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


@contextlib.contextmanager
def output_set_in_place(out, run_id=None, kind="demo", inputs=()):
    """Write a set directly in ``out`` (for files that record their own paths), as a whole.

    Yields ``out``.  The checks are those of :func:`output_set`.  An earlier set of the same
    kind is moved aside first and removed once the new set is complete (its marker written
    last); on any error or interrupt the new files are removed and the earlier set is put
    back.  A run killed midway leaves a marker with ``state=writing`` and its process id: the
    next run on ``out`` removes that set and restores the earlier one.
    """
    out = Path(out)
    run_id = run_id or new_run_id()
    out.parent.mkdir(parents=True, exist_ok=True)
    remove_leftovers(out)
    check_output_folder(out, kind, inputs)
    prev = out.parent / f".{out.name}.prev.{os.getpid()}-{run_id}.tmp"
    with deferred_interrupt():
        if out.exists():
            os.replace(out, prev)
        out.mkdir()
        atomic_write(out / MARKER, marker_text(run_id, kind, (), state="writing", pid=os.getpid()))
    try:
        yield out
        atomic_write(out / MARKER, marker_text(run_id, kind, _files_of(out)))
    except BaseException:
        with deferred_interrupt():
            shutil.rmtree(out, ignore_errors=True)
            if prev.exists():
                os.replace(prev, out)
        raise
    shutil.rmtree(prev, ignore_errors=True)
