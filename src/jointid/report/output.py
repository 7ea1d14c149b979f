"""Write a :class:`~jointid.app.workflow.CampaignResult` to a folder: JSON, CSV, text and figures.

The files of one run form a set: they are written into a temporary folder beside the output
folder and moved into place once all are complete (:func:`jointid.io.outputset.output_set`),
so a reader sees the previous set or the new one, never a mix, and files of an earlier run
that the new one does not write (figures of groups no longer present) are gone; only an
earlier identify set is replaced, never the campaign or a folder of other files.  Each set carries a run id
(``results.json`` key ``run_id``, the reports).  Labels taken from a manifest are made safe
for file names (:func:`slug`), for matplotlib text (:func:`tex_safe`) and for spreadsheets
(see :func:`jointid.io.results.write_csv`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..io.outputset import MARKER, check_output_folder, new_run_id, output_set
from ..io.results import atomic_write, misfits, write_csv, write_json
from .formatting import SLUG_MAX, format_value, slug, tex_safe  # noqa: F401  (slug, tex_safe re-exported)
from .html import Section, figure_to_png, write_html
from .identify_plots import new_axes, plot_damping_law, plot_hysteresis, plot_parameters_vs_frequency, plot_power_law
from .tables import _delay_text, _law_rows, _power_rows, _reprediction_table, group_rows, record_rows  # noqa: F401

__all__ = ["write_results", "campaign_figures", "campaign_sections", "slug", "tex_safe", "check_output_folder",
           "output_set", "new_run_id", "MARKER"]

def write_results(result, out_dir, figures=True, html=True) -> dict:
    """Write ``results.json``, ``records.csv``, ``groups.csv``, ``damping_laws.csv``,
    ``report.txt``, PNG figures and a self-contained ``report.html``, as one set.
    ``figures="summary"`` draws the figures of each preload only (``per_group=False`` of
    :func:`campaign_figures`), ``False`` none.

    The set replaces ``out_dir`` as a whole once complete (see :func:`output_set`);
    ``results.json`` gets the run id under ``run_id``.

    Returns a dict of the written paths (in ``out_dir``).

    Raises
    ------
    OutputError
        When ``out_dir`` cannot be written (see :func:`check_output_folder`).
    """
    final = Path(out_dir)
    run_id = new_run_id()
    with output_set(final, run_id, kind="identify", inputs=(getattr(result, "root", None),)) as out:
        paths = _write_set(result, out, run_id, figures, html)
    return {k: ([final / Path(p).relative_to(out) for p in v] if isinstance(v, list) else final / Path(v).relative_to(out))
            for k, v in paths.items()}


def flagged_lines(result) -> list:
    """One line per flagged record (empty when none)."""
    flagged = [r for r in result.records if r.ok and getattr(r, "flags", ())]
    if not flagged:
        return []
    kept = "kept in" if getattr(result.settings, "keep_flagged", False) else "left out of"
    lines = [f"{len(flagged)} record(s) flagged by the plausibility checks ({kept} the pooled fits):"]
    lines += [f"  record {r.spec.index} ({r.spec.file}): " + "; ".join(f.report() for f in r.flags) for r in flagged]
    return lines


def _write_set(result, out, run_id, figures, html) -> dict:
    if hasattr(result, "write_set"):  # a result of another record type (first harmonics) writes its own files
        return result.write_set(out, run_id, figures=bool(figures), html=html)
    summary = result.summary()
    summary["run_id"] = run_id
    if getattr(result, "provenance", None):  # versions, host, workers, times (not results: not in summary())
        summary["provenance"] = result.provenance
    text = result.report() + "\n"
    if flagged_lines(result):
        text += "\n" + "\n".join(flagged_lines(result)) + "\n"
    if misfit_text(summary):
        text += "\n" + misfit_text(summary) + "\n"
    text += f"\nrun id {run_id}\n"
    if getattr(result, "provenance", None):
        from .provenance_text import provenance_line

        text += provenance_line(result.provenance) + "\n"
    paths = {
        "results": write_json(out / "results.json", summary),
        "records": write_csv(out / "records.csv", record_rows(result)),
        "groups": write_csv(out / "groups.csv", group_rows(result)),
        "report": atomic_write(out / "report.txt", text),
    }
    law_rows = [{"preload": p, **({f"c{k}": v for k, v in enumerate(l.coefficients)} if l else {})}
                for p, l in result.damping_laws.items()]
    cols = ["preload"] + [f"c{k}" for k in range(result.settings.damping_order + 1)]
    paths["damping_laws"] = write_csv(out / "damping_laws.csv", law_rows, cols)
    # each figure is rendered once; the same PNG bytes are written and embedded
    # each figure is drawn once (PNG file and HTML); --no-figures skips them in both
    figs = [(n, c, figure_to_png(f, dpi=120)) for n, c, f in campaign_figures(result, per_group=figures != "summary")] if figures else []
    if figures:
        paths["figures"] = [atomic_write(out / "figures" / name, png) for name, _, png in figs]
    if html:
        paths["html"] = out / "report.html"
        n_flagged = len(flagged_lines(result)[1:])
        from .html import page_meta

        write_html(paths["html"], f"jointid: {result.name}", campaign_sections(result, figs, summary),
                   intro=f"{len(result.records)} records, {len(result.failed)} failed, {n_flagged} flagged.",
                   meta=_with_provenance(page_meta(run_id), result))
    return paths


def _with_provenance(meta, result):
    prov = getattr(result, "provenance", None)
    if prov:
        from .provenance_text import provenance_line

        meta = {**meta, "run": provenance_line(prov)}
    return meta


def misfit_text(summary) -> str:
    """One sentence naming the regressions whose model does not fit the data to their errors
    (``results.json`` ``fit_checks``, :mod:`jointid.app.fit_checks`); empty when all fit."""
    bad = misfits(summary.get("fit_checks"))
    if not bad:
        return ""
    return "The model does not fit the data to their errors: " + "; ".join(c.get("message", "") for c in bad) + "."


#: Significant digits of values shown without a standard error, where four would hide the differences.
_DIGITS = {"frequency_hz": 6, "omega1": 6, "f1_hz": 7, "f1_hz_mean": 7, "f_peak_predicted": 6, "f_peak_reference": 6}


def _display(rows, columns) -> list:
    """Rows with display headers (units in brackets) for the ``{key: header}`` of ``columns``;
    numbers without a standard error get :data:`_DIGITS` significant digits (default four)."""
    def cell(k, v):
        if k in _DIGITS and isinstance(v, (float, np.floating)):
            return format_value(v, _DIGITS[k])
        return v

    return [{h: cell(k, r.get(k)) for k, h in columns.items()} for r in rows]


def _record_columns(units) -> dict:
    F, (k3n, k3u), (cn, cu) = units["F"][1], units["k3"], units["c"]
    return {"index": "index", "file": "file", "preload": "preload", "force_level": f"F [{F}]",
            "frequency_hz": "f [Hz]", "status": "status", "q_max": "q_max [m]", "omega1": "omega1 [rad/s]",
            "k3": f"{k3n} [{k3u}]", "c": f"{cn} [{cu}]", "c_pooled": f"{cn} pooled [{cu}]", "error": "error"}


def _group_columns(units) -> dict:
    F, (k3n, k3u) = units["F"][1], units["k3"]
    return {"preload": "preload", "force_level": f"F [{F}]", "n_records": "records", "f1_hz": "f1 [Hz]",
            "omega1": "omega1 [rad/s]", "k3": f"{k3n} [{k3u}]", "k3_stderr": f"se({k3n}) [{k3u}]",
            "f1_hz_mean": "f1 band average [Hz]", "k3_mean": f"{k3n} band average [{k3u}]",
            "alpha": "alpha [m²/s² / (m/s²)^n]" if F == "V" else "alpha [J/N^n]",
            "n": "n [1]"}


def _reprediction_columns(units) -> dict:
    F = units["F"][1]
    return {"preload": "preload", "force_level": f"F [{F}]", "forcing": f"modal forcing [{'V' if F == 'V' else 'N'}]",
            "f_peak_predicted": "peak f predicted [Hz]", "f_peak_reference": "peak f reference [Hz]",
            "f_peak_error_%": "peak f error [%]", "H_peak_error_%": "peak magnitude error [%]",
            "points_rms_error_%": "rms error at the dwells [%]", "reference": "reference",
            "folds_hz": "folds [Hz]", "loop_rms_filtered": "loop rms difference, filtered [1]",
            "loop_rms_unfiltered": "loop rms difference, unfiltered [1]"}


def campaign_sections(result, figs, summary=None) -> list:
    """HTML sections of a campaign result: the summary first (which model to believe, the model
    the data select and the preload model with 95 % intervals, the force gain when identified,
    the paper's Table 5 with the band average flagged, damping law, adequacy and selection
    tables), then the re-prediction errors, figures, warnings and flagged records, records, and
    an appendix."""
    from .reprediction_plots import reprediction_rows
    from .summary import error_lines, lead_tables, run_units, warning_rows

    summary = result.summary() if summary is None else summary
    units = run_units(summary)
    s = summary.get("settings") or {}
    choice, tables = lead_tables([summary])
    gain_free = units["F"][1] == "V"
    head = Section("Summary", choice + [
        f"{summary.get('n_records', len(result.records))} records, {summary.get('n_failed', len(result.failed))} failed, "
        f"{len(summary.get('flagged') or [])} flagged by the plausibility checks. Model terms: "
        f"{' + '.join(s.get('terms') or [])}; {s.get('n_harmonics', '?')} harmonics; damping law order "
        f"{s.get('damping_order', '?')}. "
        + ("The force column is a voltage with an unknown gain (--force-gain unknown): force levels are in V and "
           "the stiffness and damping coefficients are ratios to the identified inertia coefficient m = 1/g "
           "(k3/m in 1/(m² s²), c/m in 1/s: per unit modal mass). " if gain_free else
           "Modal quantities of the mass-normalised first mode in the seed paper's units (k3 in N/m³ and c in N s/m "
           "for one kg of modal mass, i.e. 1/(m² s²) and 1/s per unit modal mass as in jointid.conventions). ")
        + "Values are rounded to two significant digits of their standard error."])
    at = next(i for i, t in enumerate(tables) if t[0].startswith("The paper's Table 5"))
    head.tables += tables[:at + 1]
    law_title = ("Damping law c(q_max)/m = c0 + c1 q_max + c2 q_max² (per unit modal mass)" if gain_free else
                 "Damping law c(q_max) = c0 + c1 q_max + c2 q_max² (the paper's two-step method, Table 2)")
    head.tables.append((law_title, _law_rows(summary), None))
    head.tables += tables[at + 1:]
    if len(tables) == at + 1:
        head.paragraphs.append("No model adequacy verdict in these results.")
    if misfit_text(summary):  # a regression whose model does not fit its data (results.json fit_checks)
        head.paragraphs.insert(0, misfit_text(summary))
    laws = Section("Energy per cycle", ["U = alpha F^n over each group's records (seed Figs 15, 16); " + (
        "U per unit modal mass in m²/s² and F the modal joint force per unit modal mass in m/s²." if gain_free else
        "U in J and F, the modal joint force amplitude, in N (one kg of modal mass).")
        + " A group of two records fits U = alpha F^n exactly: its n has no standard error."])
    laws.tables.append(("U = alpha F^n", _power_rows(summary), None))
    repred = Section("Identified vs measured", [
        "Each group's identified model solved by harmonic balance at the group's forcing, against the measured "
        "dwells: peak frequency and magnitude errors (only where the dwells bracket the peak), rms error at the "
        "measured points, and the rms difference between measured and identified hysteresis loops (relative to the "
        "measured loop's rms)."])
    repred.tables.append(("re-prediction errors", _reprediction_table(summary), None))
    figures = Section("Figures", figures=[(caption, fig) for _, caption, fig in figs])
    notes = Section("Warnings and flagged records")
    notes.paragraphs += flagged_lines(result) or ["No record flagged by the plausibility checks."]
    errs = error_lines(summary)
    notes.paragraphs += (["Failed records:"] + errs) if errs else ["No record failed."]
    wrows = warning_rows(summary)
    if wrows:
        notes.tables.append(("warnings per group (kind and number of records; every message is in results.json)",
                             wrows, None))
    for m in summary.get("models") or []:
        for w in m.get("warnings") or []:
            notes.paragraphs.append(f"preload {m.get('preload')} model: {w}")
    records = Section("Records")
    records.tables.append(("records", _display(record_rows(result), _record_columns(units)), None))
    appendix = Section("Appendix: settings and checks")
    appendix.tables.append(("settings", [{"setting": k, "value": v if isinstance(v, (int, float, str)) or v is None
                                          else str(v)} for k, v in s.items()], None))
    appendix.tables.append(("groups (all numbers)", _display(group_rows(result), _group_columns(units)), None))
    appendix.tables.append(("re-predicted FRFs (all numbers)",
                            _display(reprediction_rows(result), _reprediction_columns(units)), None))
    delay = summary.get("channel_delay") or {}
    if delay.get("delay_s") is not None or delay.get("error"):
        appendix.paragraphs.append(_delay_text(delay))
    return [head, laws, repred, figures, notes, records, appendix]


#: Most figures drawn for one campaign (a campaign of many groups would otherwise spend
#: minutes drawing figures nobody pages through); the tables and results.json hold every group.
MAX_FIGURES = 60


def campaign_figures(result, max_figures=MAX_FIGURES, per_group=True) -> list:
    """``(file name, caption, figure)`` of the damping laws, power laws, per-record
    parameters and hysteresis loops (filtered and unfiltered, as the result carries them in
    ``hysteresis_loops``) of a campaign result;
    at most ``max_figures`` (preload by preload, group by group).  ``per_group=False``
    leaves out the two figures of each group (per-record parameters, hysteresis loops)."""
    written = []
    loops = {(x.preload, x.force_level): x for x in getattr(result, "hysteresis_loops", ())}
    preloads = list(result.damping_laws)
    for p in preloads:
        if len(written) >= max_figures:
            break
        law = result.damping_laws[p]
        groups = [g for g in result.groups if g.preload == p]
        gain_free = any(g.gain is not None for g in groups)  # force gain identified: per unit modal mass
        if law is not None:
            ax = new_axes()
            plot_damping_law(law, ax=ax, label=f"preload {tex_safe(p)}", gain_free=gain_free)
            ax.set_title(f"damping law, preload {tex_safe(p)}")
            written.append((f"damping_law_{slug(p)}.png", f"damping law c(q_max), preload {p}", ax.figure))
        laws = [g for g in groups if g.power_law is not None]
        if laws:
            ax = new_axes()
            for g in laws:
                plot_power_law(g.power_law, ax=ax, label=f"F = {tex_safe(g.force_level)}", gain_free=gain_free)
            ax.set_title(f"energy per cycle, preload {tex_safe(p)}")
            written.append((f"power_law_{slug(p)}.png", f"energy per cycle vs joint force, preload {p}", ax.figure))
        for g in groups if per_group else ():
            if len(written) + 2 > max_figures:
                break
            indices = set(g.record_indices)
            members = [r for r in result.records if r.spec.index in indices]
            if not members:
                continue
            tag = f"{slug(p)}_F{slug(g.force_level)}"
            from .identify_plots import plot_record_parameters

            axes = plot_record_parameters(members, g, gain_free=g.gain is not None, title=f"per-record parameters, "
                                          f"preload {tex_safe(p)}, F = {tex_safe(g.force_level)}")
            written.append((f"parameters_{tag}.png", f"per-record parameters, preload {p}, F = {g.force_level}",
                            axes[0].figure))
            if g.gain is not None:  # the force column is not a force: no loops in force units
                continue
            found = loops.get((g.preload, g.force_level))  # formed once in the identification (hysteresis_loops)
            drawn = [] if found is None else [x for x in (found.filtered, found.unfiltered) if not isinstance(x, str)]
            if not drawn:
                continue
            axes = np.atleast_1d(new_axes(None, figsize=(9.0, 3.8), ncols=2))
            for ax, loop in zip(axes, drawn):
                plot_hysteresis(loop, ax=ax, show_identified=True)
            axes[0].set_title(f"hysteresis, {tex_safe(found.record.spec.file)}")
            written.append((f"hysteresis_{tag}.png", f"hysteresis loops (filtered, unfiltered) of "
                                                     f"{found.record.spec.file}, preload {p}, F = {g.force_level}",
                            axes[0].figure))
    from .reprediction_plots import reprediction_figures

    written += reprediction_figures(result)
    from .selection_plots import selection_figures

    written += selection_figures(result)  # model-selection ranking and level-equality plots per preload
    from .backbone_plots import backbone_figures

    written += backbone_figures(result)  # omega(a), zeta(a) and the joint laws per preload
    return written
