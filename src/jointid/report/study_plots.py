"""Tables, figures and the HTML report of a Monte Carlo study (:mod:`jointid.app.study`).

Every plotting function takes an optional ``ax`` and returns what it drew on; nothing is
shown or saved here except by :func:`write_study_report`.
"""

from __future__ import annotations

import numpy as np

from .formatting import format_value
from .html import Section, write_html
from .identify_plots import new_axes

__all__ = ["distribution_text", "statistics_table", "plot_calibration", "plot_z_histograms", "study_sections",
           "write_study_report"]

_COLUMNS = ("parameter", "n", "n_missing", "rel_bias", "rel_rmse", "mean_z", "std_z", "coverage")


def _fmt(v, digits=4) -> str:
    if v is None:
        return "-"
    return format_value(v, digits)


def _pct(fraction) -> str:
    """A fraction shown in % (the column's unit), three significant digits."""
    return "-" if fraction is None else format_value(100 * float(fraction), 3)


def distribution_text(spec) -> str:
    """A plan's distribution in words: ``{"loguniform": [0.001, 0.02]}`` -> ``log-uniform 0.001 .. 0.02``."""
    if not isinstance(spec, dict):
        return str(spec)
    names = {"uniform": "uniform", "loguniform": "log-uniform", "normal": "normal", "choice": "one of",
             "integers": "integers"}
    parts = []
    for k, v in spec.items():
        if k in ("uniform", "loguniform", "integers") and isinstance(v, (list, tuple)) and len(v) == 2:
            parts.append(f"{names[k]} {_fmt(v[0])} .. {_fmt(v[1])}")
        elif k == "normal" and isinstance(v, (list, tuple)) and len(v) == 2:
            parts.append(f"normal, mean {_fmt(v[0])}, sd {_fmt(v[1])}")
        elif k == "choice":
            parts.append("one of " + ", ".join(str(x).lower() if isinstance(x, bool) else str(x) for x in v))
        elif k == "random_sign":
            if v:
                parts.append("random sign")
        elif k == "size":
            parts.append(f"{v[0]} to {v[1]} values" if isinstance(v, (list, tuple)) and len(v) == 2
                         else f"{v} values")
        else:
            parts.append(f"{names.get(k, k)} {v}")
    return ", ".join(parts)


def _stat_rows(stats) -> list:
    """Display rows of one grid point's statistics: few columns, the coverage with its interval."""
    rows = []
    for s in stats:
        lo, hi, cov = s.get("coverage_low"), s.get("coverage_high"), s.get("coverage")
        rows.append({
            "parameter": str(s["parameter"]),
            "n (missing)": f"{_fmt(s.get('n'))} ({_fmt(s.get('n_missing'))})",
            "rel. bias [%]": _pct(s.get("rel_bias")),
            "rel. RMSE [%]": _pct(s.get("rel_rmse")),
            "mean(z) [1]": _fmt(s.get("mean_z"), 3),
            "std(z) [1]": _fmt(s.get("std_z"), 3),
            "coverage [%] (95 % interval)": _pct(cov) + ("" if cov is None or lo is None or hi is None
                                                         else f" ({_pct(lo)} .. {_pct(hi)})"),
        })
    return rows


def statistics_table(statistics) -> str:
    """A fixed-width text table of :func:`~jointid.app.study.study_statistics` rows."""
    rows = [[str(s["parameter"])] + [_fmt(s.get(c)) for c in _COLUMNS[1:]] for s in statistics]
    if not rows:
        return "  (no comparisons)"
    widths = [max(len(c), *(len(r[j]) for r in rows)) for j, c in enumerate(_COLUMNS)]
    line = lambda cells: "  " + "  ".join(c.ljust(w) if j == 0 else c.rjust(w)  # noqa: E731
                                          for j, (c, w) in enumerate(zip(cells, widths)))
    return "\n".join([line(_COLUMNS)] + [line(r) for r in rows])


def plot_calibration(statistics, ax=None, std_band=(0.8, 1.25), coverage_band=(0.92, 0.98)):
    """std(z) and 95 % coverage per parameter, against the bands a calibrated method stays in.

    Parameters
    ----------
    statistics : list of dict
        Rows of one grid point.
    ax : pair of Axes, optional
    std_band, coverage_band : (low, high)
        Shaded acceptance bands.

    Returns
    -------
    pair of Axes
    """
    axes = new_axes(ax, figsize=(9.0, 0.35 * max(len(statistics), 4) + 1.5), ncols=2)
    names = [s["parameter"] for s in statistics]
    y = np.arange(len(names))
    std = np.array([np.nan if s["std_z"] is None else s["std_z"] for s in statistics], float)
    cov = np.array([np.nan if s["coverage"] is None else s["coverage"] for s in statistics], float)
    lo = np.array([np.nan if s["coverage_low"] is None else s["coverage_low"] for s in statistics], float)
    hi = np.array([np.nan if s["coverage_high"] is None else s["coverage_high"] for s in statistics], float)
    a, b = axes
    a.axvspan(*std_band, color="tab:green", alpha=0.15)
    a.axvline(1.0, color="k", lw=0.8)
    a.plot(std, y, "o")
    a.set_xlim(0, max(2.0, 1.1 * float(np.nanmax(std))) if np.any(np.isfinite(std)) else 2.0)
    a.set_xlabel("std(z) [1]")
    a.set_yticks(y, names, fontsize=8)
    b.axvspan(*coverage_band, color="tab:green", alpha=0.15)
    b.axvline(0.95, color="k", lw=0.8)
    b.errorbar(cov, y, xerr=np.clip([cov - lo, hi - cov], 0, None), fmt="o", capsize=2)
    b.set_xlabel("coverage of the 95 % interval [1]")
    b.set_yticks(y, [""] * len(y))
    for x in (a, b):
        x.invert_yaxis()
        x.grid(True, alpha=0.3)
    return axes


def plot_z_histograms(campaigns, parameters, grid_point=0, axes=None, ncols=3):
    """Histograms of z per parameter, with the standard normal density.

    Returns
    -------
    ndarray of Axes
    """
    n = len(parameters)
    nrows = max(1, -(-n // ncols))
    if axes is None:
        axes = np.atleast_1d(new_axes(figsize=(3.2 * ncols, 2.4 * nrows), nrows=nrows, ncols=ncols))
    axes = np.ravel(axes)
    zz = np.linspace(-4, 4, 200)
    for ax, name in zip(axes, parameters):
        z = np.array([r["z"] for c in campaigns if c.get("grid_point") == grid_point for r in c.get("rows") or []
                      if r["parameter"] == name and r["z"] is not None], float)
        z = z[np.isfinite(z)]
        if z.size:
            lim = max(4.0, min(float(np.max(np.abs(z))), 20.0))
            ax.hist(np.clip(z, -lim, lim), bins=30, range=(-lim, lim), density=True, alpha=0.6)
        ax.plot(zz, np.exp(-zz**2 / 2) / np.sqrt(2 * np.pi), "k-", lw=1)
        ax.set_title(f"{name} (n={z.size})", fontsize=8)
        ax.set_xlabel("z = (estimate - truth) / stderr [1]", fontsize=7)
        ax.set_ylabel("density [1]", fontsize=7)
        ax.tick_params(labelsize=7)
    for ax in axes[n:]:
        ax.set_visible(False)
    return axes


def study_sections(result) -> list:
    """HTML sections of a :class:`~jointid.app.study.StudyResult`."""
    from .html import figure_to_png

    plan = result.plan
    intro = Section("Study", [
        f"{len(result.campaigns)} campaigns ({plan.campaigns} per grid point, {len(plan.points)} grid points), "
        f"{len(result.failed)} failed; study seed {plan.seed}, plan fingerprint {plan.fingerprint}.",
        "z = (estimate - truth) / stderr. A calibrated estimate has std(z) near 1 and its 95 % interval "
        "covers the truth in 95 % of the campaigns; the coverage interval shown is Wilson's 95 % interval "
        "of that fraction. Relative bias and RMSE are relative to |truth|.",
    ])
    if getattr(result, "provenance", None):
        from .provenance_text import provenance_line

        intro.paragraphs.append(provenance_line(result.provenance) + ".")
    intro.tables.append(("drawn per campaign", [{"path": p, "distribution": distribution_text(s)}
                                                for p, s in plan.vary], None))
    sections = [intro]
    for k, point in enumerate(plan.points):
        stats = [s for s in result.statistics if s["grid_point"] == k]
        title = "Statistics" if len(plan.points) == 1 else f"Grid point {k}: " + ", ".join(
            f"{p} = {v}" for p, v in point.items())
        sec = Section(title)
        sec.tables.append(("per parameter (relative bias and RMSE against |truth|; all numbers in results.json)",
                           _stat_rows(stats), None))
        if stats:
            fig = plot_calibration(stats)[0].figure
            sec.figures.append(("std(z) and 95 % coverage per parameter (shaded: 0.8-1.25 and 92-98 %)",
                                figure_to_png(fig)))
            zfig = plot_z_histograms(result.campaigns, [s["parameter"] for s in stats], grid_point=k)[0].figure
            sec.figures.append(("z per parameter and the standard normal density", figure_to_png(zfig)))
        sections.append(sec)
    if result.failed:
        fail = Section("Failed campaigns")
        fail.tables.append(("failed", [{"index": c["index"], "seed": str(c["seed"]), "error": c["error"]}
                                       for c in result.failed], None))
        sections.append(fail)
    return sections


def write_study_report(result, path) -> None:
    """Write the self-contained HTML report of a study."""
    write_html(path, f"jointid study: {result.name}", study_sections(result))
