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

from ..numerics.intervals import Z95, band_mean_resolution
from .formatting import (
    UNITS,
    format_ci,
    format_estimate,
    format_percent,
    format_pm,
    format_value,
    quantity_units,
    text_table,
    unit_of,
)

__all__ = ["coefficient_note", "model_rows", "table5_rows", "band_resolution", "adequacy_rows", "selection_rows",
           "selected_model_rows", "model_choice_lines", "gain_rows", "run_units", "parameter_unit", "message_kind",
           "group_messages", "warning_rows", "error_lines", "backbone_lines", "summary_lines", "console_lines", "lead_lines", "lead_tables", "Z95",
           "ADEQUACY_NOTE"]


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


def run_units(summary) -> dict:
    """Labels and units of one run's quantities (:func:`~jointid.report.formatting.quantity_units`:
    force levels in V and ``k3/m``, ``c/m`` when the force gain was unknown)."""
    return quantity_units((summary.get("settings") or {}).get("force_gain", "known"))


def _items(part) -> list:
    """A results.json part that is a list of per-preload dicts, a dict of them, or one dict."""
    if not part:
        return []
    if isinstance(part, list):
        return part
    if isinstance(part, dict) and all(isinstance(v, dict) for v in part.values()) and "verdict" not in part:
        return [dict(v, preload=v.get("preload", k)) for k, v in part.items()]
    return [part]


def parameter_unit(name, names=(), units=None, values=None) -> str:
    """Unit of a model parameter, given the model's other parameter names (and values): a
    fitted power law ``base + coefficient q_max^p`` gives its coefficient the unit of the base
    per ``m^p`` (with the fitted ``p`` when ``values`` are given)."""
    name, names, units = str(name), [str(n) for n in names], units or {}
    vals = dict(zip(names, values)) if values is not None else {}

    def power(base):
        p = vals.get(f"p({base})")
        return format_value(p, 3) if _finite(p) else "p"

    if name.startswith("p(") and name.endswith(")"):
        return "1"
    m = re.fullmatch(r"omega1\^2_(\d+)", name)
    if m:
        k = int(m.group(1))
        if "p(omega1^2)" in names:
            return f"rad²/(s² m^{power('omega1^2')})"
        return "rad²/(s² m)" if k == 1 else f"rad²/(s² m^{k})"
    if "p(c)" in names and name == "c1":
        p = vals.get("p(c)")
        return f"N s/m^{format_value(1 + p, 3)}" if _finite(p) else "N s/m^(1+p)"
    if name in units:
        return units[name][1]
    return unit_of(name)


def _label(name, units) -> str:
    return units[name][0] if name in units else str(name)


def _model_name(terms) -> str:
    t = [str(x).replace(" ", "") for x in terms or []]
    if not t:
        return "the preload model"
    return "the paper's cubic (Eq 21)" if t == ["q", "-q^3", "q'"] else " + ".join(terms)


def model_rows(summary) -> list:
    """One row per identified quantity of each preload's model (value ± standard error, 95 %
    interval, unit): f1 in Hz and omega1 in rad/s, then k3 and the damping law c0, c1, ..."""
    rows = []
    units = run_units(summary)
    for m in summary.get("models") or []:
        p = m.get("preload")
        model = _model_name(m.get("terms"))
        if m.get("omega1") is None and m.get("error"):
            rows.append({"preload": str(p), "model": model, "quantity": "model",
                         "value ± standard error": "not identified", "95 % interval": "–", "unit": "",
                         "note": str(m.get("error"))})
            continue
        w, sw = m.get("omega1"), m.get("omega1_stderr")
        if _finite(w):
            sf = sw / (2 * np.pi) if _finite(sw) else None
            for name, v, s_, unit in (("f1", w / (2 * np.pi), sf, "Hz"), ("omega1", w, sw, "rad/s")):
                v_txt, ci_txt, _ = _pm_ci(v, s_, unit)
                rows.append({"preload": str(p), "model": model, "quantity": name, "value ± standard error": v_txt,
                             "95 % interval": ci_txt, "unit": unit, "note": ""})
        names = m.get("parameter_names") or []
        vals, errs = m.get("parameters") or [], m.get("stderr") or []
        for n, v, s_ in zip(names, vals, errs):
            if n == "omega1^2":
                continue
            v_txt, ci_txt, unit = _pm_ci(v, s_, parameter_unit(n, names, units, vals))
            note = coefficient_note(n, v, s_)
            rows.append({"preload": str(p), "model": model, "quantity": _label(n, units),
                         "value ± standard error": v_txt, "95 % interval": ci_txt, "unit": unit, "note": note})
        if m.get("q_max_range"):
            lo, hi = m["q_max_range"]
            rows.append({"preload": str(p), "model": model, "quantity": "q_max range", "value ± standard error":
                         f"{format_value(lo, 3)} .. {format_value(hi, 3)}", "95 % interval": "–", "unit": "m",
                         "note": f"{m.get('n_records', '?')} records"})
    return rows


def _chosen(sel) -> dict | None:
    """The selected entry of a selection's ranking (with its parameters), or None."""
    for r in sel.get("ranking") or []:
        if r.get("selected") and r.get("parameters") is not None:
            return r
    return None


def _same_model(model, chosen) -> bool:
    return bool(model) and list(model.get("parameter_names") or []) == list(chosen.get("parameter_names") or [])


def selected_model_rows(summary) -> list:
    """The parameters of the model the data select for each preload (results.json ``selection``:
    the ranking's selected entry) with standard errors, 95 % intervals and units; f1 and
    omega1 (at zero amplitude when the stiffness has an amplitude law) come first.  Empty when
    no selection was made or the selected model is the preload model already shown."""
    rows = []
    units = run_units(summary)
    models = {str(m.get("preload")): m for m in summary.get("models") or []}
    for sel in _items(summary.get("selection")):
        chosen = _chosen(sel) if isinstance(sel, dict) else None
        if chosen is None or _same_model(models.get(str(sel.get("preload"))), chosen):
            continue
        p, name = str(sel.get("preload")), str(chosen.get("name") or sel.get("selected"))
        names = list(chosen.get("parameter_names") or [])
        vals, errs = list(chosen.get("parameters") or []), list(chosen.get("stderr") or [])
        dof = chosen.get("dof")
        dof = dof if _finite(dof) and float(dof) <= 0 else None
        at0 = " (at zero amplitude)" if any(n.startswith("omega1^2_") for n in names) else ""
        hm = sel.get("hysteretic_model") if isinstance(sel.get("hysteretic_model"), dict) else {}
        law_units = hm.get("units") if chosen.get("hysteretic_law") and isinstance(hm.get("units"), dict) else {}
        if "omega1^2" in names:
            w2, s2 = vals[names.index("omega1^2")], errs[names.index("omega1^2")]
            if _finite(w2) and w2 > 0:
                w = math.sqrt(w2)
                sw = s2 / (2 * w) if _finite(s2) else None
                for q, v, s_, unit in (("f1", w / (2 * np.pi), None if sw is None else sw / (2 * np.pi), "Hz"),
                                       ("omega1", w, sw, "rad/s")):
                    v_txt, ci_txt, _ = _pm_ci(v, s_, unit)
                    rows.append({"preload": p, "model": name, "quantity": q + at0, "value ± standard error": v_txt,
                                 "95 % interval": ci_txt, "unit": unit, "note": ""})
        for n, v, s_ in zip(names, vals, errs):
            if n == "omega1^2":
                continue
            v_txt, ci_txt, unit = _pm_ci(v, s_, parameter_unit(n, names, units, vals) or str(law_units.get(n) or ""))
            if dof is not None:
                v_txt, ci_txt = format_pm(v, s_, dof=0), "not available"
            rows.append({"preload": p, "model": name, "quantity": _label(n, units), "value ± standard error": v_txt,
                         "95 % interval": ci_txt, "unit": unit, "note": coefficient_note(n, v, s_)})
    return rows


def _adequacy_of(summary, preload):
    for a in _items(summary.get("adequacy")):
        if isinstance(a, dict) and str(a.get("preload")) == str(preload):
            return a
    return None


def model_choice_lines(summary) -> list:
    """One sentence per preload saying which model to believe and why: the model the data
    select (results.json ``selection``) against the paper's cubic and the adequacy verdict."""
    out = []
    models = {str(m.get("preload")): m for m in summary.get("models") or []}
    sels = {str(x.get("preload")): x for x in _items(summary.get("selection")) if isinstance(x, dict)}
    for p in dict.fromkeys(list(models) + list(sels)):
        m, sel = models.get(p), sels.get(p)
        adq = _adequacy_of(summary, p)
        fitted = _model_name((m or {}).get("terms")) if m else "the preload model"
        verdict = adq.get("verdict") if adq else None
        holds = adq.get("adequate") if adq else None
        chosen = _chosen(sel) if sel else None
        if chosen is None:
            if adq is None:
                continue
            if holds is None:
                out.append(f"Preload {p}: {fitted}, {verdict}.")
                continue
            state = "passes the adequacy checks" if holds else f"does not hold ({verdict})"
            out.append(f"Preload {p}: {fitted} {state}; no other model was ranked (identify --terms auto ranks the "
                       "candidates).")
            continue
        name = str(chosen.get("name"))
        crit = str(sel.get("criterion") or "ic").upper()
        cubic = next((r for r in sel.get("ranking") or [] if r.get("name") == "cubic"), None)
        behind = (f"; the paper's cubic is {format_value(cubic.get('delta_ic'), 3)} behind in {crit}"
                  if cubic and _finite(cubic.get("delta_ic")) and name != "cubic" else "")
        # the rule that decided (held-out prediction since it exists; older results: the information criterion)
        why = ("the simplest model predicting the held-out force levels within noise of the best"
               if sel.get("decided_by") == "held-out prediction" else f"lowest {crit}")
        if sel.get("hysteretic_model") and adq and isinstance(adq.get("stand_in_adequacy"), dict):
            st = adq["stand_in_adequacy"]
            st_v = "not assessed" if st.get("adequate") is None else "holds" if st.get("adequate") else "does not hold"
            out.append(f"Preload {p}: the data select the {name} model ({why}{behind}); adequacy of its own fit: "
                       f"{verdict}. The preload model shown below ({fitted}) is its polynomial stand-in for "
                       f"re-prediction only ({st.get('model')}: {st_v}; not the selected model's verdict).")
        elif _same_model(m, chosen):
            out.append(f"Preload {p}: the data select the {name} model, the preload model shown below ({why}{behind})" + (f"; adequacy: {verdict}." if verdict else "."))
        elif holds is False:
            out.append(f"Preload {p}: believe the {name} model: the data select it ({why}{behind}) and the "
                       f"adequacy checks reject {fitted} ({verdict}). {fitted[0].upper() + fitted[1:]} is shown for "
                       "comparison with the paper: its parameters are equivalent values over the measured amplitudes, "
                       "not properties of the joint.")
        elif holds:
            out.append(f"Preload {p}: the data prefer the {name} model ({why}{behind}) although {fitted} passes "
                       "the adequacy checks; use the selected model for prediction and the cubic for comparison "
                       "with the paper.")
        else:
            out.append(f"Preload {p}: the data select the {name} model ({why}{behind}); {fitted} was not "
                       "assessed for adequacy.")
    return out


def gain_rows(summary) -> list:
    """The identified force gain per group (``Q = g V`` when the force column is a voltage)
    with its standard error and 95 % interval; empty when the gain was known."""
    units = run_units(summary)
    rows = []
    for g in summary.get("groups") or []:
        if g.get("force_gain") is None:
            continue
        v, se = g.get("force_gain"), g.get("force_gain_stderr")
        rows.append({"preload": str(g.get("preload")), f"F [{units['F'][1]}]": format_value(g.get("force_level")),
                     "force gain g ± standard error [N/V]": format_pm(v, se),
                     "95 % interval [N/V]": format_ci(g.get("force_gain_ci95"), se),
                     "records": len(g.get("records") or [])})
    return rows


def band_resolution(summary, group) -> dict:
    """Whether the band average of single-record ``k3`` (the paper's Table 5 method) is resolved.

    The band average's standard error is the scatter of the single-record values over the
    square root of their number.  It is *unresolved* when its 95 % interval includes zero and
    *inconsistent* when it differs from the pooled fit by more than their combined 95 %
    interval.  The campaign identification computes it (the group's ``band_resolution`` in
    ``results.json``); for older results without that key it is computed here from the
    records.  Returns ``{"mean", "stderr", "resolved", "consistent", "note"}`` (``{}``
    without single-record ``k3``).
    """
    band = group.get("band_resolution")
    if band is None:
        band = band_mean_resolution(_band_k3(summary, group), group.get("k3_mean"), group.get("k3"),
                                    group.get("k3_stderr"))
    if not band:
        return {}
    se = float(band["stderr"]) if _finite(band.get("stderr")) else float("nan")  # null in results.json
    notes = []
    if not band["resolved"]:
        notes.append("unresolved: its 95 % interval includes zero")
    if band.get("consistent") is False:
        notes.append("differs from the pooled fit beyond their 95 % intervals")
    return {"mean": float(band["mean"]), "stderr": se, "resolved": bool(band["resolved"]),
            "consistent": band.get("consistent"), "note": "; ".join(notes)}


def _band_k3(summary, group) -> list:
    """Single-record ``k3`` of a group's identified records (results.json written before the
    group carried its ``band_resolution``)."""
    # records are numbered per campaign: the group's records are those of its own preload and
    # force level with these indices (summaries of several campaigns may share indices)
    key = (str(group.get("preload")), str(group.get("force_level")))
    members = set(group.get("records") or [])
    return [r.get("k3") for r in summary.get("records") or [] if r.get("index") in members
            and r.get("status") == "ok" and (str(r.get("preload", key[0])), str(r.get("force_level", key[1]))) == key]


def table5_rows(summary) -> list:
    """The paper's Table 5 per (preload, force level): the pooled fit's f1, omega1 and k3, and
    the band average of single-record k3 (the paper's own number), flagged when unresolved.
    ``summary`` is one campaign's (record indices are per campaign)."""
    rows = []
    units = run_units(summary)
    F = f"F [{units['F'][1]}]"
    k3 = f"{units['k3'][0]} [{units['k3'][1]}]"
    for g in summary.get("groups") or []:
        w, sw = g.get("omega1"), g.get("omega1_stderr")
        row = {"preload": str(g.get("preload")), F: format_value(g.get("force_level")),
               "records": len(g.get("records") or []),
               "f1 [Hz]": format_pm(w / (2 * np.pi), sw / (2 * np.pi) if _finite(sw) else None) if _finite(w) else "–",
               "omega1 [rad/s]": format_pm(w, sw) if _finite(w) else "–",
               f"{k3} (pooled)": format_pm(g.get("k3"), g.get("k3_stderr")) if g.get("k3") is not None else "–"}
        band = band_resolution(summary, g) if g.get("k3_mean") is not None else {}
        if band:
            row[f"{k3} band average (paper)"] = format_pm(band["mean"], band["stderr"])
            row["band average"] = band["note"] or "resolved"
        else:
            row[f"{k3} band average (paper)"] = "–"
            row["band average"] = ""
        rows.append(row)
    return rows


#: What the adequacy table's columns are.
ADEQUACY_NOTE = (
    "equality across force levels: chi² test that the parameters shared by the records of a force level are the "
    "same at every level (p below 1e-3: the model does not hold); median record misfit: each record's residual "
    "against the preload model over what its noise explains (1 = explained to the noise); restoring force "
    "explained: 1 - residual/measured energy of Q - q'' over all records; harmonics above the first: residual "
    "energy of the model there over the measured energy there (0 = explained, 1 = no better than leaving them out, "
    "above 1 = the model's harmonics are further from the measured ones than none at all) and over what the noise "
    "alone leaves there (1 = explained to the noise).")


def _p_text(p) -> str:
    if not _finite(p):
        return "p –"
    return "p < 1e-6" if float(p) < 1e-6 else f"p = {format_value(p, 2)}"


def _verdict(d):
    for key in ("verdict", "adequate", "passed", "ok", "selected", "best"):
        if key in d:
            v = d[key]
            return ("adequate" if v else "not adequate") if isinstance(v, bool) and key != "selected" else str(v)
    return None


_ADEQUACY_KEYS = {"preload", "terms", "model", "adequate", "verdict", "messages", "level_equality", "misfit_median",
                  "outliers", "drift", "explained_force", "explained_force_min", "explained_harmonics",
                  "explained_harmonics_min", "harmonic_residual_to_noise", "records", "stand_in_adequacy"}


def _ratio(x) -> float | None:
    return 1.0 - float(x) if _finite(x) else None


def adequacy_rows(summary) -> list:
    """The model adequacy verdicts (results.json ``adequacy``) as a readable table: one row per
    preload with the verdict, the equality test across force levels, the median record misfit,
    the restoring force explained and the residual of the harmonics above the first
    (:data:`ADEQUACY_NOTE` says what each column is)."""
    rows = []
    for it in _items(summary.get("adequacy")):
        if not isinstance(it, dict):
            rows.append({"preload": "", "model": "", "verdict": str(it)})
            continue
        eq = it.get("level_equality") or {}
        eq_txt = (f"chi² {format_value(eq.get('chi2'), 3)} on {eq.get('dof')} dof, {_p_text(eq.get('p_value'))}"
                  if eq.get("dof") else "–")
        if not eq.get("dof") and "(hysteretic)" in str(it.get("model")):
            eq_txt = "not assessed (one law fitted over all levels)"
        ef, efmin = it.get("explained_force"), it.get("explained_force_min")
        hr, hrmax = _ratio(it.get("explained_harmonics")), _ratio(it.get("explained_harmonics_min"))
        verdict = _verdict(it) or "–"
        if isinstance(it.get("adequate"), bool) and verdict == it.get("verdict"):
            verdict = ("holds: " if it["adequate"] else "does not hold: ") + verdict
        other = "; ".join(f"{k} = {format_value(v) if not isinstance(v, str) else v}" for k, v in it.items()
                          if k not in _ADEQUACY_KEYS and isinstance(v, (str, int, float, bool)))
        row = {"preload": str(it.get("preload", "")), "model": str(it.get("model") or _model_name(it.get("terms"))),
               "verdict": verdict, "equality across force levels": eq_txt,
               "median record misfit [× noise]": format_value(it.get("misfit_median"), 3),
               "restoring force explained [%] (lowest record)":
                   "–" if not _finite(ef) else f"{format_value(100 * ef, 7)} ({format_value(100 * efmin, 7)})",
               "harmonics above the first: residual / measured energy [1] (worst record)":
                   "–" if hr is None else f"{format_value(hr, 3)} ({format_value(hrmax, 3)})",
               "harmonics above the first: residual / noise [1]": format_value(it.get("harmonic_residual_to_noise"), 3),
               "outlier records": len(it.get("outliers") or [])}
        if other:
            row["other"] = other[:400]
        rows.append(row)
        stand_in = it.get("stand_in_adequacy")
        if isinstance(stand_in, dict):  # a hysteretic pick: its polynomial stand-in's checks, labelled as such
            for r in adequacy_rows({"adequacy": [stand_in]}):
                r["model"] = f"{r['model']} (polynomial stand-in for re-prediction, not the selected model)"
                r["verdict"] = f"stand-in only, not the selected model's verdict: {r['verdict']}"
                rows.append(r)
    return rows


def selection_rows(summary) -> list:
    """The model selection per preload (results.json ``selection``): the selected model, its
    terms, the rule, and how far behind the paper's cubic is."""
    rows = []
    for it in _items(summary.get("selection")):
        if not isinstance(it, dict):
            rows.append({"preload": "", "selected model": str(it)})
            continue
        crit = str(it.get("criterion") or "").upper()
        cubic = next((r for r in it.get("ranking") or [] if r.get("name") == "cubic"), None)
        chosen = _chosen(it)
        rows.append({"preload": str(it.get("preload", "")), "selected model": str(it.get("selected") or "–"),
                     "terms": str(it.get("selected_terms") or (chosen or {}).get("terms") or "–"),
                     "parameters": (chosen or {}).get("n_parameters", "–"),
                     f"the paper's cubic behind by [{crit or 'IC'}]": ("selected" if cubic.get("selected") else
                                                                         format_value(cubic.get("delta_ic"), 3))
                     if cubic else "–",
                     "records": it.get("n_records", "–"), "rule": str(it.get("rule") or "–"),
                     "warnings": "; ".join(str(f) for f in it.get("flags") or []) or "–"})
    return rows


def warning_rows(summary) -> list:
    """Warnings of the records grouped by (preload, force level) and kind, with counts."""
    F = f"F [{run_units(summary)['F'][1]}]"
    groups = {}
    for r in summary.get("records") or []:
        key = (str(r.get("preload")), format_value(r.get("force_level")))
        groups.setdefault(key, []).extend(r.get("warnings") or [])
    rows = []
    for (p, f), msgs in groups.items():
        for kind, n, example in group_messages(msgs):
            rows.append({"preload": p, F: f, "warning": kind, "records": n, "example": example})
    return rows


def error_lines(summary) -> list:
    """Failed records: one line per kind of error with a count and one example."""
    failed = [r for r in summary.get("records") or [] if r.get("status") != "ok"]
    return [f"{n} record(s): {example}" if n == 1 else f"{n} records: {kind} (e.g. {example})"
            for kind, n, example in group_messages(r.get("error") or r.get("status") for r in failed)]


def lead_tables(summaries) -> tuple:
    """``(paragraphs, tables)`` that open a report of one or more campaigns (one summary per
    campaign: record indices are per campaign): which model to believe and why, the selected
    model's parameters, the preload model (the paper's cubic beside the selected one), the
    identified force gain, the paper's Table 5, and the adequacy and selection tables.
    ``tables`` are ``(caption, rows, columns)``."""
    summaries = list(summaries)

    def each(fn):
        return [row for s_ in summaries for row in fn(s_)]

    paragraphs = [line for s_ in summaries for line in model_choice_lines(s_)]
    sel, models = each(selected_model_rows), each(model_rows)
    tables = []
    if sel:
        tables.append(("Identified model per preload: the model the data select (ranked over the candidate models; "
                       "value ± standard error, 95 % interval)", sel, None))
    names = list(dict.fromkeys(r["model"] for r in models))
    what = names[0] if len(names) == 1 else "the preload model"
    tables.append((f"{'For comparison, the fitted' if sel else 'Identified'} model per preload: {what}, one regression over all records of a preload, damping law inside (value ± standard error, 95 % "
                   "interval)", models, None))
    gains = each(gain_rows)
    if gains:
        tables.append(("Identified force gain Q = g V per force level (the force column was a voltage; value ± "
                       "standard error, 95 % interval)", gains, None))
    tables.append(("The paper's Table 5 per force level: pooled fit (shared omega1 and k3, one c per record) and the "
                   "band average of single-record k3 (the paper's number), flagged where unresolved",
                   each(table5_rows), None))
    adq = each(adequacy_rows)
    if adq:
        tables.append(("Model adequacy per preload (the columns are explained in the text above the tables)", adq,
                       None))
        paragraphs.append("Model adequacy: " + ADEQUACY_NOTE)
    sels = each(selection_rows)
    if sels:
        tables.append(("Model selection per preload", sels, None))
    return paragraphs, tables


def _row_lines(rows) -> list:
    return [f"  preload {r['preload']}: {r['quantity']} = {r['value ± standard error']} "
            f"{r['unit'] if r['unit'] != '1' else ''}".rstrip()
            + (f"  95 % {r['95 % interval']}" if r["95 % interval"] not in ("–", "") else "")
            + (f"  ({r['note']})" if r["note"] else "") for r in rows]


def lead_lines(summary) -> list:
    """What a reader needs first, as text: which model to believe and why, the model the data
    select with its parameters, then the preload model (the paper's cubic unless other terms
    were asked for), each value with its standard error, 95 % interval and unit; and the
    identified force gain when it was unknown."""
    out = []
    choice = model_choice_lines(summary)
    if choice:
        out += ["Which model to believe:"] + ["  " + c for c in choice]
    sel = selected_model_rows(summary)
    for name in dict.fromkeys(r["model"] for r in sel):
        out.append(f"Selected model: {name} (value ± standard error, 95 % interval):")
        out += _row_lines([r for r in sel if r["model"] == name])
    rows = model_rows(summary)
    if rows:
        names = list(dict.fromkeys(r["model"] for r in rows))
        what = names[0] if len(names) == 1 else "preload model"
        out.append(f"{what[0].upper() + what[1:]}{' (for comparison)' if sel else ''}: one regression over all "
                   "records of a preload, damping law inside (value ± standard error, 95 % interval):")
        out += _row_lines(rows)
    gains = gain_rows(summary)
    if gains:
        out.append("Identified force gain Q = g V per group (value ± standard error, 95 % interval):")
        F = next(k for k in gains[0] if k.startswith("F ["))
        out += [f"  preload {r['preload']}, F = {r[F]} {F[3:-1]}: g = {r['force gain g ± standard error [N/V]']} N/V"
                f"  95 % {r['95 % interval [N/V]']}" for r in gains]
    return out


def summary_lines(summary) -> list:
    """A short plain-text summary for the console: which model to believe, the models, Table 5
    with the band average flagged, verdicts, then the warnings per group and the grouped errors."""
    out = lead_lines(summary)
    units = run_units(summary)
    Fu, (k3n, k3u) = units["F"][1], units["k3"]
    t5 = table5_rows(summary)
    if t5:
        out.append("Table 5 (pooled fit per force level; band average = the paper's mean of single-record fits):")
        for r in t5:
            flag = f"  <- {r['band average']}" if r["band average"] not in ("", "resolved") else ""
            out.append(f"  preload {r['preload']}, F = {r[f'F [{Fu}]']} {Fu}: f1 {r['f1 [Hz]']} Hz, {k3n} "
                       f"{r[f'{k3n} [{k3u}] (pooled)']} {k3u}; band average {k3n} "
                       f"{r[f'{k3n} [{k3u}] band average (paper)']}{flag}")
    for r in adequacy_rows(summary):
        out.append(f"adequacy, preload {r['preload']}: {r['verdict']}")
    w = warning_rows(summary)
    if w:
        out.append("Warnings per group (details per record in results.json):")
        out += [f"  preload {r['preload']}, F = {r[f'F [{Fu}]']} {Fu}: {r['records']} x {r['warning']}" for r in w]
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
    units = run_units(summary)
    Fu, (k3n, k3u) = units["F"][1], units["k3"]
    bands = [(g, band_resolution(summary, g)) for g in summary.get("groups") or [] if g.get("k3_mean") is not None]
    bands = [(g, b) for g, b in bands if b]
    if bands:
        out.append(f"* {k3n} band avg: the paper's Table 5 number, the mean of single-record fits (standard error from "
                   f"their scatter); the pooled {k3n} is the estimate to use:")
        for g, b in bands:
            out.append(f"  preload {g.get('preload')}, F = {format_value(g.get('force_level'))} {Fu}: band average "
                       f"{format_pm(b['mean'], b['stderr'])} {k3u}" + (f"  <- {b['note']}" if b["note"] else ""))
    w = warning_rows(summary)
    if w:
        out.append("Warnings per group (every message is in results.json):")
        out += [f"  preload {r['preload']}, F = {r[f'F [{Fu}]']} {Fu}: {r['records']} x {r['warning']}" for r in w]
    for m in summary.get("models") or []:
        out += [f"preload {m.get('preload')} model: {w_}" for w_ in m.get("warnings") or []]
    return out


def backbone_lines(backbone, max_rows=12) -> list:
    """A backbone curve as a text table: amplitude ``a`` in m, natural frequency in Hz and
    damping ratio in %, each value with its standard error (at most ``max_rows`` points,
    spread over the amplitude range)."""
    b = backbone
    n = len(b)
    head = (f"Backbone ({b.source}{', ' + b.label if b.label else ''}): {n} points, "
            f"{format_value(b.decades(), 3)} decades of amplitude")
    idx = range(n) if n <= max_rows else np.unique(np.linspace(0, n - 1, max_rows).astype(int))
    rows = [{"a [m]": format_value(b.amplitude[i], 4),
             "f ± standard error [Hz]": format_pm(b.frequency_hz[i], b.omega_stderr[i] / (2 * np.pi)),
             "zeta ± standard error [%]": format_pm(100 * b.zeta[i], 100 * b.zeta_stderr[i])} for i in idx]
    return [head] + (["  " + line for line in text_table(rows).splitlines()] if rows else [])
