"""The demo's report: figures (PNG, SVG), tables and the self-contained ``report.html``.

:func:`demo_figures` draws the seed's Figs 9-19 from a :class:`~jointid.app.demo.DemoResult`,
:func:`save_figures` writes them, :func:`demo_sections` lays out the page and
:func:`write_demo_html` writes it with :func:`jointid.report.html.write_html` (every
figure embedded, every text escaped, no network needed).
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from ..io.results import atomic_write
from .formatting import format_pm, format_value, unit_of
from .html import Section, write_html
from .identify_plots import new_axes, plot_damping_law, plot_hysteresis, plot_power_law
from .rig_plots import (
    FORCE_MARKERS,
    plot_joint_dissipation,
    plot_joint_law,
    plot_linear_frfs,
    plot_nonlinear_frfs,
    plot_record,
)

__all__ = ["demo_figures", "save_figures", "demo_sections", "write_demo_html", "check_rows"]

#: Figures also written as SVG (line plots, small files).
SVG_FIGURES = ("fig10_nonlinear_frf", "fig13_damping_law_120", "fig14_damping_law_540", "fig19_filtered_unfiltered")


def _pl(p) -> str:
    return f"{float(p):g}"


def _fig_rig(demo):
    figs = []
    axes = new_axes(None, figsize=(10.0, 4.0), ncols=len(demo.preloads))
    axes = np.atleast_1d(axes)
    for ax, pr in zip(axes, demo.preloads):
        law = pr.rig.model.laws[0]
        top = max((float(np.max(r.exact.joint_amplitude)) for r in pr.repredictions), default=law.iwan.phi_max / 4)
        plot_joint_law(law, [0.25 * top, 0.5 * top, top], ax=ax)
        ax.set_title(f"joint law, preload {_pl(pr.preload)} N (relative rotation)")
    figs.append(("rig_joint_law", "The rig's joint law (Iwan micro-slip minus cubic softening) on the relative rotation: "
                 "steady loops at the relative rotations of the 6 N tests, with the closed-form virgin curve.",
                 axes[0].figure))
    ax = new_axes(None, figsize=(6.0, 4.2))
    for pr in demo.preloads:
        p = pr.rig.model.laws[0].iwan
        plot_joint_dissipation(pr.rig.model.laws[0], (1e-3 * p.F_S, 0.8 * p.F_S), ax=ax,
                               label=f"{_pl(pr.preload)} N: discrete Iwan")
    ax.set_title("Iwan dissipation per cycle (closed-form check)")
    figs.append(("rig_joint_dissipation", "Energy dissipated per cycle by the discretised Iwan joint against the "
                 "moment amplitude (points) and Segalman's closed forms (lines); the micro-slip slope is 3 + chi.",
                 ax.figure))
    return figs


def _fig09(demo):
    axes = np.atleast_1d(new_axes(None, figsize=(11.0, 4.2), ncols=2))
    curves = []
    for pr in demo.preloads:
        style = "--" if pr.preload == min(p.preload for p in demo.preloads) else "-"
        names = list(pr.rig.sensors)
        i = names.index("accel_42") if "accel_42" in names else -1
        curves.append((f"{_pl(pr.preload)} N (H1, random test)", pr.frf.frequency_hz, pr.frf.H[i], style))
    plot_linear_frfs(curves, ax=axes[0], f_range=(10.0, 600.0))
    f1 = [float(pr.modal_fit.frequencies_hz[0]) for pr in demo.preloads]
    plot_linear_frfs(curves, ax=axes[1], f_range=(min(f1) - 1.0, max(f1) + 1.0))
    for pr in demo.preloads:
        for f in pr.modal_fit.frequencies_hz:
            axes[0].axvline(f, color="0.8", lw=0.6, zorder=0)
        axes[1].axvline(pr.modal_fit.frequencies_hz[0], color="0.8", lw=0.6, zorder=0)
    axes[1].set_xlim(min(f1) - 1.0, max(f1) + 1.0)
    axes[0].set_title("Linear FRFs at 42 cm: 120 N (dashed), 540 N (solid)")
    axes[1].set_title("around mode 1")
    return [("fig09_linear_frf", "Seed Fig 9 analogue: linear FRFs (H1 from the low-level random test) at the 42 cm "
             "accelerometer, 120 N dashed and 540 N solid; right: around mode 1; vertical lines: fitted natural "
             "frequencies.", axes[0].figure)]


def _fig10(demo):
    axes = np.atleast_1d(new_axes(None, figsize=(11.0, 4.4), ncols=len(demo.preloads)))
    for ax, pr in zip(axes, demo.preloads):
        plot_nonlinear_frfs(pr.repredictions, ax=ax, title=f"preload {_pl(pr.preload)} N")
    return [("fig10_nonlinear_frf", "Seed Fig 10 analogue: nonlinear FRFs (fundamental of accel_42 over the force) "
             "of the stepped-sine dwells at F = 1.5 (+), 3 (o) and 6 N (filled); lines: the identified single-mode "
             "model re-predicted by harmonic balance; dotted: the rig's exact steady states.", axes[0].figure)]


def _fig11(demo):
    pr = demo.preloads[-1]
    top = max(g.force_level for g in pr.result.groups)
    recs = [o for o in pr.result.records if o.ok and o.spec.force_level == top]
    if not recs:
        return []
    o = max(recs, key=lambda r: r.fit.q_max)
    s = o.signals
    q, v, a_fit = s.states()
    axes = plot_record(s.t, s.force, s.accel_measured, a_fit, v, q, periods=3.0 / s.frequency_hz,
                       title=f"{o.spec.file}: preload {_pl(pr.preload)} N, F = {top:g} N, {s.frequency_hz:.3f} Hz")
    return [("fig11_record", "Seed Fig 11 analogue: modal force, measured and fitted modal acceleration and the "
             "analytically integrated velocity and displacement of the resonant 6 N dwell.", axes[0].figure)]


def _fig12(demo):
    axes = np.atleast_1d(new_axes(None, figsize=(11.0, 4.0), ncols=len(demo.preloads)))
    for ax, pr in zip(axes, demo.preloads):
        for i, g in enumerate(sorted((g for g in pr.result.groups if g.pooled is not None),
                                     key=lambda g: g.force_level)):
            m, fill = FORCE_MARKERS.get(float(g.force_level), ("s", "full"))
            ax.errorbar(g.pooled.q_max, g.pooled.get("c"), yerr=g.pooled.get_stderr("c"), fmt=m, fillstyle=fill,
                        ms=5, capsize=2, label=f"F = {g.force_level:g} N")
        je = pr.joint_exponent
        if je:
            qq = np.linspace(0.0, je["q_ref"], 200)
            ax.plot(qq, je["c0"] + je["a"] * (qq / je["q_ref"]) ** je["m"], "k--", lw=0.9,
                    label=f"c0 + a q^m: 2 + m = {je['exponent']:.2f} (rig 3 + chi = "
                          f"{pr.rig.model.laws[0].iwan.dissipation_exponent:.2f})")
        ax.set_title(f"identified damping, preload {_pl(pr.preload)} N")
        ax.set_xlabel("q_max [m]")
        ax.set_ylabel("c [N s/m]")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    from .figure_meta import mark_comparison

    mark_comparison(axes[0], "per-record damping vs c0 + a q_max^m", "stderr bars")
    return [("fig12_damping", "Seed Fig 12 analogue: per-record damping coefficient c (pooled regression, error "
             "bars: standard errors) against the response amplitude q_max; dashed: c0 + a q_max^m, whose 2 + m "
             "estimates the joint's dissipation exponent 3 + chi.", axes[0].figure)]


def _fig13_16(demo):
    figs = []
    for k, pr in enumerate(demo.preloads):
        law = pr.damping_law
        if law is not None:
            ax = new_axes(None, figsize=(6.0, 4.0))
            plot_damping_law(law, ax=ax, label=f"preload {_pl(pr.preload)} N")
            c0 = 2 * float(pr.rig.model.zeta[0] * pr.rig.model.omega[0])
            ax.axhline(c0, color="0.5", ls=":", lw=0.8, label="rig material damping 2 zeta w1")
            ax.legend(fontsize=7)
            ax.set_title(f"damping law, preload {_pl(pr.preload)} N")
            figs.append((f"fig{13 + k}_damping_law_{_pl(pr.preload)}",
                         f"Seed Fig {13 + k} analogue: damping coefficients (points) and the fitted c(q_max) of order "
                         f"{law.order}, preload {_pl(pr.preload)} N.", ax.figure))
    for k, pr in enumerate(demo.preloads):
        ax = new_axes(None, figsize=(6.0, 4.0))
        groups = [g for g in pr.result.groups if g.power_law is not None]
        for g in sorted(groups, key=lambda g: g.force_level):
            plot_power_law(g.power_law, ax=ax, label=f"F = {g.force_level:g} N, n = {g.power_law.n:.3f}")
        if groups:
            chi3 = pr.rig.model.laws[0].iwan.dissipation_exponent
            g = max(groups, key=lambda g: g.force_level)
            F = np.geomspace(min(np.min(x.power_law.force) for x in groups), max(np.max(x.power_law.force)
                                                                              for x in groups), 20)
            Fr = float(np.max(g.power_law.force))
            ax.loglog(F, g.power_law(Fr) * (F / Fr) ** chi3, "k:", lw=0.9, label=f"slope 3 + chi = {chi3:.2f} (rig)")
            ax.legend(fontsize=7)
        ax.set_title(f"energy per cycle, preload {_pl(pr.preload)} N")
        figs.append((f"fig{15 + k}_energy_{_pl(pr.preload)}",
                     f"Seed Fig {15 + k} analogue: energy dissipated per cycle by the identified damping against the "
                     f"modal joint force amplitude, per force level, with U = alpha F^n; dotted: the rig's Iwan "
                     f"exponent 3 + chi.", ax.figure))
    return figs


def _fig17_19(demo):
    """Seed Figs 17-19 from the loops the demo carries (:class:`~jointid.app.reprediction.DwellLoops`)."""
    figs = []
    for k, pr in enumerate(demo.preloads):
        dl = pr.loops
        if dl is None:
            continue
        axes = np.atleast_1d(new_axes(None, figsize=(11.0, 3.6), ncols=len(dl.records)))
        for ax, o, loop in zip(axes, dl.records, dl.filtered):
            plot_hysteresis(loop, ax=ax)
            ax.set_title(f"{o.signals.frequency_hz:.3f} Hz", fontsize=9)
        top = dl.force_level
        axes[0].figure.suptitle(f"hysteresis loops, preload {_pl(pr.preload)} N, F = {top:g} N", fontsize=10)
        figs.append((f"fig{17 + k}_hysteresis_{_pl(pr.preload)}",
                     f"Seed Fig {17 + k} analogue: nonlinear restoring force Q - q'' - omega1^2 q against q, from the "
                     f"filtered signals (full) and from the identified parameters (dashed), preload "
                     f"{_pl(pr.preload)} N, F = {top:g} N.", axes[0].figure))
    pr = demo.preloads[0]
    dl = pr.loops
    if dl is not None:
        o = dl.largest
        ax = new_axes(None, figsize=(6.0, 4.2))
        for loop, style in ((dl.largest_unfiltered, "-"), (dl.largest_filtered, "--")):
            q = np.append(loop.q, loop.q[:1])
            m = np.append(loop.measured, loop.measured[:1])
            ax.plot(q, m, style, lw=1.1, label="filtered" if loop.filtered else "unfiltered")
        ax.set_xlabel("q [m] (modal)")
        ax.set_ylabel("Q - q'' - omega1² q [N] (modal)")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
        ax.set_title(f"filtered and unfiltered loops, preload {_pl(pr.preload)} N, {o.signals.frequency_hz:.3f} Hz")
        figs.append(("fig19_filtered_unfiltered", "Seed Fig 19 analogue: measured hysteresis loop from the unfiltered "
                     "signals (full) and the filtered ones (dashed); the higher harmonics (joint harmonics and the "
                     "higher modes they excite) make the difference.", ax.figure))
    return figs


def demo_figures(demo) -> list:
    """``(name, caption, figure)`` of every figure of the demo report."""
    figs = []
    for make in (_fig_rig, _fig09, _fig10, _fig11, _fig12, _fig13_16, _fig17_19):
        figs += make(demo)
    return figs


def save_figures(figs, folder, svg=SVG_FIGURES, dpi=100) -> tuple:
    """Write each figure as PNG (and SVG for the names in ``svg``).

    Returns
    -------
    paths : dict
        Figure name -> written paths.
    cached : list
        ``(name, caption, PNG bytes)``: the PNG bytes, so that the HTML embeds them
        without drawing the figures again.
    """
    folder = Path(folder)
    out = {}
    cached = []
    for name, caption, fig in figs:
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=dpi)
        png = buf.getvalue()
        paths = [atomic_write(folder / f"{name}.png", png)]
        if name in svg:
            sbuf = io.BytesIO()
            fig.savefig(sbuf, format="svg")
            paths.append(atomic_write(folder / f"{name}.svg", sbuf.getvalue()))
        out[name] = paths
        cached.append((name, caption, png))
    return out, cached


def check_rows(demo) -> list:
    """The acceptance checks as table rows ``{check, value, passed}``."""
    c = demo.checks
    labels = {
        "w1_error_percent_max": "identified f1 vs the rig's linear f1 (max |error| %, limit 0.2)",
        "damping_grows_with_amplitude": "identified damping grows with amplitude",
        "lower_preload_more_nonlinear": "the lower preload is the more nonlinear",
        "n_in_2_3": "power-law exponent n in [2, 3]",
        "peak_amplitude_error_percent_max": "re-predicted FRF peak amplitude (max |error| %, limit 2)",
        "peak_frequency_error_percent_max": "re-predicted FRF peak frequency (max |error| %, limit 0.1)",
        "uff_csv_identical": "UFF58 records read back identical to the CSV ones",
        "no_failed_records": "records that failed (none allowed)",
    }
    value_key = {"damping_grows_with_amplitude": "damping_vs_amplitude_correlation_min",
                 "lower_preload_more_nonlinear": "damping_growth_at_top_amplitude", "n_in_2_3": "n_range",
                 "no_failed_records": "n_failed_records"}
    rows = []
    for key, ok in c["passed"].items():
        val = c["values"].get(value_key.get(key, key))
        if isinstance(val, dict):
            val = ", ".join(f"{format_value(k)}: {format_value(v)}" for k, v in val.items())
        elif isinstance(val, list):
            val = ", ".join(format_value(v) for v in val)
        else:
            val = format_value(val)
        rows.append({"check": labels.get(key, key), "value": val, "passed": bool(ok)})
    return rows


def demo_sections(demo, figs) -> list:
    """The report's sections."""
    by = {name: (caption, fig) for name, caption, fig in figs}

    def fig(name):
        return [by[name]] if name in by else []

    overview = Section("Overview", [
        "The seed paper's experiment (Jalali, Ahmadian and Mottershead 2007, sections 5-7) repeated on a virtual "
        "bolted-beam rig: a finite element cantilever of two steel beams with a nonlinear bolted lap joint "
        "(four-parameter Iwan micro-slip and cubic stiffness on the joint's relative rotation), two bolt preloads, "
        "a shaker at 5 cm with a force cell, accelerometers at 30 and 42 cm, sensor noise, higher modes present.",
        "The rig writes physical campaigns (CSV and UFF 58 records, campaign.toml with a [structure] section); "
        "the identification reads only those files: random test -> H1 -> modal fit -> FE updating -> first mode "
        "shape -> modal coordinates -> force-state mapping -> damping and power laws -> harmonic-balance "
        "re-prediction.",
    ])

    rig = Section("The virtual rig", [
        "Each preload is the seed beam updated to its Table 4 frequencies (joint k_w, k_t and clamp k_c) with the "
        "joint stuck; the joint law's small-amplitude stiffness K_T is part of the updated rotational spring. "
        "Steady states come from multi-harmonic balance of the modal-truncated model (harmonics up to 1.5 x the "
        "highest kept mode, Iwan force by alternating frequency/time), each dwell checked by a time integration "
        "started on its orbit (settle check) before it is recorded."])
    rows = []
    for pr in demo.preloads:
        law = pr.rig.model.laws[0]
        p = law.iwan
        rows.append({
            "preload [N]": pr.preload,
            "f1..f4 stuck [Hz]": ", ".join(format_value(f, 5) for f in pr.rig.linear_frequencies_hz),
            "modal damping ratio [%]": 100 * float(pr.rig.model.zeta[0]),
            "F_S [N m]": p.F_S, "K_T [N m/rad]": p.K_T, "chi [1]": p.chi, "beta [1]": p.beta,
            "phi_max [rad]": p.phi_max, "k3 joint [N m/rad³]": law.k3,
            "3 + chi [1]": p.dissipation_exponent,
            "settle check max relative deviation [1]": max(d.settle_deviation for d in pr.campaign.dwells),
        })
    rig.tables.append(("rig parameters per preload", rows, None))
    rig.figures += fig("rig_joint_law") + fig("rig_joint_dissipation")

    lin = Section("Linear test and FE updating (seed Fig 9, Table 4)", [
        "Low-level random force (band-limited white noise); H1 estimates at both accelerometers; a single-mode fit "
        "around each of the first three peaks gives the natural frequencies that update the seed beam's joint and "
        "clamp stiffnesses. The updated model's mass-normalised first mode at the force point and at the two "
        "accelerometers turns the records into the first modal coordinate."])
    lin.tables.append(("Table 4 analogue: linear natural frequencies", [pr.table4_row() for pr in demo.preloads],
                       None))
    rows = []
    for pr in demo.preloads:
        up = dict(zip(pr.update.parameters, pr.update.values))
        rb = pr.rig.beam
        shape_true = pr.rig.modes.shape_at([pr.rig.force_position] + [pr.rig.sensors[n] for n in pr.rig.sensors], 0)
        shape_id = np.concatenate([pr.structure.phi_force[:1], pr.structure.phi_sensors[:, 0]])
        rows.append({
            "preload [N]": pr.preload,
            "k_w updated / rig [1]": format_value(up.get("k_w", np.nan) / rb.joint.k_w, 5),
            "k_t updated / rig [1]": format_value(up.get("k_t", np.nan) / rb.joint.k_t, 5),
            "k_c updated / rig [1]": format_value(up.get("k_c", np.nan) / rb.clamp_stiffness, 5),
            "phi_1 (force, 30, 42 cm) max relative error [1]": float(np.max(np.abs(shape_id / shape_true - 1))),
            "random test: joint secant loss at RMS / max motion [1]": " / ".join(
                format_value(v, 3) for k in ("rms", "max")
                for v in pr.rig.random_linearity(pr.campaign.random_joint_motion[k])),
        })
    lin.tables.append(("updated model against the rig", rows, None))
    lin.figures += fig("fig09_linear_frf")

    selected = {pr.preload: getattr((pr.result.selections or {}).get(pr.preload), "selected", None)
                for pr in demo.preloads}
    if any(selected.values()):
        which = ("The single-mode model the data select for each preload (column 'model': its terms and amplitude "
                 "laws fitted over all the preload's force levels; the seed cubic is judged in the adequacy "
                 "section)")
    else:
        which = ("The identified single-mode model of each preload and force level (omega1 and k3 of that level, "
                 "the preload's damping law c(q_max))")
    nl = Section("Nonlinear FRFs and re-prediction (seed Fig 10)", [
        "Stepped sine at constant force amplitude around mode 1. " + which + " is solved by harmonic balance with "
        "the modal force phi_1(x_f) F; its peak is compared with the peak of the rig's exact steady states (both "
        "located by halving the frequency intervals beside the highest point, then a parabola)."])
    rows = []
    for pr in demo.preloads:
        for r in pr.repredictions:
            rows.append({"preload [N]": pr.preload, "F [N]": r.force_level,
                         "peak f rig [Hz]": format_value(r.peak_exact[0], 7),
                         "peak f model [Hz]": format_value(r.peak_predicted[0], 7),
                         "f error [%]": format_value(r.peak_frequency_error_percent, 3),
                         "peak |a/F| rig [(m/s²)/N]": r.peak_exact[1], "peak |a/F| model [(m/s²)/N]": r.peak_predicted[1],
                         "amplitude error [%]": format_value(r.peak_amplitude_error_percent, 3),
                         "model": selected[pr.preload] or "seed cubic"})
    nl.tables.append(("peaks of the nonlinear FRFs", rows, None))
    nl.figures += fig("fig10_nonlinear_frf")

    ident = Section("Identified parameters (seed Table 5, Figs 11-12)", [
        "Force-state mapping of Q - q'' = omega1^2 q - k3 q^3 + c q' per record and pooled per (preload, force level): "
        "omega1 and k3 shared, one damping coefficient per record. The rig's linear f1 is the stuck-joint first "
        "frequency; its joint is not a cubic spring plus a viscous damper, so k3 and c are the model's equivalent "
        "values. The rig's modal cubic coefficient alone is "
        + ", ".join(f"{format_value(pr.rig.modal_cubic_coefficient, 3)} N/m³ ({_pl(pr.preload)} N)"
                    for pr in demo.preloads)
        + "; the Iwan joint's softening adds to it."])
    rows = []
    for pr in demo.preloads:
        for r in pr.table5_rows():
            g = pr.group(r["F [N]"])
            rows.append({"preload [N]": r["preload [N]"], "F [N]": r["F [N]"],
                         "f1 identified [Hz]": format_pm(r["f1 identified [Hz]"], g.pooled.omega1_stderr / (2 * np.pi)),
                         "f1 band average [Hz]": format_value(r["f1 band average [Hz]"], 7),
                         "f1 rig [Hz]": format_value(r["f1 rig [Hz]"], 7), "f1 error [%]": format_value(r["f1 error [%]"], 3),
                         "k3 identified [N/m³]": format_pm(r["k3 identified"], r["k3 stderr"]),
                         "n (U = alpha F^n) [1]": format_pm(r["n (U = alpha F^n)"], g.power_law.n_stderr)
                         if g.power_law is not None else "–"})
    ident.tables.append(("Table 5 analogue (value ± standard error)", rows, None))
    ident.figures += fig("fig11_record") + fig("fig12_damping")

    laws = Section("Damping laws (seed Figs 13-14)")
    rows = []
    for pr in demo.preloads:
        law = pr.damping_law
        if law is None:
            continue
        se = list(law.stderr)
        rows.append({"preload [N]": pr.preload,
                     **{f"c{k} [{unit_of(f'c{k}')}]": format_pm(v, se[k] if k < len(se) else None)
                        for k, v in enumerate(law.coefficients)},
                     "rig 2 zeta w1 [N s/m]": 2 * float(pr.rig.model.zeta[0] * pr.rig.model.omega[0]),
                     "fit": (f"chi²/dof {format_value(law.chi2 / law.dof, 3)}, {len(law.q_max)} records"
                             if law.dof else f"{len(law.q_max)} records")})
    laws.tables.append(("c(q_max) = c0 + c1 q_max + c2 q_max² (value ± standard error)", rows, None))
    laws.figures += [f for p in demo.preloads for f in fig(f"fig{13 + demo.preloads.index(p)}_damping_law_"
                                                               f"{_pl(p.preload)}")]

    energy = Section("Energy dissipation power law (seed Figs 15-16)", [
        "U = integral of c(q_max) q'^2 over one period of each record, against the modal elastic force amplitude, "
        "fitted by U = alpha F^n per (preload, force level). The rig's joint alone dissipates as F^(3 + chi) in "
        "micro-slip; the beam's material damping is viscous (F^2), so the rig's own energy curve over the same "
        "records has the effective exponent of the column 'n rig effective', which the identified n should match.",
        "The joint's exponent itself can be recovered from the identified damping: an Iwan joint's equivalent "
        "viscous damping grows as q_max^(1 + chi), so c = c0 + a (q_max / q_ref)^m fitted to the per-record damping "
        "of a preload gives 2 + m as an estimate of 3 + chi (second table)."])
    rows = []
    for pr in demo.preloads:
        for g in pr.result.groups:
            if g.power_law is None:
                continue
            ex = pr.exact_energy.get(str(g.force_level), {})
            rows.append({"preload [N]": pr.preload, "F [N]": g.force_level,
                         "n identified [1]": format_pm(g.power_law.n, g.power_law.n_stderr,
                                                       dof=len(g.power_law.force) - 2),
                         "in [2, 3]": g.power_law.within_bounds,
                         "n rig effective [1]": ex.get("n_rig_effective"), "3 + chi (rig joint) [1]": ex.get("n_iwan")})
    energy.tables.append(("power-law exponents", rows, None))
    rows = []
    for pr in demo.preloads:
        je = pr.joint_exponent or {}
        rows.append({"preload [N]": pr.preload, "c0 [N s/m]": je.get("c0"),
                     "m [1]": format_pm(je.get("m"), je.get("m_stderr")),
                     "2 + m (identified) [1]": format_pm(je.get("exponent"), je.get("m_stderr")),
                     "3 + chi (rig joint) [1]": pr.rig.model.laws[0].iwan.dissipation_exponent,
                     "rig 2 zeta w1 [N s/m]": 2 * float(pr.rig.model.zeta[0] * pr.rig.model.omega[0])})
    energy.tables.append(("joint exponent from c = c0 + a q_max^m", rows, None))
    energy.figures += [f for k, p in enumerate(demo.preloads) for f in fig(f"fig{15 + k}_energy_{_pl(p.preload)}")]

    hyst = Section("Hysteresis loops (seed Figs 17-19)")
    hyst.figures += [f for k, p in enumerate(demo.preloads) for f in fig(f"fig{17 + k}_hysteresis_{_pl(p.preload)}")]
    hyst.figures += fig("fig19_filtered_unfiltered")

    files = Section("Files", [
        "Each preload is a campaign folder (campaign.toml with coordinates = \"physical\" and a [structure] "
        "section; records as CSV and as UFF dataset 58; the random test under random/). "
        "results.json holds every number of this page."])
    rows = []
    for pr in demo.preloads:
        camp = pr.campaign
        rows.append({"preload [N]": pr.preload, "folder": str(camp.folder), "records": len(camp.entries),
                     "manifest names": camp.plan.manifest_format, "formats": ", ".join(camp.plan.formats),
                     "failed": len(pr.result.failed), "UFF = CSV": pr.uff_csv_identical})
    files.tables.append(("campaigns", rows, None))
    failed = [{"preload [N]": pr.preload, "file": o.spec.file, "error": o.error}
              for pr in demo.preloads for o in pr.result.failed]
    if failed:
        files.tables.append(("failed records", failed, None))
    appendix = Section("Appendix: acceptance checks and timings",
                       [f"Total run time {format_value(demo.timings.get('total'), 3)} s."])
    appendix.tables.append(("acceptance checks", check_rows(demo), ["check", "value", "passed"]))
    appendix.tables.append(("run time per stage [s]", [{"stage": k, "time [s]": format_value(v, 3)}
                                                      for k, v in demo.timings.items()], ["stage", "time [s]"]))
    return [demo_summary_section(demo), overview, rig, lin, nl, ident, laws, energy, hyst, files, appendix]


def demo_summary_section(demo) -> Section:
    """The demo's summary: which model to believe and why, the model the data select for each
    preload with 95 % intervals, the paper's cubic beside it, the paper's Tables 4 and 5 in the
    paper's units, and the adequacy and selection verdicts."""
    from .summary import error_lines, lead_tables, warning_rows

    summaries = [pr.result.summary() for pr in demo.preloads]  # one per campaign: record indices are per campaign
    choice, tables = lead_tables(summaries)
    sec = Section("Summary", choice + [
        "Modal quantities of the mass-normalised first mode (k3 in N/m³ and c in N s/m for one kg of modal mass, "
        "i.e. 1/(m² s²) and 1/s per unit modal mass); values rounded to two significant digits of their standard "
        "error."])
    t4 = []
    for pr in demo.preloads:
        f = float(pr.modal_fit.frequencies_hz[0])
        t4.append({"preload [N]": pr.preload, "f1 measured [Hz]": format_value(f, 5),
                   "omega1 measured [rad/s]": format_value(2 * np.pi * f, 5),
                   "f1 rig [Hz]": format_value(float(pr.rig.linear_frequencies_hz[0]), 5),
                   "f2, f3 measured [Hz]": ", ".join(format_value(v, 4) for v in pr.modal_fit.frequencies_hz[1:3])})
    at = next(i for i, t in enumerate(tables) if t[0].startswith("The paper's Table 5"))
    sec.tables += tables[:at] + [("Table 4: linear natural frequencies (random test, H1 modal fit)", t4, None)]
    sec.tables += tables[at:]
    w = [row for s_ in summaries for row in warning_rows(s_)]
    n_flag = sum(len(pr.result.flagged) for pr in demo.preloads)
    sec.paragraphs.append(f"{sum(len(pr.result.failed) for pr in demo.preloads)} failed and {n_flag} flagged records"
                          + (f"; {sum(r['records'] for r in w)} record warnings (kinds per group below)" if w else ""))
    sec.paragraphs += [line for s_ in summaries for line in error_lines(s_)]
    if w:
        sec.tables.append(("record warnings per group", w, None))
    return sec


def write_demo_html(demo, out_dir, figs) -> Path:
    """Write ``report.html`` (self-contained) for a demo result and its (cached) figures."""
    path = Path(out_dir) / "report.html"
    from .html import page_meta

    write_html(path, "jointid demo: the seed paper's experiment on a virtual bolted-beam rig",
               demo_sections(demo, figs),
               intro="Identification of nonlinear bolted lap-joint parameters by force-state mapping, "
                     "end to end on simulated measurements.",
               meta=page_meta(getattr(demo, "run_id", None)))
    return path
