"""Predicted responses at new force levels (``jointid predict``): curves, peaks and their table.

:func:`plot_predictions` draws, for the predictions of one preload, ``q_max`` against
frequency of each force level (solid where stable, dashed where unstable), the folds and
the located peak with its 95 % interval, and the measured dwells of a fitted level (their
fundamental amplitude); an extrapolated level is marked in the legend.
:func:`prediction_rows` gives the table of peaks.  Nothing is computed here.
"""

from __future__ import annotations

import numpy as np

from .identify_plots import new_axes

__all__ = ["plot_predictions", "prediction_rows"]


def _level(pred) -> str:
    """``F = 14 N`` (the unit of the force levels when identify knew it)."""
    unit = getattr(pred, "force_level_unit", None)
    return f"F = {pred.force_level:g}" + (f" {unit}" if unit else "")


def _runs(mask):
    """Start and stop indices of the runs of True in ``mask``."""
    m = np.concatenate([[False], np.asarray(mask, bool), [False]])
    d = np.diff(m.astype(int))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def plot_predictions(predictions, ax=None, *, title=None):
    """``q_max`` against frequency of each prediction, with its peak and 95 % interval.

    Parameters
    ----------
    predictions : sequence of Prediction
        Typically the force levels of one preload (failed ones are skipped).
    ax : Axes, optional
    title : str, optional

    Returns
    -------
    Axes
    """
    ax = new_axes(ax, figsize=(7.5, 4.6))
    colours = [f"C{i % 10}" for i in range(len(predictions))]
    for pred, col in zip(predictions, colours):
        f = np.asarray(pred.frequency_hz, float)
        q = np.asarray(pred.q_max, float)
        if f.size == 0:
            continue
        stable = np.asarray(pred.stable, bool) if np.size(pred.stable) == f.size else np.ones(f.size, bool)
        label = _level(pred) + (" (extrapolated)" if pred.extrapolated else "")
        first = True
        for a, b in _runs(stable):
            ax.plot(f[a:b], q[a:b], color=col, lw=1.4, label=label if first else None)
            first = False
        for a, b in _runs(~stable):  # joined to the stable points on either side
            s = slice(max(a - 1, 0), min(b + 1, f.size))
            ax.plot(f[s], q[s], color=col, lw=1.0, ls="--", label=(label + ", unstable") if first else None)
            first = False
        for fold in pred.folds_hz:
            k = int(np.argmin(np.abs(f - fold)))
            ax.plot([f[k]], [q[k]], marker="o", ms=3, mfc="none", color=col)
        if pred.measured is not None:
            ax.plot(pred.measured[0], pred.measured[1], ls="none", marker="o", ms=3.5, mfc="none", color=col,
                    label=f"{_level(pred)} measured (fundamental)")
        if pred.has_peak:
            xerr = yerr = None
            if np.isfinite(pred.peak_frequency_hz_stderr):
                xerr = 1.959963984540054 * pred.peak_frequency_hz_stderr
            if np.isfinite(pred.peak_q_max_stderr):
                yerr = 1.959963984540054 * pred.peak_q_max_stderr
            ax.errorbar([pred.peak_frequency_hz], [pred.peak_q_max], xerr=xerr, yerr=yerr, marker="x", ms=7,
                        color=col, capsize=3, lw=1.0)
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("q_max [m, modal]")
    ax.grid(True, alpha=0.3)
    if title:
        ax.set_title(title, fontsize=10)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
    return ax


def prediction_rows(predictions) -> list:
    """One row per prediction: preload, force level (its unit in the header when known), modal force, the model
    solved (polynomial terms or the hysteretic joint law), peak with 95 % intervals, flags."""
    from ..rounding import format_ci, format_pm, format_value

    rows = []
    for p in predictions:
        unit = getattr(p, "force_level_unit", None)
        row = {"preload": p.preload,
               f"force level [{unit}]" if unit else "force level": format_value(p.force_level),
               "modal force": format_value(p.modal_force), "model": getattr(p, "joint_law", "polynomial")}
        if p.error:
            row.update({"peak frequency [Hz]": "failed", "peak q_max [m]": p.error[:80]})
        elif not p.has_peak:
            row.update({"peak frequency [Hz]": "no peak in the band", "peak q_max [m]": "–"})
        else:
            row.update({
                "peak frequency [Hz]": format_pm(p.peak_frequency_hz, p.peak_frequency_hz_stderr, digits=7),
                "95 % interval [Hz]": format_ci(p.ci95("peak_frequency_hz"), p.peak_frequency_hz_stderr),
                "peak q_max [m]": format_pm(p.peak_q_max, p.peak_q_max_stderr),
                "95 % interval [m]": format_ci(p.ci95("peak_q_max"), p.peak_q_max_stderr),
            })
        row["folds [Hz]"] = ", ".join(format_value(f, 7) for f in p.folds_hz) or "none"
        row["extrapolated"] = "YES" if p.extrapolated else "no"
        row["amplitude beyond fitted"] = "YES" if p.amplitude_beyond_fitted else "no"
        rows.append(row)
    return rows
