"""Write a :class:`~jointid.workflow.CampaignResult` to a folder: JSON, CSV, text and figures."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..identify.hysteresis import hysteresis_loop
from ..io.results import atomic_savefig, atomic_write, write_csv, write_json
from .identify_plots import new_axes, plot_damping_law, plot_hysteresis, plot_parameters_vs_frequency, plot_power_law
from .tables import group_rows, record_rows

__all__ = ["write_results", "write_figures", "slug"]


def slug(value) -> str:
    """A file-name-safe form of a grouping value."""
    return re.sub(r"[^A-Za-z0-9.+-]+", "_", str(value)).strip("_") or "none"


def write_results(result, out_dir, figures=True) -> dict:
    """Write ``results.json``, ``records.csv``, ``groups.csv``, ``report.txt`` and PNG figures.

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
    if figures:
        paths["figures"] = write_figures(result, out / "figures")
    return paths


def write_figures(result, fig_dir) -> list:
    """PNG figures: damping laws, power laws, hysteresis loops and per-record parameters."""
    fig_dir = Path(fig_dir)
    written = []
    preloads = list(result.damping_laws)
    for p in preloads:
        law = result.damping_laws[p]
        groups = [g for g in result.groups if g.preload == p]
        if law is not None:
            ax = new_axes()
            plot_damping_law(law, ax=ax, label=f"preload {p}")
            ax.set_title(f"damping law, preload {p}")
            written.append(atomic_savefig(ax.figure, fig_dir / f"damping_law_{slug(p)}.png", dpi=120))
        laws = [g for g in groups if g.power_law is not None]
        if laws:
            ax = new_axes()
            for g in laws:
                plot_power_law(g.power_law, ax=ax, label=f"F = {g.force_level}")
            ax.set_title(f"energy per cycle, preload {p}")
            written.append(atomic_savefig(ax.figure, fig_dir / f"power_law_{slug(p)}.png", dpi=120))
        for g in groups:
            members = [r for r in result.records if r.ok and r.spec.group == (g.preload, g.force_level)]
            if not members:
                continue
            tag = f"{slug(p)}_F{slug(g.force_level)}"
            f = np.array([r.signals.frequency_hz for r in members])
            vals = {"f1 [Hz]": [r.fit.omega1 / (2 * np.pi) for r in members]}
            if members[0].fit.k3 is not None:
                vals["k3"] = [r.fit.k3 for r in members]
            if members[0].fit.c is not None:
                vals["c"] = [r.fit.c for r in members]
            axes = plot_parameters_vs_frequency(f, vals)
            axes[0].set_title(f"per-record parameters, preload {p}, F = {g.force_level}")
            written.append(atomic_savefig(axes[0].figure, fig_dir / f"parameters_{tag}.png", dpi=120))
            best = max(members, key=lambda r: r.fit.q_max)
            axes = new_axes(None, figsize=(9.0, 3.8), ncols=2)
            theta = np.array(best.fit.coefficients)
            if "c" in best.fit.coefficient_names and best.c_pooled is not None:
                theta[best.fit.coefficient_names.index("c")] = best.c_pooled
            for ax, filt in zip(axes, (True, False)):
                loop = hysteresis_loop(best.signals, best.fit.terms, theta, filtered=filt)
                plot_hysteresis(loop, ax=ax, show_identified=True)
            axes[0].set_title(f"hysteresis, {best.spec.file}")
            written.append(atomic_savefig(axes[0].figure, fig_dir / f"hysteresis_{tag}.png", dpi=120))
    return written
