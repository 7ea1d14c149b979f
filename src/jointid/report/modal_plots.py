"""Plots of the linear structure: mode shapes, FRFs (seed Fig 9), updating residuals.

Each function draws into given axes or a new figure and returns ``(fig, ax)``; nothing
is shown or saved, so any backend (including Agg) works.
"""

from __future__ import annotations

import numpy as np

__all__ = ["plot_mode_shapes", "plot_frf", "plot_update_residuals"]


def _new(ax, nrows=1, figsize=(6.4, 4.2), sharex=False):
    import matplotlib.pyplot as plt

    if ax is None:
        fig, ax = plt.subplots(nrows, 1, figsize=figsize, sharex=sharex, squeeze=True)
        return fig, ax
    axes = np.atleast_1d(ax)
    return axes[0].figure, ax


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
    ax.legend(loc="best", fontsize="small")
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
    show_coh = coherence and coh is not None
    n = 3 if show_coh else 2
    fig, axes = _new(ax, nrows=n, figsize=(6.4, 6.4 if show_coh else 5.0), sharex=True)
    axes = np.atleast_1d(axes)
    f = np.asarray(f)
    keep = f > 0 if f_max is None else (f > 0) & (f <= f_max)
    axes[0].semilogy(f[keep], np.abs(H[keep]), label=label or "H1")
    axes[1].plot(f[keep], np.degrees(np.angle(H[keep])))
    if fit is not None:
        Hs = fit.synthesize(f[keep])
        axes[0].semilogy(f[keep], np.abs(Hs), "--", color="C3", label="modal fit")
        for fr in fit.frequencies_hz:
            for a in axes[:2]:
                a.axvline(fr, color="C3", linestyle=":", linewidth=0.8)
    axes[0].set_ylabel("|H|")
    axes[1].set_ylabel("phase [deg]")
    if show_coh:
        axes[2].plot(f[keep], np.asarray(coh)[keep])
        axes[2].set_ylim(0, 1.05)
        axes[2].set_ylabel(r"$\gamma^2$")
    axes[-1].set_xlabel("frequency [Hz]")
    for a in axes:
        a.grid(True, alpha=0.3)
    axes[0].legend(loc="best", fontsize="small")
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
    ax.set_xlabel("mode")
    ax.set_ylabel(r"$f_{model}/f_{measured} - 1$ [%]")
    ax.set_title(", ".join(result.parameters), fontsize="small")
    ax.grid(True, axis="y", alpha=0.3)
    return fig, ax
