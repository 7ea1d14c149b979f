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

__all__ = ["UNITS", "unit_of", "format_value", "format_pm", "format_ci", "html_table", "label_with_unit"]

#: Units of the identified quantities (the seed's Tables 2-5; modal coordinates with unit modal mass).
UNITS = {
    "omega1": "rad/s",
    "omega1^2": "rad²/s²",
    "f1_hz": "Hz",
    "frequency_hz": "Hz",
    "k3": "N/m³",
    "k5": "N/m⁵",
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


def format_pm(value, stderr, unit="", digits=4) -> str:
    """``value ± stderr`` rounded to what the standard error supports.

    The standard error keeps two significant digits and the value is rounded to the same
    decimal place; very large or small numbers share one power of ten.  Without a finite
    standard error the value is printed with ``digits`` significant digits.

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
    """
    tail = f" {unit}" if unit else ""
    if not _finite(value):
        return format_value(value, digits) + tail
    v = float(value)
    if not _finite(stderr) or float(stderr) == 0.0:
        return format_value(v, digits) + tail
    s = abs(float(stderr))
    big = max(abs(v), s)
    e = math.floor(math.log10(big))
    if -3 <= e < 5:
        d = _decimals(s)
        return f"{_fixed(v, d)} ± {_fixed(s, d)}{tail}"
    # common power of ten
    scale = 10.0 ** e
    d = _decimals(s / scale)
    return f"({_fixed(v / scale, d)} ± {_fixed(s / scale, d)})e{e}{tail}"


def format_ci(interval, stderr=None, unit="") -> str:
    """A 95 % interval ``[lo, hi]`` rounded like :func:`format_pm` (to the standard error's
    second significant digit; ``stderr`` defaults to the interval's half width / 1.96)."""
    if interval is None or len(interval) != 2 or not all(_finite(x) for x in interval):
        return "–"
    lo, hi = (float(x) for x in interval)
    s = float(stderr) if _finite(stderr) and float(stderr) > 0 else (hi - lo) / (2 * 1.96)
    tail = f" {unit}" if unit else ""
    if not s > 0:
        return f"[{format_value(lo)}, {format_value(hi)}]{tail}"
    big = max(abs(lo), abs(hi))
    e = math.floor(math.log10(big)) if big > 0 else 0
    if -3 <= e < 5:
        d = _decimals(s)
        return f"[{_fixed(lo, d)}, {_fixed(hi, d)}]{tail}"
    scale = 10.0 ** e
    d = _decimals(s / scale)
    return f"[{_fixed(lo / scale, d)}, {_fixed(hi / scale, d)}]e{e}{tail}"


def html_table(rows, columns=None, caption=None, css_class="jointid") -> str:
    """A small HTML table of ``rows`` (dicts); strings are escaped, numbers formatted by
    :func:`format_value`.  Used by the result objects' ``_repr_html_``."""
    rows = list(rows)
    if not rows:
        return ""
    columns = list(columns or rows[0])
    cap = f"<caption>{html.escape(str(caption))}</caption>" if caption else ""
    head = "".join(f"<th>{html.escape(str(c))}</th>" for c in columns)
    body = []
    for r in rows:
        cells = []
        for c in columns:
            v = r.get(c)
            text = v if isinstance(v, str) else format_value(v)
            cells.append(f"<td style='text-align:{'left' if isinstance(v, str) else 'right'}'>"
                         f"{html.escape(str(text))}</td>")
        body.append("<tr>" + "".join(cells) + "</tr>")
    return (f"<table class='{css_class}'>{cap}<thead><tr>{head}</tr></thead>"
            f"<tbody>{''.join(body)}</tbody></table>")
