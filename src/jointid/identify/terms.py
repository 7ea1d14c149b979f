"""Named restoring-force terms and term libraries.

A restoring-force model is a sum of named terms ``phi_j(q, q')`` times coefficients
``theta_j``: ``h(q, q') = sum_j theta_j phi_j(q, q')``.  Terms combine with ``+`` into a
:class:`TermLibrary`; a library evaluates its regression matrix ``(n_samples, n_terms)``
and, for harmonic balance, the partial derivatives of every term.

The seed paper's model (Eq 21) is ``q + -q^3 + q'`` with coefficients
``omega1^2``, ``k3`` and ``c``:

>>> from jointid.identify.terms import library
>>> lib = library("q + -q^3 + q'")
>>> lib.names
('q', '-q^3', "q'")
>>> lib.coefficient_names
('omega1^2', 'k3', 'c')

Users add their own terms with :class:`Term`:

>>> import numpy as np
>>> quintic_damping = Term("q^4 q'", "d5", lambda q, v: q**4 * v, kind="damping")
>>> (lib + quintic_damping).names[-1]
"q^4 q'"
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..errors import IdentificationError

__all__ = ["Term", "TermLibrary", "STANDARD_TERMS", "term", "library", "SEED_TERMS", "EQ22_TERMS"]

Func = Callable[[np.ndarray, np.ndarray], np.ndarray]

_FD_STEP = 1e-6


@dataclass(frozen=True)
class Term:
    """One named restoring-force term ``phi(q, v)``.

    Parameters
    ----------
    name : str
        How the term prints, e.g. ``"-q^3"``.
    coefficient : str
        Name of its coefficient, e.g. ``"k3"``.
    func : callable
        ``func(q, v) -> array`` evaluated elementwise.
    dq, dv : callable, optional
        Partial derivatives ``d phi / d q`` and ``d phi / d v``.  When absent a central
        difference is used (harmonic balance only needs them for its Jacobian).
    kind : {"stiffness", "damping"}
        Whether the term depends on displacement only (stiffness) or on velocity
        (damping).  In a pooled regression damping terms get one coefficient per record
        by default.
    odd : bool
        True when ``phi(-q, -v) = -phi(q, v)``; such terms create odd harmonics only.
    dq_const, dv_const : float, optional
        The value of ``dq`` (``dv``) when it is the same at every state (``1`` and ``0``
        for ``q``): sums over a record then need no evaluation of the derivative.
    """

    name: str
    coefficient: str
    func: Func
    dq: Func | None = None
    dv: Func | None = None
    kind: str = "stiffness"
    odd: bool = True
    dq_const: float | None = None
    dv_const: float | None = None

    def __post_init__(self):
        if self.kind not in ("stiffness", "damping"):
            raise ValueError(f"Term {self.name!r}: kind must be 'stiffness' or 'damping', got {self.kind!r}")

    def __call__(self, q, v):
        return np.asarray(self.func(np.asarray(q, float), np.asarray(v, float)), dtype=float)

    def derivatives(self, q, v):
        """Return ``(d phi/d q, d phi/d v)`` at the given states."""
        q = np.asarray(q, float)
        v = np.asarray(v, float)
        if self.dq is not None:
            gq = np.broadcast_to(np.asarray(self.dq(q, v), float), q.shape)
        else:
            h = _FD_STEP * (1.0 + np.abs(q))
            gq = (self.func(q + h, v) - self.func(q - h, v)) / (2 * h)
        if self.dv is not None:
            gv = np.broadcast_to(np.asarray(self.dv(q, v), float), v.shape)
        else:
            h = _FD_STEP * (1.0 + np.abs(v))
            gv = (self.func(q, v + h) - self.func(q, v - h)) / (2 * h)
        return gq, gv

    def derivative_values(self, q, v):
        """:meth:`derivatives`, with a derivative declared constant returned as that float
        (and not evaluated)."""
        gq, gv = self.dq_const, self.dv_const
        if gq is None and gv is not None and self.dq is not None:
            return np.broadcast_to(np.asarray(self.dq(q, v), float), np.shape(q)), gv
        if gv is None and gq is not None and self.dv is not None:
            return gq, np.broadcast_to(np.asarray(self.dv(q, v), float), np.shape(v))
        if gq is None or gv is None:
            a, b = self.derivatives(q, v)
            gq, gv = (a if gq is None else gq), (b if gv is None else gv)
        return gq, gv

    def __add__(self, other):
        return TermLibrary((self,)) + other

    def __repr__(self):
        return f"Term({self.name!r}, coefficient={self.coefficient!r}, kind={self.kind!r})"


@dataclass(frozen=True)
class TermLibrary:
    """An ordered set of :class:`Term` objects with distinct names."""

    terms: tuple[Term, ...]

    def __post_init__(self):
        object.__setattr__(self, "terms", tuple(self.terms))
        names = [t.name for t in self.terms]
        dup = {n for n in names if names.count(n) > 1}
        if dup:
            raise IdentificationError(f"term library has duplicate terms: {sorted(dup)}")
        coefs = [t.coefficient for t in self.terms]
        dup = {n for n in coefs if coefs.count(n) > 1}
        if dup:
            raise IdentificationError(f"term library has duplicate coefficient names: {sorted(dup)}")

    def __add__(self, other):
        if isinstance(other, Term):
            return TermLibrary(self.terms + (other,))
        if isinstance(other, TermLibrary):
            return TermLibrary(self.terms + other.terms)
        if isinstance(other, str):
            return self + library(other)
        return NotImplemented

    def __radd__(self, other):
        if isinstance(other, Term):
            return TermLibrary((other,) + self.terms)
        return NotImplemented

    def __len__(self):
        return len(self.terms)

    def __iter__(self):
        return iter(self.terms)

    def __getitem__(self, key):
        if isinstance(key, str):
            return self.terms[self.index(key)]
        return self.terms[key]

    def index(self, name: str) -> int:
        """Position of the term (or coefficient) called ``name``."""
        for i, t in enumerate(self.terms):
            if name in (t.name, t.coefficient):
                return i
        raise KeyError(f"no term or coefficient {name!r} in library {self.names}")

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(t.name for t in self.terms)

    @property
    def coefficient_names(self) -> tuple[str, ...]:
        return tuple(t.coefficient for t in self.terms)

    @property
    def odd(self) -> bool:
        return all(t.odd for t in self.terms)

    def evaluate(self, q, v, out=None) -> np.ndarray:
        """Regression matrix ``(n_samples, n_terms)`` of the terms at states ``q, v`` (into ``out``)."""
        q = np.asarray(q, float)
        v = np.asarray(v, float)
        if out is None:
            out = np.empty(q.shape + (len(self.terms),))
        for j, t in enumerate(self.terms):
            out[..., j] = t(q, v)
        return out

    def restoring_force(self, q, v, coefficients) -> np.ndarray:
        """``h(q, v) = sum_j theta_j phi_j(q, v)``."""
        q = np.asarray(q, float)
        v = np.asarray(v, float)
        coefficients = np.asarray(coefficients, float)
        if coefficients.shape[-1] != len(self.terms):
            raise ValueError(f"{len(self.terms)} coefficients expected for {self.names}, got {coefficients.shape[-1]}")
        h = np.zeros(np.broadcast(q, v).shape)
        for t, c in zip(self.terms, coefficients):
            if c != 0.0:
                h = h + c * t(q, v)
        return h

    def derivatives(self, q, v, coefficients):
        """``(dh/dq, dh/dv)`` of the restoring force."""
        q = np.asarray(q, float)
        v = np.asarray(v, float)
        gq = np.zeros(np.broadcast(q, v).shape)
        gv = np.zeros_like(gq)
        for t, c in zip(self.terms, np.asarray(coefficients, float)):
            if c != 0.0:
                dq, dv = t.derivatives(q, v)
                gq = gq + c * dq
                gv = gv + c * dv
        return gq, gv

    def equation(self, coefficients, errors=None, lhs="Q - q''") -> str:
        """The fitted model as an equation with values (and standard errors when given).

        >>> print(library("q + q'").equation([900.0, 0.5], [0.1, 0.01]))
        Q - q'' = omega1^2·[q] + c·[q']
          omega1^2 = 900 ± 0.1
          c = 0.5 ± 0.01
        """
        head = f"{lhs} = " + " + ".join(f"{t.coefficient}·[{t.name}]" for t in self.terms)
        lines = [head]
        for j, (t, c) in enumerate(zip(self.terms, coefficients)):
            err = f" ± {errors[j]:.2g}" if errors is not None and np.isfinite(errors[j]) else ""
            lines.append(f"  {t.coefficient} = {c:.8g}{err}")
        return "\n".join(lines)

    def __repr__(self):
        return "TermLibrary(" + " + ".join(self.names) + ")"


def _sgn(v):
    return np.sign(v)


STANDARD_TERMS: dict[str, Term] = {
    t.name: t
    for t in (
        Term("q", "omega1^2", lambda q, v: q, lambda q, v: np.ones_like(q), lambda q, v: np.zeros_like(q),
             dq_const=1.0, dv_const=0.0),
        Term("-q^3", "k3", lambda q, v: -(q * q * q), lambda q, v: -3.0 * (q * q), lambda q, v: np.zeros_like(q),
             dv_const=0.0),
        Term("q^2", "k2", lambda q, v: q * q, lambda q, v: 2.0 * q, lambda q, v: np.zeros_like(q), odd=False,
             dv_const=0.0),
        Term(
            "q^5", "k5", lambda q, v: (q * q) * (q * q) * q, lambda q, v: 5.0 * ((q * q) * (q * q)),
            lambda q, v: np.zeros_like(q), dv_const=0.0,
        ),
        Term("|q|q", "k_abs", lambda q, v: np.abs(q) * q, lambda q, v: 2 * np.abs(q), lambda q, v: np.zeros_like(q),
             dv_const=0.0),
        Term("q'", "c", lambda q, v: v, lambda q, v: np.zeros_like(v), lambda q, v: np.ones_like(v), kind="damping",
             dq_const=0.0, dv_const=1.0),
        Term(
            "|q'|q'", "c_quad", lambda q, v: np.abs(v) * v, lambda q, v: np.zeros_like(v),
            lambda q, v: 2 * np.abs(v), kind="damping", dq_const=0.0,
        ),
        Term(
            "q'^3", "c_cubic", lambda q, v: v * v * v, lambda q, v: np.zeros_like(v), lambda q, v: 3.0 * (v * v),
            kind="damping", dq_const=0.0,
        ),
        # Coulomb friction; its derivative is taken as zero away from v = 0 (harmonic balance
        # then relies on the smooth terms for its Jacobian).
        Term(
            "sign(q')", "f_c", lambda q, v: _sgn(v), lambda q, v: np.zeros_like(v),
            lambda q, v: np.zeros_like(v), kind="damping", dq_const=0.0, dv_const=0.0,
        ),
        Term("q^2 q'", "c_qq", lambda q, v: (q * q) * v, lambda q, v: 2.0 * q * v, lambda q, v: q * q, kind="damping"),
    )
}

#: The seed paper's model, Eq 21 / 24: ``omega1^2 q - k3 q^3 + c q'``.
SEED_TERMS = ("q", "-q^3", "q'")
#: The richer set of Eq 22.
EQ22_TERMS = ("q", "-q^3", "q'", "|q'|q'", "q'^3")


def _canonical(name: str) -> str:
    """A term name with white space, ``*`` products and ``**`` powers normalised away."""
    return name.replace("’", "'").replace("**", "^").replace("*", "").replace(" ", "")


#: Other spellings of standard terms: the velocity as ``v`` or ``dq``; a cubic written without its sign.
_ALIASES = {"v": "q'", "dq": "q'", "|v|v": "|q'|q'", "v^3": "q'^3", "sign(v)": "sign(q')", "q^3": "-q^3",
            "q^2v": "q^2q'"}
_BY_CANONICAL = {_canonical(n): n for n in STANDARD_TERMS}
#: Named term sets.
_NAMED_SETS = {"seed": SEED_TERMS, "paper": SEED_TERMS, "eq21": SEED_TERMS, "eq22": EQ22_TERMS}


def term(name: str) -> Term:
    """Look up a standard term by name (``"q"``, ``"-q^3"``, ``"q'"``, ``"sign(q')"``, ...).

    White space and ``*`` are ignored, ``**`` reads as ``^`` and the velocity may be written
    ``v``.  A name that is none of these is refused with the closest standard names.
    """
    key = _canonical(name.strip())
    key = _BY_CANONICAL.get(_ALIASES.get(key, key))
    if key is None:
        import difflib
        import re

        written = _canonical(name.strip())
        power = re.fullmatch(r"(-?q'?)(\d)", written)  # q3 for q^3
        close = [power[1] + "^" + power[2]] if power else []
        close = [_ALIASES.get(c, c) for c in close if _ALIASES.get(c, c) in _BY_CANONICAL] or difflib.get_close_matches(
            written, list(_BY_CANONICAL), n=3, cutoff=0.5)
        hint = f"; did you mean {' or '.join(repr(_BY_CANONICAL[c]) for c in close)}?" if close else ""
        raise IdentificationError(
            f"unknown term {name.strip()!r}{hint} The standard terms are {sorted(STANDARD_TERMS)}"
        )
    return STANDARD_TERMS[key]


def _split_algebra(spec: str) -> list:
    """Split ``"q - q^3 + q'"`` into signed pieces ``["q", "-q^3", "q'"]``.

    A ``+`` or ``-`` starts a new term unless it follows ``^`` (an exponent's sign) or
    opens the expression; the sign stays with the term it precedes.
    """
    pieces, cur, depth = [], "", 0
    for ch in spec:
        depth += ch == "("
        depth -= ch == ")"
        if ch in "+-" and depth == 0 and cur.strip(" +-") and not cur.rstrip().endswith("^"):
            pieces.append(cur)
            cur = ch
        else:
            cur += ch
    pieces.append(cur)
    return [p.strip() for p in pieces]


def _signed_term(piece: str, spec: str) -> Term:
    """The standard term of one signed piece of an expression.

    A coefficient is free in the regression, so the sign written before a term only
    selects the name it is reported under: ``- q^3`` and ``+ q^3`` both mean the cubic
    term ``-q^3`` with coefficient ``k3`` (seed convention, ``k3 > 0`` softening), and
    ``- q'`` is the term ``q'``.
    """
    if piece.startswith("+"):
        piece = piece[1:].strip()
    body = piece[1:].strip() if piece.startswith("-") else piece
    if not body or body[0] in "+-":
        raise IdentificationError(f"term specification {spec!r}: a '+' or '-' is not followed by a term")
    if piece.startswith("-") and _canonical("-" + body) in _BY_CANONICAL:
        return term("-" + body)
    return term(body)


def library(spec="q + -q^3 + q'") -> TermLibrary:
    """Build a :class:`TermLibrary` from names or from algebra.

    ``spec`` is a library, a sequence of names/terms, or a string: natural algebra
    (``"q - q^3 + q'"``), names separated by commas (``"q, -q^3, q'"``), or a named set:
    ``"seed"``/``"eq21"`` (seed Eq 21) and ``"eq22"`` (Eq 22).  Coefficients are not
    written: every term gets its own, whose sign is free.

    >>> library("q - q^3 + q'").coefficient_names
    ('omega1^2', 'k3', 'c')
    >>> library("eq22").names
    ('q', '-q^3', "q'", "|q'|q'", "q'^3")
    """
    if isinstance(spec, TermLibrary):
        return spec
    if isinstance(spec, Term):
        return TermLibrary((spec,))
    if isinstance(spec, str):
        s = spec.strip()
        if s.lower() in _NAMED_SETS:
            return library(_NAMED_SETS[s.lower()])
        pieces = [p for chunk in s.split(",") for p in _split_algebra(chunk)]
        if not s or not any(pieces):
            raise IdentificationError(f"empty term specification {spec!r}")
        if any(not p for p in pieces):
            raise IdentificationError(f"term specification {spec!r}: an empty term (two separators in a row)")
        return TermLibrary(tuple(_signed_term(p, spec) for p in pieces))
    return TermLibrary(tuple(t if isinstance(t, Term) else term(t) for t in spec))
