"""Write a :class:`~jointid.app.workflow.CampaignResult` to a folder: JSON, CSV, text and figures.

The files of one run form a set: they are written into a temporary folder beside the output
folder and moved into place once all are complete (:func:`output_set`), so a reader sees the
previous set or the new one, never a mix, and files of an earlier run that the new one does
not write (figures of groups no longer present) are gone.  Each set carries a run id
(``results.json`` key ``run_id``, the reports).  Labels taken from a manifest are made safe
for file names (:func:`slug`), for matplotlib text (:func:`tex_safe`) and for spreadsheets
(see :func:`jointid.io.results.write_csv`).
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import re
import shutil
import time
import uuid
from pathlib import Path

import numpy as np

from ..identify.hysteresis import hysteresis_loop
from ..io.results import MARKER, atomic_write, check_output_folder, write_csv, write_json
from .html import Section, figure_to_png, write_html
from .identify_plots import new_axes, plot_damping_law, plot_hysteresis, plot_parameters_vs_frequency, plot_power_law
from .tables import group_rows, record_rows

__all__ = ["write_results", "campaign_figures", "campaign_sections", "slug", "tex_safe", "check_output_folder",
           "output_set", "new_run_id", "MARKER"]

#: Longest label kept in a file name (the rest is replaced by a hash of the whole label).
SLUG_MAX = 40


def slug(value) -> str:
    """A file-name-safe form of a grouping value: ASCII letters, digits and ``.+-_``, at most
    ``SLUG_MAX`` characters; a label that had to be changed gets a short hash of itself, so
    two different labels never share a file name.

    Examples
    --------
    >>> slug(120), slug("1.5 N"), slug("a/../b")[:6]
    ('120', '1.5_N', 'a_.._b')
    """
    text = str(value)
    safe = re.sub(r"[^A-Za-z0-9.+-]+", "_", text).strip("_.") or "none"
    if len(safe) > SLUG_MAX or safe != text.replace(" ", "_"):
        digest = hashlib.sha1(text.encode("utf-8", "surrogatepass")).hexdigest()[:8]
        safe = f"{safe[:SLUG_MAX]}_{digest}"
    return safe


def tex_safe(value) -> str:
    """A label for matplotlib text: ``$`` escaped so that it is not read as mathtext.

    Examples
    --------
    >>> print(tex_safe("$x^2$"))
    \\$x^2\\$
    """
    return str(value).replace("$", r"\$")


def new_run_id() -> str:
    """A run id: UTC time and a random suffix (``20261122T184501Z-3f9a1c``)."""
    return time.strftime("%Y%m%dT%H%M%SZ", time.gmtime()) + "-" + uuid.uuid4().hex[:6]


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _remove_leftovers(out: Path) -> None:
    """Temporary sets of earlier runs on ``out`` whose process is gone (killed mid-write)."""
    for p in out.parent.glob(f".{out.name}.*-*.tmp"):
        try:
            pid = int(p.name[len(out.name) + 2:].split(".", 2)[1].split("-")[0])
        except (IndexError, ValueError):
            continue
        if not _pid_alive(pid):
            shutil.rmtree(p, ignore_errors=True)


@contextlib.contextmanager
def output_set(out, run_id=None):
    """Write a set of files into a temporary folder, then put it in place of ``out``.

    Yields the temporary folder.  On success the previous ``out`` (if any) is moved aside and
    removed, and the new set renamed to ``out``; on any error or interrupt the temporary folder
    is removed and ``out`` is left as it was.  A set interrupted by SIGKILL leaves a hidden
    ``.<name>.new.<pid>-<run id>.tmp`` folder, removed by the next run on the same ``out``.
    """
    out = Path(out)
    run_id = run_id or new_run_id()
    check_output_folder(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    _remove_leftovers(out)
    tmp = out.parent / f".{out.name}.new.{os.getpid()}-{run_id}.tmp"
    tmp.mkdir()
    try:
        atomic_write(tmp / MARKER, run_id + "\n")
        yield tmp
        old = out.parent / f".{out.name}.old.{os.getpid()}-{run_id}.tmp"
        if out.exists():
            os.replace(out, old)
        os.replace(tmp, out)
        shutil.rmtree(old, ignore_errors=True)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def write_results(result, out_dir, figures=True, html=True) -> dict:
    """Write ``results.json``, ``records.csv``, ``groups.csv``, ``damping_laws.csv``,
    ``report.txt``, PNG figures and a self-contained ``report.html``, as one set.

    The set replaces ``out_dir`` as a whole once complete (see :func:`output_set`);
    ``results.json`` gets the run id under ``run_id``.

    Returns a dict of the written paths (in ``out_dir``).

    Raises
    ------
    OutputError
        When ``out_dir`` cannot be written (see :func:`check_output_folder`).
    """
    final = Path(out_dir)
    run_id = new_run_id()
    with output_set(final, run_id) as out:
        paths = _write_set(result, out, run_id, figures, html)
    return {k: ([final / Path(p).relative_to(out) for p in v] if isinstance(v, list) else final / Path(v).relative_to(out))
            for k, v in paths.items()}


def flagged_lines(result) -> list:
    """One line per flagged record (empty when none)."""
    flagged = [r for r in result.records if r.ok and getattr(r, "flags", ())]
    if not flagged:
        return []
    kept = "kept in" if getattr(result.settings, "keep_flagged", False) else "left out of"
    lines = [f"{len(flagged)} record(s) flagged by the plausibility checks ({kept} the pooled fits):"]
    lines += [f"  record {r.spec.index} ({r.spec.file}): " + "; ".join(f.report() for f in r.flags) for r in flagged]
    return lines


def _write_set(result, out, run_id, figures, html) -> dict:
    summary = result.summary()
    summary["run_id"] = run_id
    text = result.report() + "\n"
    if flagged_lines(result):
        text += "\n" + "\n".join(flagged_lines(result)) + "\n"
    text += f"\nrun id {run_id}\n"
    paths = {
        "results": write_json(out / "results.json", summary),
        "records": write_csv(out / "records.csv", record_rows(result)),
        "groups": write_csv(out / "groups.csv", group_rows(result)),
        "report": atomic_write(out / "report.txt", text),
    }
    law_rows = [{"preload": p, **({f"c{k}": v for k, v in enumerate(l.coefficients)} if l else {})}
                for p, l in result.damping_laws.items()]
    cols = ["preload"] + [f"c{k}" for k in range(result.settings.damping_order + 1)]
    paths["damping_laws"] = write_csv(out / "damping_laws.csv", law_rows, cols)
    # each figure is rendered once; the same PNG bytes are written and embedded
    # each figure is drawn once (PNG file and HTML); --no-figures skips them in both
    figs = [(n, c, figure_to_png(f, dpi=120)) for n, c, f in campaign_figures(result)] if figures else []
    if figures:
        paths["figures"] = [atomic_write(out / "figures" / name, png) for name, _, png in figs]
    if html:
        paths["html"] = out / "report.html"
        n_flagged = len(flagged_lines(result)[1:])
        write_html(paths["html"], f"jointid: {result.name}", campaign_sections(result, figs),
                   intro=f"{len(result.records)} records, {len(result.failed)} failed, {n_flagged} flagged. "
                         f"Run id {run_id}.")
    return paths


def campaign_sections(result, figs) -> list:
    """HTML sections of a campaign result: groups, laws, figures, failures."""
    groups = Section("Groups", ["Pooled regression over the records of each (preload, force level): shared omega1 "
                                "and k3, one damping coefficient per record; band averages of single-record fits."])
    groups.tables.append(("groups", group_rows(result), None))
    laws = Section("Damping laws and power laws")
    laws.tables.append(("c(q_max)", [{"preload": p, "law": l.report() if l else result.damping_law_errors.get(p)}
                                     for p, l in result.damping_laws.items()], None))
    laws.tables.append(("U = alpha F^n", [{"preload": g.preload, "force level": g.force_level,
                                           "alpha": g.power_law.alpha if g.power_law else None,
                                           "n": g.power_law.n if g.power_law else None,
                                           "n in [2, 3]": g.power_law.within_bounds if g.power_law else None}
                                          for g in result.groups], None))
    figures = Section("Figures", figures=[(caption, fig) for _, caption, fig in figs])
    flagged = flagged_lines(result)
    records = Section("Records", flagged if flagged else [])
    records.tables.append(("records", record_rows(result), ["index", "file", "preload", "force_level", "frequency_hz",
                                                             "status", "q_max", "omega1", "k3", "c", "c_pooled",
                                                             "error"]))
    from .reprediction_plots import reprediction_rows

    repred = Section("Re-prediction", ["Each group's identified model solved by harmonic balance at the group's "
                                       "forcing, against the measured dwells: peak frequency and magnitude errors, "
                                       "rms error at the measured points, and the rms difference between measured "
                                       "and identified hysteresis loops."])
    repred.tables.append(("re-predicted FRFs", reprediction_rows(result), None))
    return [groups, laws, repred, figures, records]


#: Most figures drawn for one campaign (a campaign of many groups would otherwise spend
#: minutes drawing figures nobody pages through); the tables and results.json hold every group.
MAX_FIGURES = 60


def campaign_figures(result, max_figures=MAX_FIGURES) -> list:
    """``(file name, caption, figure)`` of the damping laws, power laws, per-record
    parameters and hysteresis loops (filtered and unfiltered) of a campaign result;
    at most ``max_figures`` (preload by preload, group by group)."""
    written = []
    preloads = list(result.damping_laws)
    for p in preloads:
        if len(written) >= max_figures:
            break
        law = result.damping_laws[p]
        groups = [g for g in result.groups if g.preload == p]
        if law is not None:
            ax = new_axes()
            plot_damping_law(law, ax=ax, label=f"preload {tex_safe(p)}")
            ax.set_title(f"damping law, preload {tex_safe(p)}")
            written.append((f"damping_law_{slug(p)}.png", f"damping law c(q_max), preload {p}", ax.figure))
        laws = [g for g in groups if g.power_law is not None]
        if laws:
            ax = new_axes()
            for g in laws:
                plot_power_law(g.power_law, ax=ax, label=f"F = {tex_safe(g.force_level)}")
            ax.set_title(f"energy per cycle, preload {tex_safe(p)}")
            written.append((f"power_law_{slug(p)}.png", f"energy per cycle vs joint force, preload {p}", ax.figure))
        for g in groups:
            if len(written) + 2 > max_figures:
                break
            indices = set(g.record_indices)
            members = [r for r in result.records if r.spec.index in indices]
            if not members:
                continue
            tag = f"{slug(p)}_F{slug(g.force_level)}"
            f = np.array([r.signals.frequency_hz for r in members])
            summaries = [r.summary() for r in members]
            vals = {"f1 [Hz]": [d["f1_hz"] for d in summaries]}
            for name in ("k3", "c"):
                if all(d[name] is not None for d in summaries):
                    vals[name] = [d[name] for d in summaries]
            axes = plot_parameters_vs_frequency(f, vals)
            axes[0].set_title(f"per-record parameters, preload {tex_safe(p)}, F = {tex_safe(g.force_level)}")
            written.append((f"parameters_{tag}.png", f"per-record parameters, preload {p}, F = {g.force_level}",
                            axes[0].figure))
            if g.gain is not None:  # the force column is not a force: no loops in force units
                continue
            j = int(np.argmax([r.fit.q_max for r in members]))
            best = members[j]
            axes = new_axes(None, figsize=(9.0, 3.8), ncols=2)
            # the identified model of the group: shared omega1^2, k3 and this record's own damping
            theta = np.array([g.pooled.get(n) if n in g.pooled.shared_names else g.pooled.get(n)[j]
                              for n in best.fit.coefficient_names])
            for ax, filt in zip(axes, (True, False)):
                loop = hysteresis_loop(best.signals, best.fit.terms, theta, filtered=filt)
                plot_hysteresis(loop, ax=ax, show_identified=True)
            axes[0].set_title(f"hysteresis, {tex_safe(best.spec.file)}")
            written.append((f"hysteresis_{tag}.png", f"hysteresis loops (filtered, unfiltered) of {best.spec.file}, "
                                                     f"preload {p}, F = {g.force_level}", axes[0].figure))
    from .reprediction_plots import reprediction_figures

    written += reprediction_figures(result)
    return written
