"""Rounding a value to its uncertainty: the one number formatter of jointid.

The standard error is printed with two significant digits and the value is rounded to the
same decimal place (:func:`format_pm`); very large or small numbers share one power of ten;
no number shows more digits than a float holds; a fit without degrees of freedom says that
its standard error is not available.  Values without an uncertainty get a fixed number of
significant digits (:func:`format_value`).

This module imports nothing from the package, so every floor can use it: the text reports
of the core numerics (``report()`` methods) as well as :mod:`jointid.report.formatting`,
which re-exports it beside the units and tables of the reports.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["FLOAT_DIGITS", "NOT_AVAILABLE", "format_value", "format_pm", "format_ci", "format_estimate",
           "format_percent"]

#: Most significant digits a double carries faithfully; no displayed number has more.
FLOAT_DIGITS = 15

#: What a standard error that cannot be estimated (a fit with no degrees of freedom) reads as.
NOT_AVAILABLE = "standard error not available: no degrees of freedom"

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
