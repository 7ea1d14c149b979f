"""Backbone figures: omega(a) and zeta(a) of a model, stepped-sine points and ring-downs, each with its band.

Nothing is shown or saved here; every function returns ``(figure, (ax_omega, ax_zeta))``.
"""

from __future__ import annotations

import numpy as np

from .formatting import slug, tex_safe
from .identify_plots import new_axes

__all__ = ["plot_backbone", "plot_backbones", "joint_law_table", "backbone_figures", "backbone_report_lines"]

_STYLE = {
    "model": dict(fmt="-", marker=None),
    "rig": dict(fmt="--", marker=None),
    "stepped-sine": dict(fmt="o", marker="o"),
    "phase-resonance": dict(fmt="s", marker="s"),
    "ringdown": dict(fmt=".", marker="."),
}


def _axes(ax):
    if ax is None:
        axes = new_axes(None, figsize=(6.0, 6.0), nrows=2, ncols=1)
        return axes[0].figure, (axes[0], axes[1])
    if isinstance(ax, (tuple, list, np.ndarray)) and len(ax) == 2:
        return ax[0].figure, (ax[0], ax[1])
    raise ValueError("ax must be a pair of axes (omega, zeta)")


def plot_backbone(backbone, ax=None, label=None, units="Hz", amplitude_unit="m"):
    """Draw one backbone on a pair of axes (``omega`` or ``f`` above, ``zeta`` in % below), log amplitude.

    Curves (``model``, ``rig``) are lines with a shaded 95 % band; measured points carry 95 %
    error bars.  ``amplitude_unit`` is the unit of the first-harmonic amplitude ``a``.
    """
    fig, (aw, az) = _axes(ax)
    b = backbone.sorted()
    k = 1 / (2 * np.pi) if units == "Hz" else 1.0
    style = _STYLE.get(b.source, dict(fmt="o", marker="o"))
    lab = _tex_safe(label or (f"{b.source}" + (f" ({b.label})" if b.label else "")))  # user text: no mathtext
    measures = []
    if style["marker"] is None:
        (line,) = aw.plot(b.amplitude, k * b.omega, style["fmt"], label=lab)
        az.plot(b.amplitude, 100 * b.zeta, style["fmt"], color=line.get_color())
        if np.any(np.isfinite(b.omega_stderr) & (b.omega_stderr > 0)):
            lo, hi = b.omega_band
            aw.fill_between(b.amplitude, k * lo, k * hi, color=line.get_color(), alpha=0.2, lw=0)
            lo, hi = b.zeta_band
            az.fill_between(b.amplitude, 100 * lo, 100 * hi, color=line.get_color(), alpha=0.2, lw=0)
            measures.append("band95")
    else:
        se_w = np.nan_to_num(b.omega_stderr)
        se_z = np.nan_to_num(b.zeta_stderr)
        c = aw.errorbar(b.amplitude, k * b.omega, yerr=1.96 * k * se_w, fmt=style["fmt"], ms=3, capsize=1.5,
                        label=lab)
        az.errorbar(b.amplitude, 100 * b.zeta, yerr=196 * se_z, fmt=style["fmt"], ms=3, capsize=1.5,
                    color=c.lines[0].get_color())
        if np.any(se_w > 0) or np.any(se_z > 0):
            measures.append("ci95 bars")
    for a in (aw, az):
        a.set_xscale("log")
        a.grid(True, which="both", alpha=0.3)
    aw.set_ylabel("natural frequency [Hz]" if units == "Hz" else "omega [rad/s]")
    az.set_ylabel("damping ratio zeta [%]")
    for a in (aw, az):  # shared amplitude axis: labelled on both panels
        a.set_xlabel(f"first-harmonic amplitude a [{amplitude_unit}] (modal)")
    aw.legend(fontsize="small")
    if measures:
        from .figure_meta import mark_comparison

        mark_comparison(aw, "backbones omega(a), zeta(a): model vs measured points", *measures)
    return fig, (aw, az)


def plot_backbones(backbones, ax=None, title=None, units="Hz", amplitude_unit="m"):
    """Several backbones on one pair of axes (a model curve, stepped-sine points, ring-downs ...)."""
    fig, axes = _axes(ax) if ax is not None else (None, None)
    for b in backbones:
        fig, axes = plot_backbone(b, ax=axes, units=units, amplitude_unit=amplitude_unit)
    if title and axes is not None:
        axes[0].set_title(_tex_safe(title, 120))
    return fig, axes


def _tex_safe(text, max_length=80):
    return tex_safe(text, max_length)


def joint_law_table(fits) -> str:
    """Plain-text table of joint-law fits (``{name: JointLawFit}``): parameters, 95 % intervals, adequacy."""
    lines = []
    for name, f in fits.items():
        lines.append(f.report())
    return "\n\n".join(lines)


def backbone_figures(result) -> list:
    """``(file name, caption, figure)`` of each preload's backbones in a campaign result (none without them)."""
    bb = getattr(result, "backbones", None)
    out = []
    for p in (bb.preloads if bb is not None else ()):
        if p.model is None and p.stepped is None and not p.ringdown:
            continue
        fig, _ = p.plot()
        out.append((f"backbone_{slug(p.preload)}.png", f"omega(a) and zeta(a), preload {p.preload}: model with its "
                    "95 % band, stepped-sine and phase-resonance points, ring-downs, fitted joint laws", fig))
    return out


def backbone_report_lines(result) -> list:
    """Text lines of the joint laws fitted per preload (empty without them)."""
    bb = getattr(result, "backbones", None)
    lines = []
    for p in (bb.preloads if bb is not None else ()):
        if p.joint_laws:
            lines.append(f"Joint laws from the backbone, preload {p.preload}:")
            lines += ["  " + f.report().replace("\n", "\n  ") for f in p.joint_laws.values()]
    if bb is not None and bb.error:
        lines.append(f"Backbones: {bb.error}")
    return lines + ([""] if lines else [])
