"""Numbers, units and small HTML tables shared by every report and result display.

One rule for every estimate shown to a reader: the standard error is printed with two
significant digits and the value is rounded to the same decimal place
(:func:`format_pm`), so a value never shows more digits than its uncertainty supports.
The units are those of the seed paper's tables (modal quantities of the mass-normalised
first mode, modal mass one): :data:`UNITS`.

This module imports nothing from the rest of the package, so the result classes of the
core numerics can import it lazily in their ``report()`` and ``_repr_html_()`` methods.
"""

from __future__ import annotations

import html
import math

import numpy as np

__all__ = ["UNITS", "unit_of", "format_value", "format_pm", "format_ci", "format_estimate", "format_percent",
           "html_table", "text_table", "label_with_unit", "quantity_units", "FLOAT_DIGITS", "NOT_AVAILABLE"]

#: Most significant digits a double carries faithfully; no displayed number has more.
FLOAT_DIGITS = 15

#: What a standard error that cannot be estimated (a fit with no degrees of freedom) reads as.
NOT_AVAILABLE = "standard error not available: no degrees of freedom"

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


def _finite(x) -> bool:
    try:
        return x is not None and math.isfinite(float(x))
    except (TypeError, ValueError):
        return False


def format_value(value, digits=4) -> str:
    """A value without an uncertainty: ``digits`` significant digits (``"–"`` when missing)."""
    if value is None:
        return "–"
    if isinstance(value, (bool, np.bool_)):
        return "yes" if value else "no"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if not _finite(value):
        return "nan" if isinstance(value, (float, np.floating)) else str(value)
    v = float(value)
    if v == 0.0:
        return "0"
    digits = max(1, min(int(digits), FLOAT_DIGITS))
    e = math.floor(math.log10(abs(v)))
    if e >= 5 or e < -3:  # the power of ten of format_pm's shared exponent
        text = f"{v:.{digits - 1}e}"
        mant, exp = text.split("e")
        if "." in mant:
            mant = mant.rstrip("0").rstrip(".")
        return f"{mant}e{int(exp)}"
    text = f"{v:.{digits}g}"
    if "e" in text:
        mant, exp = text.split("e")
        text = f"{mant}e{int(exp)}"
    return text


def _decimals(stderr) -> int:
    """Decimal place that keeps two significant digits of ``stderr`` (negative: tens, hundreds...)."""
    s = float(f"{abs(float(stderr)):.2g}")  # rounding may carry to the next decade (0.0996 -> 0.1)
    return 1 - math.floor(math.log10(s))


def _fixed(v, d) -> str:
    if d >= 0:
        return f"{v:.{d}f}"
    return f"{round(v, d):.0f}"


def _no_stderr(dof) -> bool:
    return dof is not None and _finite(dof) and float(dof) <= 0


def format_pm(value, stderr, unit="", digits=4, dof=None) -> str:
    """``value ± stderr`` rounded to what the standard error supports.

    The standard error keeps two significant digits and the value is rounded to the same
    decimal place; very large or small numbers share one power of ten.  Without a finite
    standard error the value is printed with ``digits`` significant digits.  A value never
    shows more than :data:`FLOAT_DIGITS` significant digits: a standard error below what a
    float resolves is printed on its own in powers of ten.  ``dof <= 0`` (an exact fit:
    as many parameters as data) says that no standard error is available instead of
    printing the zero or round-off one such a fit returns.

    Examples
    --------
    >>> format_pm(0.09221303616276932, 0.0012345)
    '0.0922 ± 0.0012'
    >>> format_pm(5013504.6, 1.4e4, "N/m³")
    '(5.014 ± 0.014)e6 N/m³'
    >>> format_pm(170.00031, 0.00019, "rad/s")
    '170.00031 ± 0.00019 rad/s'
    >>> format_pm(-1644.2, 370.0)
    '-1640 ± 370'
    >>> format_pm(27.05634032562221, 5.3e-19)
    '27.0563403256222 ± 5.3e-19'
    >>> format_pm(1.11, 5e-13, dof=0)
    '1.11 (standard error not available: no degrees of freedom)'
    """
    tail = f" {unit}" if unit else ""
    if not _finite(value):
        return format_value(value, digits) + tail
    v = float(value)
    if _no_stderr(dof):
        return f"{format_value(v, digits)} ({NOT_AVAILABLE}){tail}"
    if not _finite(stderr) or float(stderr) == 0.0:
        return format_value(v, digits) + tail
    s = abs(float(stderr))
    big = max(abs(v), s)
    e = math.floor(math.log10(big))
    scale = 1.0 if -3 <= e < 5 else 10.0 ** e
    d = _decimals(s / scale)
    if v != 0.0 and math.floor(math.log10(abs(v) / scale)) + 1 + d > FLOAT_DIGITS:
        # the standard error is below the float's resolution of the value
        return f"{format_value(v, FLOAT_DIGITS)} ± {format_value(s, 2)}{tail}"
    if scale == 1.0:
        return f"{_fixed(v, d)} ± {_fixed(s, d)}{tail}"
    return f"({_fixed(v / scale, d)} ± {_fixed(s / scale, d)})e{e}{tail}"


def format_ci(interval, stderr=None, unit="", dof=None) -> str:
    """A 95 % interval ``[lo, hi]`` rounded like :func:`format_pm` (to the standard error's
    second significant digit; ``stderr`` defaults to the interval's half width / 1.96);
    ``dof <= 0``: not available."""
    if _no_stderr(dof):
        return "not available"
    if interval is None or len(interval) != 2 or not all(_finite(x) for x in interval):
        return "–"
    lo, hi = (float(x) for x in interval)
    s = float(stderr) if _finite(stderr) and float(stderr) > 0 else (hi - lo) / (2 * 1.96)
    tail = f" {unit}" if unit else ""
    if not s > 0:
        return f"[{format_value(lo)}, {format_value(hi)}]{tail}"
    big = max(abs(lo), abs(hi))
    e = math.floor(math.log10(big)) if big > 0 else 0
    scale = 1.0 if -3 <= e < 5 else 10.0 ** e
    d = _decimals(s / scale)
    if big > 0 and math.floor(math.log10(big / scale)) + 1 + d > FLOAT_DIGITS:
        return f"[{format_value(lo, FLOAT_DIGITS)}, {format_value(hi, FLOAT_DIGITS)}]{tail}"
    if scale == 1.0:
        return f"[{_fixed(lo, d)}, {_fixed(hi, d)}]{tail}"
    return f"[{_fixed(lo / scale, d)}, {_fixed(hi / scale, d)}]e{e}{tail}"


def format_estimate(value, stderr, unit="", dof=None, z=1.959963984540054) -> str:
    """``value ± stderr [unit], 95 % [lo, hi]``: one estimate as a sentence fragment
    (the interval ``value ± z stderr``), or the value with "standard error not available"."""
    if _no_stderr(dof) or not _finite(stderr) or not _finite(value):
        return format_pm(value, stderr, unit, dof=dof)
    v, s = float(value), float(stderr)
    return f"{format_pm(v, s, unit)}, 95 % {format_ci([v - z * s, v + z * s], s)}"


def format_percent(value, digits=3, sign=False) -> str:
    """A percentage with ``digits`` significant digits (``"–"`` when missing)."""
    if not _finite(value):
        return "–"
    text = format_value(float(value), digits)
    if sign and float(value) > 0:
        text = "+" + text
    return f"{text} %"


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
