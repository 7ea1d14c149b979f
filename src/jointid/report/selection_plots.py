"""Figures and tables of model selection and model adequacy."""

from __future__ import annotations

import numpy as np

from .formatting import slug, tex_safe
from .identify_plots import new_axes
from .tables import format_table

__all__ = ["plot_selection", "plot_level_equality", "selection_table", "selection_figures"]


def selection_table(selection) -> str:
    """Plain-text ranking table of a :class:`~jointid.identify.selection.SelectionResult` (or its summary)."""
    d = selection if isinstance(selection, dict) else selection.summary()
    rows = []
    for r in d["ranking"]:
        rows.append({**r, "model": ("* " if r["selected"] else "  ") + r["name"],
                     "unresolved": ", ".join(r["unresolved"]) or "-"})
    crit = d["criterion"].upper()
    return format_table(rows, ["model", "n_parameters", "chi2", "delta_ic", "cv_force", "cv_force_se",
                               "cv_amplitude_rms_percent", "unresolved"],
                        ["model", "P", "chi2", f"d{crit}", "CV force", "se", "CV amplitude [%]", "unresolved"],
                        floatfmt=".4g")


def plot_selection(selection, ax=None):
    """The measure that decided, per candidate: the held-out prediction score (bars, log scale; the dashed
    line is the within-noise limit) with the criterion difference as dots, or, where no held-out
    prediction exists, the criterion difference (bars) with the cross-validated restoring-force score."""
    from jointid.identify.selection import HELDOUT_FLOOR, HELDOUT_RATIO

    ax = new_axes(ax, figsize=(7.0, 4.0))
    rows = selection.table()
    names = [r["name"] for r in rows]

    def column(key):
        return np.array([np.nan if r.get(key) is None else r[key] for r in rows], float)

    crit = selection.criterion.upper()
    dic, held = column("delta_ic"), column("heldout_score")
    by_heldout = bool(getattr(selection, "heldout", False)) and np.any(np.isfinite(held))
    y = np.arange(len(rows))
    colors = ["tab:green" if r["selected"] else "tab:blue" for r in rows]
    if by_heldout:
        ax.barh(y, held, color=colors, alpha=0.8)
        ax.axvline(HELDOUT_RATIO * np.nanmin(held) + HELDOUT_FLOOR, color="k", ls="--", lw=0.8)
        ax.set_xlabel("held-out prediction score [1] (dashed: within noise of the best)", fontsize=9)
        second, second_label = dic + 1.0, f"Δ{crit} + 1 (calibrated chi-square) [1]"
    else:
        ax.barh(y, np.maximum(dic, 0.0) + 1.0, color=colors, alpha=0.8)
        ax.set_xlabel(f"Δ{crit} + 1 (calibrated chi-square) [1]")
        second, second_label = column("cv_force"), "leave-one-level-out restoring-force score (1 = noise) [1]"
    ax.set_xscale("log")
    ax.set_yticks(y, names, fontsize=8)
    ax.invert_yaxis()
    if np.any(np.isfinite(second) & (second > 0)):
        ax2 = ax.twiny()
        ax2.plot(np.where(second > 0, second, np.nan), y, "ko", ms=4)
        ax2.set_xscale("log")
        ax2.set_xlabel(f"dots: {second_label}", fontsize=8)
    title = f"model selection, preload {tex_safe(selection.preload)}" if selection.preload is not None \
        else "model selection"
    ax.set_title(title, fontsize=9)
    ax.grid(True, axis="x", alpha=0.3)
    return ax


def plot_level_equality(adequacy, ax=None):
    """Each shared parameter at each force level, relative to its common value, with 95 % intervals."""
    ax = new_axes(ax)
    for j, e in enumerate(adequacy.equality):
        ref = e.common if e.common != 0 else 1.0
        x = np.arange(len(e.levels)) + 0.1 * j
        ax.errorbar(x, e.values / ref, yerr=1.96 * e.stderr / abs(ref), fmt="o-", capsize=3,
                    label=f"{tex_safe(e.name)} ({'differs' if e.differs else 'same'}, p = {e.p_value:.2g})")
    if adequacy.equality:
        ax.set_xticks(np.arange(len(adequacy.equality[0].levels)), [tex_safe(v) for v in adequacy.equality[0].levels])
    ax.axhline(1.0, color="0.5", lw=0.8)
    ax.set_xlabel("force level F [N]")
    ax.set_ylabel("parameter / common value [1]")
    ax.set_title(f"{tex_safe(adequacy.model_name)} model across force levels, preload {tex_safe(adequacy.preload)}",
                 fontsize=9)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    return ax


def selection_figures(result) -> list:
    """``(file name, caption, figure)`` of the selection ranking and level-equality plots of a campaign result."""
    out = []
    for p, sel in (getattr(result, "selections", None) or {}).items():
        if sel is None:
            continue
        ax = plot_selection(sel)
        out.append((f"selection_{slug(p)}.png", f"model selection ranking, preload {p}", ax.figure))
    for p, adq in (getattr(result, "adequacy", None) or {}).items():
        if adq is None or not adq.equality:
            continue
        ax = plot_level_equality(adq)
        out.append((f"adequacy_{slug(p)}.png", f"shared parameters across force levels, preload {p}", ax.figure))
    return out

