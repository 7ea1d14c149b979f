"""Segalman's four-parameter Iwan model and its discretisation into Jenkins elements.

A continuum of Jenkins elements of unit stiffness, element ``phi`` slipping when its spring
deflection reaches ``phi``, with the density of slip displacements (Segalman 2005, Eq 7)

``rho(phi) = R phi^chi [H(phi) - H(phi - phi_max)] + S delta(phi - phi_max)``.

Its four parameters are the macro-slip force ``F_S``, the stuck stiffness ``K_T``, the
exponent ``chi`` (``-1 < chi``) and the ratio ``beta = S / int_0^phi_max R phi^chi dphi``.
From ``K_T = int rho``, ``F_S = int phi rho`` and the definition of ``beta``:

``phi_max = F_S (1 + beta) / (K_T (beta + (chi + 1) / (chi + 2)))``,
``R = F_S (chi + 1) / (phi_max^(chi + 2) (beta + (chi + 1) / (chi + 2)))``,
``S = F_S beta / (phi_max (beta + (chi + 1) / (chi + 2)))``.

Closed forms (amplitude ``a``; Masing, so a symmetric cycle's branches are the backbone
scaled by two): backbone ``f(a) = K_T a - R a^(chi + 2) / ((chi + 1)(chi + 2))`` for
``a < phi_max`` and ``F_S`` beyond; dissipation per symmetric cycle, as every element
``phi < a`` dissipates ``4 phi (a - phi)``,
``D(a) = 4 R a^(chi + 3) / ((chi + 2)(chi + 3))`` for ``a <= phi_max`` and
``D(a) = 4 R (a phi_max^(chi + 2) / (chi + 2) - phi_max^(chi + 3) / (chi + 3)) + 4 S phi_max (a - phi_max)``
beyond.  In terms of the force amplitude ``F0 << F_S`` (``a ~ F0 / K_T``) the micro-slip
dissipation is Segalman's power law ``D ~ 4 R (F0 / K_T)^(chi + 3) / ((chi + 2)(chi + 3))``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
from scipy import integrate

from ..errors import StructureError
from ._core import JointLaw, _number, _scalar_out
from .sliders import DiscreteIwan, jenkins_harmonic_stiffness

__all__ = ["Iwan4", "MAX_SLIDERS", "discretize_iwan4"]


@dataclass(frozen=True, eq=False)
class Iwan4(JointLaw):
    """Segalman's four-parameter Iwan model.

    Parameters
    ----------
    F_S : float
        Macro-slip force [N] (N m for a rotational joint).
    K_T : float
        Stiffness with every element stuck [N/m] (N m/rad).
    chi : float
        Exponent of the slip density, ``-1 < chi < 1`` (lap joints about ``-0.5``);
        the micro-slip dissipation per cycle grows as ``a^(3 + chi)``.
    beta : float
        Delta (``S``) part over the continuous part of the stiffness, ``>= 0``.
    n_sliders : int
        Jenkins elements of the continuous part in the discretisation that :meth:`force`
        and :meth:`aft` evaluate (the delta part adds one element when ``beta > 0``), from 2 to
        :data:`MAX_SLIDERS`.
    phi_min_ratio : float
        Smallest interval edge of that discretisation relative to ``phi_max``.

    The closed forms (:meth:`backbone`, :meth:`dissipation`) are those of the continuous
    model; :meth:`force` and :meth:`aft` are exact for the discretisation
    :attr:`sliders`, which converges to them as ``n_sliders`` grows
    (:func:`discretize_iwan4`).  State: the slider positions of :attr:`sliders`.
    """

    F_S: float
    K_T: float
    chi: float
    beta: float
    n_sliders: int = 300
    phi_min_ratio: float = 1e-6
    UNITS: ClassVar[dict] = {"F_S": "N", "K_T": "N/m", "chi": "1", "beta": "1"}
    masing: ClassVar[bool] = True
    name: ClassVar[str] = "4-parameter Iwan"
    sliders: DiscreteIwan = field(init=False, repr=False, compare=False, default=None)

    def __post_init__(self):
        nm = self.name
        object.__setattr__(self, "F_S", _number(nm, "F_S", self.F_S, positive=True))
        object.__setattr__(self, "K_T", _number(nm, "K_T", self.K_T, positive=True))
        object.__setattr__(self, "chi", _number(nm, "chi", self.chi, lo=-1.0, hi=1.0))
        object.__setattr__(self, "beta", _number(nm, "beta", self.beta, nonneg=True))
        object.__setattr__(self, "n_sliders", _slider_count(nm, self.n_sliders))
        object.__setattr__(self, "phi_min_ratio", _number(nm, "phi_min_ratio", self.phi_min_ratio, lo=0.0, hi=1.0))
        object.__setattr__(self, "sliders", discretize_iwan4(self, self.n_sliders, self.phi_min_ratio))

    # --- derived parameters ---------------------------------------------------------
    @property
    def _den(self) -> float:
        return self.beta + (self.chi + 1.0) / (self.chi + 2.0)

    @property
    def phi_max(self) -> float:
        """Largest slip displacement [m]: every element slips beyond it."""
        return self.F_S * (1.0 + self.beta) / (self.K_T * self._den)

    @property
    def R(self) -> float:
        """Coefficient of the continuous density ``R phi^chi`` [N / m^(chi + 2)]."""
        return self.F_S * (self.chi + 1.0) / (self.phi_max ** (self.chi + 2.0) * self._den)

    @property
    def S(self) -> float:
        """Weight of the delta at ``phi_max`` (stiffness of the last element) [N/m]."""
        return self.F_S * self.beta / (self.phi_max * self._den)

    @property
    def n_state(self) -> int:
        return self.sliders.n_elements

    def derived(self) -> dict:
        return {"phi_max": self.phi_max, "R": self.R, "S": self.S, "dissipation_exponent": 3.0 + self.chi,
                "n_elements": self.sliders.n_elements, "n_sliders": self.n_sliders, "phi_min_ratio": self.phi_min_ratio}

    # --- closed forms ---------------------------------------------------------------
    def backbone(self, a):
        """Initial-loading force (odd in ``a``; ``F_S sign(a)`` in macro-slip)."""
        a = np.asarray(a, float)
        x = np.minimum(np.abs(a), self.phi_max)
        c = self.chi
        micro = self.K_T * x - self.R * x ** (c + 2.0) / ((c + 1.0) * (c + 2.0))
        f = np.where(np.abs(a) < self.phi_max, micro, self.F_S)
        return _scalar_out(np.sign(a) * f)

    def dissipation(self, a, omega=None):
        """Energy dissipated per symmetric cycle of displacement amplitude ``a`` (closed form)."""
        a = np.abs(np.asarray(a, float))
        c, R, S, pm = self.chi, self.R, self.S, self.phi_max
        micro = 4.0 * R * a ** (c + 3.0) / ((c + 2.0) * (c + 3.0))
        macro = 4.0 * R * (a * pm ** (c + 2.0) / (c + 2.0) - pm ** (c + 3.0) / (c + 3.0)) + 4.0 * S * pm * (a - pm)
        return _scalar_out(np.where(a <= pm, micro, macro))

    def first_harmonic(self, a, omega=None, n=None):
        """``(k_eq, k_loss)`` of the continuous model at amplitude ``a``.

        ``k_eq = K_T - R a^(chi + 1) I(chi)`` in micro-slip, with
        ``I(chi) = int_0^1 s^chi (1 - g(s)) ds`` and ``g`` the first-harmonic stiffness of a
        unit Jenkins element slipping at ``s a`` (:func:`jenkins_harmonic_stiffness`); in
        macro-slip ``int_0^phi_max R phi^chi g(phi / a) dphi + S g(phi_max / a)``.  The
        integrals by adaptive quadrature; ``k_loss = D / (pi a^2)``.
        """
        a_arr = np.abs(np.asarray(a, float))
        c, R, S, pm = self.chi, self.R, self.S, self.phi_max
        k = np.empty(a_arr.shape)
        for idx, ai in np.ndenumerate(a_arr):
            if ai == 0.0:
                k[idx] = self.K_T
            elif ai <= pm:
                k[idx] = self.K_T - R * ai ** (c + 1.0) * _loss_integral(c, 1.0)
            else:
                top = pm / ai
                part = R * ai ** (c + 1.0) * (top ** (c + 1.0) / (c + 1.0) - _loss_integral(c, top))
                k[idx] = part + S * float(jenkins_harmonic_stiffness(top))
        with np.errstate(invalid="ignore", divide="ignore"):
            kl = self.dissipation(a_arr) / (np.pi * a_arr**2)
        return _scalar_out(k), _scalar_out(kl)

    def microslip_dissipation(self, force_amplitude):
        """Segalman's small-force law ``4 R (F0 / K_T)^(chi + 3) / ((chi + 2)(chi + 3))``."""
        F0 = np.abs(np.asarray(force_amplitude, float))
        c = self.chi
        return _scalar_out(4.0 * self.R * (F0 / self.K_T) ** (c + 3.0) / ((c + 2.0) * (c + 3.0)))

    # --- time and frequency domain: the discretisation --------------------------------
    def force(self, u, v, state):
        """One step of :attr:`sliders`: ``(f, new_state)``."""
        return self.sliders.force(u, v, state)

    def aft(self, u_t, v_t=None, *, velocity_jacobian=False, jacobian=True, state0=None):
        """Periodic force and exact Jacobian of :attr:`sliders` (see :meth:`DiscreteIwan.aft`)."""
        return self.sliders.aft(u_t, v_t, velocity_jacobian=velocity_jacobian, jacobian=jacobian, state0=state0)

    def aft_projected(self, u_t, P, E, *, state0=None, lazy=False):
        """Projected force Jacobian of :attr:`sliders` (see :meth:`DiscreteIwan.aft_projected`)."""
        return self.sliders.aft_projected(u_t, P, E, state0=state0, lazy=lazy)


#: Largest ``n_sliders`` of an :class:`Iwan4` (each harmonic-balance point costs time in proportion:
#: 1e6 sliders took 78 s for one small prediction; the discretisation converges long before).
MAX_SLIDERS = 10_000


def _slider_count(law, value) -> int:
    """``n_sliders`` as an int from 2 to :data:`MAX_SLIDERS`, or a :class:`StructureError` naming it."""
    want = f"{law} parameter n_sliders: expected an integer from 2 to {MAX_SLIDERS}, got {value!r}"
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise StructureError(want)
    v = float(value)
    if not np.isfinite(v) or v != int(v) or not 2 <= v <= MAX_SLIDERS:
        raise StructureError(want)
    return int(v)


def _loss_integral(chi, top):
    """``int_0^top s^chi (1 - g(s)) ds`` (``g``: :func:`jenkins_harmonic_stiffness`)."""
    val, _ = integrate.quad(
        lambda s: s**chi * (1.0 - jenkins_harmonic_stiffness(s)), 0.0, top, limit=200, epsabs=0.0, epsrel=1e-12
    )
    return float(val)


def discretize_iwan4(law: Iwan4, n_sliders: int = 300, phi_min_ratio: float = 1e-6) -> DiscreteIwan:
    """Jenkins elements approximating a four-parameter Iwan model.

    ``[0, phi_max]`` is cut at ``0`` and at ``n_sliders`` edges geometrically spaced from
    ``phi_min_ratio phi_max`` to ``phi_max`` (the first interval ``[0, phi_min]`` holds the
    integrable singularity of ``phi^chi``).  Each interval ``[p0, p1]`` becomes one element
    with the exact weights of the continuous density on it: stiffness
    ``k = int R phi^chi dphi = R (p1^(chi+1) - p0^(chi+1)) / (chi + 1)`` and slip force
    ``F = int R phi^(chi+1) dphi = R (p1^(chi+2) - p0^(chi+2)) / (chi + 2)`` (so its slip
    displacement ``F / k`` is the density-weighted mean of the interval).  The delta part is
    one more element (``S``, ``S phi_max``).  The discrete model therefore has exactly the
    stiffness ``K_T`` and the macro-slip force ``F_S`` of the continuous one.
    """
    n = _slider_count(getattr(law, "name", "4-parameter Iwan"), n_sliders)
    pm, c, R = law.phi_max, law.chi, law.R
    edges = np.concatenate([[0.0], pm * np.geomspace(phi_min_ratio, 1.0, n)])
    k = R * np.diff(edges ** (c + 1.0)) / (c + 1.0)
    F = R * np.diff(edges ** (c + 2.0)) / (c + 2.0)
    if law.S > 0:
        k = np.append(k, law.S)
        F = np.append(F, law.S * pm)
    return DiscreteIwan(k, F)
