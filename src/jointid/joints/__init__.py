"""Joint laws: one protocol for time integration and harmonic balance.

A joint law maps the relative motion ``u`` of the two sides of a joint (a deflection [m] or
a rotation [rad]; forces then read as moments) and its history to the force the joint
carries.  This package sits on the ground floor: it imports only numpy, scipy and
:mod:`jointid.errors` / :mod:`jointid.conventions`, so identification, simulation, the rig
and prediction can all use it.

The protocol
------------
A law is an immutable (frozen) dataclass whose fields are its named parameters;
``law.parameters`` gives their values and ``law.units`` their SI units; a change makes a new
law (``law.replace(kt=...)``).

``force(u, v, state) -> (f, new_state)``
    One time step to the motion ``u`` (any shape).  The hysteretic state is an explicit
    array with ``law.n_state`` entries on its last axis, created by
    ``law.initial_state(shape)`` (the virgin joint at rest at ``u = 0``); the law object never
    changes.  ``v`` (velocity) is needed only by rate-dependent laws
    (``law.rate_dependent``).

``aft(u_t, v_t=None, *, velocity_jacobian=False, jacobian=True) -> (f_t, df_du[, df_dv])``
    The steady periodic force over one period sampled at ``n`` equispaced instants (time on
    the last axis; leading axes are a batch), for the alternating frequency/time method.
    Hysteretic laws carry the slip history through the period twice (Masing: after one
    sweep every element that slipped is on its periodic orbit; elements that never slip
    keep their state before the period, by default the virgin one, set by ``state0`` for
    the slider laws); Bouc-Wen solves for its periodic state.  ``df_du[..., j, m] =
    d f_j / d u_m`` is the EXACT derivative of the sampled map, returned dense with shape
    ``(..., n, n)``.  It is not triangular: a slider's position at sample ``j`` depends on
    the sample where it last slipped, which may lie later in the period (the history wraps
    round).  For the slider laws each row has at most one non-zero per element plus the
    diagonal (two for an element that never slips with ``state0="centre"``: the largest
    and smallest samples); for polynomial terms it is diagonal.  The map is piecewise smooth: at a
    sample where an element is exactly at its slip limit the derivative is one-sided.
    ``jacobian=False`` skips the Jacobians (returned as ``None``) for long periods.

``backbone(a)``
    Initial-loading (Masing) curve ``f(a)`` from the virgin state, odd in ``a``.

``dissipation(a, omega=None)``
    Energy dissipated per symmetric cycle of amplitude ``a`` (``omega`` only for
    rate-dependent laws), in closed form.

``first_harmonic(a, omega=None)``
    Equivalent linearisation ``(k_eq, k_loss)``: the first harmonic of the force over
    ``u = a cos(omega t)`` is ``a (k_eq cos - k_loss sin)``, ``k_loss = D / (pi a^2)``
    (closed form where one exists, else sampled from ``aft``).

``summary()``
    JSON-safe dictionary: law, parameters, units, derived quantities.

Laws
----
:class:`PolynomialLaw`    named stiffness / damping terms of :data:`jointid.conventions.TERMS`
:class:`Jenkins`          spring ``kt`` in series with a Coulomb slider ``Fs``
:class:`DiscreteIwan`     Jenkins elements in parallel
:class:`Iwan4`            Segalman's four-parameter Iwan model (closed forms; evaluated on its
                          discretisation :func:`discretize_iwan4`)
:class:`BoucWen`          smooth hysteresis (exponent one, integrated exactly between samples)
:class:`ExactReversals`   a slider law whose ``aft`` reverses at the exact extrema of the motion
:class:`Parallel`         laws side by side on one relative motion (e.g. an Iwan joint with a cubic spring)

The closed forms and references are in ``docs/joint-laws.md``.

Examples
--------
>>> import numpy as np
>>> law = Jenkins(kt=1000.0, Fs=2.0)
>>> u = harmonic_motion(0.01, 512)
>>> f, D = law.aft(u)
>>> round(float(loop_energy(u, f)), 4), round(float(law.dissipation(0.01)), 4)   # 4 Fs (a - Fs/kt)
(0.064, 0.064)
"""

from ._core import JointLaw, harmonic_motion, loop_energy
from .boucwen import BoucWen
from .iwan import Iwan4, discretize_iwan4
from .parallel import Parallel
from .polynomial import TERM_FUNCTIONS, PolynomialLaw
from .reversals import ExactReversals
from .sliders import DiscreteIwan, Jenkins, jenkins_harmonic_stiffness

__all__ = [
    "JointLaw",
    "PolynomialLaw",
    "TERM_FUNCTIONS",
    "Jenkins",
    "DiscreteIwan",
    "Iwan4",
    "discretize_iwan4",
    "BoucWen",
    "ExactReversals",
    "Parallel",
    "jenkins_harmonic_stiffness",
    "harmonic_motion",
    "loop_energy",
]
