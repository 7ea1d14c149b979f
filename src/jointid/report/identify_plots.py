"""Figures of identification results (seed Figs 5, 6, 12-19).

Every function takes an optional ``ax`` and returns the axes it drew on; nothing is
shown or saved here.  A figure that compares the identified model with the measurement
draws an error measure (error bars from the standard errors, a 95 % band or a printed rms
error) and names it with :func:`~jointid.report.figure_meta.mark_comparison`.
"""

from __future__ import annotations

import numpy as np

from .formatting import label_with_unit

__all__ = [
    "new_axes",
    "axis_label",
    "compact_ticks",
    "plot_per_record",
    "plot_damping_law",
    "plot_power_law",
    "plot_hysteresis",
    "plot_parameters_vs_frequency",
    "plot_record_parameters",
]

#: Axis labels of the identified quantities when the force gain is unknown: the "force" is the
#: recorded excitation (a voltage) and the coefficients are per unit modal mass (``1/m = g``).
GAIN_FREE_LABELS = {
    "k3": ("k3/m", "1/(m² s²)"),
    "c": ("c/m", "1/s"),
    "c0": ("c0/m", "1/s"),
    "c1": ("c1/m", "1/(m s)"),
    "c2": ("c2/m", "1/(m² s)"),
    "F": ("excitation amplitude", "V"),
    "restoring": ("restoring force / m - omega1² q", "m/s²"),
}


def axis_label(name, gain_free=False) -> str:
    """``name [unit]`` of an identified quantity; per unit modal mass when the force gain is unknown."""
    if gain_free and name in GAIN_FREE_LABELS:
        n, u = GAIN_FREE_LABELS[name]
        return f"{n} [{u}]"
    return label_with_unit(name)


def new_axes(ax=None, figsize=(6.0, 4.0), nrows=1, ncols=1):
    """Return ``ax`` or a new figure's axes (Agg-safe: no display needed).

    The new figure is a :class:`~jointid.report.figure_meta.ReportFigure`, which writes its
    comparison note (if any) into the PNG it is saved as.
    """
    if ax is not None:
        return ax
    from .figure_meta import ReportFigure

    fig = ReportFigure(figsize=figsize, layout="constrained")
    axes = fig.subplots(nrows, ncols)
    return axes


def compact_ticks(ax, axis="both", nbins=5):
    """At most ``nbins`` ticks and a shared power of ten outside ``[1e-2, 1e4)``, so that the
    labels of a narrow panel do not run into each other (``-0.0050-0.0025`` becomes ``-5 ... x1e-3``)."""
    from matplotlib.ticker import MaxNLocator, ScalarFormatter

    for which in ("x", "y"):
        if axis not in ("both", which):
            continue
        a = ax.xaxis if which == "x" else ax.yaxis
        if a.get_scale() != "linear":
            continue
        a.set_major_locator(MaxNLocator(nbins=nbins, steps=[1, 2, 2.5, 5, 10]))
        fmt = ScalarFormatter(useMathText=True)
        fmt.set_powerlimits((-2, 4))
        a.set_major_formatter(fmt)


def _mark(ax, comparison, *measures):
    from .figure_meta import mark_comparison

    mark_comparison(ax, comparison, *measures)


def plot_per_record(pooled, name="c", ax=None, label=None, marker="o"):
    """Per-record coefficient of a pooled fit against ``q_max`` (seed Fig 12), ± 1 standard error."""
    ax = new_axes(ax)
    y = pooled.get(name)
    err = pooled.get_stderr(name)
    ax.errorbar(pooled.q_max, y, yerr=err, fmt=marker, ms=4, capsize=2, label=label)
    ax.set_xlabel(label_with_unit("q_max"))
    ax.set_ylabel(label_with_unit(name))
    ax.grid(True, alpha=0.3)
    _mark(ax, f"per-record {name} of a pooled fit", "stderr bars")
    return ax


def _law_band(law, qq):
    """95 % band of ``c(q)`` from the law's coefficient covariance (``None`` without one)."""
    cov = getattr(law, "covariance", None)
    if cov is None:
        return None
    cov = np.asarray(cov, float)
    J = np.vander(np.asarray(qq, float), cov.shape[0], increasing=True)
    var = np.einsum("ij,jk,ik->i", J, cov, J)
    if not np.all(np.isfinite(var)):
        return None
    se = np.sqrt(np.clip(var, 0, None))
    return law(qq) - 1.96 * se, law(qq) + 1.96 * se


def plot_damping_law(law, ax=None, label=None, color=None, gain_free=False):
    """Per-record damping (± 1 standard error) and the fitted ``c(q_max)`` with its 95 % band
    (seed Figs 6, 13, 14)."""
    ax = new_axes(ax)
    q = np.asarray(law.q_max)
    err = law.c_stderr if np.all(np.isfinite(law.c_stderr)) else None
    pts = ax.errorbar(q, law.c, yerr=err, fmt="o", ms=4, capsize=2, color=color,
                      label=f"{label or 'identified'}" + (" ± 1 standard error" if err is not None else ""))
    qq = np.linspace(0, q.max() * 1.05, 200)
    col = pts[0].get_color()
    ax.plot(qq, law(qq), "-", color=col, label=f"c(q_max), polynomial of order {law.order}")
    band = _law_band(law, qq)
    measures = ["stderr bars"] if err is not None else []
    if band is not None:
        ax.fill_between(qq, band[0], band[1], color=col, alpha=0.25, lw=0, label="95 % band of the law")
        measures.append("band95")
    resid = np.asarray(law.c) - law(q)
    rel = 100 * np.sqrt(np.mean(resid**2)) / max(np.sqrt(np.mean(np.asarray(law.c) ** 2)), 1e-300)
    ax.plot([], [], " ", label=f"rms residual of the points {rel:.2g} %")
    measures.append("rms error")
    ax.set_xlabel(label_with_unit("q_max"))
    ax.set_ylabel(axis_label("c", gain_free).replace("c/m [", "c/m(q_max) [").replace("c [", "c(q_max) ["))
    ax.grid(True, alpha=0.3)
    compact_ticks(ax)
    ax.legend(fontsize=7, loc="best")
    _mark(ax, "fitted damping law c(q_max) vs the per-record damping", *measures)
    return ax


def plot_power_law(law, ax=None, label=None, gain_free=False):
    """Energy dissipated per cycle against joint force, log-log (seed Figs 15, 16), with the
    rms scatter of the records about ``U = alpha F^n`` in the legend."""
    ax = new_axes(ax)
    F = np.asarray(law.force, float)
    U = np.asarray(law.energy, float)
    pts = ax.loglog(F, U, "o", ms=4, label=label or "records")
    FF = np.geomspace(F.min(), F.max(), 50)
    ok = (F > 0) & (U > 0)
    rms = 100 * float(np.sqrt(np.mean((U[ok] / law(F[ok]) - 1.0) ** 2))) if np.any(ok) else float("nan")
    ax.loglog(FF, law(FF), "-", color=pts[0].get_color(),
              label=f"U = {law.alpha:.3g} F^{law.n:.3f} ± {law.n_stderr:.1g}, rms scatter {rms:.2g} %")
    if gain_free:
        ax.set_xlabel("joint force amplitude per unit modal mass F/m [m/s²]", fontsize=9)
        ax.set_ylabel("energy per cycle U/m [m²/s²]")
    else:
        ax.set_xlabel("joint force amplitude F [N] (modal)")
        ax.set_ylabel("energy per cycle U [J]")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, loc="upper left")
    _mark(ax, "power law U = alpha F^n vs the per-record energies", "rms error")
    return ax


def plot_hysteresis(loop, ax=None, label=None, show_identified=True, gain_free=False):
    """Nonlinear restoring force vs displacement, measured (full) and identified (dashed), with
    the rms difference of the two loops in the legend (seed Figs 17-19)."""
    ax = new_axes(ax)
    kind = "filtered" if loop.filtered else "unfiltered"
    q = np.append(loop.q, loop.q[:1])
    m = np.append(loop.measured, loop.measured[:1])
    ax.plot(q, m, "-", lw=1.2, label=label or f"measured ({kind}) {loop.frequency_hz:.4g} Hz")
    if show_identified:
        i = np.append(loop.identified, loop.identified[:1])
        err = getattr(loop, "rms_difference", None)
        shown = err is not None and np.isfinite(err)
        ax.plot(q, i, "--", lw=1.2, color="k",
                label="identified" + (f" (rms difference {100 * err:.1f} %)" if shown else ""))
        if shown:
            _mark(ax, "identified vs measured hysteresis loop", "rms error")
    ax.set_xlabel("q [m] (modal)")
    ax.set_ylabel("g u - q'' - omega1² q [m/s²]" if gain_free else "Q - q'' - omega1² q [N] (modal)")
    ax.grid(True, alpha=0.3)
    compact_ticks(ax)
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.2), frameon=False)
    return ax


def plot_parameters_vs_frequency(frequency, values: dict, exact: dict | None = None, axes=None, stderr=None,
                                 frequency_unit="Hz", title=None):
    """Per-record identified coefficients against excitation frequency (seed Fig 5).

    Parameters
    ----------
    frequency : array
        Excitation frequency of each record, in ``frequency_unit``.
    values : dict
        Axis label (or quantity name) -> per-record values.
    exact : dict, optional
        Same keys -> exact value (a dashed line).
    stderr : dict, optional
        Same keys -> per-record standard errors (error bars).
    frequency_unit : {"Hz", "rad/s"}
    title : str, optional
        Figure title (above every panel, clear of the offset text of the axes).
    """
    names = list(values)
    if axes is None:
        axes = new_axes(None, figsize=(6.0, 2.2 * len(names) + (0.3 if title else 0.0)), nrows=len(names))
        axes = np.atleast_1d(axes)
    stderr = stderr or {}
    bars = False
    for ax, n in zip(axes, names):
        e = stderr.get(n)
        e = None if e is None or not np.all(np.isfinite(np.asarray(e, float))) else np.asarray(e, float)
        ax.errorbar(frequency, values[n], yerr=e, fmt="o", ms=3, capsize=1.5,
                    label="identified" + (" ± 1 standard error" if e is not None else ""))
        bars |= e is not None
        if exact and n in exact and exact[n] is not None:
            ax.axhline(exact[n], color="k", lw=0.8, ls="--", label="exact")
        ax.set_ylabel(n if "[" in n else label_with_unit(n))
        ax.grid(True, alpha=0.3)
        ax.set_xlabel(f"excitation frequency [{frequency_unit}]")
        compact_ticks(ax, "y", nbins=4)
    axes[0].legend(fontsize=7, loc="lower right", bbox_to_anchor=(1.0, 1.0), ncols=2, frameon=False,
                   borderaxespad=0.2)
    if title:
        axes[0].figure.suptitle(title, fontsize=10)
    if bars:
        _mark(axes, "per-record identified parameters" + (" vs the exact values" if exact else ""), "stderr bars")
    return axes


def plot_record_parameters(records, group=None, gain_free=False, title=None):
    """``f1``, ``k3`` and ``c`` of each record of a group (± 1 standard error) against the
    excitation frequency, with the group's pooled ``f1`` and ``k3`` as dashed lines.

    Parameters
    ----------
    records : sequence of RecordOutcome
        The group's records (``.signals``, ``.fit``).
    group : GroupResult, optional
        Its pooled fit gives the dashed reference lines.
    gain_free : bool
        The force gain was identified: ``k3`` and ``c`` are per unit modal mass.
    """
    f = np.array([r.signals.frequency_hz for r in records])
    fits = [r.fit for r in records]
    pooled = getattr(group, "pooled", None)
    gain_free = gain_free or any(getattr(r, "omega1_own", None) is not None for r in records)

    def col(name):
        v, s = [], []
        for fit in fits:
            names = list(fit.coefficient_names)
            if name not in names:
                return None, None
            i = names.index(name)
            v.append(float(fit.coefficients[i]))
            s.append(float(fit.stderr[i]))
        return np.array(v), np.array(s)

    vals, errs, exact = {}, {}, {}
    key = "f1 [Hz]"
    if gain_free:  # the single-record fit is in excitation units: its omega1 with the shared inertia held
        vals[key] = np.array([np.nan if r.omega1_own is None else r.omega1_own for r in records]) / (2 * np.pi)
    else:
        w2, w2s = col("omega1^2")
        if w2 is not None:
            w = np.sqrt(np.clip(w2, 0, None))
            vals[key] = w / (2 * np.pi)
            errs[key] = w2s / (2 * np.where(w > 0, w, np.nan)) / (2 * np.pi)
    if key in vals and pooled is not None and np.isfinite(getattr(pooled, "omega1", np.nan)):
        exact[key] = pooled.omega1 / (2 * np.pi)
    if not gain_free:
        v, s = col("k3")
        if v is not None:
            key = axis_label("k3")
            vals[key], errs[key] = v, s
            if pooled is not None and getattr(pooled, "k3", None) is not None:
                exact[key] = float(pooled.k3)
        v, s = col("c")
        if v is not None:
            vals[axis_label("c")], errs[axis_label("c")] = v, s
    else:
        c = np.array([np.nan if r.c_pooled is None else r.c_pooled for r in records], float)
        cs = np.array([np.nan if r.c_pooled_stderr is None else r.c_pooled_stderr for r in records], float)
        if np.any(np.isfinite(c)):
            vals[axis_label("c", True)], errs[axis_label("c", True)] = c, cs
    axes = plot_parameters_vs_frequency(f, vals, exact=None, stderr=errs, title=title)
    for ax, key in zip(axes, vals):
        if key in exact:
            ax.axhline(exact[key], color="C1", lw=0.9, ls="--", label="pooled fit of the group")
    axes[0].legend(fontsize=7, loc="lower right", bbox_to_anchor=(1.0, 1.0), ncols=2, frameon=False,
                   borderaxespad=0.2)
    return axes
