"""Numbers, units, labels and small HTML tables shared by every report and result display.

One rule for every estimate shown to a reader: the standard error is printed with two
significant digits and the value is rounded to the same decimal place
(:func:`format_pm`), so a value never shows more digits than its uncertainty supports.
The units are those of the seed paper's tables (modal quantities of the mass-normalised
first mode, modal mass one): :data:`UNITS`.

The numbers are rounded by :mod:`jointid.rounding` (re-exported here), which the core
numerics' own text reports use as well.
"""

from __future__ import annotations

import hashlib
import html
import re

from ..rounding import (  # noqa: F401  (the one number formatter, re-exported here)
    FLOAT_DIGITS,
    NOT_AVAILABLE,
    _finite,
    format_ci,
    format_estimate,
    format_percent,
    format_pm,
    format_value,
)

__all__ = ["UNITS", "unit_of", "format_value", "format_pm", "format_ci", "format_estimate", "format_percent",
           "html_table", "text_table", "label_with_unit", "quantity_units", "FLOAT_DIGITS", "NOT_AVAILABLE",
           "slug", "tex_safe", "SLUG_MAX"]

#: Units of the identified quantities (the seed's Tables 2-5; modal coordinates with unit modal mass).
UNITS = {
    "omega1": "rad/s",
    "omega1^2": "rad²/s²",
    "f1_hz": "Hz",
    "frequency_hz": "Hz",
    "k3": "N/m³",
    "k5": "N/m⁵",
    "k2": "N/m²",
    "k_abs": "N/m²",
    "c_quad": "N s²/m²",
    "c_cubic": "N s³/m³",
    "c_qq": "N s/m³",
    "f_c": "N",
    "force_gain": "N/V",
    "c": "N s/m",
    "c0": "N s/m",
    "c1": "N s/m²",
    "c2": "N s/m³",
    "c3": "N s/m⁴",
    "q_max": "m",
    "q": "m",
    "F": "N",
    "force_level": "N",
    "U": "J",
    "energy": "J",
    "joint_force": "N",
    "alpha": "J/Nⁿ",
    "n": "1",
    "zeta": "1",
    "delay_s": "s",
}


def unit_of(name) -> str:
    """Unit of a quantity name (``""`` when unknown); ``c_k`` coefficients follow ``N s/m^(k+1)``."""
    name = str(name)
    if name in UNITS:
        return UNITS[name]
    if name.startswith("c") and name[1:].isdigit():
        k = int(name[1:])
        return "N s/m" if k == 0 else f"N s/m^{k + 1}"
    return ""


def label_with_unit(name, unit=None) -> str:
    """Axis or column label ``name [unit]`` (the unit looked up by name when not given)."""
    unit = unit_of(name) if unit is None else unit
    return f"{name} [{unit}]" if unit else str(name)


def quantity_units(force_gain="known") -> dict:
    """Labels and units of the identified quantities of one run: ``{quantity: (label, unit)}``.

    With an unknown force gain the "force" column is the recorded excitation (a voltage):
    force levels are in V, and the stiffness and damping coefficients are ratios to the
    identified inertia coefficient ``m = 1/g`` (``k3/m``, ``c/m``: per unit modal mass,
    the same numbers as the paper's for one kg of modal mass).
    """
    if str(force_gain) == "unknown":
        return {"F": ("F", "V"), "k3": ("k3/m", "1/(m² s²)"), "c": ("c/m", "1/s"),
                "c0": ("c0/m", "1/s"), "c1": ("c1/m", "1/(m s)"), "c2": ("c2/m", "1/(m² s)"),
                "force_gain": ("force gain g", "N/V")}
    return {"F": ("F", "N"), "k3": ("k3", UNITS["k3"]), "c": ("c", UNITS["c"]), "c0": ("c0", UNITS["c0"]),
            "c1": ("c1", UNITS["c1"]), "c2": ("c2", UNITS["c2"])}


def _cell_text(v, digits=4) -> str:
    return v if isinstance(v, str) else format_value(v, digits)


def html_table(rows, columns=None, caption=None, css_class="jointid", empty=None) -> str:
    """The one HTML table of jointid (reports and notebook displays): ``rows`` are dicts,
    strings are escaped and left-aligned (class ``text``), numbers formatted by
    :func:`format_value`.  No rows: ``""``, or a note ``caption: empty`` when ``empty`` is given."""
    rows = list(rows)
    if not rows:
        if empty is None:
            return ""
        return f"<p class='note'>{html.escape(str(caption or ''))}: {html.escape(str(empty))}</p>"
    columns = list(columns or rows[0])
    cap = f"<caption>{html.escape(str(caption))}</caption>" if caption else ""
    head = "".join(f"<th>{html.escape(str(c))}</th>" for c in columns)
    body = []
    for r in rows:
        cells = []
        for c in columns:
            v = r.get(c)
            cls = " class='text'" if isinstance(v, str) else ""
            cells.append(f"<td{cls}>{html.escape(_cell_text(v))}</td>")
        body.append("<tr>" + "".join(cells) + "</tr>")
    klass = f" class='{css_class}'" if css_class else ""
    return (f"<table{klass}>{cap}<thead><tr>{head}</tr></thead>"
            f"<tbody>{''.join(body)}</tbody></table>")


def text_table(rows, columns=None, headers=None) -> str:
    """Fixed-width text table (console, ``report.txt``) of ``rows`` (dicts) restricted to
    ``columns``; numbers formatted by :func:`format_value`, strings as they are."""
    rows = list(rows)
    columns = list(columns or (rows[0] if rows else []))
    headers = list(headers or columns)
    body = [[_cell_text(r.get(c)) if r.get(c) is not None else "-" for c in columns] for r in rows]
    widths = [max(len(str(h)), *(len(b[i]) for b in body)) if body else len(str(h)) for i, h in enumerate(headers)]
    out = ["  ".join(str(h).rjust(w) for h, w in zip(headers, widths)), "  ".join("-" * w for w in widths)]
    out += ["  ".join(b[i].rjust(widths[i]) for i in range(len(widths))) for b in body]
    return "\n".join(out)


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
