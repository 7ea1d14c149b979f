"""Polynomial stiffness and damping terms: today's single-mode restoring force as a joint law.

``f(u, v) = sum_i theta_i phi_i(u, v)`` over the named terms of
:data:`jointid.conventions.TERMS` (``q``, ``-q^3``, ``q'``, ``|q'|q'``, ``sign(q')`` ...),
with the sign written in each name, so the seed's model ``q - q^3 + q'`` is
``PolynomialLaw({"q": omega1**2, "-q^3": k3, "q'": c})``.  The units are those of the term
library (per unit modal mass: ``u`` in m, ``f`` in m/s^2).  No hysteretic state.

Closed forms for the harmonic motion ``u = a cos(omega t)``: the backbone is the
displacement part ``f(a, 0)``; the dissipation per cycle
``oint f du`` is ``pi c omega a^2`` (``q'``), ``8/3 c omega^2 a^3`` (``|q'|q'``),
``3 pi / 4 c omega^3 a^4`` (``q'^3``), ``4 f_c a`` (``sign(q')``) and
``pi / 4 c omega a^4`` (``q^2 q'``); the displacement terms dissipate nothing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..conventions import TERMS
from ..errors import StructureError, unknown_key_message
from ._core import JointLaw, _number, _scalar_out

__all__ = ["PolynomialLaw", "TERM_FUNCTIONS"]


def _sgn(x):
    return np.sign(x)


#: term -> (phi(u, v), d phi / du, d phi / dv); ``sign(q')`` has d/dv = 0 almost everywhere.
TERM_FUNCTIONS = {
    "q": (lambda u, v: u, lambda u, v: np.ones_like(u), None),
    "-q^3": (lambda u, v: -(u**3), lambda u, v: -3.0 * u**2, None),
    "q^2": (lambda u, v: u**2, lambda u, v: 2.0 * u, None),
    "q^5": (lambda u, v: u**5, lambda u, v: 5.0 * u**4, None),
    "|q|q": (lambda u, v: np.abs(u) * u, lambda u, v: 2.0 * np.abs(u), None),
    "q'": (lambda u, v: v, None, lambda u, v: np.ones_like(v)),
    "|q'|q'": (lambda u, v: np.abs(v) * v, None, lambda u, v: 2.0 * np.abs(v)),
    "q'^3": (lambda u, v: v**3, None, lambda u, v: 3.0 * v**2),
    "sign(q')": (lambda u, v: _sgn(v), None, lambda u, v: np.zeros_like(v)),
    "q^2 q'": (lambda u, v: u**2 * v, lambda u, v: 2.0 * u * v, lambda u, v: u**2),
}

#: dissipation per cycle of u = a cos(omega t) for a unit coefficient: (a, omega) -> energy.
_DISSIPATION = {
    "q'": lambda a, w: math.pi * w * a**2,
    "|q'|q'": lambda a, w: 8.0 / 3.0 * w**2 * a**3,
    "q'^3": lambda a, w: 0.75 * math.pi * w**3 * a**4,
    "sign(q')": lambda a, w: 4.0 * a,
    "q^2 q'": lambda a, w: 0.25 * math.pi * w * a**4,
}


@dataclass(frozen=True, eq=False)
class PolynomialLaw(JointLaw):
    """Named polynomial terms with coefficients (see the module docstring).

    Parameters
    ----------
    terms : mapping or sequence of (name, coefficient)
        Term names of :data:`jointid.conventions.TERMS`; stored as a tuple of pairs.

    Examples
    --------
    >>> law = PolynomialLaw({"q": 1.0, "-q^3": 1.0, "q'": 1.0})      # q - q^3 + q'
    >>> f, _ = law.force(0.5, 2.0, law.initial_state())
    >>> float(f)
    2.375
    """

    terms: tuple
    name: ClassVar[str] = "polynomial terms"

    def __post_init__(self):
        items = self.terms.items() if hasattr(self.terms, "items") else self.terms
        pairs = []
        for pair in items:
            try:
                term, value = pair
            except (TypeError, ValueError):
                raise StructureError(f"{self.name}: expected (term, coefficient) pairs, got {pair!r}") from None
            if term not in TERM_FUNCTIONS:
                raise StructureError(f"{self.name}: " + unknown_key_message(term, TERM_FUNCTIONS, "term"))
            if any(term == t for t, _ in pairs):
                raise StructureError(f"{self.name}: term {term!r} given twice")
            pairs.append((term, _number(self.name, TERMS[term][0], value)))
        if not pairs:
            raise StructureError(f"{self.name}: expected at least one term")
        object.__setattr__(self, "terms", tuple(pairs))

    @classmethod
    def from_terms(cls, names, coefficients):
        """From parallel sequences of term names and coefficients (a fitted model's order)."""
        names, coefficients = list(names), list(coefficients)
        if len(names) != len(coefficients):
            raise StructureError(f"{cls.name}: {len(names)} terms but {len(coefficients)} coefficients")
        return cls(tuple(zip(names, coefficients)))

    @property
    def rate_dependent(self) -> bool:  # type: ignore[override]
        return any(TERM_FUNCTIONS[t][2] is not None for t, _ in self.terms)

    @property
    def parameters(self) -> dict:
        return {TERMS[t][0]: v for t, v in self.terms}

    @property
    def units(self) -> dict:
        return {TERMS[t][0]: TERMS[t][1] for t, _ in self.terms}

    def derived(self) -> dict:
        return {}

    def replace(self, **changes):
        """A new law with some coefficients changed, named as in :attr:`parameters` (``k3``, ``c``, ...)."""
        names = [TERMS[t][0] for t, _ in self.terms]
        unknown = [k for k in changes if k not in names]
        if unknown:
            raise StructureError(f"{self.name}: " + unknown_key_message(unknown[0], names, "parameter"))
        return type(self)(tuple((t, changes.get(TERMS[t][0], v)) for t, v in self.terms))

    def summary(self) -> dict:
        out = super().summary()
        out["terms"] = [t for t, _ in self.terms]
        return out

    def equation(self) -> str:
        """``"1 q + 1 (-q^3) + 1 q'"`` style text of the law."""
        return " + ".join(f"{v:.6g} ({t})" if t.startswith("-") else f"{v:.6g} {t}" for t, v in self.terms)

    # --- protocol -----------------------------------------------------------------
    def _eval(self, u, v):
        u = np.asarray(u, float)
        if v is None:
            v = np.zeros_like(u)
        v = np.asarray(v, float)
        u, v = np.broadcast_arrays(u, v)
        f = np.zeros(u.shape)
        du = np.zeros(u.shape)
        dv = np.zeros(u.shape)
        for t, c in self.terms:
            phi, pu, pv = TERM_FUNCTIONS[t]
            f = f + c * phi(u, v)
            if pu is not None:
                du = du + c * pu(u, v)
            if pv is not None:
                dv = dv + c * pv(u, v)
        return f, du, dv

    def force(self, u, v, state):
        """``(f, state)``; ``v`` is required when a damping term is present."""
        if self.rate_dependent:
            self._need_velocity(v, "the velocity v")
        f, _, _ = self._eval(u, v)
        return _scalar_out(f), state

    def aft(self, u_t, v_t=None, *, velocity_jacobian=False, jacobian=True):
        """Force samples and their Jacobians (diagonal, returned dense ``(..., n, n)``).

        ``v_t`` (the velocity samples, e.g. from the harmonic coefficients) is required
        when a damping term is present; ``velocity_jacobian=True`` also returns ``df_dv``.
        """
        if self.rate_dependent:
            self._need_velocity(v_t, "the velocity samples v_t")
        f, du, dv = self._eval(u_t, v_t)
        if not jacobian:
            return (f, None, None) if velocity_jacobian else (f, None)
        eye = np.eye(f.shape[-1])
        D = du[..., :, None] * eye
        return (f, D, dv[..., :, None] * eye) if velocity_jacobian else (f, D)

    def backbone(self, a):
        """Displacement part ``f(a, 0)``."""
        a = np.asarray(a, float)
        f = np.zeros(a.shape)
        for t, c in self.terms:
            if TERM_FUNCTIONS[t][2] is None:
                f = f + c * TERM_FUNCTIONS[t][0](a, 0.0)
        return _scalar_out(f)

    def dissipation(self, a, omega=None):
        """Energy per cycle of ``u = a cos(omega t)`` (``omega`` [rad/s] needed for damping terms)."""
        a = np.abs(np.asarray(a, float))
        if self.rate_dependent and omega is None:
            raise StructureError(f"{self.name}: the dissipation of a damping term depends on omega; give omega")
        out = np.zeros(a.shape)
        for t, c in self.terms:
            if t in _DISSIPATION:
                out = out + c * _DISSIPATION[t](a, float(omega))
        return _scalar_out(out)
