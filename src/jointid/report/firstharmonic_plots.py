"""Figures of a first-harmonic identification: measured vs re-predicted FRF per level, backbones of both tests."""

from __future__ import annotations

import numpy as np

from .identify_plots import new_axes

__all__ = ["plot_level_predictions", "plot_first_harmonic_backbones", "AMPLITUDE_LABEL"]

#: x label of a backbone against the stepped-sine controller's amplitude.
AMPLITUDE_LABEL = "first-harmonic acceleration amplitude at the driving point [m/s^2]"


def plot_level_predictions(predictions, title=None, ax=None):
    """Measured lines (points) and the amplitude and phase re-predicted from each line's measured force (lines).

    ``predictions``: :class:`~jointid.identify.firstharmonic.LevelPrediction` of each level;
    the legend gives each level's RMS errors.
    """
    axes = new_axes(ax, figsize=(7.0, 6.5), nrows=2, ncols=1)
    aa, ap = axes[0], axes[1]
    for pr in predictions:
        order = np.argsort(pr.frequency_hz)
        f = pr.frequency_hz[order]
        (pts,) = aa.plot(f, pr.accel_measured[order], "o", ms=3,
                         label=f"{pr.label}: {100 * pr.amplitude_rms_rel:.1f} % rms, {pr.phase_rms_deg:.1f} deg rms")
        aa.plot(f, pr.accel_predicted[order], "-", color=pts.get_color(), lw=1.2)
        ap.plot(f, np.degrees(np.unwrap(pr.phase_measured[order])), "o", ms=3, color=pts.get_color())
        ap.plot(f, np.degrees(np.unwrap(pr.phase_predicted[order])), "-", color=pts.get_color(), lw=1.2)
    aa.set_ylabel("acceleration amplitude [m/s^2]")
    ap.set_ylabel("phase of accelerance [deg]")
    ap.set_xlabel("frequency [Hz]")
    for a in (aa, ap):
        a.grid(True, alpha=0.3)
    aa.legend(fontsize="x-small", title="points: measured, lines: re-predicted", title_fontsize="x-small")
    if title:
        aa.set_title(title)
    from .figure_meta import mark_comparison

    mark_comparison(aa, "measured vs re-predicted first harmonics (measured force of each line)", "rms error")
    return aa.figure, (aa, ap)


def plot_first_harmonic_backbones(backbones, title=None, ax=None):
    """Backbones against the driving point's acceleration amplitude: the model with its 95 % band, the
    stepped-sine lines and the ring-downs, on one pair of axes (frequency above, damping below)."""
    from .backbone_plots import plot_backbones

    fig, axes = plot_backbones([b for b in backbones if b is not None and len(b)], ax=ax, title=title,
                               amplitude_unit="m/s^2")
    if axes is None:
        return fig, axes
    for a in axes:
        a.set_xlabel(AMPLITUDE_LABEL)
    return fig, axes
