"""Units of the imported channels: one table of names, factors to SI and dimensions.

A dimension is the tuple of SI exponents ``(kg, m, s, A)``; angles are dimensionless and
told apart by name.  The import column map (:mod:`jointid.io.importer`) converts with the
factors and refuses a unit whose dimension does not fit the column's kind (an ``accel``
column in ``kN``, a ``force`` column in ``ms``); the MAT reader (:mod:`jointid.io.matlab`)
names the SI unit of a set of exponents with :data:`SI_NAMES`.
"""

from __future__ import annotations

import math

from ..errors import ManifestError

__all__ = ["UNITS", "SI_NAMES", "KINDS", "unit_factor", "unit_dimension", "column_kind", "case_hint", "unit_problem",
           "check_column_unit"]

MASS, LENGTH, TIME, CURRENT = (1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 1, 0), (0, 0, 0, 1)
NONE = (0, 0, 0, 0)
FORCE = (1, 1, -2, 0)
ACCELERATION = (0, 1, -2, 0)
VELOCITY = (0, 1, -1, 0)
DISPLACEMENT = LENGTH
VOLTAGE = (1, 2, -3, -1)
FREQUENCY = (0, 0, -1, 0)
ANGLE = "angle"  # dimensionless, but not to be mixed with a plain number

#: Unit name -> (factor to SI, dimension).  Names are case-sensitive, as SI prefixes are (``mN`` is a
#: milli-newton, ``MN`` a mega-newton, not in the table); ``""`` and ``"SI"`` are SI of any dimension.
#: A few spellings in another case are kept where no other unit is spelt so (``hz``, ``si``).
UNITS = {
    "": (1.0, None), "SI": (1.0, None), "si": (1.0, None),
    "s": (1.0, TIME), "ms": (1e-3, TIME),
    "N": (1.0, FORCE), "kN": (1e3, FORCE), "mN": (1e-3, FORCE), "lbf": (4.4482216152605, FORCE),
    "m/s^2": (1.0, ACCELERATION), "m/s2": (1.0, ACCELERATION), "mm/s^2": (1e-3, ACCELERATION),
    "mm/s2": (1e-3, ACCELERATION),
    "g": (9.80665, ACCELERATION), "mg": (9.80665e-3, ACCELERATION),
    "m/s": (1.0, VELOCITY), "mm/s": (1e-3, VELOCITY), "in/s": (0.0254, VELOCITY),
    "m": (1.0, LENGTH), "mm": (1e-3, LENGTH), "um": (1e-6, LENGTH), "\u00b5m": (1e-6, LENGTH),
    "in": (0.0254, LENGTH),
    "V": (1.0, VOLTAGE), "mV": (1e-3, VOLTAGE),
    "Hz": (1.0, FREQUENCY), "hz": (1.0, FREQUENCY),
    "rad": (1.0, ANGLE), "deg": (math.pi / 180, ANGLE), "degree": (math.pi / 180, ANGLE),
    "degrees": (math.pi / 180, ANGLE),
}

#: SI exponents ``(kg, m, s, A)`` -> the usual name of the SI unit.
SI_NAMES = {
    LENGTH: "m", VELOCITY: "m/s", ACCELERATION: "m/s^2", TIME: "s", FREQUENCY: "Hz", FORCE: "N",
    (1, 2, -2, 0): "N m", (1, -1, -2, 0): "Pa", VOLTAGE: "V", CURRENT: "A", (1, 0, -2, 0): "N/m",
    (1, 0, -1, 0): "N s/m", NONE: "",
}

#: Kind of channel -> the dimensions its unit may have, and the words that name it.
KINDS = {
    "time": (TIME,),
    "force": (FORCE, VOLTAGE),  # a force cell, or the shaker voltage standing for it (force gain unknown)
    "acceleration": (ACCELERATION,),
    "velocity": (VELOCITY,),
    "displacement": (LENGTH,),
    "voltage": (VOLTAGE,),
    "frequency": (FREQUENCY,),
    "phase": (ANGLE,),
}
_DIM_NAMES = {TIME: "time", FORCE: "force", VOLTAGE: "voltage", ACCELERATION: "acceleration",
              VELOCITY: "velocity", LENGTH: "length", FREQUENCY: "frequency", ANGLE: "angle"}


def unit_factor(unit: str) -> float:
    """Factor from ``unit`` to SI (KeyError for an unknown unit; names are case-sensitive)."""
    return UNITS[str(unit).strip()][0]


def unit_dimension(unit: str):
    """Dimension of ``unit`` (``None``: SI of any dimension; KeyError for an unknown unit)."""
    return UNITS[str(unit).strip()][1]


def column_kind(column: str) -> str | None:
    """Kind of a campaign column by its name (``time``, ``force``, ``accel...``...), or ``None``
    when the name does not say (a sensor named by its position: any unit is taken)."""
    name = str(column).strip().lower()
    if name == "time":
        return "time"
    if name.endswith("_phase"):
        return "phase"
    if name == "frequency_hz":
        return "frequency"
    for prefix, kind in (("force", "force"), ("accel", "acceleration"), ("acc_", "acceleration"),
                         ("vel", "velocity"), ("disp", "displacement"), ("voltage", "voltage")):
        if name.startswith(prefix):
            return kind
    return None


def case_hint(label: str) -> str:
    """`` (unit names are case-sensitive ...: did you mean 'mN'?)`` for a unit written in another case
    than a known one, or ``""``; never a suggestion that turns a prefix M (mega) into m (milli) or back
    (``MN`` is not a mis-typed ``mN``: the factor differs by 1e9)."""
    key = str(label).strip()
    other = [u for u in UNITS if u and u.lower() == key.lower() and (u[:1] == key[:1] or u[:1].lower() != "m")]
    return (f" (unit names are case-sensitive, as SI prefixes are: m is milli, M mega; did you mean "
            f"{' or '.join(repr(u) for u in other)}?)" if other else
            " (unit names are case-sensitive, as SI prefixes are: m is milli, M mega)" if key[:1] == "M" else "")


def unit_problem(column: str, unit: str) -> str:
    """What is wrong with ``unit`` for the column named ``column``, or ``""``: an unknown name (with
    :func:`case_hint` and the known names), or a dimension other than the column's kind allows."""
    key = str(unit).strip()
    if key not in UNITS:
        return f"unknown unit {unit!r}{case_hint(key)}; known: {', '.join(u for u in UNITS if u)}"
    kind = column_kind(column)
    dim = UNITS[key][1]
    if kind is None or dim is None or dim in KINDS[kind]:
        return ""
    allowed = [u for u, (_, d) in UNITS.items() if d in KINDS[kind]]
    return (f"unit {unit!r} is a {_DIM_NAMES.get(dim, str(dim))}, but column {column!r} holds a {kind}; units of "
            f"a {kind}: {', '.join(allowed)}")


def check_column_unit(column: str, unit: str, context: str = "") -> None:
    """Raise a :class:`ManifestError` when ``unit`` is unknown or of another dimension than the
    column's kind (:func:`unit_problem`; ``context`` names the file and record)."""
    problem = unit_problem(column, unit)
    if problem:
        scale = " (or give scale)" if str(unit).strip() not in UNITS else ""
        raise ManifestError(f"{context}channels.{column}: {problem}{scale}")
