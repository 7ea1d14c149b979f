"""Rich display of result objects in a notebook (``_repr_html_``): real tables, values rounded
to their standard error (:func:`~jointid.report.formatting.format_pm`), units, warnings counted.

The result classes import :func:`result_html` lazily inside their ``_repr_html_`` methods, so
the core numerics do not import this package at module level.
"""

from __future__ import annotations

import html

import numpy as np

from .formatting import format_ci, format_pm, format_value, html_table, quantity_units, unit_of

__all__ = ["result_html", "coefficient_rows"]

_STYLE = ("<style>table.jointid{border-collapse:collapse;margin:.4em 0}table.jointid td,table.jointid th"
          "{border:1px solid #ccc;padding:.15em .5em;text-align:right}table.jointid td.text{text-align:left}"
          "table.jointid caption{text-align:left;font-weight:600}</style>")


def _unit(name):
    return unit_of("k3" if name == "k3" else name) if name != "omega1^2" else "rad²/s²"


def coefficient_rows(names, values, stderr, units=None) -> list:
    """``{name, value ± standard error, 95 % interval, unit}`` per coefficient (``units``: the
    run's labels and units, :func:`~jointid.report.formatting.quantity_units`)."""
    units = units or {}
    rows = []
    for n, v, s in zip(names, np.atleast_1d(values), np.atleast_1d(stderr)):
        ci = [v - 1.96 * s, v + 1.96 * s] if np.isfinite(v) and np.isfinite(s) else None
        label, unit = units.get(str(n), (str(n), _unit(str(n))))
        rows.append({"coefficient": label, "value ± standard error": format_pm(v, s), "95 % interval": format_ci(ci, s),
                     "unit": unit})
    return rows


def _omega_rows(omega1, omega1_stderr) -> list:
    if omega1 is None or not np.isfinite(omega1):
        return []
    se = omega1_stderr if omega1_stderr is not None and np.isfinite(omega1_stderr) else np.nan
    return [{"coefficient": "f1", "value ± standard error": format_pm(omega1 / (2 * np.pi), se / (2 * np.pi)),
             "95 % interval": format_ci([(omega1 - 1.96 * se) / (2 * np.pi), (omega1 + 1.96 * se) / (2 * np.pi)]),
             "unit": "Hz"},
            {"coefficient": "omega1", "value ± standard error": format_pm(omega1, se),
             "95 % interval": format_ci([omega1 - 1.96 * se, omega1 + 1.96 * se], se), "unit": "rad/s"}]


def _head(title, lines=()) -> str:
    return (_STYLE + f"<div><strong>{html.escape(title)}</strong>"
            + "".join(f"<br><span>{html.escape(str(t))}</span>" for t in lines) + "</div>")


def _warnings(ws) -> str:
    from .summary import group_messages

    kinds = group_messages(ws)
    if not kinds:
        return ""
    return "<ul>" + "".join(f"<li>{n} × {html.escape(k)}</li>" for k, n, _ in kinds) + "</ul>"


def _campaign(r) -> str:
    from .summary import error_lines, model_rows, table5_rows, warning_rows

    s = r.summary()
    parts = [_head(f"CampaignResult {r.name!r}", [f"{len(r.records)} records, {len(r.failed)} failed, "
                                                  f"{len(r.flagged)} flagged, {len(r.groups)} groups"])]
    parts.append(html_table(model_rows(s), caption="identified model per preload (95 % intervals)"))
    parts.append(html_table(table5_rows(s), caption="Table 5: pooled fit per force level and the paper's band average"))
    parts.append(html_table(warning_rows(s), ["preload", "F", "warning", "records"], caption="warnings per group"))
    errs = error_lines(s)
    if errs:
        parts.append("<p>failed: " + "<br>".join(html.escape(e) for e in errs) + "</p>")
    return "".join(parts)


def _group(g) -> str:
    lines = [f"{len(g.record_indices)} records"]
    if g.band is not None and g.band.get("k3") is not None:
        lines.append(f"band average of single-record k3 (the paper's number): {format_value(g.band['k3'])} N/m³")
    parts = [_head(f"GroupResult preload {g.preload}, force level {g.force_level}", lines)]
    if g.pooled is not None:
        parts.append(_pooled_table(g.pooled, quantity_units("unknown" if g.gain is not None else "known")))
    if g.power_law is not None:
        parts.append(_power(g.power_law, head=False))
    elif g.power_law_error:
        parts.append(f"<p>power law: {html.escape(g.power_law_error)}</p>")
    return "".join(parts)


def _pooled_table(p, units=None) -> str:
    units = units or {}
    rows = _omega_rows(p.omega1, p.omega1_stderr) + [r for r in coefficient_rows(p.shared_names, p.shared,
                                                                               p.shared_stderr, units)]
    for j, n in enumerate(p.own_names):
        v = np.asarray(p.own)[:, j]
        label, unit = units.get(n, (n, _unit(n)))
        rows.append({"coefficient": f"{label} (per record)", "value ± standard error":
                     f"{format_value(np.min(v))} .. {format_value(np.max(v))}", "95 % interval": "–", "unit": unit})
    return html_table(rows, caption="pooled fit (shared coefficients; per-record range)")


def _pooled(p) -> str:
    return (_head("PooledFit", [f"{len(p.q_max)} records, condition number {format_value(p.condition_number, 3)}"])
            + _pooled_table(p) + _warnings(p.warnings))


def _record_fit(f) -> str:
    rows = _omega_rows(f.omega1, f.omega1_stderr) + coefficient_rows(f.coefficient_names, f.coefficients, f.stderr)
    return (_head("RecordFit", [f"{format_value(f.frequency_hz, 6)} Hz, q_max {format_value(f.q_max)} m, condition "
                                f"number {format_value(f.condition_number, 3)}"])
            + html_table(rows) + _warnings(f.warnings))


def _damping(law) -> str:
    names = [f"c{k}" for k in range(len(law.coefficients))]
    lines = [f"{len(law.q_max)} records, q_max {format_value(np.min(law.q_max))} .. {format_value(np.max(law.q_max))} m"]
    if law.dof:
        lines.append(f"chi²/dof {format_value(law.chi2 / law.dof, 3)}")
    return _head("DampingLaw c(q_max)", lines) + html_table(coefficient_rows(names, law.coefficients, law.stderr))


def _power(pl, head=True) -> str:
    rows = [{"quantity": "alpha", "value ± standard error": format_value(pl.alpha), "unit": "J/N^n"},
            {"quantity": "n", "value ± standard error": format_pm(pl.n, pl.n_stderr), "unit": "1"}]
    out = html_table(rows, caption=f"U = alpha F^n over {len(pl.force)} records (U in J, F in N)")
    return (_head("PowerLaw") if head else "") + out


def _model(m) -> str:
    lines = [f"{m.n_records} records, condition number {format_value(m.condition_number, 3)}"]
    rows = _omega_rows(m.omega1, m.omega1_stderr) + coefficient_rows(
        [n for n in m.parameter_names if n != "omega1^2"],
        [v for n, v in zip(m.parameter_names, m.parameters) if n != "omega1^2"],
        [s for n, s in zip(m.parameter_names, m.stderr) if n != "omega1^2"])
    return _head(f"PreloadModel, preload {m.preload}", lines) + html_table(rows) + _warnings(m.warnings)


_BY_NAME = {"CampaignResult": _campaign, "GroupResult": _group, "PooledFit": _pooled, "RecordFit": _record_fit,
            "DampingLaw": _damping, "PowerLaw": _power, "PreloadModel": _model}


def result_html(obj) -> str:
    """HTML of a result object (tables; the text report in ``<pre>`` for other objects)."""
    fn = _BY_NAME.get(type(obj).__name__)
    if fn is not None:
        return fn(obj)
    return "<pre>" + html.escape(obj.report()) + "</pre>"
