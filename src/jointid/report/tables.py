"""Plain-text tables of identification results."""

from __future__ import annotations

import re

import numpy as np

from .formatting import format_estimate, format_percent, format_value, text_table

__all__ = ["format_table", "campaign_report", "record_rows", "group_rows"]


def format_table(rows, columns, headers=None, floatfmt=".6g") -> str:
    """Fixed-width text table of ``rows`` (dicts) restricted to ``columns``; numbers go through
    :func:`~jointid.report.formatting.format_value` with the significant digits of ``floatfmt``
    (``".6g"``: six)."""
    m = re.fullmatch(r"\.(\d+)[gGeEf]", str(floatfmt))
    digits = int(m.group(1)) if m else 6
    shown = [{c: (format_value(r.get(c), digits) if isinstance(r.get(c), (float, np.floating)) else r.get(c))
              for c in columns} for r in rows]
    return text_table(shown, columns, headers)


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


def _indent(lines) -> list:
    return ["  " + line for line in lines]


def campaign_report(result) -> str:
    """Text report (console, ``report.txt``): which model to believe, the selected and the
    preload model with 95 % intervals, the force gain when identified, adequacy and selection,
    the paper's Table 5 per group, damping laws (Table 2), power laws, re-predictions,
    failures.  Every number goes through :mod:`jointid.report.formatting`."""
    from .output import _delay_text, _law_rows, _power_rows, _reprediction_table
    from .summary import adequacy_rows, lead_lines, run_units, selection_rows, table5_rows

    summary = result.summary()
    units = run_units(summary)
    Fu, (k3n, k3u) = units["F"][1], units["k3"]
    out = [f"campaign {result.name!r}: {len(result.records)} records, {len(result.failed)} failed",
           f"terms: {' + '.join(result.settings.summary()['terms'])}, "
           f"{result.settings.n_harmonics} harmonics, damping law order {result.settings.damping_order}"
           + ("; force gain unknown: force levels in V, k3/m and c/m per unit modal mass" if Fu == "V" else ""), ""]
    out += lead_lines(summary) + [""]
    adq = adequacy_rows(summary)
    if adq:
        out.append("Model adequacy per preload:")
        for r in adq:
            out.append(f"  preload {r['preload']}, {r['model']}: {r['verdict']}")
            if r.get("equality across force levels", "–") != "–":
                out.append(f"    equality across force levels: {r['equality across force levels']}; median record "
                           f"misfit {r['median record misfit [× noise]']} x the noise; restoring force explained "
                           f"{r['restoring force explained [%] (lowest record)']} %")
                out.append("    harmonics above the first: residual / measured energy "
                           f"{r['harmonics above the first: residual / measured energy [1] (worst record)']} "
                           "(0 = explained, 1 = as if left out), residual / noise "
                           f"{r['harmonics above the first: residual / noise [1]']} (1 = explained to the noise)")
        out.append("")
    sels = selection_rows(summary)
    if sels:
        out.append("Model selection per preload:")
        out += [f"  preload {r['preload']}: {r['selected model']} ({r['terms']}, {r['parameters']} parameters, "
                f"{r['records']} records); " + "; ".join(f"{k} {v}" for k, v in r.items() if k.startswith("the paper"))
                for r in sels]
        out.append("")
    from .backbone_plots import backbone_report_lines

    out += backbone_report_lines(result)
    t5 = table5_rows(summary)
    if t5:
        out.append(f"Groups (the paper's method, Table 5): pooled regression per force level (shared omega1, {k3n}; "
                   "one c per record) and band average (value ± standard error)")
        cols = [c for c in t5[0] if c != "band average"]
        out.append(text_table(t5, cols))
    for g in summary.get("groups") or []:
        if g.get("omega1") is None:
            continue
        txt = (f"  preload {g.get('preload')}, F = {format_value(g.get('force_level'))} {Fu}: omega1 = "
               f"{format_estimate(g['omega1'], g.get('omega1_stderr'), 'rad/s')}")
        if g.get("k3") is not None:
            txt += f"; {k3n} = {format_estimate(g['k3'], g.get('k3_stderr'), k3u)}"
        out.append(txt)
    out.append("")
    laws = _law_rows(summary)
    if laws:
        out.append("Damping laws c(q_max) (the paper's two-step method: polynomial fitted to the pooled per-record c):")
        for r in laws:
            out.append(f"  preload {r['preload']}: {r['coefficient']} = {r['value ± standard error']} {r['unit']}"
                       + (f"  95 % {r['95 % interval']}" if r["95 % interval"] not in ("–", "") else "")
                       + (f"  ({r['note']})" if r["note"] else "") + (f"  [{r['fit']}]" if r["fit"] else ""))
        out.append("")
    power = _power_rows(summary)
    if power:
        out.append("Power laws U = alpha F^n of the dissipated energy per cycle:")
        for r in power:
            a_key = next(k for k in r if k.startswith("alpha"))
            out.append(f"  preload {r['preload']}, F = {r[f'F [{Fu}]']} {Fu}: {a_key.split(' ', 1)[0]} = {r[a_key]} "
                       f"{a_key.split('[', 1)[1][:-1]}, n = {r['n ± standard error [1]']} ({r['records']} records)")
    delay = summary.get("channel_delay") or {}
    if delay.get("delay_s") is not None or delay.get("error"):
        out += ["", "Records corrected by the " + _delay_text(delay)]
    broadband = getattr(result, "broadband", ())
    if broadband:
        out.append("")
        out.append("Broadband records (broadband force-state mapping; free-run simulation of held-out records):")
        out += ["  " + line for b in broadband for line in b.report().splitlines()]
    reps = _reprediction_table(summary)
    if reps:
        out.append("")
        out.append("Re-predicted FRFs (identified model by harmonic balance vs the measured dwells):")
        for r in reps:
            peak = (f"peak frequency error {r['peak frequency error [%]']}, peak magnitude error "
                    f"{r['peak magnitude error [%]']}" if r["peak resolved by the dwells"] is not False
                    else f"peak {r['peak frequency error [%]']}: no peak error")
            out.append(f"  preload {r['preload']}, F = {r[f'F [{Fu}]']} {Fu}: {peak}, rms error at the measured "
                       f"dwells {r['rms error at the measured dwells [%]']}")
    for row in getattr(result, "loops", ()):
        d = row.get("filtered") or {}
        if "rms_difference" in d:
            out.append(f"  loops, preload {row['preload']}, F = {format_value(row['force_level'])} {Fu} ({row['file']}): "
                       f"measured vs identified rms difference {format_percent(100 * d['rms_difference'], 2)} "
                       "(filtered)")
    if result.failed:
        out.append("")
        out.append(f"Failed records ({len(result.failed)}; each error in results.json):")
        from .summary import group_messages

        for kind, n, example in group_messages(r.error for r in result.failed):  # one line per kind of error
            out.append(f"  {example}" if n == 1 else f"  {n} records: {kind} (e.g. {example})")
    return "\n".join(out)
