"""Figures of the virtual rig and the demo (seed Figs 9-11 and the joint law).

Every function takes an optional ``ax`` and returns the axes it drew on; nothing is
shown or saved here (Agg-safe :class:`matplotlib.figure.Figure` objects).
"""

from __future__ import annotations

import numpy as np

from .identify_plots import new_axes

__all__ = [
    "plot_joint_law",
    "plot_joint_dissipation",
    "plot_linear_frfs",
    "plot_nonlinear_frfs",
    "plot_record",
    "FORCE_MARKERS",
]

#: Markers of the seed's Figs 10 and 12: F = 1.5 N (+), 3 N (o), 6 N (filled dot).
FORCE_MARKERS = {1.5: ("+", "none"), 3.0: ("o", "none"), 6.0: ("o", "full")}


def _marker(force_level, i):
    m = FORCE_MARKERS.get(float(force_level))
    if m is None:
        return ("s^v<>"[i % 5], "full")
    return m


def plot_joint_law(law, amplitudes, ax=None, n=512, label_unit="rad", force_unit="N m"):
    """Steady hysteresis loops of a joint law at several amplitudes, with its backbone."""
    ax = new_axes(ax)
    tau = 2 * np.pi * np.arange(n) / n
    U = np.outer(amplitudes, np.sin(tau))
    Fs, _ = law.periodic_force(U)  # one batch over the amplitudes
    for a, u, f in zip(amplitudes, U, Fs):
        ax.plot(np.append(u, u[:1]), np.append(f, f[:1]), lw=1.1, label=f"amplitude {a:.3g} {label_unit}")
    if law.iwan is not None:
        uu = np.linspace(-max(amplitudes), max(amplitudes), 301)
        ax.plot(uu, law.iwan.backbone(uu) - law.k3 * uu**3, "k--", lw=0.8, label="virgin loading (closed form)")
        ax.plot(uu, law.linear_stiffness * uu, ":", color="0.5", lw=0.8, label="K_T u")
    ax.set_xlabel(f"relative motion u [{label_unit}]")
    ax.set_ylabel(f"joint force (moment) [{force_unit}]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    return ax


def plot_joint_dissipation(law, force_range, ax=None, n_points=12, label=None, force_unit="N m"):
    """Energy dissipated per cycle against force amplitude: discrete Iwan (points) and
    Segalman's closed forms (lines), log-log, with the slope ``3 + chi``."""
    ax = new_axes(ax)
    p = law.iwan
    F = np.geomspace(force_range[0], force_range[1], n_points)
    u0 = p.displacement_at_force(F)
    tau = 2 * np.pi * np.arange(1024) / 1024
    f, _ = law.elements.periodic_force(np.outer(u0, np.sin(tau)))  # one batch over the amplitudes
    D = np.sum(f * np.outer(u0, np.cos(tau)), axis=-1) * 2 * np.pi / tau.size  # closed loop integral of f du
    pts = ax.loglog(F, D, "o", ms=4, label=label or "discrete Iwan (periodic AFT)")
    FF = np.geomspace(force_range[0], force_range[1], 100)
    ax.loglog(FF, p.dissipation(p.displacement_at_force(FF)), "-", color=pts[0].get_color(), lw=1,
              label="closed form D(u0(F))")
    ax.loglog(FF, p.microslip_dissipation(FF), "k--", lw=0.8,
              label=f"micro-slip asymptote ~ F^{p.dissipation_exponent:.2f}")
    ax.set_xlabel(f"force (moment) amplitude F [{force_unit}]")
    ax.set_ylabel("energy dissipated per cycle D [J]")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    return ax


def _envelope(x, y, max_points=3000):
    """Min/max decimation of a long curve: the drawn envelope (and every peak) is unchanged."""
    n = x.size
    if n <= max_points:
        return x, y
    b = int(np.ceil(2 * n / max_points))
    m = n // b * b
    xs, ys = x[:m].reshape(-1, b), y[:m].reshape(-1, b)
    i_lo, i_hi = ys.argmin(axis=1), ys.argmax(axis=1)
    first = np.minimum(i_lo, i_hi)
    second = np.maximum(i_lo, i_hi)
    r = np.arange(xs.shape[0])
    xx = np.column_stack([xs[r, first], xs[r, second]]).ravel()
    yy = np.column_stack([ys[r, first], ys[r, second]]).ravel()
    return np.append(xx, x[m:]), np.append(yy, y[m:])


def plot_linear_frfs(curves, ax=None, f_range=None):
    """Linear FRF magnitudes (seed Fig 9): ``curves`` is a list of
    ``(label, frequency_hz, H, style)`` drawn on a log magnitude axis."""
    ax = new_axes(ax)
    for label, f, H, style in curves:
        f = np.asarray(f)
        sel = np.ones_like(f, bool) if f_range is None else (f >= f_range[0]) & (f <= f_range[1])
        ax.semilogy(*_envelope(f[sel], np.abs(np.asarray(H)[sel])), style, lw=1.0, label=label)
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("|accelerance| at 42 cm [(m/s²)/N]")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    return ax


def plot_nonlinear_frfs(repredictions, ax=None, title=None, show_exact=True):
    """Nonlinear FRFs (seed Fig 10): measured dwells per force level (markers) and the
    identified model's harmonic-balance re-prediction (lines), with each curve's rms error at
    the dwells in the legend (outside the axes, clear of the peaks)."""
    ax = new_axes(ax)
    rms_shown = False
    for i, r in enumerate(sorted(repredictions, key=lambda r: r.force_level)):
        marker, fill = _marker(r.force_level, i)
        pts = ax.plot(r.measured_frequency_hz, r.measured, marker, ms=5, fillstyle=fill, ls="none",
                      label=f"measured F = {r.force_level:g} N")
        err = getattr(r, "point_rms_error_percent", None)
        rms_shown |= err is not None
        ax.plot(r.frequency_hz, r.predicted, "-", lw=1.1, color=pts[0].get_color(),
                label=f"identified model (HBM), F = {r.force_level:g} N"
                      + (f":\nrms error at the dwells {err:.2f} %" if err is not None else ""))
        if show_exact:
            ax.plot(r.exact.frequency_hz, np.abs(r.exact.H), ":", lw=0.9, color="0.35")
    if show_exact and repredictions:
        ax.plot([], [], ":", color="0.35", label="rig exact (multi-harmonic balance)")
    ax.set_xlabel("excitation frequency [Hz]")
    ax.set_ylabel("|a_42 / F| fundamental [(m/s²)/N]")
    if title:
        ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=6.5, loc="upper center", bbox_to_anchor=(0.5, -0.16), ncols=2, frameon=False)
    if rms_shown:
        from .figure_meta import mark_comparison

        mark_comparison(ax, "re-predicted (harmonic balance) vs measured nonlinear FRF", "rms error")
    return ax


def plot_record(t, force, accel, accel_fit, velocity, displacement, axes=None, title=None, periods=None):
    """A record and its analytically integrated states (seed Fig 11): modal force,
    measured and fitted modal acceleration, velocity and displacement."""
    if axes is None:
        axes = np.atleast_1d(new_axes(None, figsize=(7.0, 6.5), nrows=4))
    sel = slice(None) if periods is None else t < t[0] + periods
    axes[0].plot(t[sel], force[sel], lw=0.9)
    axes[0].set_ylabel("Q [N] (modal)")
    axes[1].plot(t[sel], accel[sel], lw=0.7, color="0.6", label="measured")
    axes[1].plot(t[sel], accel_fit[sel], lw=1.0, label="fitted harmonic series")
    axes[1].set_ylabel("q'' [m/s²]")
    axes[1].legend(fontsize=7, loc="center left", bbox_to_anchor=(1.01, 0.5), frameon=False)
    axes[2].plot(t[sel], velocity[sel], lw=1.0)
    axes[2].set_ylabel("q' [m/s]")
    axes[3].plot(t[sel], displacement[sel], lw=1.0)
    axes[3].set_ylabel("q [m]")
    for ax in axes:
        ax.set_xlabel("time [s]")
    for ax in axes:
        ax.grid(True, alpha=0.3)
    if title:
        axes[0].set_title(title)
    return axes
