"""Joint laws of the virtual rig: cubic stiffness plus Segalman's four-parameter Iwan model.

A joint law maps the relative motion ``u`` of the two joint nodes (relative rotation
``th2 - th1`` or relative deflection ``w2 - w1``, :mod:`jointid.modal.joint`) and its
history to the force (or moment) the joint carries.  One protocol serves time
integration and harmonic balance (DESIGN example 5):

``force(u, v, state) -> (f, new_state)``
    One time step.  ``state`` is an explicit array (the slider positions of the Jenkins
    elements), created by ``initial_state(shape)``; the law object itself never changes.
``periodic_force(u) -> (f, state0)``
    The steady periodic force of a periodic motion sampled at ``N`` equispaced points of
    one period (time on the last axis), for the alternating frequency/time (AFT) method
    of harmonic balance.  ``state0`` is the hysteretic state at the first sample, so a
    time integration can start on the periodic orbit.

Four-parameter Iwan model (Segalman 2005)
-----------------------------------------
A parallel (Iwan) set of Jenkins elements -- a unit spring in series with a Coulomb
slider that slips when the spring deflection reaches ``phi`` -- with the density of slip
displacements ``rho(phi) = R phi^chi [H(phi) - H(phi - phi_max)] + S delta(phi - phi_max)``.
Its four parameters are

* ``F_S``: the force at which the whole joint slips (macro-slip);
* ``K_T``: the joint stiffness at small amplitude (all elements stuck);
* ``chi`` in ``(-1, 0]`` typically: the exponent of the dissipation power law, the energy
  dissipated per cycle in micro-slip grows as ``F^(3 + chi)``;
* ``beta >= 0``: the ratio of the delta (``S``) part to the continuous part of the stiffness.

with (Segalman 2005, Eq 24-26)

``phi_max = F_S (1 + beta) / (K_T (beta + (chi + 1) / (chi + 2)))``,
``R = F_S (chi + 1) / (phi_max^(chi + 2) (beta + (chi + 1) / (chi + 2)))``,
``S = F_S / phi_max * beta / (beta + (chi + 1) / (chi + 2))``.

Closed forms used in the tests: the virgin loading curve
``f(u) = K_T u - R u^(chi + 2) / ((chi + 1)(chi + 2))`` for ``u < phi_max`` and ``F_S``
beyond; the dissipation per cycle at displacement amplitude ``u0 < phi_max``,
``D = 4 R u0^(chi + 3) / ((chi + 2)(chi + 3))``, and, in terms of the force amplitude,
``D ~ 4 R / ((chi + 2)(chi + 3)) (F0 / K_T)^(chi + 3)`` for ``F0 << F_S``.

Discretisation
--------------
:func:`discretize_iwan` splits ``[0, phi_max]`` into intervals whose edges are
geometrically spaced down to ``phi_min`` (the first interval is ``[0, phi_min]``, which
holds the integrable singularity of ``phi^chi``).  Each interval becomes one Jenkins
element whose stiffness is the exact integral of ``R phi^chi`` over the interval and
whose slip force is the exact integral of ``R phi^(chi + 1)``; the delta part is one more
element.  The discrete joint therefore has exactly the stiffness ``K_T`` and the
macro-slip force ``F_S`` of the continuous one.

Examples
--------
>>> law = JointLaw(IwanParameters(F_S=2.0, K_T=2000.0, chi=-0.4, beta=0.5), k3=0.0)
>>> u = 1e-9 * np.sin(np.linspace(0, 2 * np.pi, 64, endpoint=False))
>>> f, state0 = law.periodic_force(u)
>>> round(float(f.max() / u.max()), 1)          # full stiffness K_T at small amplitude
2000.0
"""

from __future__ import annotations

import html
import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import StructureError
from ..joints import DiscreteIwan, Iwan4, discretize_iwan4

__all__ = ["IwanParameters", "JenkinsElements", "JointLaw", "discretize_iwan"]


def _finite(name, value, *, positive=False, nonneg=False):
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise StructureError(f"Iwan parameter {name}: expected a number, got {value!r}") from None
    if not math.isfinite(v) or (positive and v <= 0) or (nonneg and v < 0):
        kind = "a positive" if positive else "a non-negative" if nonneg else "a finite"
        raise StructureError(f"Iwan parameter {name}: expected {kind} finite number, got {value!r}")
    return v


def _shape(shape) -> tuple:
    return (int(shape),) if np.ndim(shape) == 0 else tuple(int(n) for n in shape)


@dataclass(frozen=True)
class IwanParameters:
    """Segalman's four-parameter Iwan model of a lap joint.

    Parameters
    ----------
    F_S : float
        Macro-slip force (or moment) [N, or N m for a rotational joint].
    K_T : float
        Stiffness at small amplitude [N/m, or N m/rad].
    chi : float
        Exponent of the slip-density power law, ``-1 < chi < 1`` (lap joints: about
        ``-0.5``); the dissipation per cycle grows as ``F^(3 + chi)`` in micro-slip.
    beta : float
        Ratio of the delta (``S``) part to the continuous part of the stiffness, ``>= 0``.

    Examples
    --------
    >>> p = IwanParameters(F_S=1.0, K_T=1000.0, chi=-0.5, beta=1.0)
    >>> round(p.phi_max, 6), float(p.backbone(2 * p.phi_max))     # macro-slip: F_S
    (0.0015, 1.0)
    """

    F_S: float
    K_T: float
    chi: float
    beta: float
    _law: Iwan4 = field(init=False, repr=False, compare=False, default=None)

    def __post_init__(self):
        object.__setattr__(self, "F_S", _finite("F_S", self.F_S, positive=True))
        object.__setattr__(self, "K_T", _finite("K_T", self.K_T, positive=True))
        chi = _finite("chi", self.chi)
        if not -1.0 < chi < 1.0:
            raise StructureError(f"Iwan parameter chi: expected -1 < chi < 1, got {self.chi!r}")
        object.__setattr__(self, "chi", chi)
        object.__setattr__(self, "beta", _finite("beta", self.beta, nonneg=True))
        # the ground law carries the closed forms that are the same to the bit (its sliders are not used)
        object.__setattr__(self, "_law", Iwan4(self.F_S, self.K_T, chi, self.beta, n_sliders=2))

    # --- derived parameters ---------------------------------------------------------
    @property
    def _den(self) -> float:
        return self.beta + (self.chi + 1.0) / (self.chi + 2.0)

    @property
    def phi_max(self) -> float:
        """Largest slip displacement: every element slips beyond it [m or rad]."""
        return self.F_S * (1.0 + self.beta) / (self.K_T * self._den)

    @property
    def R(self) -> float:
        """Coefficient of the continuous density ``R phi^chi``."""
        return self.F_S * (self.chi + 1.0) / (self.phi_max ** (self.chi + 2.0) * self._den)

    @property
    def S(self) -> float:
        """Weight of the delta at ``phi_max`` (stiffness of the last element)."""
        return self.F_S / self.phi_max * self.beta / self._den

    @property
    def dissipation_exponent(self) -> float:
        """``3 + chi``: the micro-slip power-law exponent of dissipation per cycle vs force."""
        return 3.0 + self.chi

    # --- closed forms -----------------------------------------------------------------
    def backbone(self, u):
        """Virgin loading force ``f(u)`` (odd in ``u``; ``F_S sign(u)`` in macro-slip): the ground
        law's closed form, :meth:`jointid.joints.Iwan4.backbone`."""
        return self._law.backbone(u)

    def dissipation(self, amplitude):
        """Energy dissipated in one symmetric cycle of displacement amplitude ``u0``.

        ``4 R u0^(chi + 3) / ((chi + 2)(chi + 3))`` in micro-slip (``u0 < phi_max``);
        beyond, every element slips and
        ``D = 4 R (u0 phi_max^(chi + 2) / (chi + 2) - phi_max^(chi + 3) / (chi + 3))
        + 4 S phi_max (u0 - phi_max)``.  The same closed form as
        :meth:`jointid.joints.Iwan4.dissipation`, kept here because it uses this class's ``S``
        (``F_S / phi_max * beta / den``, which can differ from the ground's ``F_S beta /
        (phi_max den)`` in the last bit and is the delta element's stiffness of the rig).
        """
        u0 = np.abs(np.asarray(amplitude, float))
        chi, R, S, pm = self.chi, self.R, self.S, self.phi_max
        micro = 4.0 * R * u0 ** (chi + 3.0) / ((chi + 2.0) * (chi + 3.0))
        macro = 4.0 * R * (u0 * pm ** (chi + 2.0) / (chi + 2.0) - pm ** (chi + 3.0) / (chi + 3.0)) + 4.0 * S * pm * (
            u0 - pm
        )
        out = np.where(u0 < pm, micro, macro)
        return out[()] if out.ndim == 0 else out

    def microslip_dissipation(self, force_amplitude):
        """Segalman's small-force closed form ``4 R (F0 / K_T)^(chi + 3) / ((chi + 2)(chi + 3))``
        (:meth:`jointid.joints.Iwan4.microslip_dissipation`)."""
        return self._law.microslip_dissipation(force_amplitude)

    def displacement_at_force(self, force_amplitude):
        """Inverse of the backbone on ``[0, F_S)``: the amplitude ``u0`` whose force amplitude is ``F0``."""
        F0 = np.atleast_1d(np.abs(np.asarray(force_amplitude, float)))
        if np.any(F0 >= self.F_S):
            raise StructureError(f"force amplitude must be below the macro-slip force F_S = {self.F_S}, got {F0.max()}")
        u = F0 / self.K_T
        for _ in range(60):  # Newton on the concave backbone from below: monotone convergence
            chi, R = self.chi, self.R
            g = self.K_T * u - R * u ** (chi + 2.0) / ((chi + 1.0) * (chi + 2.0)) - F0
            dg = self.K_T - R * u ** (chi + 1.0) / (chi + 1.0)
            step = g / np.where(dg > 0, dg, np.inf)
            u = np.clip(u - step, 0.0, self.phi_max)
            if np.all(np.abs(step) <= 1e-15 * np.maximum(u, 1e-300)):
                break
        out = u.reshape(np.shape(force_amplitude))
        return out[()] if out.ndim == 0 else out

    def summary(self) -> dict:
        return {
            "F_S": self.F_S,
            "K_T": self.K_T,
            "chi": self.chi,
            "beta": self.beta,
            "phi_max": self.phi_max,
            "R": self.R,
            "S": self.S,
            "dissipation_exponent": self.dissipation_exponent,
        }


@dataclass(frozen=True, eq=False)
class JenkinsElements:
    """A parallel set of Jenkins elements (spring ``k_i`` in series with a slider).

    Element ``i`` carries ``k_i (u - x_i)`` with ``|u - x_i| <= phi_i``; ``x_i`` (the slider
    position) is the state.  Rate-independent: the velocity argument of :meth:`force`
    is accepted for the common protocol and ignored.  The time step and the periodic force
    with its Jacobian are those of the ground law :class:`jointid.joints.DiscreteIwan`
    (:attr:`sliders`, slip forces ``k_i phi_i``); this class adds the rig's conventions: the
    elements that never slip over a period sit at the centre of its range, and the slider
    positions at the first sample of the periodic orbit (:meth:`orbit_state`).

    Parameters
    ----------
    stiffness : array, shape (n,)
        Element stiffnesses ``k_i`` (> 0).
    slip : array, shape (n,)
        Slip displacements ``phi_i`` (> 0); the slip force of element ``i`` is ``k_i phi_i``.
        Stored as the ground law's ``slip_force / stiffness`` (equal to the given values to
        the last bit or within one rounding).
    """

    stiffness: np.ndarray
    slip: np.ndarray
    sliders: DiscreteIwan = field(init=False, repr=False, compare=False, default=None)

    def __post_init__(self):
        k = np.array(self.stiffness, dtype=float).ravel()
        p = np.array(self.slip, dtype=float).ravel()
        if k.shape != p.shape or k.size == 0:
            raise StructureError(f"Jenkins elements: stiffness {k.shape} and slip {p.shape} must be equal, non-empty")
        if not (np.all(np.isfinite(k)) and np.all(k > 0) and np.all(np.isfinite(p)) and np.all(p > 0)):
            raise StructureError("Jenkins elements: stiffnesses and slip displacements must be positive and finite")
        self._attach(DiscreteIwan(k, k * p))

    @classmethod
    def from_sliders(cls, sliders: DiscreteIwan) -> JenkinsElements:
        """The rig's view of a ground :class:`~jointid.joints.DiscreteIwan` (its stiffnesses and
        slip forces kept to the bit)."""
        out = object.__new__(cls)
        out._attach(sliders)
        return out

    def _attach(self, sliders: DiscreteIwan):
        phi = sliders.slip_displacement
        phi.setflags(write=False)
        object.__setattr__(self, "sliders", sliders)
        object.__setattr__(self, "stiffness", sliders.stiffness)
        object.__setattr__(self, "slip", phi)

    @property
    def n_elements(self) -> int:
        return self.sliders.n_elements

    @property
    def total_stiffness(self) -> float:
        """Stiffness with every element stuck."""
        return self.sliders.total_stiffness

    @property
    def slip_force(self) -> float:
        """Force with every element slipping (macro-slip)."""
        return float(self.stiffness @ self.slip)

    def initial_state(self, shape=()) -> np.ndarray:
        """Virgin state (all sliders at zero) for a batch of the given shape."""
        return np.zeros(_shape(shape) + (self.n_elements,))

    def force(self, u, v, state):
        """One time step: ``(force, new_state)`` for relative motion ``u`` (any shape)."""
        return self.sliders.force(u, v, state)

    def periodic_force(self, u, jacobian: bool = False):
        """Steady periodic force of a periodic motion sampled over one period.

        Parameters
        ----------
        u : array, shape (..., N)
            Relative motion at ``N`` equispaced instants of one period.
        jacobian : bool
            Also return ``D[j, m] = d f_j / d u_m`` (only for a 1-D ``u``).

        Returns
        -------
        f : array, shape (..., N)
            The force on the periodic orbit.
        state0 : array, shape (..., n_elements)
            Slider positions at the first sample (:meth:`orbit_state`).
        D : array, shape (N, N)
            Only with ``jacobian=True``.

        Notes
        -----
        ``f`` and ``D`` are :meth:`DiscreteIwan.aft <jointid.joints.DiscreteIwan.aft>` with
        ``state0="centre"``: an element that slips over the period reaches its periodic
        (Masing) state whatever its start; one that never slips keeps the centre of the range
        ``(u_max + u_min) / 2`` (the state reached by a vibration growing from rest), and the
        Jacobian includes that dependence on the largest and smallest samples.
        """
        u = np.asarray(u, float)
        if jacobian and u.ndim != 1:
            raise ValueError(f"the Jacobian is available for a single period (1-D u), got shape {u.shape}")
        f, D = self.sliders.aft(u, state0="centre", jacobian=jacobian)
        return (f, self.orbit_state(u), D) if jacobian else (f, self.orbit_state(u))

    def orbit_state(self, u) -> np.ndarray:
        """Slider positions after the first sample of the periodic orbit of ``u (..., N)``.

        On the orbit the state at the largest sample ``u_max`` is known (Masing): an element
        whose slip displacement is below half the range has just slipped forward,
        ``x = u_max - phi``; one that never slips sits at the centre of the range.  The time
        step (:meth:`force`) carries it from that sample to the first one; a time
        integration started there stays on the orbit.
        """
        u = np.asarray(u, float)
        N = u.shape[-1]
        i0 = np.argmax(u, axis=-1)
        ur = np.take_along_axis(u, (i0[..., None] + np.arange(N)) % N, axis=-1)
        umax, umin = ur[..., 0], ur.min(axis=-1)
        phi = self.slip
        x = np.where(phi < 0.5 * (umax - umin)[..., None], umax[..., None] - phi, 0.5 * (umax + umin)[..., None])
        j0 = (N - i0) % N  # step at which the original sample 0 is reached
        state0 = np.empty_like(x)
        for j in range(int(np.max(j0)) + 1):
            _, x = self.force(ur[..., j], None, x)
            hit = j0 == j
            if np.any(hit):
                state0[hit] = x[hit]
        return state0


def discretize_iwan(params: IwanParameters, n_elements: int = 100, phi_min_ratio: float = 1e-5) -> JenkinsElements:
    """Jenkins elements approximating a four-parameter Iwan model.

    The discretisation of the ground law, :func:`jointid.joints.discretize_iwan4` (geometric
    interval edges down to ``phi_min_ratio phi_max``, each element the exact integral of the
    density over its interval, the delta part one more element), with the rig's defaults.

    Parameters
    ----------
    params : IwanParameters
    n_elements : int
        Elements of the continuous part (the delta part adds one when ``beta > 0``).
    phi_min_ratio : float
        Smallest interval edge relative to ``phi_max``; the edges above it are geometric.

    Returns
    -------
    JenkinsElements
        With exactly ``K_T`` total stiffness and ``F_S`` macro-slip force.

    Examples
    --------
    >>> p = IwanParameters(2.0, 2000.0, -0.5, 0.3)
    >>> e = discretize_iwan(p, 50)
    >>> round(e.total_stiffness, 9), round(e.slip_force, 12)
    (2000.0, 2.0)
    """
    n = int(n_elements)
    if n < 2:
        raise StructureError(f"n_elements: expected an integer >= 2, got {n_elements!r}")
    if not 0.0 < phi_min_ratio < 1.0:
        raise StructureError(f"phi_min_ratio: expected a value in (0, 1), got {phi_min_ratio!r}")
    return JenkinsElements.from_sliders(discretize_iwan4(params, n, phi_min_ratio))


@dataclass(frozen=True, eq=False)
class JointLaw:
    """Joint force of one relative coordinate: Iwan micro-slip plus cubic stiffness.

    ``f(u) = Iwan(u; history) - k3 u^3`` (the seed's sign: ``k3 > 0`` softens).  The
    stiffness at small amplitude is ``K_T`` of the Iwan part; in the rig it is already in
    the linear finite element model, and only ``f(u) - K_T u`` acts as a nonlinear force.

    Parameters
    ----------
    iwan : IwanParameters or None
        The micro-slip part (``None``: no friction).
    k3 : float
        Cubic coefficient [N/m^3 or N m/rad^3]; positive is softening.
    n_elements : int
        Jenkins elements of the discretised Iwan part.
    phi_min_ratio : float
        See :func:`discretize_iwan`.

    Attributes
    ----------
    elements : JenkinsElements or None
        The discretised Iwan part.
    """

    iwan: IwanParameters | None = None
    k3: float = 0.0
    n_elements: int = 100
    phi_min_ratio: float = 1e-5
    elements: JenkinsElements | None = field(init=False, repr=False, default=None)

    def __post_init__(self):
        if self.iwan is not None and not isinstance(self.iwan, IwanParameters):
            raise StructureError(f"iwan: expected IwanParameters or None, got {type(self.iwan).__name__}")
        object.__setattr__(self, "k3", _finite("k3", self.k3))
        if self.iwan is not None:
            object.__setattr__(self, "elements", discretize_iwan(self.iwan, self.n_elements, self.phi_min_ratio))

    @property
    def linear_stiffness(self) -> float:
        """Tangent stiffness at zero amplitude (``K_T``; 0 without an Iwan part)."""
        return self.elements.total_stiffness if self.elements is not None else 0.0

    @property
    def n_state(self) -> int:
        return self.elements.n_elements if self.elements is not None else 0

    def initial_state(self, shape=()) -> np.ndarray:
        """Virgin hysteretic state, shape ``shape + (n_state,)``."""
        return np.zeros(_shape(shape) + (self.n_state,))

    def force(self, u, v, state):
        """``(f, new_state)`` after one step to relative motion ``u`` (velocity ``v`` unused)."""
        u = np.asarray(u, float)
        f = -self.k3 * u**3
        if self.elements is None:
            return f, state
        fi, state = self.elements.force(u, v, state)
        return f + fi, state

    def nonlinear_force(self, u, v, state):
        """``(f - K_T u, new_state)``: the part not in the linear model."""
        f, state = self.force(u, v, state)
        return f - self.linear_stiffness * np.asarray(u, float), state

    def periodic_force(self, u, jacobian: bool = False):
        """Steady force over one sampled period ``u (..., N)``: ``(f, state at sample 0)``.

        With ``jacobian=True`` (1-D ``u``) also ``D = d f / d u``, shape ``(N, N)``
        (see :meth:`JenkinsElements.periodic_force`).
        """
        u = np.asarray(u, float)
        if jacobian and u.ndim != 1:
            raise ValueError(f"the Jacobian is available for a single period (1-D u), got shape {u.shape}")
        f, D = self.aft(u, jacobian=jacobian)
        return (f, self.orbit_state(u), D) if jacobian else (f, self.orbit_state(u))

    def aft(self, u, jacobian: bool = False):
        """``(f, D)`` of :meth:`periodic_force` without the state (``D`` is None unless asked)."""
        u = np.asarray(u, float)
        f = -self.k3 * u**3
        if self.elements is None:
            return f, (np.diag(-3.0 * self.k3 * u**2) if jacobian else None)
        fi, D = self.elements.sliders.aft(u, state0="centre", jacobian=jacobian)
        return f + fi, (D + np.diag(-3.0 * self.k3 * u**2) if jacobian else None)

    def orbit_state(self, u) -> np.ndarray:
        """Hysteretic state at the first sample of the periodic orbit of ``u (..., N)``
        (:meth:`JenkinsElements.orbit_state`; shape ``(..., 0)`` without an Iwan part)."""
        u = np.asarray(u, float)
        if self.elements is None:
            return np.zeros(u.shape[:-1] + (0,))
        return self.elements.orbit_state(u)

    def summary(self) -> dict:
        return {
            "iwan": None if self.iwan is None else self.iwan.summary(),
            "k3": self.k3,
            "n_elements": self.n_state,
            "linear_stiffness": self.linear_stiffness,
        }

    def report(self) -> str:
        if self.iwan is None:
            return f"JointLaw: f = -k3 u^3, k3 = {self.k3:.4g}"
        p = self.iwan
        return (
            f"JointLaw: Iwan(F_S={p.F_S:.4g}, K_T={p.K_T:.4g}, chi={p.chi:.3g}, beta={p.beta:.3g}; "
            f"phi_max={p.phi_max:.4g}) - k3 u^3 with k3 = {self.k3:.4g}; {self.n_state} Jenkins elements"
        )

    def _repr_html_(self) -> str:
        return f"<pre>{html.escape(self.report())}</pre>"
