"""Shared pieces of the joint-law protocol: the base class, parameter checks, loop energy."""

from __future__ import annotations

import dataclasses
import math
from typing import ClassVar

import numpy as np

from ..errors import StructureError

__all__ = ["JointLaw", "loop_energy", "harmonic_motion"]


def _number(law, name, value, *, positive=False, nonneg=False, lo=None, hi=None):
    """A finite float, or a :class:`StructureError` naming the law and the parameter."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise StructureError(f"{law} parameter {name}: expected a number, got {value!r}") from None
    bad = not math.isfinite(v) or (positive and v <= 0) or (nonneg and v < 0)
    bad = bad or (lo is not None and v <= lo) or (hi is not None and v >= hi)
    if bad:
        want = "a positive" if positive else "a non-negative" if nonneg else "a finite"
        rng = f" in ({lo}, {hi})" if lo is not None or hi is not None else ""
        raise StructureError(f"{law} parameter {name}: expected {want} finite number{rng}, got {value!r}")
    return v


def _scalar_out(x):
    x = np.asarray(x, float)
    return x[()] if x.ndim == 0 else x


def _shape(shape) -> tuple:
    return (int(shape),) if np.ndim(shape) == 0 else tuple(int(n) for n in shape)


class JointLaw:
    """Base class of the joint laws (see :mod:`jointid.joints` for the protocol).

    Subclasses are frozen dataclasses; their dataclass fields listed in ``UNITS`` are the
    named parameters.
    """

    #: parameter name -> unit (SI; "m" reads "rad" for a rotational joint, "N" reads "N m").
    UNITS: ClassVar[dict] = {}
    #: True when the force depends on the velocity (``v`` / ``v_t`` are then required).
    rate_dependent: ClassVar[bool] = False
    #: True when unloading branches are the backbone scaled by two (Masing's rule).
    masing: ClassVar[bool] = False
    #: Short name used in :meth:`summary`.
    name: ClassVar[str] = "joint law"

    # --- parameters ---------------------------------------------------------------
    @property
    def parameters(self) -> dict:
        """Named parameter values (floats), in the order of :attr:`UNITS`."""
        return {k: float(getattr(self, k)) for k in self.UNITS}

    @property
    def units(self) -> dict:
        return dict(self.UNITS)

    @property
    def n_state(self) -> int:
        """Length of the hysteretic state vector (last axis of a state array)."""
        return 0

    def initial_state(self, shape=()) -> np.ndarray:
        """Virgin state (the joint at rest at ``u = 0``) for a batch of the given shape."""
        return np.zeros(_shape(shape) + (self.n_state,))

    def derived(self) -> dict:
        """Derived quantities worth reporting (JSON-safe floats)."""
        return {}

    def summary(self) -> dict:
        """JSON-safe description: law, parameters, units, derived quantities."""
        return {
            "law": self.name,
            "parameters": self.parameters,
            "units": self.units,
            "rate_dependent": bool(self.rate_dependent),
            "masing": bool(self.masing),
            "n_state": int(self.n_state),
            "derived": {k: float(v) for k, v in self.derived().items()},
        }

    def replace(self, **changes):
        """A new law with some parameters changed (the law itself never changes)."""
        return dataclasses.replace(self, **changes)

    # --- protocol (implemented by subclasses) ---------------------------------------
    def force(self, u, v, state):  # pragma: no cover - interface
        raise NotImplementedError

    def aft(self, u_t, v_t=None, *, velocity_jacobian=False, jacobian=True):  # pragma: no cover - interface
        raise NotImplementedError

    def backbone(self, a):  # pragma: no cover - interface
        raise NotImplementedError

    def dissipation(self, a, omega=None):  # pragma: no cover - interface
        raise NotImplementedError

    def first_harmonic(self, a, omega=None, n: int = 4096):
        """Equivalent linearisation at amplitude ``a``: ``(k_eq, k_loss)``.

        For ``u = a cos(omega t)`` the force's first harmonic is
        ``a (k_eq cos(omega t) - k_loss sin(omega t))``; ``k_loss = D / (pi a^2)`` with ``D`` the
        dissipation per cycle.  This generic version samples :meth:`aft` over ``n`` points
        (laws with a closed form override it).
        """
        a = np.asarray(a, float)
        u = harmonic_motion(a, n)
        t = 2.0 * np.pi * np.arange(n) / n
        v = None
        if self.rate_dependent:
            self._need_velocity(omega, "omega")
            v = -a[..., None] * float(omega) * np.sin(t)
        f = self.aft(u, v, jacobian=False)[0]
        with np.errstate(invalid="ignore", divide="ignore"):
            k = 2.0 / n * (f @ np.cos(t)) / a
            kl = -2.0 / n * (f @ np.sin(t)) / a
        return _scalar_out(k), _scalar_out(kl)

    def _need_velocity(self, v, what):
        if v is None:
            raise StructureError(f"{self.name}: the law depends on the velocity; give {what}")


def harmonic_motion(a, n: int, mean: float = 0.0) -> np.ndarray:
    """``mean + a cos(2 pi j / n)``, ``j = 0 .. n-1``: one period starting at the maximum.

    ``a`` may be an array; the samples are on a new last axis.
    """
    a = np.asarray(a, float)
    return mean + a[..., None] * np.cos(2.0 * np.pi * np.arange(int(n)) / int(n))


def loop_energy(u_t, f_t) -> np.ndarray:
    """Area of the closed sampled loop ``oint f du`` (trapezoidal rule, the period closed).

    Positive for a loop run clockwise in the ``(u, f)`` plane (upper branch on loading), i.e. the energy the joint
    dissipates per cycle.  Time on the last axis.
    """
    u = np.asarray(u_t, float)
    f = np.asarray(f_t, float)
    du = np.roll(u, -1, axis=-1) - u
    fm = 0.5 * (np.roll(f, -1, axis=-1) + f)
    return _scalar_out(np.sum(fm * du, axis=-1))
