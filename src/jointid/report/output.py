"""Write a :class:`~jointid.app.workflow.CampaignResult` to a folder: JSON, CSV, text and figures."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..identify.hysteresis import hysteresis_loop
from ..io.results import atomic_write, write_csv, write_json
from .html import Section, figure_to_png, write_html
from .identify_plots import new_axes, plot_damping_law, plot_hysteresis, plot_parameters_vs_frequency, plot_power_law
from .tables import group_rows, record_rows

__all__ = ["write_results", "campaign_figures", "campaign_sections", "slug"]


def slug(value) -> str:
    """A file-name-safe form of a grouping value."""
    return re.sub(r"[^A-Za-z0-9.+-]+", "_", str(value)).strip("_") or "none"


def write_results(result, out_dir, figures=True, html=True) -> dict:
    """Write ``results.json``, ``records.csv``, ``groups.csv``, ``damping_laws.csv``,
    ``report.txt``, PNG figures and a self-contained ``report.html``.

    Returns a dict of the written paths.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = {
        "results": write_json(out / "results.json", result.summary()),
        "records": write_csv(out / "records.csv", record_rows(result)),
        "groups": write_csv(out / "groups.csv", group_rows(result)),
        "report": atomic_write(out / "report.txt", result.report() + "\n"),
    }
    law_rows = [{"preload": p, **({f"c{k}": v for k, v in enumerate(l.coefficients)} if l else {})}
                for p, l in result.damping_laws.items()]
    cols = ["preload"] + [f"c{k}" for k in range(result.settings.damping_order + 1)]
    paths["damping_laws"] = write_csv(out / "damping_laws.csv", law_rows, cols)
    # each figure is rendered once; the same PNG bytes are written and embedded
    figs = [(n, c, figure_to_png(f, dpi=120)) for n, c, f in campaign_figures(result)] if (figures or html) else []
    if figures:
        paths["figures"] = [atomic_write(out / "figures" / name, png) for name, _, png in figs]
    if html:
        paths["html"] = out / "report.html"
        write_html(paths["html"], f"jointid: {result.name}", campaign_sections(result, figs),
                   intro=f"{len(result.records)} records, {len(result.failed)} failed.")
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
    records = Section("Records")
    records.tables.append(("records", record_rows(result), ["index", "file", "preload", "force_level", "frequency_hz",
                                                             "status", "q_max", "omega1", "k3", "c", "c_pooled",
                                                             "error"]))
    return [groups, laws, figures, records]


def campaign_figures(result) -> list:
    """``(file name, caption, figure)`` of the damping laws, power laws, per-record
    parameters and hysteresis loops (filtered and unfiltered) of a campaign result."""
    written = []
    preloads = list(result.damping_laws)
    for p in preloads:
        law = result.damping_laws[p]
        groups = [g for g in result.groups if g.preload == p]
        if law is not None:
            ax = new_axes()
            plot_damping_law(law, ax=ax, label=f"preload {p}")
            ax.set_title(f"damping law, preload {p}")
            written.append((f"damping_law_{slug(p)}.png", f"damping law c(q_max), preload {p}", ax.figure))
        laws = [g for g in groups if g.power_law is not None]
        if laws:
            ax = new_axes()
            for g in laws:
                plot_power_law(g.power_law, ax=ax, label=f"F = {g.force_level}")
            ax.set_title(f"energy per cycle, preload {p}")
            written.append((f"power_law_{slug(p)}.png", f"energy per cycle vs joint force, preload {p}", ax.figure))
        for g in groups:
            members = [r for r in result.records if r.ok and r.spec.group == (g.preload, g.force_level)]
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
            axes[0].set_title(f"per-record parameters, preload {p}, F = {g.force_level}")
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
            axes[0].set_title(f"hysteresis, {best.spec.file}")
            written.append((f"hysteresis_{tag}.png", f"hysteresis loops (filtered, unfiltered) of {best.spec.file}, "
                                                     f"preload {p}, F = {g.force_level}", axes[0].figure))
    return written
