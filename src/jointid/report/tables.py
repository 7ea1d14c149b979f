"""Plain-text tables of identification results."""

from __future__ import annotations

import re

import numpy as np

from .formatting import format_ci, format_estimate, format_percent, format_pm, format_value, text_table, unit_of

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
            if r.get("equality across force levels", "–") != "–" or r.get("median record misfit [× noise]", "–") != "–":
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
        out += [f"  preload {r['preload']}: warning: {r['warnings']}" for r in sels if r.get("warnings", "–") != "–"]
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


def _law_rows(summary) -> list:
    from .summary import Z95, coefficient_note, run_units

    units = run_units(summary)
    rows = []
    for d in summary.get("damping_law") or []:
        coef, se = d.get("coefficients"), d.get("stderr") or []
        if coef is None:
            rows.append({"preload": str(d.get("preload")), "coefficient": "–", "value ± standard error": "not fitted",
                         "95 % interval": "–", "unit": "", "note": "", "fit": str(d.get("error") or "")})
            continue
        fit = (f"chi²/dof {format_value(d.get('chi2_dof'), 3)}, p = {format_value(d.get('p_value'), 2)}, "
               f"{d.get('n_records', '?')} records") if d.get("chi2_dof") is not None else ""
        for k, v in enumerate(coef):
            s_k = se[k] if k < len(se) else None
            name = f"c{k}"
            label, unit = units.get(name, (name, unit_of(name)))
            ci = [v - Z95 * s_k, v + Z95 * s_k] if s_k is not None and np.isfinite(s_k) else None
            rows.append({"preload": str(d.get("preload")), "coefficient": label,
                         "value ± standard error": format_pm(v, s_k), "95 % interval": format_ci(ci, s_k),
                         "unit": unit if k <= 2 or label == name else f"1/(m^{k} s)",
                         "note": coefficient_note(name, v, s_k), "fit": fit if k == 0 else ""})
    return rows


def _power_rows(summary) -> list:
    from .summary import run_units

    gain_free = run_units(summary)["F"][1] == "V"
    F = f"F [{run_units(summary)['F'][1]}]"
    alpha_unit = "m²/s² / (m/s²)^n" if gain_free else "J/N^n"
    rows = []
    for d in summary.get("power_law") or []:
        n_pts = len(d.get("force") or []) or None
        dof = None if n_pts is None else n_pts - 2  # U = alpha F^n: two parameters
        rows.append({"preload": str(d.get("preload")), F: format_value(d.get("force_level")),
                     "records": n_pts if n_pts is not None else "–",
                     f"alpha [{alpha_unit}]": format_value(d.get("alpha"), 4),
                     "n ± standard error [1]": format_pm(d.get("n"), d.get("n_stderr"), dof=dof)
                     if d.get("n") is not None else str(d.get("error") or "–"),
                     "n within [2, 3]": d.get("within_2_3")})
    return rows


def _reprediction_table(summary) -> list:
    from .summary import run_units

    F = f"F [{run_units(summary)['F'][1]}]"
    rows = []
    loops = {(str(x.get("preload")), str(x.get("force_level"))): x for x in (summary.get("reprediction") or {}).get("loops", [])}
    for d in (summary.get("reprediction") or {}).get("groups", []):
        key = (str(d.get("preload")), str(d.get("force_level")))
        loop = loops.get(key, {})
        resolved = d.get("peak_resolved")
        why = "not bracketed by the dwells" if d.get("peak_bracketed") is False else "not resolved by the dwells"
        peak = (lambda v: format_percent(v, 3, sign=True)) if resolved is not False else (lambda v: why)
        lrms = (loop.get("filtered") or {}).get("rms_difference")
        rows.append({
            "preload": key[0], F: format_value(d.get("force_level")),
            "peak frequency error [%]": peak(d.get("peak_frequency_error_percent")),
            "peak magnitude error [%]": peak(d.get("peak_amplitude_error_percent")),
            "rms error at the measured dwells [%]": format_percent(d.get("point_rms_error_percent"), 2),
            "loop rms difference (filtered) [%]": format_percent(None if lrms is None else 100 * lrms, 2),
            "peak resolved by the dwells": resolved,
        })
    return rows


def _delay_text(delay) -> str:
    """The channel delay as a sentence with its standard error, 95 % interval and unit (or its error)."""
    if delay.get("delay_s") is None:
        return f"channel delay not estimated: {delay.get('error')}"
    v, se = float(delay["delay_s"]) * 1e3, delay.get("stderr_s")
    se = float(se) * 1e3 if se is not None and np.isfinite(se) and se > 0 else None
    return ("channel delay tau of the response channel behind the excitation channel (negative: the response "
            f"leads): {format_estimate(v, se, 'ms') if se is not None else format_value(v, 4) + ' ms (given)'}")
