"""Figures of a structure model (``MODEL.toml``): its predicted responses, nonlinear modes and joint update.

:func:`plot_structure_frf` draws the first-harmonic amplitude of each response DOF against
frequency at each force level (dots: the located peaks) with the backbones dashed;
:func:`plot_backbones` the nonlinear modes' frequency and damping ratio against modal
amplitude; :func:`plot_update_fit` the measured first harmonics (error bars: one standard
error) beside the updated model's.  The predictions, backbones and fitted responses are
computed in ``app`` (:mod:`jointid.app.structure_predict`, :mod:`jointid.app.update_joint`)
and passed in; nothing is computed here.  Each function returns a new figure, drawn
without pyplot (no backend or global state needed).
"""

from __future__ import annotations

import numpy as np

from .figure_meta import ReportFigure

__all__ = ["plot_backbones", "plot_structure_frf", "plot_update_backbone", "plot_update_fit"]


def plot_structure_frf(prediction):
    """First-harmonic amplitude of each response DOF against frequency, one panel per DOF.

    Parameters
    ----------
    prediction : StructurePrediction
        Its ``model`` (``name``, ``response``), ``levels`` (failed ones skipped), ``backbones``
        (those with points drawn dashed) and ``unit(dof)``.

    Returns
    -------
    Figure
    """
    resp = prediction.model["response"]
    fig = ReportFigure(figsize=(7, 2.6 * len(resp) + 0.6))
    axes = fig.subplots(len(resp), 1, squeeze=False)
    ok = [lv for lv in prediction.levels if not lv.error]
    for ax, d in zip(axes[:, 0], resp):
        for lv in ok:
            line, = ax.plot(lv.frequency_hz, lv.amplitude[d], lw=1.2, label=f"F = {lv.force_level:g} N")
            pk = lv.peaks[d]
            if pk.get("peak_frequency_hz") is not None:  # none where the curve has no peak in the band
                ax.plot(pk["peak_frequency_hz"], pk["peak_amplitude"], "o", color=line.get_color(), ms=4)
        for b in prediction.backbones:
            if b.amplitude:
                ax.plot(b.frequency_hz, b.response_amplitude[d], "k--", lw=0.9, label=f"backbone, mode {b.mode}")
        ax.set_ylim(bottom=0.0, top=1.1 * max([max(lv.amplitude[d]) for lv in ok] or [1.0]))
        ax.set_ylabel(f"|{d}| first harmonic [{prediction.unit(d)}]")
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("frequency [Hz]")
    axes[0, 0].legend(fontsize=8)
    axes[0, 0].set_title(f"{prediction.model['name']}: multi-harmonic balance with continuation (dots: peaks)")
    fig.tight_layout()
    return fig


def plot_backbones(backbones, model_name):
    """Frequency and damping ratio of each nonlinear mode against its modal amplitude.

    Parameters
    ----------
    backbones : sequence of ModeBackbone
        Those without points are skipped.
    model_name : str
        The model's name, in the title.

    Returns
    -------
    Figure or None
        None when no backbone has points.
    """
    drawn = [b for b in backbones if b.amplitude]
    if not drawn:
        return None
    fig = ReportFigure(figsize=(9, 3.4))
    ax1, ax2 = fig.subplots(1, 2)
    for b in drawn:
        ax1.semilogx(b.amplitude, b.frequency_hz, lw=1.2, label=f"mode {b.mode}")
        ax2.semilogx(b.amplitude, b.damping_ratio, lw=1.2)
    ax1.set_ylabel("backbone frequency [Hz]")
    ax2.set_ylabel("damping ratio")
    for ax in (ax1, ax2):
        ax.set_xlabel("modal amplitude, first harmonic [kg$^{1/2}$ m]")  # mass-normalised modes
        ax.grid(alpha=0.3)
    ax1.legend(fontsize=8)
    fig.suptitle(f"{model_name}: nonlinear modes (extended periodic motion concept)", fontsize=10)
    fig.tight_layout()
    return fig


def plot_update_fit(measured, model, *, joint, law, response_units=None):
    """Measured first harmonics (± one standard error) and the updated model's, one curve per force level.

    Parameters
    ----------
    measured : MeasuredFRF
        ``force_level``, ``frequency_hz``, ``dof``, ``X`` (complex), ``se`` and ``levels()``.
    model : array_like of complex
        The updated model's first harmonic at each measured point.
    joint, law : str
        Named in the title.
    response_units : mapping, optional
        Unit of each response DOF (``m`` where not given).

    Returns
    -------
    Figure
    """
    units_of = dict(response_units or {})
    model = np.asarray(model)
    fig = ReportFigure(figsize=(7, 3.6))
    ax = fig.subplots()
    for lv in measured.levels():
        i = np.flatnonzero(measured.force_level == lv)
        o = i[np.argsort(measured.frequency_hz[i])]
        line, = ax.plot(measured.frequency_hz[o], np.abs(model[o]), "-", lw=1.1, label=f"F = {lv:g} N, fitted")
        ax.errorbar(measured.frequency_hz[o], np.abs(measured.X[o]), yerr=measured.se[o], fmt="o", ms=3,
                    color=line.get_color())
    ax.set_xlabel("frequency [Hz]")
    dofs = sorted(set(measured.dof))
    units = sorted({units_of.get(d, "m") for d in dofs})
    ax.set_ylabel(f"{', '.join(f'|{d}|' for d in dofs)} first harmonic [{', '.join(units)}]")
    ax.set_title(f"{joint}: updated {law} (dots: measured)")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return fig


def plot_update_backbone(backbones, *, joint, law, curves=None, response_units=None):
    """Measured backbones (± 1.96 standard errors) and the updated model's nonlinear mode.

    Parameters
    ----------
    backbones : sequence of (MeasuredBackbone, (frequency_hz, damping_ratio))
        Each measured backbone (``path``, ``dof``, ``amplitude``, ``frequency_hz``, ``se_frequency_hz``,
        ``damping_ratio``, ``se_damping_ratio``) with the model's values at its points.
    joint, law : str
        Named in the title.
    curves : sequence, optional
        Per backbone, ``(amplitude, frequency_hz, damping_ratio)`` of the model on a fine grid of
        amplitudes (drawn as its line; without it, the line joins the model's values at the points).
    response_units : mapping, optional
        Unit of each DOF's motion (``m`` where not given), for the amplitude axis.

    Returns
    -------
    Figure
    """
    units_of = dict(response_units or {})
    fig = ReportFigure(figsize=(7, 5.2))
    axf, axz = fig.subplots(2, 1, sharex=True)
    curves = list(curves) if curves is not None else [None] * len(backbones)
    for (bb, (f, z)), curve in zip(backbones, curves):
        o = np.argsort(bb.amplitude)
        a_line, f_line, z_line = (bb.amplitude[o], np.asarray(f)[o], np.asarray(z)[o]) if curve is None else curve
        name = str(bb.path).replace("\\", "/").rsplit("/", 1)[-1]
        line, = axf.plot(a_line, f_line, "-", lw=1.1, label=f"{name}: fitted")
        axf.errorbar(bb.amplitude[o], bb.frequency_hz[o], yerr=1.96 * bb.se_frequency_hz[o], fmt="o", ms=3,
                     color=line.get_color())
        axz.plot(a_line, 100 * np.asarray(z_line), "-", lw=1.1, color=line.get_color())
        axz.errorbar(bb.amplitude[o], 100 * bb.damping_ratio[o], yerr=196 * bb.se_damping_ratio[o], fmt="o", ms=3,
                     color=line.get_color())
    from matplotlib.ticker import NullFormatter

    axf.set_xscale("log")
    axz.xaxis.set_minor_formatter(NullFormatter())  # the minor labels of a short log axis overlap
    axf.set_ylabel("natural frequency [Hz]")
    axz.set_ylabel("damping ratio [%]")
    dofs = sorted({d for bb, _ in backbones for d in bb.dof})
    units = sorted({units_of.get(d, "m") for d in dofs})
    axz.set_xlabel(f"first-harmonic amplitude of {', '.join(dofs)} [{', '.join(units)}]")
    axf.set_title(f"{joint}: updated {law}, backbone (dots: measured, 95 %)")
    axf.legend(fontsize=8)
    for ax in (axf, axz):
        ax.grid(alpha=0.3)
    fig.tight_layout()
    return fig
