"""The micro-slip amplitude law ``c(q_max) = c0 + c1 q_max^p`` of a coefficient.

A joint in micro-slip (the Iwan model of :mod:`jointid.identify.jointlaw` and
:mod:`jointid.rig.iwan`) loses stiffness and dissipates energy as powers of its amplitude:
with the slip-displacement density ``R phi^chi`` its first-harmonic stiffness falls by
``R I(chi) u0^(1 + chi)`` and it dissipates ``D = 4 R u0^(3 + chi) / ((2 + chi)(3 + chi))``
per cycle, an equivalent viscous damping ``D / (pi omega u0^2)`` that grows as
``u0^(1 + chi)``.  Through the mode shape the joint amplitude is proportional to the modal
amplitude, so a single-mode model carries the same powers of ``q_max``:

``c(q_max) = c0 + c1 q_max^p``, ``omega^2(q_max) = omega1^2 + s q_max^p'``

(``c0``: the structure's own damping; ``s < 0`` a softening joint), ``p = 1 + chi`` of the
joint's dissipation.  Unlike a polynomial in ``q_max`` this law keeps its shape outside the
measured amplitudes, which is what a prediction at a higher force level asks of it.  The
exponent is a nonlinear parameter: the preload model is fitted by variable projection (the
other parameters by linear least squares at each exponent) and the exponent's derivative
column enters the Jacobian of its covariance (:mod:`jointid.identify.model`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["POWER", "PowerLaw", "is_power"]

#: The amplitude-law specification of the power law (``{"q'": "power"}``).
POWER = "power"
#: Range of the fitted exponent (a micro-slip joint has ``0 < p = 1 + chi < 2``; wider to
#: let the data show where the law does not hold).
EXPONENT_BOUNDS = (0.05, 4.0)


def is_power(spec) -> bool:
    """Whether an amplitude-law specification (an order or ``"power"``) is the power law."""
    return isinstance(spec, str) and spec.strip().lower() == POWER


@dataclass(frozen=True)
class PowerLaw:
    """``base + coefficient * q_max^exponent``, with its derivatives.

    Parameters
    ----------
    base : float
        Value at zero amplitude (``c0``, ``omega1^2``).
    coefficient : float
        Factor of the power (``c1``, ``s``).
    exponent : float
        ``p > 0``.

    Examples
    --------
    >>> law = PowerLaw(0.5, 20.0, 0.7)
    >>> round(law.value(1e-3), 6)
    0.6589
    >>> round(law.chi, 3)     # the Iwan exponent of a damping law
    -0.3
    """

    base: float
    coefficient: float
    exponent: float

    def __post_init__(self):
        for name in ("base", "coefficient", "exponent"):
            object.__setattr__(self, name, float(getattr(self, name)))
        if not (np.isfinite(self.exponent) and self.exponent > 0):
            raise ValueError(f"power-law exponent must be a positive finite number, got {self.exponent}")

    @property
    def parameters(self) -> tuple:
        return (self.base, self.coefficient, self.exponent)

    @property
    def chi(self) -> float:
        """``p - 1``: the Iwan exponent when the law is the equivalent damping of a micro-slip joint."""
        return self.exponent - 1.0

    def value(self, q_max):
        q = np.abs(q_max)
        return self.base + self.coefficient * q**self.exponent

    def derivative(self, q_max):
        """``d value / d q_max`` (amplitudes floored at the smallest positive float)."""
        q = np.maximum(np.abs(q_max), np.finfo(float).tiny)
        return self.coefficient * self.exponent * q ** (self.exponent - 1.0)

    def jacobian(self, q_max) -> np.ndarray:
        """``d value / d (base, coefficient, exponent)`` at one amplitude."""
        q = abs(float(q_max))
        qp = q**self.exponent
        return np.array([1.0, qp, self.coefficient * qp * np.log(q) if q > 0 else 0.0])

    def summary(self) -> dict:
        return {"law": POWER, "base": self.base, "coefficient": self.coefficient, "exponent": self.exponent}
