"""Figures of the broadband and public-data-set identifications.

Every function takes an optional ``ax`` (or ``fig``) and returns what it drew on; nothing
is shown or saved here (save with :func:`jointid.io.results.atomic_savefig`).  Figures are
made with :class:`matplotlib.figure.Figure`, so no display is needed.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "new_figure",
    "plot_broadband_fit",
    "plot_gain_fit",
    "plot_restoring_force_surface",
    "plot_silverbox_levels",
    "plot_simulation_error",
]


def new_figure(nrows=1, ncols=1, figsize=(6.0, 4.0)):
    """A new constrained-layout figure and its axes (no pyplot state)."""
    from .figure_meta import ReportFigure

    fig = ReportFigure(figsize=figsize, layout="constrained")
    return fig, fig.subplots(nrows, ncols, squeeze=False)


def plot_broadband_fit(fit, ax=None, q=None, label=None, q_unit="unit of q"):
    """Identified stiffness curve ``h(q, 0) / m`` of a :class:`~jointid.identify.broadband.BroadbandFit`.

    Parameters
    ----------
    fit : BroadbandFit
    ax : matplotlib axes, optional
    q : array, optional
        Displacements at which to draw it (default ``±q_max`` of the fit).
    q_unit : str
        Unit of the response coordinate (``"m"``, or ``"V"`` for an electronic oscillator).
    """
    if ax is None:
        _, axes = new_figure()
        ax = axes[0, 0]
    qm = fit.q_max if np.isfinite(fit.q_max) else 1.0
    q = np.linspace(-qm, qm, 201) if q is None else np.asarray(q, float)
    h = fit.restoring_force(q, np.zeros_like(q)) / fit.mass
    ax.plot(q, h, "-", label=label or f"{' + '.join(fit.terms)}")
    lin = fit.get("omega1^2") / fit.mass if "omega1^2" in fit.coefficient_names else None
    if lin is not None:
        ax.plot(q, lin * q, "--", lw=0.8, color="0.5", label="linear part")
    ax.set_xlabel(f"q [{q_unit}]")
    ax.set_ylabel(f"h(q, 0) / m [{q_unit}/s²]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    return ax


def plot_gain_fit(fit, ax=None, q_unit="m"):
    """Per-record ``c/m`` and single-record ``omega1`` against amplitude for a :class:`~jointid.identify.gain.GainFit`.

    With ``ax`` given (a pair of axes), draws into them; otherwise makes a 1 x 2 figure.
    Returns the pair of axes.
    """
    if ax is None:
        _, axes = new_figure(1, 2, figsize=(9.0, 3.6))
        ax = axes[0]
    a0, a1 = ax[0], ax[1]
    qm = np.asarray(fit.q_max, float)
    if "c" in fit.own_names:
        cm, cs = fit.per_record("c")
        a0.errorbar(qm, cm, yerr=cs, fmt="o", capsize=2, label="each dwell, ± 1 standard error")
        for x, y, f in zip(qm, cm, fit.frequency_hz):
            a0.annotate(f"{f:g} Hz", (x, y), fontsize=7, xytext=(3, 3), textcoords="offset points")
        a0.axhline(0.0, color="0.6", lw=0.8)
        a0.set_ylabel("c / m [1/s]")
        a0.legend(fontsize=7)
    a0.set_xlabel(f"q_max [{q_unit}]")
    a0.grid(True, alpha=0.3)
    w = np.asarray(fit.omega1_per_record, float) / (2 * np.pi)
    a1.plot(qm, w, "o", label="each record alone (m, k3 fixed)")
    rms = float(np.sqrt(np.mean((w - fit.f1_hz) ** 2))) if w.size else float("nan")
    a1.axhline(fit.f1_hz, color="C1", label=f"pooled f1 = {fit.f1_hz:.4g} Hz, rms difference {rms:.2g} Hz")
    a1.set_xlabel(f"q_max [{q_unit}]")
    a1.set_ylabel("f1 [Hz]")
    a1.grid(True, alpha=0.3)
    a1.legend(fontsize=7)
    from .figure_meta import mark_comparison

    mark_comparison(a0, "pooled gain fit vs the single-dwell fits", "stderr bars", "rms error")
    return ax


def plot_restoring_force_surface(x, v, f, *, track=None, window=None, fig=None, x_label="relative displacement [m]",
                                 v_label="relative velocity [m/s]", f_label="restoring force / mass [m/s²]",
                                 frac=0.1, max_points=20000):
    """Restoring-force plots of a joint: stiffness and damping curves, surface and equivalent stiffness.

    Parameters
    ----------
    x, v, f : array
        Relative displacement, relative velocity and restoring force (same samples).
    track : EquivalentLinearTrack, optional
        Sliding-window equivalent stiffness, drawn against amplitude in the last panel.
    window : slice, optional
        Samples drawn (default all).
    fig : Figure, optional
    frac : float
        The stiffness curve uses the samples with ``|v| < frac max|v|``, the damping curve
        those with ``|x| < frac max|x|``.
    max_points : int
        Thinning of the scatter plots.

    Returns
    -------
    matplotlib.figure.Figure
    """
    if fig is None:
        fig, axes = new_figure(2, 2, figsize=(10.0, 7.5))
    else:
        axes = np.asarray(fig.subplots(2, 2, squeeze=False))
    sl = slice(None) if window is None else window
    x, v, f = (np.asarray(a, float)[sl] for a in (x, v, f))
    step = max(1, x.size // max_points)
    ax = axes[0, 0]
    s = np.abs(v) < frac * np.abs(v).max()
    ax.plot(x[s][::step], f[s][::step], ".", ms=2, alpha=0.5)
    ax.set_xlabel(x_label)
    ax.set_ylabel(f_label)
    ax.set_title(f"stiffness curve (|v| < {frac:g} max)", fontsize=9)
    ax.grid(True, alpha=0.3)
    ax = axes[0, 1]
    s = np.abs(x) < frac * np.abs(x).max()
    ax.plot(v[s][::step], f[s][::step], ".", ms=2, alpha=0.5, color="C1")
    ax.set_xlabel(v_label)
    ax.set_ylabel(f_label)
    ax.set_title(f"damping curve (|x| < {frac:g} max)", fontsize=9)
    ax.grid(True, alpha=0.3)
    ax = axes[1, 0]
    sc = ax.scatter(x[::step], v[::step], c=f[::step], s=2, cmap="coolwarm")
    fig.colorbar(sc, ax=ax, label=f_label)
    ax.set_xlabel(x_label)
    ax.set_ylabel(v_label)
    ax.set_title("restoring-force surface (colour = force)", fontsize=9)
    ax = axes[1, 1]
    if track is not None and track.t.size:
        sc = ax.scatter(track.amplitude, track.k, c=track.t, s=12, cmap="viridis")
        fig.colorbar(sc, ax=ax, label="window centre [s]")
        ax.set_xlabel("displacement amplitude in window [m]")
        ax.set_ylabel("equivalent stiffness / mass [1/s²]")
        ax.set_title("apparent stiffness against amplitude", fontsize=9)
    else:
        ax.set_axis_off()
    ax.grid(True, alpha=0.3)
    return fig


def plot_silverbox_levels(levels, f1_hz, f1_err, zeta, zeta_err, k3k, k3k_err, *, f_ref=None, zeta_ref=None, fig=None):
    """Natural frequency, damping ratio and ``k3/k`` against excitation level (three panels)."""
    if fig is None:
        fig, axes = new_figure(1, 3, figsize=(11.0, 3.4))
    else:
        axes = np.asarray(fig.subplots(1, 3, squeeze=False))
    lv = np.asarray(levels, float)
    for ax, y, e, ref, lab in (
        (axes[0, 0], f1_hz, f1_err, f_ref, "f1 [Hz]"),
        (axes[0, 1], 100 * np.asarray(zeta), 100 * np.asarray(zeta_err), None if zeta_ref is None else 100 * zeta_ref,
         "damping ratio [%]"),
        (axes[0, 2], k3k, k3k_err, None, "k3 / k [1/V²]"),
    ):
        from .figure_meta import mark_comparison

        mark_comparison(fig, "identified values per level vs the published reference", "stderr bars")
        ax.errorbar(lv, y, yerr=e, fmt="o-", capsize=2, label="identified, ± 1 standard error")
        if ref is not None:
            ax.axhline(ref, color="C3", lw=0.8, ls="--", label="reference")
            ax.legend(fontsize=8)
        ax.set_xscale("log")
        ax.set_xlabel("input level [mV RMS]")
        ax.set_ylabel(lab)
        ax.grid(True, alpha=0.3)
    return fig


def plot_simulation_error(t, y, y_sim, *, window=None, ax=None, unit_scale=1e3, unit="mV"):
    """Measured output and simulation error against time (e.g. the Silverbox arrow)."""
    if ax is None:
        _, axes = new_figure(figsize=(9.0, 3.6))
        ax = axes[0, 0]
    sl = slice(None) if window is None else window
    t, y, y_sim = (np.asarray(a, float)[sl] for a in (t, y, y_sim))
    ax.plot(t, unit_scale * y, lw=0.4, color="0.6", label="measured")
    ax.plot(t, unit_scale * (y - y_sim), lw=0.4, color="C3",
            label=f"error, RMS {unit_scale * np.sqrt(np.mean((y - y_sim) ** 2)):.3g} {unit}")
    ax.set_xlabel("time [s]")
    ax.set_ylabel(f"output [{unit}]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="upper left")
    from .figure_meta import mark_comparison

    mark_comparison(ax, "simulated vs measured output", "rms error")
    return ax
