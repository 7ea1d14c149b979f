"""Plots of nonlinear frequency responses (the seed paper's Fig 4).

:func:`plot_frequency_response` is the plotting third of the response/plot trio:
:func:`jointid.simulate.hbm.frequency_response` returns a
:class:`~jointid.simulate.hbm.FrequencyResponse` whose ``plot()`` calls this function.
Stable parts are drawn solid, unstable parts dashed (open markers for sweeps), folds are
marked with crosses.  Works with any matplotlib backend, including Agg.
"""

from __future__ import annotations

import numpy as np

__all__ = ["plot_frequency_response"]

_QUANTITIES = {
    "q_max": ("q_max", r"$q_{\max}$ [m]"),
    "amplitude": ("amplitude", "fundamental amplitude [m]"),
    "phase": ("phase", "phase [rad]"),
}


def _runs(mask):
    """Contiguous runs ``(start, stop)`` of equal values of a boolean array."""
    if mask.size == 0:
        return []
    edges = np.flatnonzero(np.diff(mask.astype(np.int8))) + 1
    starts = np.concatenate(([0], edges))
    stops = np.concatenate((edges, [mask.size]))
    return list(zip(starts.tolist(), stops.tolist()))


def plot_frequency_response(
    response,
    ax=None,
    *,
    quantity="q_max",
    linear=None,
    show_folds=True,
    markers=None,
    label=None,
    color=None,
    hz=False,
):
    """Plot a :class:`~jointid.simulate.hbm.FrequencyResponse`.

    Parameters
    ----------
    response : FrequencyResponse
    ax : matplotlib Axes, optional
        Axes to draw into; a new figure is created when omitted.
    quantity : {"q_max", "amplitude", "phase"}
        What to plot against frequency.
    linear : None, bool, float or array_like
        Overlay the linear part's FRF (:func:`jointid.simulate.hbm.linear_frf`) as in
        the seed's Fig 4: ``True`` freezes amplitude laws at ``q_max = 0``, a float at
        that ``q_max``, an array (one value per point) at each point's own amplitude.
        For ``"q_max"`` and ``"amplitude"`` the linear curve is ``|X|``.
    show_folds : bool
        Mark fold points with crosses.
    markers : bool, optional
        Draw point markers (filled stable, open unstable).  Default: for sweeps only.
    label : str, optional
    color : optional
        Matplotlib colour of the nonlinear curve.
    hz : bool
        Frequency axis in hertz instead of rad/s.

    Returns
    -------
    fig, ax
    """
    if quantity not in _QUANTITIES:
        raise ValueError(f"quantity must be one of {sorted(_QUANTITIES)}, got {quantity!r}")
    from .figure_meta import ReportFigure

    if ax is None:  # no pyplot: a figure written by a report is freed with its last reference
        fig = ReportFigure(figsize=(6.4, 4.2))
        ax = fig.subplots()
    else:
        fig = ax.figure
    attr, ylabel = _QUANTITIES[quantity]
    scale = 1.0 / (2.0 * np.pi) if hz else 1.0
    w = np.asarray(response.omega) * scale
    y = np.asarray(getattr(response, attr))
    stable = response.stable
    if stable is None:
        stable = np.ones(w.size, bool)
    stable = np.asarray(stable, bool)
    if markers is None:
        markers = response.method == "sweep"
    if color is None:
        color = "C0"
    if label is None:
        label = f"nonlinear, F = {response.force_amplitude:g}"

    first = True
    for start, stop in _runs(stable):
        ok = bool(stable[start])
        lo = max(start - 1, 0) if not ok else start  # connect unstable runs to neighbours
        hi = min(stop + 1, w.size) if not ok else stop
        ax.plot(
            w[lo:hi], y[lo:hi], color=color, linestyle="-" if ok else "--", linewidth=1.4,
            label=label if first else None,
        )
        first = False
    if markers:
        ax.plot(w[stable], y[stable], "o", color=color, markersize=3.5, linestyle="none")
        if np.any(~stable):
            ax.plot(
                w[~stable], y[~stable], "o", markerfacecolor="none", markeredgecolor=color,
                markersize=3.5, linestyle="none", label="unstable",
            )
    elif np.any(~stable):
        ax.plot([], [], color=color, linestyle="--", label="unstable (Hill)")
    if show_folds and len(response.folds):
        idx = list(response.folds)
        ax.plot(w[idx], y[idx], "x", color="k", markersize=8, mew=1.6, linestyle="none", label="fold")

    if linear is not None and linear is not False and quantity != "phase":
        q_lin = 0.0 if linear is True else np.asarray(linear, float)
        X = response.linear(q_max=q_lin)
        order = np.argsort(w) if np.ndim(q_lin) == 0 else np.arange(w.size)
        ax.plot(w[order], np.abs(X)[order], "+", color="C3", markersize=4, linestyle="none", label="linear")
    elif linear is not None and linear is not False:
        q_lin = 0.0 if linear is True else np.asarray(linear, float)
        ax.plot(w, np.angle(response.linear(q_max=q_lin)), "+", color="C3", markersize=4,
                linestyle="none", label="linear")

    ax.set_xlabel("frequency [Hz]" if hz else r"$\omega$ [rad/s]")
    ax.set_ylabel(ylabel)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize="small")
    return fig, ax
