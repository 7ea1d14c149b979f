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

import hashlib
import re
from pathlib import Path

import numpy as np

from ..identify.hysteresis import hysteresis_loop
from ..io.outputset import MARKER, check_output_folder, new_run_id, output_set
from ..io.results import atomic_write, write_csv, write_json
from .formatting import format_pm, format_value, unit_of
from .html import Section, figure_to_png, write_html
from .identify_plots import new_axes, plot_damping_law, plot_hysteresis, plot_parameters_vs_frequency, plot_power_law
from .tables import group_rows, record_rows

__all__ = ["write_results", "campaign_figures", "campaign_sections", "slug", "tex_safe", "check_output_folder",
           "output_set", "new_run_id", "MARKER"]

#: Longest label kept in a file name (the rest is replaced by a hash of the whole label).
SLUG_MAX = 40


def slug(value) -> str:
    """A file-name-safe form of a grouping value: ASCII letters, digits and ``.+-_``, at most
    ``SLUG_MAX`` characters; a label that had to be changed gets a short hash of itself, so
    two different labels never share a file name.

    Examples
    --------
    >>> slug(120), slug("1.5 N"), slug("a/../b")[:6]
    ('120', '1.5_N', 'a_.._b')
    """
    text = str(value)
    safe = re.sub(r"[^A-Za-z0-9.+-]+", "_", text).strip("_.") or "none"
    if len(safe) > SLUG_MAX or safe != text.replace(" ", "_"):
        digest = hashlib.sha1(text.encode("utf-8", "surrogatepass")).hexdigest()[:8]
        safe = f"{safe[:SLUG_MAX]}_{digest}"
    return safe


def tex_safe(value, max_length=60) -> str:
    """A label for matplotlib text: ``$`` escaped so that it is not read as mathtext, and
    shortened to ``max_length`` characters (a long label would squeeze the axes away).

    Examples
    --------
    >>> print(tex_safe("$x^2$"))
    \\$x^2\\$
    """
    text = str(value)
    if len(text) > max_length:
        text = text[: max_length - 3] + "..."
    return text.replace("$", r"\$")


def write_results(result, out_dir, figures=True, html=True) -> dict:
    """Write ``results.json``, ``records.csv``, ``groups.csv``, ``damping_laws.csv``,
    ``report.txt``, PNG figures and a self-contained ``report.html``, as one set.

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
    summary = result.summary()
    summary["run_id"] = run_id
    text = result.report() + "\n"
    if flagged_lines(result):
        text += "\n" + "\n".join(flagged_lines(result)) + "\n"
    text += f"\nrun id {run_id}\n"
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
    figs = [(n, c, figure_to_png(f, dpi=120)) for n, c, f in campaign_figures(result)] if figures else []
    if figures:
        paths["figures"] = [atomic_write(out / "figures" / name, png) for name, _, png in figs]
    if html:
        paths["html"] = out / "report.html"
        n_flagged = len(flagged_lines(result)[1:])
        from .html import page_meta

        write_html(paths["html"], f"jointid: {result.name}", campaign_sections(result, figs, summary),
                   intro=f"{len(result.records)} records, {len(result.failed)} failed, {n_flagged} flagged.",
                   meta=page_meta(run_id))
    return paths


def _law_rows(summary) -> list:
    from .summary import coefficient_note

    rows = []
    for d in summary.get("damping_law") or []:
        coef, se = d.get("coefficients"), d.get("stderr") or []
        if coef is None:
            rows.append({"preload": str(d.get("preload")), "coefficient": "–", "value ± standard error": "not fitted",
                         "unit": "", "note": "", "fit": str(d.get("error") or "")})
            continue
        fit = (f"chi²/dof {format_value(d.get('chi2_dof'), 3)}, p = {format_value(d.get('p_value'), 2)}, "
               f"{d.get('n_records', '?')} records") if d.get("chi2_dof") is not None else ""
        for k, v in enumerate(coef):
            s_k = se[k] if k < len(se) else None
            rows.append({"preload": str(d.get("preload")), "coefficient": f"c{k}",
                         "value ± standard error": format_pm(v, s_k), "unit": unit_of(f"c{k}"),
                         "note": coefficient_note(f"c{k}", v, s_k), "fit": fit if k == 0 else ""})
    return rows


def _power_rows(summary) -> list:
    rows = []
    for d in summary.get("power_law") or []:
        rows.append({"preload": str(d.get("preload")), "F [N]": format_value(d.get("force_level")),
                     "alpha": format_value(d.get("alpha"), 4),
                     "n ± standard error": format_pm(d.get("n"), d.get("n_stderr")) if d.get("n") is not None
                     else str(d.get("error") or "–"),
                     "n within [2, 3]": d.get("within_2_3")})
    return rows


def _reprediction_table(summary) -> list:
    rows = []
    loops = {(str(x.get("preload")), str(x.get("force_level"))): x for x in (summary.get("reprediction") or {}).get("loops", [])}
    for d in (summary.get("reprediction") or {}).get("groups", []):
        key = (str(d.get("preload")), str(d.get("force_level")))
        loop = loops.get(key, {})

        def pct(v, digits=2):
            return "–" if v is None else f"{v:+.{digits}f} %"

        rows.append({
            "preload": key[0], "F": format_value(d.get("force_level")),
            "peak frequency error": pct(d.get("peak_frequency_error_percent"), 3),
            "peak magnitude error": pct(d.get("peak_amplitude_error_percent")),
            "rms error at the measured dwells": "–" if d.get("point_rms_error_percent") is None
            else f"{d['point_rms_error_percent']:.2f} %",
            "loop rms difference (filtered)": "–" if (loop.get("filtered") or {}).get("rms_difference") is None
            else f"{100 * loop['filtered']['rms_difference']:.1f} %",
            "peak resolved by the dwells": d.get("peak_resolved"),
        })
    return rows


def campaign_sections(result, figs, summary=None) -> list:
    """HTML sections of a campaign result: the summary first (model per preload with 95 %
    intervals, the paper's Table 5 with the band average flagged, damping law, verdicts), then
    the re-prediction errors, figures, warnings and flagged records, records, and an appendix."""
    from .reprediction_plots import reprediction_rows
    from .summary import adequacy_rows, error_lines, model_rows, table5_rows, warning_rows

    summary = result.summary() if summary is None else summary
    s = summary.get("settings") or {}
    head = Section("Summary", [
        f"{summary.get('n_records', len(result.records))} records, {summary.get('n_failed', len(result.failed))} failed, "
        f"{len(summary.get('flagged') or [])} flagged by the plausibility checks. Model terms: "
        f"{' + '.join(s.get('terms') or [])}; {s.get('n_harmonics', '?')} harmonics; damping law order "
        f"{s.get('damping_order', '?')}. Modal quantities of the mass-normalised first mode in the seed paper's units "
        "(k3 in N/m³ and c in N s/m for one kg of modal mass, i.e. 1/(m² s²) and 1/s per unit modal mass as in "
        "jointid.conventions); values are rounded to two significant digits of their standard error."])
    head.tables.append(("Identified model per preload: one regression over all its records, damping law inside "
                        "(value ± standard error, 95 % interval)", model_rows(summary), None))
    head.tables.append(("The paper's Table 5 per force level: pooled fit (shared omega1 and k3, one c per record) and "
                        "the band average of single-record k3 (the paper's number), flagged where unresolved",
                        table5_rows(summary), None))
    head.tables.append(("Damping law c(q_max) = c0 + c1 q_max + c2 q_max² (the paper's two-step method, Table 2)",
                        _law_rows(summary), None))
    verdicts = adequacy_rows(summary)
    if verdicts:
        head.tables.append(("Model adequacy and selection", verdicts, None))
    else:
        head.paragraphs.append("No model adequacy verdict in these results.")
    laws = Section("Energy per cycle", ["U = alpha F^n over each group's records (seed Figs 15, 16); U in J, F in N."])
    laws.tables.append(("U = alpha F^n", _power_rows(summary), None))
    repred = Section("Identified vs measured", [
        "Each group's identified model solved by harmonic balance at the group's forcing, against the measured "
        "dwells: peak frequency and magnitude errors, rms error at the measured points, and the rms difference "
        "between measured and identified hysteresis loops (relative to the measured loop's rms)."])
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
    records.tables.append(("records", record_rows(result), ["index", "file", "preload", "force_level", "frequency_hz",
                                                             "status", "q_max", "omega1", "k3", "c", "c_pooled",
                                                             "error"]))
    appendix = Section("Appendix: settings and checks")
    appendix.tables.append(("settings", [{"setting": k, "value": v if isinstance(v, (int, float, str)) or v is None
                                          else str(v)} for k, v in s.items()], None))
    appendix.tables.append(("groups (all numbers)", group_rows(result), None))
    appendix.tables.append(("re-predicted FRFs (all numbers)", reprediction_rows(result), None))
    delay = summary.get("channel_delay") or {}
    if delay.get("delay_s") is not None or delay.get("error"):
        appendix.paragraphs.append(f"channel delay: {delay}")
    return [head, laws, repred, figures, notes, records, appendix]


#: Most figures drawn for one campaign (a campaign of many groups would otherwise spend
#: minutes drawing figures nobody pages through); the tables and results.json hold every group.
MAX_FIGURES = 60


def campaign_figures(result, max_figures=MAX_FIGURES) -> list:
    """``(file name, caption, figure)`` of the damping laws, power laws, per-record
    parameters and hysteresis loops (filtered and unfiltered) of a campaign result;
    at most ``max_figures`` (preload by preload, group by group)."""
    written = []
    preloads = list(result.damping_laws)
    for p in preloads:
        if len(written) >= max_figures:
            break
        law = result.damping_laws[p]
        groups = [g for g in result.groups if g.preload == p]
        if law is not None:
            ax = new_axes()
            plot_damping_law(law, ax=ax, label=f"preload {tex_safe(p)}")
            ax.set_title(f"damping law, preload {tex_safe(p)}")
            written.append((f"damping_law_{slug(p)}.png", f"damping law c(q_max), preload {p}", ax.figure))
        laws = [g for g in groups if g.power_law is not None]
        if laws:
            ax = new_axes()
            for g in laws:
                plot_power_law(g.power_law, ax=ax, label=f"F = {tex_safe(g.force_level)}")
            ax.set_title(f"energy per cycle, preload {tex_safe(p)}")
            written.append((f"power_law_{slug(p)}.png", f"energy per cycle vs joint force, preload {p}", ax.figure))
        for g in groups:
            if len(written) + 2 > max_figures:
                break
            indices = set(g.record_indices)
            members = [r for r in result.records if r.spec.index in indices]
            if not members:
                continue
            tag = f"{slug(p)}_F{slug(g.force_level)}"
            f = np.array([r.signals.frequency_hz for r in members])
            summaries = [r.summary() for r in members]
            vals = {"f1 [Hz]": [d["f1_hz"] for d in summaries]}
            for name in ("k3", "c"):
                if all(d[name] is not None for d in summaries):
                    vals[name] = [d[name] for d in summaries]
            axes = plot_parameters_vs_frequency(f, vals)
            axes[0].set_title(f"per-record parameters, preload {tex_safe(p)}, F = {tex_safe(g.force_level)}")
            written.append((f"parameters_{tag}.png", f"per-record parameters, preload {p}, F = {g.force_level}",
                            axes[0].figure))
            if g.gain is not None:  # the force column is not a force: no loops in force units
                continue
            j = int(np.argmax([r.fit.q_max for r in members]))
            best = members[j]
            axes = new_axes(None, figsize=(9.0, 3.8), ncols=2)
            # the identified model of the group: shared omega1^2, k3 and this record's own damping
            theta = np.array([g.pooled.get(n) if n in g.pooled.shared_names else g.pooled.get(n)[j]
                              for n in best.fit.coefficient_names])
            for ax, filt in zip(axes, (True, False)):
                loop = hysteresis_loop(best.signals, best.fit.terms, theta, filtered=filt)
                plot_hysteresis(loop, ax=ax, show_identified=True)
            axes[0].set_title(f"hysteresis, {tex_safe(best.spec.file)}")
            written.append((f"hysteresis_{tag}.png", f"hysteresis loops (filtered, unfiltered) of {best.spec.file}, "
                                                     f"preload {p}, F = {g.force_level}", axes[0].figure))
    from .reprediction_plots import reprediction_figures

    written += reprediction_figures(result)
    from .selection_plots import selection_figures

    written += selection_figures(result)  # model-selection ranking and level-equality plots per preload
    from .backbone_plots import backbone_figures

    written += backbone_figures(result)  # omega(a), zeta(a) and the joint laws per preload
    return written
