"""Harmonic balance (alternating frequency/time) for the single-mode model.

Solves the periodic steady state of

    ``q'' + h(q, q'; theta) = F sin(omega t)``

where ``h`` is the model's term library and ``theta`` its coefficients (seed paper
Eq 19).  The unknown is the harmonic coefficient vector of ``q`` in the convention of
:mod:`jointid.conventions` (``[a0, a1, b1, ..., aH, bH]``).  The restoring force is
evaluated in time on an equispaced grid of one period and projected back on the
harmonics (AFT); the Jacobian is built analytically from the terms' partial
derivatives (the values of :meth:`jointid.identify.terms.TermLibrary.derivatives`; each
term's ``dq``/``dv`` is called directly to avoid per-call overhead) through the same
transforms.  For odd libraries only odd harmonics are solved for.

Amplitude closure
    When the model has amplitude laws (seed Eq 20) the coefficients of a steady state
    are ``model.coefficients_at(q_max)`` with ``q_max = max_t |q(t)|`` of that same
    steady state.  ``q_max`` is then an extra unknown with the extra equation
    ``q_max - max_t |q(t)| = 0``; the maximum is found to machine precision (dense grid
    then Newton on ``dq/dt = 0``) and, by the envelope theorem, its derivative with
    respect to the coefficients is ``sign(q(t*)) * basis(t*)``.

Public functions
    :func:`steady_state` (one frequency), :func:`frequency_response` (a sequential
    sweep at given frequencies, or pseudo-arclength continuation over a range with fold
    detection), :func:`linear_frf` (the linear part's receptance, for "linear vs
    nonlinear" plots as in the seed's Fig 4).

Layout
    :mod:`.problem` (the residual, Jacobian and Newton of one model, force level and
    truncation), :mod:`.batch` (their batched twins, many frequencies at once),
    :mod:`.stability` (Floquet exponents by Magnus monodromy, Hill's method),
    :mod:`.solve` (the public :func:`steady_state` and :func:`frequency_response`),
    :mod:`.sweep` (the sequential sweep), :mod:`.continuation` (pseudo-arclength
    continuation and folds), :mod:`.results` (:class:`SteadyState`,
    :class:`FrequencyResponse`, :func:`linear_frf`) and :mod:`.kernels` (bases, peak, small
    linear algebra, extrapolation).  Every name stays importable from this module; the
    sweep's knobs (``BATCH_GUESS``, ``HISTORY``, ``BATCH_MAX``, ``SAME_BRANCH``) are read
    from here at each call.

Examples
--------
>>> from jointid.simulate.model import seed_model
>>> s = steady_state(seed_model(), 169.5, 1.0)
>>> round(s.q_max * 1e3, 4)
6.333
>>> bool(s.stable)
True
"""

from __future__ import annotations

from .batch import _BatchMixin
from .continuation import CONT_HISTORY, _amplitude_scale, _Arclength, _continuation, _locate_fold
from .kernels import (
    PEAK_STEP,
    _TINY,
    _basis,
    _basis_at,
    _cos_sin,
    _expm2,
    _extrapolate,
    _extrapolate_one,
    _gauss_basis,
    _gauss_nodes,
    _horner,
    _matmul2,
    _peak,
    _product_gather,
    _readonly,
    _solve,
    default_n_time,
)
from .problem import _linear_closure_amplitude, _Problem
from .results import FrequencyResponse, SteadyState, linear_frf
from .solve import _assemble, _check_omega, _guess_vector, frequency_response, steady_state
from .stability import _StabilityMixin
from .sweep import BATCH_GUESS, BATCH_MAX, HISTORY, SAME_BRANCH, _block, _sweep

__all__ = [
    "SteadyState",
    "FrequencyResponse",
    "steady_state",
    "frequency_response",
    "linear_frf",
    "default_n_time",
]
