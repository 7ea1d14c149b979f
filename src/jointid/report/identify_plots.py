"""Figures of identification results (seed Figs 5, 6, 12-19).

Every function takes an optional ``ax`` and returns the axes it drew on; nothing is
shown or saved here.
"""

from __future__ import annotations

import numpy as np

from .formatting import label_with_unit

__all__ = [
    "new_axes",
    "plot_per_record",
    "plot_damping_law",
    "plot_power_law",
    "plot_hysteresis",
    "plot_parameters_vs_frequency",
]


def new_axes(ax=None, figsize=(6.0, 4.0), nrows=1, ncols=1):
    """Return ``ax`` or a new figure's axes (Agg-safe: no display needed)."""
    if ax is not None:
        return ax
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize, layout="constrained")
    axes = fig.subplots(nrows, ncols)
    return axes


def plot_per_record(pooled, name="c", ax=None, label=None, marker="o"):
    """Per-record coefficient of a pooled fit against ``q_max`` (seed Fig 12)."""
    ax = new_axes(ax)
    y = pooled.get(name)
    err = pooled.get_stderr(name)
    ax.errorbar(pooled.q_max, y, yerr=err, fmt=marker, ms=4, capsize=2, label=label)
    ax.set_xlabel(label_with_unit("q_max"))
    ax.set_ylabel(label_with_unit(name))
    ax.grid(True, alpha=0.3)
    return ax


def plot_damping_law(law, ax=None, label=None, color=None):
    """Per-record damping and the fitted ``c(q_max)`` (seed Figs 6, 13, 14)."""
    ax = new_axes(ax)
    q = np.asarray(law.q_max)
    err = law.c_stderr if np.all(np.isfinite(law.c_stderr)) else None
    pts = ax.errorbar(q, law.c, yerr=err, fmt="o", ms=4, capsize=2, color=color, label=f"{label or 'identified'}")
    qq = np.linspace(0, q.max() * 1.05, 200)
    ax.plot(qq, law(qq), "-", color=pts[0].get_color(), label=f"c(q_max), polynomial of order {law.order}")
    ax.set_xlabel("q_max [m]")
    ax.set_ylabel("c(q_max) [N s/m]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    return ax


def plot_power_law(law, ax=None, label=None):
    """Energy dissipated per cycle against joint force, log-log (seed Figs 15, 16)."""
    ax = new_axes(ax)
    pts = ax.loglog(law.force, law.energy, "o", ms=4, label=label or "records")
    FF = np.geomspace(law.force.min(), law.force.max(), 50)
    ax.loglog(FF, law(FF), "-", color=pts[0].get_color(), label=f"U = {law.alpha:.3g} F^{law.n:.3f}")
    ax.set_xlabel("joint force amplitude F [N] (modal)")
    ax.set_ylabel("energy per cycle U [J]")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    return ax


def plot_hysteresis(loop, ax=None, label=None, show_identified=True):
    """Nonlinear restoring force vs displacement, measured (full) and identified (dashed) (seed Figs 17-19)."""
    ax = new_axes(ax)
    kind = "filtered" if loop.filtered else "unfiltered"
    q = np.append(loop.q, loop.q[:1])
    m = np.append(loop.measured, loop.measured[:1])
    ax.plot(q, m, "-", lw=1.2, label=label or f"measured ({kind}) {loop.frequency_hz:.4g} Hz")
    if show_identified:
        i = np.append(loop.identified, loop.identified[:1])
        err = getattr(loop, "rms_difference", None)
        ax.plot(q, i, "--", lw=1.2, color="k",
                label="identified" + (f" (rms difference {100 * err:.1f} %)" if err is not None and np.isfinite(err)
                                      else ""))
    ax.set_xlabel("q [m] (modal)")
    ax.set_ylabel("Q - q'' - omega1² q [N] (modal)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    return ax


def plot_parameters_vs_frequency(frequency_hz, values: dict, exact: dict | None = None, axes=None):
    """Per-record identified coefficients against excitation frequency (seed Fig 5)."""
    names = list(values)
    if axes is None:
        axes = new_axes(None, figsize=(6.0, 2.2 * len(names)), nrows=len(names))
        axes = np.atleast_1d(axes)
    for ax, n in zip(axes, names):
        ax.plot(frequency_hz, values[n], "o", ms=3, label="identified")
        if exact and n in exact and exact[n] is not None:
            ax.axhline(exact[n], color="k", lw=0.8, ls="--", label="exact")
        ax.set_ylabel(n if "[" in n else label_with_unit(n))
        ax.grid(True, alpha=0.3)
        ax.set_xlabel("excitation frequency [Hz]")
    axes[0].legend(fontsize=8)
    return axes
