"""Plain-text tables of identification results."""

from __future__ import annotations

import numpy as np

__all__ = ["format_table", "campaign_report", "record_rows", "group_rows"]


def format_table(rows, columns, headers=None, floatfmt=".6g") -> str:
    """Fixed-width text table of ``rows`` (dicts) restricted to ``columns``."""
    headers = headers or columns

    def cell(v):
        if v is None:
            return "-"
        if isinstance(v, (float, np.floating)):
            return "nan" if not np.isfinite(v) else format(float(v), floatfmt)
        return str(v)

    body = [[cell(r.get(c)) for c in columns] for r in rows]
    widths = [max(len(h), *(len(b[i]) for b in body)) if body else len(h) for i, h in enumerate(headers)]
    line = "  ".join(h.rjust(w) for h, w in zip(headers, widths))
    out = [line, "  ".join("-" * w for w in widths)]
    out += ["  ".join(b[i].rjust(widths[i]) for i in range(len(widths))) for b in body]
    return "\n".join(out)


def record_rows(result) -> list[dict]:
    rows = []
    for r in result.records:
        s = r.summary()
        rows.append(
            {
                "index": s["index"],
                "file": s["file"],
                "preload": s["preload"],
                "force_level": s["force_level"],
                "frequency_hz": s["frequency_hz"],
                "status": s["status"],
                "q_max": s["q_max"],
                "omega1": s["omega1"],
                "k3": s["k3"],
                "c": s["c"],
                "c_pooled": s.get("c_pooled"),
                "c_pooled_stderr": s.get("c_pooled_stderr"),
                "energy_per_cycle": s.get("energy_per_cycle"),
                "joint_force_amplitude": s.get("joint_force_amplitude"),
                "error": s["error"],
            }
        )
    return rows


def group_rows(result) -> list[dict]:
    rows = []
    for g in result.groups:
        s = g.summary()
        pl = g.power_law
        rows.append(
            {
                "preload": g.preload,
                "force_level": g.force_level,
                "n_records": len(g.record_indices),
                "f1_hz": s.get("f1_hz"),
                "omega1": s.get("omega1"),
                "k3": s.get("k3"),
                "k3_stderr": s.get("k3_stderr"),
                "f1_hz_mean": s.get("f1_hz_mean"),
                "k3_mean": s.get("k3_mean"),
                "alpha": pl.alpha if pl else None,
                "n": pl.n if pl else None,
            }
        )
    return rows


def _pm(value, stderr) -> str:
    """``value ± stderr [lo, hi]`` with the normal 95 % interval."""
    from ..identify.uncertainty import ci95

    ci = ci95(value, stderr)
    if ci is None:
        return f"{value:.8g}" if value is not None else "-"
    return f"{value:.8g} ± {stderr:.2g} [{ci[0]:.8g}, {ci[1]:.8g}]"


def _per_preload(title, results, errors) -> list:
    """A titled section: each preload's result report, indented, or its error."""
    lines = [title]
    for p, r in results.items():
        lines.append("  " + (r.report().replace("\n", "\n  ") if r is not None else errors.get(p, "-")))
    return lines + [""]


def campaign_report(result) -> str:
    """Text report: groups (Table 5 analogue), damping laws (Table 2), power laws, failures."""
    out = [f"campaign {result.name!r}: {len(result.records)} records, {len(result.failed)} failed",
           f"terms: {' + '.join(result.settings.summary()['terms'])}, "
           f"{result.settings.n_harmonics} harmonics, damping law order {result.settings.damping_order}", ""]
    models = getattr(result, "models", {}) or {}
    if models:
        out += _per_preload("Preload models: one regression over all records of a preload, damping law inside "
                            "(value ± standard error, 95 % interval)", models, result.model_errors)
    sels = getattr(result, "selections", None) or {}
    if sels or getattr(result, "selection_errors", None):
        out += _per_preload("Model selection per preload (--terms auto; * selected: the simplest model within "
                            "noise of the best):", sels, result.selection_errors)
    adq = getattr(result, "adequacy", None) or {}
    if adq:
        out += _per_preload("Model adequacy per preload (equality of the shared parameters across force levels, "
                            "records against the preload model, explained fractions):", adq, result.adequacy_errors)
    from .backbone_plots import backbone_report_lines

    out += backbone_report_lines(result)
    out.append("Groups (the paper's method, Table 5): pooled regression per force level (shared omega1, k3; "
               "one c per record) and band average")
    out.append(
        format_table(
            group_rows(result),
            ["preload", "force_level", "n_records", "f1_hz", "k3", "k3_stderr", "f1_hz_mean", "k3_mean", "n"],
            ["preload", "F", "records", "f1 [Hz]", "k3 [N/m^3]", "se(k3)", "f1 band avg", "k3 band avg*", "n (U~F^n)"],
        )
    )
    for g in result.groups:
        pf = g.pooled
        if pf is None or not np.isfinite(pf.omega1):
            continue
        txt = f"  preload {g.preload}, F {g.force_level}: omega1 = {_pm(pf.omega1, pf.omega1_stderr)} rad/s"
        if "k3" in pf.shared_names:
            txt += f", k3 = {_pm(pf.k3, pf.get_stderr('k3'))}"
        out.append(txt)
    out.append("")
    out.append("Damping laws c(q_max) (the paper's two-step method: polynomial fitted to the pooled per-record c):")
    for p, law in result.damping_laws.items():
        out.append(f"  preload {p}: " + (law.report() if law is not None else result.damping_law_errors.get(p, "-")))
    out.append("")
    out.append("Power laws of the dissipated energy per cycle:")
    for g in result.groups:
        txt = g.power_law.report() if g.power_law else (g.power_law_error or "-")
        out.append(f"  preload {g.preload}, F {g.force_level}: {txt}")
    delay = getattr(result, "channel_delay", None)
    if delay is not None:
        out.append("")
        out.append(f"Records corrected by the {delay.report()}")
    broadband = getattr(result, "broadband", ())
    if broadband:
        out.append("")
        out.append("Broadband records (broadband force-state mapping; free-run simulation of held-out records):")
        out += ["  " + line for b in broadband for line in b.report().splitlines()]
    reps = getattr(result, "repredictions", ())
    if reps:
        out.append("")
        out.append("Re-predicted FRFs (identified model by harmonic balance vs the measured dwells):")
        out += [f"  {r.report()}" for r in reps]
    for row in getattr(result, "loops", ()):
        d = row.get("filtered") or {}
        if "rms_difference" in d:
            out.append(f"  loops, preload {row['preload']}, F {row['force_level']} ({row['file']}): measured vs "
                       f"identified rms difference {100 * d['rms_difference']:.1f} % (filtered)")
    if result.failed:
        out.append("")
        out.append(f"Failed records ({len(result.failed)}; each error in results.json):")
        from .summary import group_messages

        for kind, n, example in group_messages(r.error for r in result.failed):  # one line per kind of error
            out.append(f"  {example}" if n == 1 else f"  {n} records: {kind} (e.g. {example})")
    return "\n".join(out)
