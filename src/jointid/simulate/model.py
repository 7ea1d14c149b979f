"""The single-mode model ``q'' + h(q, q') = Q(t)`` used for simulation and re-prediction.

The restoring force is a term library with coefficients.  Any coefficient may instead
follow a polynomial in the steady-state amplitude ``q_max`` (seed Eq 20 / 26), or the
micro-slip power law :class:`~jointid.identify.powerlaw.PowerLaw`: the damping of a
steady state then depends on that steady state's own ``q_max``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Mapping

import numpy as np

from ..identify.powerlaw import PowerLaw
from ..identify.terms import TermLibrary, library

__all__ = ["SingleModeModel", "seed_model"]


@dataclass(frozen=True)
class SingleModeModel:
    """``q'' + sum_j theta_j phi_j(q, q') = Q(t)`` with optional amplitude laws.

    Parameters
    ----------
    terms : TermLibrary or str
        The restoring-force terms; the linear term ``q`` (coefficient ``omega1^2``)
        should be among them.
    coefficients : sequence of float
        One value per term.  For a term with an amplitude law the value is ignored.
    amplitude_laws : mapping, optional
        ``{coefficient or term name: (p0, p1, p2, ...)}`` making that coefficient
        ``p0 + p1 q_max + p2 q_max^2 + ...``, or ``{name: PowerLaw(c0, c1, p)}`` making it
        ``c0 + c1 q_max^p``.

    Examples
    --------
    >>> m = seed_model()
    >>> round(m.omega1, 6)
    170.0
    >>> m.coefficients_at(0.01)[2]   # c(q_max) = 0.08 + 70 q + 1e4 q^2
    1.78
    """

    terms: TermLibrary
    coefficients: tuple[float, ...]
    amplitude_laws: Mapping[str, tuple[float, ...] | PowerLaw] = field(default_factory=dict)

    def __post_init__(self):
        terms = library(self.terms)
        object.__setattr__(self, "terms", terms)
        coefs = tuple(float(c) for c in self.coefficients)
        if len(coefs) != len(terms):
            raise ValueError(f"{len(terms)} coefficients expected for {terms.names}, got {len(coefs)}")
        object.__setattr__(self, "coefficients", coefs)
        laws = {}
        for key, law in dict(self.amplitude_laws).items():
            if isinstance(law, PowerLaw):
                laws[terms[key].coefficient] = law
            else:
                laws[terms[key].coefficient] = tuple(float(p) for p in np.atleast_1d(law))
        object.__setattr__(self, "amplitude_laws", MappingProxyType(laws))

    @property
    def omega1(self) -> float:
        """Linear natural frequency [rad/s] (square root of the ``q`` coefficient)."""
        return float(np.sqrt(self.coefficients[self.terms.index("q")]))

    @property
    def depends_on_amplitude(self) -> bool:
        return bool(self.amplitude_laws)

    def coefficients_at(self, q_max: float) -> np.ndarray:
        """Coefficient vector of a steady state whose amplitude is ``q_max``."""
        theta = np.array(self.coefficients)
        for name, law in self.amplitude_laws.items():
            theta[self.terms.index(name)] = (law.value(q_max) if isinstance(law, PowerLaw)
                                             else np.polynomial.polynomial.polyval(q_max, law))
        return theta

    def amplitude_law_derivative(self, q_max: float) -> np.ndarray:
        """``d theta / d q_max`` (zero for coefficients without a law)."""
        d = np.zeros(len(self.terms))
        P = np.polynomial.polynomial
        for name, law in self.amplitude_laws.items():
            d[self.terms.index(name)] = (law.derivative(q_max) if isinstance(law, PowerLaw)
                                         else P.polyval(q_max, P.polyder(law)))
        return d

    def restoring_force(self, q, v, q_max: float = 0.0):
        return self.terms.restoring_force(q, v, self.coefficients_at(q_max))

    def summary(self) -> dict:
        return {
            "terms": list(self.terms.names),
            "coefficients": dict(zip(self.terms.coefficient_names, self.coefficients)),
            "amplitude_laws": {k: v.summary() if isinstance(v, PowerLaw) else list(v)
                               for k, v in self.amplitude_laws.items()},
        }


def seed_model(omega1=170.0, k3=5e6, c_law=(0.08, 70.0, 1e4), terms="q + -q^3 + q'") -> SingleModeModel:
    """The seed paper's numerical example (Eq 19-20): ``q'' + c(q_max) q' + w1^2 q - k3 q^3 = Q``."""
    lib = library(terms)
    coefs = [0.0] * len(lib)
    coefs[lib.index("q")] = omega1**2
    coefs[lib.index("-q^3")] = k3
    laws = {"q'": tuple(c_law)} if c_law is not None else {}
    if c_law is None:
        coefs[lib.index("q'")] = 0.0
    return SingleModeModel(lib, tuple(coefs), laws)
