"""What a reader needs first: the identified model, the paper's tables, the verdicts, the warnings.

Every function here reads the content of ``results.json`` (a :meth:`CampaignResult.summary`
dict, or the file read back), so the same summary is shown by the HTML report, the console
and a notebook, and results written by older versions (keys absent) still display.
Values are rounded by :func:`~jointid.report.formatting.format_pm`.
"""

from __future__ import annotations

import math
import re
from collections import Counter

import numpy as np

from .formatting import format_ci, format_pm, format_value, unit_of

__all__ = ["coefficient_note", "model_rows", "table5_rows", "band_resolution", "adequacy_rows", "message_kind", "group_messages",
           "warning_rows", "error_lines", "summary_lines", "console_lines", "Z95"]

Z95 = 1.959963984540054

_PREFIX = re.compile(r"^\s*(?:[^\s\[]+\s+)?\[record\s+\d+\]:\s*")


def _finite(x) -> bool:
    try:
        return x is not None and math.isfinite(float(x))
    except (TypeError, ValueError):
        return False


def message_kind(text) -> str:
    """The kind of a warning or error message: without its ``file [record N]:`` prefix and
    cut at its first colon, numbers replaced by ``#`` (``"k3 not resolved by the data"``)."""
    body = _PREFIX.sub("", str(text).strip())
    # errors name the file first ("records/0001.csv: missing column 'force'")
    body = re.sub(r"^[^\s:]+\.(?:csv|uff|unv|mat|h5|hdf5)\b[^:]*:\s*", "", body)
    kind = body.split(": ", 1)[0] if ": " in body else body
    return re.sub(r"(?<![\w^.])[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?(?![\w.])", "#", kind).strip()


def group_messages(messages) -> list:
    """``[(kind, count, first message)]`` of a list of messages, most frequent first, so that
    123 copies of one error read as one line with a count."""
    messages = [str(m) for m in messages if m]
    counts = Counter(message_kind(m) for m in messages)
    first = {}
    for m in messages:
        first.setdefault(message_kind(m), m)
    return [(k, n, first[k]) for k, n in sorted(counts.items(), key=lambda kv: (-kv[1], kv[0]))]


def _pm_ci(value, stderr, unit):
    ci = [value - Z95 * stderr, value + Z95 * stderr] if _finite(value) and _finite(stderr) else None
    return format_pm(value, stderr), format_ci(ci, stderr), unit


def coefficient_note(name, value, stderr) -> str:
    """What a reader should know about an estimate: unresolved (its 95 % interval includes
    zero) or, for a damping-law coefficient, negative (the law decreases with amplitude)."""
    if _finite(value) and _finite(stderr) and abs(value) < Z95 * stderr:
        return "not resolved (95 % interval includes zero)"
    if str(name).startswith("c") and str(name)[1:].isdigit() and _finite(value) and value < 0:
        return "negative: this term lowers c(q_max) as the amplitude grows (a fit over the measured range)"
    return ""


def model_rows(summary) -> list:
    """One row per identified quantity of each preload's model (value ± standard error, 95 %
    interval, unit): f1 in Hz and omega1 in rad/s, then k3 and the damping law c0, c1, ..."""
    rows = []
    for m in summary.get("models") or []:
        p = m.get("preload")
        if m.get("omega1") is None and m.get("error"):
            rows.append({"preload": str(p), "quantity": "model", "value ± standard error": "not identified",
                         "95 % interval": "–", "unit": "", "note": str(m.get("error"))})
            continue
        w, sw = m.get("omega1"), m.get("omega1_stderr")
        if _finite(w):
            sf = sw / (2 * np.pi) if _finite(sw) else None
            for name, v, s, unit in (("f1", w / (2 * np.pi), sf, "Hz"), ("omega1", w, sw, "rad/s")):
                v_txt, ci_txt, _ = _pm_ci(v, s, unit)
                rows.append({"preload": str(p), "quantity": name, "value ± standard error": v_txt,
                             "95 % interval": ci_txt, "unit": unit, "note": ""})
        names = m.get("parameter_names") or []
        vals, errs = m.get("parameters") or [], m.get("stderr") or []
        for n, v, s in zip(names, vals, errs):
            if n == "omega1^2":
                continue
            v_txt, ci_txt, unit = _pm_ci(v, s, unit_of(n))
            note = coefficient_note(n, v, s)
            rows.append({"preload": str(p), "quantity": n, "value ± standard error": v_txt, "95 % interval": ci_txt,
                         "unit": unit, "note": note})
        if m.get("q_max_range"):
            lo, hi = m["q_max_range"]
            rows.append({"preload": str(p), "quantity": "q_max range", "value ± standard error":
                         f"{format_value(lo, 3)} .. {format_value(hi, 3)}", "95 % interval": "–", "unit": "m",
                         "note": f"{m.get('n_records', '?')} records"})
    return rows


def band_resolution(summary, group) -> dict:
    """Whether the band average of single-record ``k3`` (the paper's Table 5 method) is resolved.

    The band average's standard error is the scatter of the single-record values over the
    square root of their number.  It is *unresolved* when its 95 % interval includes zero and
    *inconsistent* when it differs from the pooled fit by more than their combined 95 %
    interval.  Returns ``{"mean", "stderr", "resolved", "consistent", "note"}`` (``{}``
    without single-record ``k3``).
    """
    members = set(group.get("records") or [])
    k3 = [r.get("k3") for r in summary.get("records") or [] if r.get("index") in members and r.get("status") == "ok"]
    k3 = np.array([v for v in k3 if _finite(v)], float)
    if k3.size == 0:
        return {}
    mean = float(k3.mean())
    se = float(k3.std(ddof=1) / np.sqrt(k3.size)) if k3.size > 1 else float("nan")
    resolved = bool(_finite(se) and abs(mean) > Z95 * se)
    pooled, pse = group.get("k3"), group.get("k3_stderr")
    consistent = None
    if _finite(pooled) and _finite(pse) and _finite(se):
        consistent = bool(abs(mean - pooled) <= Z95 * math.hypot(se, pse))
    notes = []
    if not resolved:
        notes.append("unresolved: its 95 % interval includes zero")
    if consistent is False:
        notes.append("differs from the pooled fit beyond their 95 % intervals")
    return {"mean": mean, "stderr": se, "resolved": resolved, "consistent": consistent, "note": "; ".join(notes)}


def table5_rows(summary) -> list:
    """The paper's Table 5 per (preload, force level): the pooled fit's f1, omega1 and k3, and
    the band average of single-record k3 (the paper's own number), flagged when unresolved."""
    rows = []
    for g in summary.get("groups") or []:
        w, sw = g.get("omega1"), g.get("omega1_stderr")
        row = {"preload": str(g.get("preload")), "F": format_value(g.get("force_level")),
               "records": len(g.get("records") or []),
               "f1 [Hz]": format_pm(w / (2 * np.pi), sw / (2 * np.pi) if _finite(sw) else None) if _finite(w) else "–",
               "omega1 [rad/s]": format_pm(w, sw) if _finite(w) else "–",
               "k3 [N/m³] (pooled)": format_pm(g.get("k3"), g.get("k3_stderr")) if g.get("k3") is not None else "–"}
        band = band_resolution(summary, g) if g.get("k3_mean") is not None else {}
        if band:
            row["k3 [N/m³] band average (paper)"] = format_pm(band["mean"], band["stderr"])
            row["band average"] = band["note"] or "resolved"
        else:
            row["k3 [N/m³] band average (paper)"] = "–"
            row["band average"] = ""
        rows.append(row)
    return rows


def _verdict(d):
    for key in ("verdict", "adequate", "passed", "ok", "selected", "best"):
        if key in d:
            v = d[key]
            return ("adequate" if v else "not adequate") if isinstance(v, bool) and key != "selected" else str(v)
    return None


def adequacy_rows(summary) -> list:
    """Rows of the model adequacy and selection verdicts, when ``results.json`` has them
    (keys ``adequacy`` and ``selection``; each a list of per-preload dicts or a dict)."""
    rows = []
    for key in ("adequacy", "selection"):
        part = summary.get(key)
        if not part:
            continue
        items = part if isinstance(part, list) else (
            [dict(v, preload=k) if isinstance(v, dict) else {"preload": k, "verdict": v} for k, v in part.items()]
            if all(isinstance(v, dict) for v in part.values()) and "verdict" not in part else [part])
        for it in items:
            if not isinstance(it, dict):
                rows.append({"what": key, "preload": "", "verdict": str(it), "details": ""})
                continue
            details = "; ".join(f"{k} {format_value(v) if not isinstance(v, str) else v}" for k, v in it.items()
                                if k not in ("preload", "verdict") and isinstance(v, (str, int, float, bool))
                                and v is not None)
            rows.append({"what": key, "preload": str(it.get("preload", "")), "verdict": _verdict(it) or "–",
                         "details": details[:400]})
    return rows


def warning_rows(summary) -> list:
    """Warnings of the records grouped by (preload, force level) and kind, with counts."""
    groups = {}
    for r in summary.get("records") or []:
        key = (str(r.get("preload")), format_value(r.get("force_level")))
        groups.setdefault(key, []).extend(r.get("warnings") or [])
    rows = []
    for (p, F), msgs in groups.items():
        for kind, n, example in group_messages(msgs):
            rows.append({"preload": p, "F": F, "warning": kind, "records": n, "example": example})
    return rows


def error_lines(summary) -> list:
    """Failed records: one line per kind of error with a count and one example."""
    failed = [r for r in summary.get("records") or [] if r.get("status") != "ok"]
    return [f"{n} record(s): {example}" if n == 1 else f"{n} records: {kind} (e.g. {example})"
            for kind, n, example in group_messages(r.get("error") or r.get("status") for r in failed)]


def summary_lines(summary) -> list:
    """A short plain-text summary for the console: models, Table 5 with the band average
    flagged, verdicts, then the warnings per group and the grouped errors."""
    out = []
    for row in model_rows(summary):
        out.append(f"  preload {row['preload']}: {row['quantity']} = {row['value ± standard error']} {row['unit']}"
                   f"  95 % {row['95 % interval']}" + (f"  ({row['note']})" if row["note"] else ""))
    if out:
        out.insert(0, "Identified model per preload (value ± standard error, 95 % interval):")
    t5 = table5_rows(summary)
    if t5:
        out.append("Table 5 (pooled fit per force level; band average = the paper's mean of single-record fits):")
        for r in t5:
            flag = f"  <- {r['band average']}" if r["band average"] not in ("", "resolved") else ""
            out.append(f"  preload {r['preload']}, F {r['F']} N: f1 {r['f1 [Hz]']} Hz, k3 {r['k3 [N/m³] (pooled)']} "
                       f"N/m³; band average k3 {r['k3 [N/m³] band average (paper)']}{flag}")
    for r in adequacy_rows(summary):
        out.append(f"{r['what']}, preload {r['preload']}: {r['verdict']}")
    w = warning_rows(summary)
    if w:
        out.append("Warnings per group (details per record in results.json):")
        out += [f"  preload {r['preload']}, F {r['F']}: {r['records']} x {r['warning']}" for r in w]
    errs = error_lines(summary)
    if errs:
        out.append(f"Failed records ({sum(1 for r in summary.get('records') or [] if r.get('status') != 'ok')}):")
        out += ["  " + e for e in errs]
    return out


def console_lines(summary) -> list:
    """What the console adds below the text report (which lists the failed records by kind of
    error): the band averages (the paper's Table 5 numbers) with their resolution and the
    warnings per group with counts."""
    out = []
    bands = [(g, band_resolution(summary, g)) for g in summary.get("groups") or [] if g.get("k3_mean") is not None]
    bands = [(g, b) for g, b in bands if b]
    if bands:
        out.append("* k3 band avg: the paper's Table 5 number, the mean of single-record fits (standard error from "
                   "their scatter); the pooled k3 is the estimate to use:")
        for g, b in bands:
            out.append(f"  preload {g.get('preload')}, F {format_value(g.get('force_level'))}: band average "
                       f"{format_pm(b['mean'], b['stderr'])} N/m³" + (f"  <- {b['note']}" if b["note"] else ""))
    w = warning_rows(summary)
    if w:
        out.append("Warnings per group (every message is in results.json):")
        out += [f"  preload {r['preload']}, F {r['F']}: {r['records']} x {r['warning']}" for r in w]
    for m in summary.get("models") or []:
        out += [f"preload {m.get('preload')} model: {w_}" for w_ in m.get("warnings") or []]
    return out
