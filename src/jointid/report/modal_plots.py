"""Plots of the linear structure: mode shapes, FRFs (seed Fig 9), updating residuals.

Each function draws into given axes or a new figure and returns ``(fig, ax)``; nothing
is shown or saved, so any backend (including Agg) works.
"""

from __future__ import annotations

import numpy as np

__all__ = ["plot_mode_shapes", "plot_frf", "plot_update_residuals"]


def _new(ax, nrows=1, figsize=(6.4, 4.2), sharex=False):
    from .figure_meta import ReportFigure

    if ax is None:  # no pyplot: a figure written by a report is freed with its last reference
        fig = ReportFigure(figsize=figsize, layout="constrained")
        return fig, fig.subplots(nrows, 1, sharex=sharex, squeeze=True)
    axes = np.atleast_1d(ax)
    return axes[0].figure, ax


#: Unit of an FRF of each response quantity per newton of force.
_FRF_UNITS = {"acceleration": "(m/s²)/N", "velocity": "(m/s)/N", "displacement": "m/N"}


def wrapped_phase_deg(H):
    """Phase of ``H`` in degrees wrapped to ``(-180, 180]``, with NaN inserted where it jumps by
    more than 180 degrees (so that a line plot breaks at a wrap instead of drawing a vertical
    stroke across the panel).

    Returns
    -------
    (index, phase) : arrays
        Positions into the original samples (fractional for the inserted breaks) and phases.
    """
    ph = np.degrees(np.angle(np.asarray(H)))
    ph = np.where(ph <= -180.0, ph + 360.0, ph)
    idx = np.arange(ph.size, dtype=float)
    jumps = np.flatnonzero(np.abs(np.diff(ph)) > 180.0)
    if jumps.size:
        idx = np.insert(idx, jumps + 1, jumps + 0.5)
        ph = np.insert(ph, jumps + 1, np.nan)
    return idx, ph


def plot_mode_shapes(modal, modes=None, ax=None, *, n_points: int = 400, sensors=None, force_position=None):
    """Plot mode shapes along the beam.

    Parameters
    ----------
    modal : ModalModel
    modes : int or sequence of int, optional
        Zero-based mode indices (default the first three, or all if fewer).
    ax : matplotlib Axes, optional
    n_points : int
        Points per beam along ``x``; the two beams are drawn separately, so a joint
        shows as a kink or step.
    sensors : mapping name -> position, optional
        Sensor positions to mark.
    force_position : float, optional
        Force position to mark.

    Returns
    -------
    fig, ax
    """
    sel = modes
    if sel is None:
        sel = list(range(min(3, modal.n_modes)))
    elif np.ndim(sel) == 0:
        sel = [int(sel)]
    fig, ax = _new(ax)
    fe = modal.fe
    L = fe.length
    segments = [(0.0, L, "left")]
    if fe.joint_nodes is not None:
        xj = float(fe.node_x[fe.joint_nodes[0]])
        segments = [(0.0, xj, "left"), (xj, L, "right")]
    for k, r in enumerate(sel):
        color = f"C{k % 10}"
        for i, (a, b, side) in enumerate(segments):
            x = np.linspace(a, b, max(n_points // len(segments), 2))
            y = modal.shape_at(x, r, side=side)
            ax.plot(x, y, color=color, label=f"mode {r + 1}: {modal.frequencies_hz[r]:.2f} Hz" if i == 0 else None)
    if fe.joint_nodes is not None:
        ax.axvline(float(fe.node_x[fe.joint_nodes[0]]), color="0.6", linestyle=":", label="joint")
    if sensors:
        xs = [x for x in dict(sensors).values() if x is not None]
        ax.plot(xs, np.zeros(len(xs)), "v", color="k", linestyle="none", label="sensors")
    if force_position is not None:
        ax.plot([force_position], [0.0], "^", color="C3", linestyle="none", label="force")
    ax.axhline(0.0, color="0.8", linewidth=0.8)
    ax.set_xlabel("x [m]")
    ax.set_ylabel(r"mass-normalised $\varphi(x)$ [kg$^{-1/2}$]")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="center left", bbox_to_anchor=(1.01, 0.5), fontsize="small", frameon=False)
    return fig, ax


def plot_frf(frf, ax=None, *, channel: int = 0, fit=None, coherence: bool = True, label=None, f_max=None):
    """Plot an FRF estimate: magnitude, phase and (optionally) coherence.

    Parameters
    ----------
    frf : FRFEstimate or tuple (frequency_hz, H[, coherence])
    ax : sequence of Axes, optional
        Two or three axes (magnitude, phase[, coherence]).
    channel : int
        Output row of a multi-output estimate.
    fit : ModalFit, optional
        Overlay the fitted modes and mark their frequencies.
    coherence : bool
        Draw the coherence panel.
    label : str, optional
    f_max : float, optional
        Upper frequency limit [Hz].

    Returns
    -------
    fig, axes
    """
    if hasattr(frf, "frequency_hz"):
        f, H, coh = frf.frequency_hz, frf.H, frf.coherence
    else:
        f, H, *rest = frf
        coh = rest[0] if rest else None
    H = np.asarray(H)
    if H.ndim == 2:
        H = H[channel]
        coh = None if coh is None else np.asarray(coh)[channel]
    output = getattr(frf, "output", None) or getattr(fit, "output", None)
    unit = _FRF_UNITS.get(output, "response unit/N")
    show_coh = coherence and coh is not None
    n = 3 if show_coh else 2
    fig, axes = _new(ax, nrows=n, figsize=(6.4, 6.4 if show_coh else 5.0), sharex=True)
    axes = np.atleast_1d(axes)
    f = np.asarray(f)
    keep = f > 0 if f_max is None else (f > 0) & (f <= f_max)
    fk = f[keep]
    axes[0].semilogy(fk, np.abs(H[keep]), lw=0.8, label=label or "H1")

    def phase_line(ax, Hk, **kw):
        i, ph = wrapped_phase_deg(Hk)
        return ax.plot(np.interp(i, np.arange(fk.size), fk), ph, **kw)

    phase_line(axes[1], H[keep], lw=0.6, marker=".", ms=1.5)
    if fit is not None:
        Hs = fit.synthesize(fk)
        errs = np.asarray(getattr(fit, "fit_errors", ()), float)
        err_text = (f" (rms misfit in the fitted bands {100 * np.nanmax(errs):.2g} % at most)"
                    if errs.size and np.any(np.isfinite(errs)) else "")
        axes[0].semilogy(fk, np.abs(Hs), "--", color="C3", lw=1.0, label="modal fit" + err_text)
        phase_line(axes[1], Hs, ls="--", color="C3", lw=1.0)
        for band in np.atleast_2d(getattr(fit, "bands_hz", np.empty((0, 2)))):
            if band.size == 2:
                for a in axes[:2]:
                    a.axvspan(band[0], band[1], color="C3", alpha=0.08, lw=0)
        for fr in fit.frequencies_hz:
            for a in axes[:2]:
                a.axvline(fr, color="C3", linestyle=":", linewidth=0.8)
        if err_text:
            from .figure_meta import mark_comparison

            mark_comparison(fig, "modal fit vs measured H1 FRF", "rms error")
    axes[0].set_ylabel(f"|H| [{unit}]")
    axes[1].set_ylabel("phase [deg]")
    axes[1].set_ylim(-200, 200)
    axes[1].set_yticks([-180, -90, 0, 90, 180])
    if show_coh:
        axes[2].plot(fk, np.asarray(coh)[keep], lw=0.6)
        axes[2].set_ylim(0, 1.05)
        axes[2].set_ylabel(r"coherence $\gamma^2$ [1]")
    axes[-1].set_xlabel("frequency [Hz]")
    for a in axes:
        a.grid(True, alpha=0.3)
    axes[0].legend(loc="lower left", bbox_to_anchor=(0.0, 1.01), ncols=2, fontsize="small", frameon=False,
                   borderaxespad=0.0)
    return fig, axes


def plot_update_residuals(result, ax=None):
    """Bar chart of the per-mode relative frequency residuals of an updating result.

    Returns
    -------
    fig, ax
    """
    fig, ax = _new(ax)
    r = 100 * np.asarray(result.relative_residuals)
    modes = np.arange(1, r.size + 1)
    ax.bar(modes, r, color="C0")
    ax.axhline(0.0, color="k", linewidth=0.8)
    ax.set_xticks(modes)
    ax.set_xlabel("mode number [1]")
    ax.set_ylabel(r"$f_{model}/f_{measured} - 1$ [%]")
    from .figure_meta import mark_comparison

    mark_comparison(fig, "updated model vs measured natural frequencies", "error axis")
    ax.set_title(", ".join(result.parameters), fontsize="small")
    ax.grid(True, axis="y", alpha=0.3)
    return fig, ax
