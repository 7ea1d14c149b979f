"""Steady states and frequency responses: :func:`steady_state`, :func:`frequency_response`
and the sequential sweep with its batched runs.

The sweep itself is in :mod:`.sweep`, the continuation in :mod:`.continuation`.
"""

from __future__ import annotations

import numpy as np

from ..._blas import single_threaded
from ...errors import ConvergenceError, RecordError
from .continuation import _continuation
from .kernels import _readonly
from .problem import _Problem
from .results import FrequencyResponse, SteadyState
from .sweep import _block, _sweep


def _check_omega(omega):
    w = float(omega)
    if not (np.isfinite(w) and w > 0):
        raise RecordError(f"omega must be a positive finite frequency in rad/s, got {omega!r}")
    return w


def _guess_vector(problem, guess):
    """Reduced unknown vector from a user guess (SteadyState or coefficient vector)."""
    if isinstance(guess, SteadyState):
        coefs, qm = guess.coefficients, guess.q_max
    else:
        coefs = np.asarray(guess, float)
        qm = None
    z = problem.reduce(coefs)
    if problem.closure:
        if qm is None:
            qm = problem.peak(z)[0]
        z = np.append(z, qm)
    return z


@single_threaded  # thousands of tiny dense solves: threaded BLAS only adds overhead
@np.errstate(all="ignore")  # diverging Newton trials are caught by their residual
def steady_state(
    model,
    omega,
    force_amplitude,
    n_harmonics=9,
    guess=None,
    tol=1e-12,
    *,
    stability=True,
    n_time=None,
    max_iter=40,
    odd=None,
) -> SteadyState:
    """Periodic steady state of ``q'' + h(q, q') = F sin(omega t)`` by harmonic balance.

    Parameters
    ----------
    model : SingleModeModel
        Restoring force and optional amplitude laws (closed on the solution's own
        ``q_max``, see the module docstring).
    omega : float
        Excitation frequency [rad/s].
    force_amplitude : float
        ``F``.
    n_harmonics : int, default 9
        Harmonics kept.  For odd libraries only the odd harmonics are solved for (the
        even ones are zero by symmetry); the stability analysis perturbs all of them.
    guess : SteadyState or array_like, optional
        Starting point (a neighbouring solution, or a coefficient vector of any length).
        Without it Newton starts from the linearised response and falls back to a
        homotopy in the force level.
    tol : float, default 1e-12
        Tolerance on the scaled residual (``|R| / max(F, (omega^2 + omega1^2) |x|)``
        and, with a closure, ``|q_max - max|q|| / |x|``).
    stability : bool, default True
        Compute the Floquet stability (monodromy matrix of the linearisation, see
        ``_Problem.floquet_batch``).  The amplitude closure is frozen (coefficients
        fixed at ``theta``) for the stability analysis.
    n_time : int, optional
        Time samples per period for the AFT (default :func:`default_n_time`).
    max_iter : int, default 40
    odd : bool, optional
        Force (or forbid) the odd-harmonic reduction; default: the library's symmetry.

    Returns
    -------
    SteadyState

    Raises
    ------
    jointid.errors.ConvergenceError
        When Newton (and the force homotopy) fail.
    """
    w = _check_omega(omega)
    problem = _Problem(model, force_amplitude, n_harmonics, n_time, odd)
    if guess is not None:
        try:
            z, ev, it = problem.newton(_guess_vector(problem, guess), w, tol, max_iter)
        except ConvergenceError:
            z, ev, it = problem.fresh(w, tol, max_iter)
    else:
        z, ev, it = problem.fresh(w, tol, max_iter)
    return problem.state(z, w, ev, it, stability)


@single_threaded  # thousands of tiny dense solves: threaded BLAS only adds overhead
@np.errstate(all="ignore")  # diverging Newton trials are caught by their residual
def frequency_response(
    model,
    force_amplitude,
    omegas=None,
    *,
    omega_range=None,
    n_harmonics=9,
    stability=True,
    tol=1e-12,
    n_time=None,
    odd=None,
    ds=0.02,
    ds_max=0.1,
    max_steps=5000,
) -> FrequencyResponse:
    """Frequency response by harmonic balance: a sweep or a continuation.

    Parameters
    ----------
    model : SingleModeModel
    force_amplitude : float
        ``F`` in ``Q = F sin(omega t)``.
    omegas : array_like, optional
        Sequential sweep at exactly these frequencies (in the given order), each point
        started from a polynomial predictor through the previous four solutions, runs of
        points it predicts well solved together.  This is the fast path.  Past a fold it
        lands on whichever branch Newton reaches (the jump of a physical sweep); use
        ``omega_range`` to follow the folds.
    omega_range : (float, float), optional
        Pseudo-arclength continuation in (harmonics, [q_max], omega) from
        ``omega_range[0]`` to ``omega_range[1]``, with step control (on the number of
        Newton iterations and the turning angle of the tangent).  The predictor is the
        polynomial through the last ``CONT_HISTORY`` points in their chord length (the
        tangent for the first step, and always with amplitude laws, whose frozen-closure
        stability near a fold depends on where the points fall).  Folds (turning points
        in omega) are located to tolerance and reported in ``folds``.
    n_harmonics : int, default 9
    stability : bool, default True
        Floquet stability of each point from the monodromy matrix of the linearisation
        about the periodic solution (two multipliers for one degree of freedom; the
        exponents agree with Hill's method, which keeps the two of smallest
        ``|imag|``).  The amplitude closure is frozen for stability (the
        coefficients stay at the point's ``theta``), as ``q_max`` is a property of the
        steady state, not a state variable.
    tol : float, default 1e-12
    n_time : int, optional
    odd : bool, optional
    ds, ds_max : float
        Initial and largest continuation step in the scaled (coefficient / amplitude
        scale, omega / range width) space.
    max_steps : int
        Continuation step limit (a :class:`~jointid.errors.ConvergenceWarning` is issued
        and the partial curve returned when reached).

    Returns
    -------
    FrequencyResponse

    Examples
    --------
    >>> import numpy as np
    >>> from jointid.simulate.model import seed_model
    >>> r = frequency_response(seed_model(), 1.0, np.linspace(160, 180, 401))
    >>> len(r), bool(r.stable.all())
    (401, True)
    """
    if (omegas is None) == (omega_range is None):
        raise RecordError("give exactly one of `omegas` (sweep) or `omega_range=(w0, w1)` (continuation)")
    problem = _Problem(model, force_amplitude, n_harmonics, n_time, odd)
    if omegas is not None:
        w = np.atleast_1d(np.asarray(omegas, float))
        if w.ndim != 1 or w.size == 0 or not np.all(np.isfinite(w)) or np.any(w <= 0):
            raise RecordError(f"omegas must be a non-empty 1-D array of positive frequencies, got {omegas!r}")
        blocks = _sweep(problem, w, tol)
        method, folds = "sweep", ()
    else:
        try:
            w0, w1 = (float(v) for v in omega_range)
        except (TypeError, ValueError):
            raise RecordError(f"omega_range must be a pair (w0, w1), got {omega_range!r}") from None
        _check_omega(w0), _check_omega(w1)
        if w0 == w1:
            raise RecordError(f"omega_range must span a non-empty interval, got {omega_range!r}")
        pts, folds = _continuation(problem, w0, w1, tol, ds, ds_max, max_steps)
        blocks = [_block(pts)]
        method = "continuation"
    return _assemble(problem, blocks, folds, method, stability)


def _assemble(problem, blocks, folds, method, stability):
    """Build the FrequencyResponse from consecutive blocks of points (see :func:`_block`)."""
    omega, Z, res, qmax, its = (np.concatenate(parts) for parts in zip(*blocks))
    n_pts = omega.size
    nx = problem.active.size
    coefs = np.zeros((n_pts, problem.n))
    coefs[:, problem.active] = Z[:, :nx]
    if problem.closure:  # the amplitude is an unknown; the laws at every point's amplitude at once
        qmax = Z[:, nx].copy()
        theta = problem._thetas(qmax)
    else:
        missing = np.isnan(qmax)
        if missing.any():  # q_max of all the points at once
            qmax[missing] = problem.peak_batch(coefs[missing][:, problem.active])[0]
        theta = np.tile(problem.theta0, (n_pts, 1))
    stable = floquet = None
    if stability:
        floquet = problem.floquet_batch(coefs, omega, theta)
        stable = floquet.real.max(axis=1) < 0.0
    amp = np.hypot(coefs[:, 1], coefs[:, 2])
    phase = np.arctan2(coefs[:, 1], coefs[:, 2])
    return FrequencyResponse(
        omega=_readonly(omega),
        q_max=_readonly(qmax),
        amplitude=_readonly(amp),
        phase=_readonly(phase),
        stable=None if stable is None else _readonly(stable),
        folds=tuple(int(i) for i in folds),
        coefficients=_readonly(coefs),
        theta=_readonly(theta),
        force_amplitude=problem.F,
        n_harmonics=problem.H,
        method=method,
        residual_norm=_readonly(res),
        iterations=_readonly(its),
        floquet_exponents=None if floquet is None else _readonly(floquet),
        model=problem.model,
    )
