"""Damped Newton iteration of both harmonic-balance engines.

One loop for :meth:`jointid.simulate.structure_hb.CondensedHB.solve` (forced response),
:mod:`jointid.simulate.nlmodes` (nonlinear modes) and the single-mode solver
(:meth:`jointid.simulate.hbm.problem._Problem.newton`): a full Newton step, halved until a merit
decreases, until the problem's own error measure is at most ``tol``.  What the engines differ in
is passed by name:

- ``merit``: the condensed engine accepts a trial on the residual's norm, the single-mode
  engine on its scaled error;
- ``on_stall``: when no halving decreases the merit, the condensed engine takes the shortest
  step anyway (``"step"``: slider laws have kinks where no step decreases the norm at first), the
  single-mode engine gives up (``"fail"``: its sweeps, fresh starts and force homotopy then try
  the next start);
- ``jacobian``: the single-mode engine evaluates trial points without Jacobian and builds it only
  for accepted points that have not converged;
- ``halvings`` and ``solve``: how often the step may be halved, and the linear solver.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["NewtonResult", "damped_newton"]

_MERITS = ("residual", "error")
_ON_STALL = ("step", "fail")


@dataclass(frozen=True, eq=False)
class NewtonResult:
    """Last iterate ``x`` with its evaluation ``state``, ``iterations``, ``error`` and whether it
    ``converged`` (``error <= tol``); ``reason`` says why not."""

    x: np.ndarray
    state: object
    iterations: int
    error: float
    converged: bool
    reason: str = ""


def damped_newton(x, residual, tol, max_iter, *, jacobian=None, merit="residual", on_stall="step", halvings=10,
                  admissible=None, solve=np.linalg.solve) -> NewtonResult:
    """Newton with step halving.

    Parameters
    ----------
    x : ndarray
        Start.
    residual : callable
        ``residual(x) -> (R, J, error, state)``: the residual, its Jacobian ``dR/dx`` (or None when
        ``jacobian`` builds it), the convergence measure (compared with ``tol``) and anything the
        caller wants back.
    tol : float
        Converged when ``error <= tol``.
    max_iter : int
    jacobian : callable, optional
        ``jacobian(state) -> J``, called only for accepted, not converged points whose ``residual``
        returned no Jacobian.
    merit : {"residual", "error"}
        A trial point is accepted when its ``|R|`` (``"residual"``) or its ``error`` (``"error"``)
        is below the current point's.
    on_stall : {"step", "fail"}
        When the trial after ``halvings`` halvings is still not accepted: take it anyway
        (``"step"``) or stop without convergence (``"fail"``).
    halvings : int
        Times the step may be halved (``halvings + 1`` trials, the last of length
        ``2**-halvings``).
    admissible : callable, optional
        ``admissible(x) -> bool``: trial points where it is false are not evaluated (the step
        is halved; at the last trial the iteration fails).
    solve : callable
        ``solve(J, b)``, raising :class:`numpy.linalg.LinAlgError` when ``J`` is singular.

    Returns
    -------
    NewtonResult
        Failures (iteration limit, singular Jacobian, non-finite step, no admissible step, no
        decrease under ``on_stall="fail"``) are reported in ``reason``, not raised.
    """
    if merit not in _MERITS:
        raise ValueError(f"merit must be one of {_MERITS}, got {merit!r}")
    if on_stall not in _ON_STALL:
        raise ValueError(f"on_stall must be one of {_ON_STALL}, got {on_stall!r}")
    by_error = merit == "error"
    take_last = on_stall == "step"
    R, J, err, state = residual(x)
    it = 0

    def stop(why):
        return NewtonResult(x, state, it, err, False, why)

    while not err <= tol:
        if it >= max_iter:
            return stop("iteration limit reached")
        it += 1
        if J is None:
            J = jacobian(state)
        try:
            step = solve(J, -R)
        except np.linalg.LinAlgError:
            return stop("singular Jacobian")
        if not np.all(np.isfinite(step)):
            return stop("non-finite Newton step")
        current = err if by_error else np.linalg.norm(R)
        lam = 1.0
        for trial in range(halvings + 1):
            xn = x + lam * step
            last = trial == halvings
            if admissible is None or admissible(xn):
                Rn, Jn, errn, staten = residual(xn)
                if (errn if by_error else np.linalg.norm(Rn)) < current or (last and take_last):
                    break
                if last:
                    return stop("no decrease of the residual along the Newton step")
            elif last:
                return stop("no admissible step")
            lam *= 0.5
        x, R, J, err, state = xn, Rn, Jn, errn, staten
    return NewtonResult(x, state, it, err, True)
