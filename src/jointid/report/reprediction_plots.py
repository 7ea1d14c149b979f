"""Re-predicted nonlinear FRFs over the measured points (seed Fig 10) for any campaign.

:func:`plot_reprediction` draws, for the groups of one preload, the measured points of
each force level (markers) and the identified model's harmonic-balance curve (line),
with the folds marked and the peak errors in the legend.
"""

from __future__ import annotations

import numpy as np

from .formatting import slug
from .identify_plots import new_axes

__all__ = ["plot_reprediction", "reprediction_rows", "reprediction_figures"]

_MARKERS = ("+", "o", "s", "^", "v", "D", "x")


def plot_reprediction(repredictions, ax=None, *, title=None, show_exact=True, gain_free=False):
    """Measured nonlinear FRF points and the re-predicted curves.

    The legend (outside the axes, clear of the peaks) gives each curve's rms error at the
    measured points and, where the dwells resolve the peak, the peak errors.

    Parameters
    ----------
    repredictions : sequence of Reprediction
        Typically the groups of one preload.
    ax : Axes, optional
    title : str, optional
    show_exact : bool
        Also draw an exact reference curve where a re-prediction carries one.
    gain_free : bool
        The force gain was identified: the levels are excitation amplitudes [V] and the FRF is
        the modal acceleration over the gain times the excitation.

    Returns
    -------
    Axes
    """
    ax = new_axes(ax, figsize=(9.0, 4.2))
    level_unit = "V" if gain_free else "N"
    rms_shown = False
    for i, r in enumerate(sorted(repredictions, key=lambda r: float(r.force_level))):
        pts = ax.plot(r.measured_frequency_hz, r.measured, _MARKERS[i % len(_MARKERS)], ms=5, ls="none",
                      label=f"measured, F = {r.force_level:g} {level_unit}")
        color = pts[0].get_color()
        pts_err = r.point_rms_error_percent
        label = "identified (HBM)" + (f": rms error at the dwells {pts_err:.2f} %" if pts_err is not None else "")
        rms_shown |= pts_err is not None
        if r.peak_resolved:
            label += (f",\npeak {r.peak_frequency_error_percent:+.3f} % in f, "
                      f"{r.peak_amplitude_error_percent:+.2f} % in |H|")
        ax.plot(r.frequency_hz, r.predicted, "-", lw=1.1, color=color, label=label)
        for f_fold in r.folds_hz:
            k = int(np.argmin(np.abs(r.frequency_hz - f_fold)))
            ax.plot([r.frequency_hz[k]], [r.predicted[k]], "x", color=color, ms=7)
        if show_exact and r.exact is not None:
            ax.plot(r.exact.frequency_hz, np.abs(r.exact.H), ":", lw=0.9, color="0.35")
    ax.set_xlabel("excitation frequency [Hz]")
    if gain_free:
        ax.set_ylabel("|modal acceleration / (gain × excitation)| [1]")
    else:
        quantity = repredictions[0].quantity if repredictions else "|response / force|"
        unit = "[m/(s² N)]" if "force" in quantity and "acceleration" in quantity \
            else "[response unit / excitation unit]"
        ax.set_ylabel(quantity if "[" in quantity else f"{quantity} {unit}")
    if title:
        ax.set_title(title, fontsize=10)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, frameon=False)
    if rms_shown:
        from .figure_meta import mark_comparison

        mark_comparison(ax, "re-predicted (harmonic balance) vs measured nonlinear FRF", "rms error")
    return ax


def reprediction_rows(result) -> list:
    """One row per re-predicted group: peak errors, point errors, folds (for tables)."""
    rows = []
    for r in getattr(result, "repredictions", ()):
        rows.append({
            "preload": r.preload,
            "force_level": r.force_level,
            "forcing": r.forcing,
            "f_peak_predicted": r.peak_predicted[0],
            "f_peak_reference": r.peak_reference[0],
            "f_peak_error_%": r.peak_frequency_error_percent,
            "H_peak_error_%": r.peak_amplitude_error_percent,
            "points_rms_error_%": r.point_rms_error_percent,
            "reference": r.reference_kind,
            "folds_hz": ", ".join(f"{f:.4f}" for f in r.folds_hz),
        })
    for row in getattr(result, "loops", ()):
        for r in rows:
            if r["preload"] == row["preload"] and r["force_level"] == row["force_level"]:
                for key in ("filtered", "unfiltered"):
                    d = row.get(key) or {}
                    r[f"loop_rms_{key}"] = d.get("rms_difference")
    return rows


def reprediction_figures(result) -> list:
    """``(file name, caption, figure)``: the re-predicted FRFs of each preload, and the
    hysteresis loops of the groups whose force gain was identified (the others' loops are
    drawn with the campaign's figures); the loops are those the result carries
    (``hysteresis_loops``, formed in the identification)."""
    from .identify_plots import plot_hysteresis

    out = []
    reps = list(getattr(result, "repredictions", ()))
    for p in dict.fromkeys(r.preload for r in reps):
        mine = [r for r in reps if r.preload == p]
        gain_free = any(g.gain is not None for g in result.groups if g.preload == p)
        ax = plot_reprediction(mine, title=f"re-predicted nonlinear FRF, preload {str(p).replace('$', '')}",
                               gain_free=gain_free)
        out.append((f"reprediction_{slug(p)}.png",
                    f"nonlinear FRFs of preload {p}: measured dwells (markers) and the identified model solved by "
                    "harmonic balance (lines); legend: peak errors", ax.figure))
    for found in getattr(result, "hysteresis_loops", ()):
        if not found.gain_free:
            continue
        drawn = [loop for loop in (found.filtered, found.unfiltered) if not isinstance(loop, str)]
        if not drawn:
            continue
        axes = np.atleast_1d(new_axes(None, figsize=(9.0, 3.8), ncols=len(drawn)))
        for ax, loop in zip(axes, drawn):
            plot_hysteresis(loop, ax=ax, show_identified=True, gain_free=True)
            ax.set_title(f"{'filtered' if loop.filtered else 'unfiltered'}: rms difference "
                         f"{100 * loop.rms_difference:.1f} %", fontsize=8)
        out.append((f"hysteresis_{slug(found.preload)}_F{slug(found.force_level)}.png",
                    f"hysteresis loops (gain-free units) of {found.record.spec.file}, preload {found.preload}, "
                    f"level {found.force_level}", axes[0].figure))
    return out
