"""Damped Newton iteration of the joint-condensed harmonic balance and its nonlinear modes.

One loop for :meth:`jointid.simulate.structure_hb.CondensedHB.solve` (forced response) and
:mod:`jointid.simulate.nlmodes` (nonlinear modes): a full Newton step, halved until the
residual's norm decreases or the step falls below ``min_step`` (then it is taken anyway:
slider laws have kinks where no step decreases the norm at first), until the problem's own
error measure is below ``tol``.

The single-mode solver keeps its own loop (:meth:`jointid.simulate.hbm.problem._Problem.newton`):
it builds the Jacobian only for accepted points, accepts a step on its scaled error rather than
the residual's norm, and fails after twelve halvings instead of taking the last step; its
sweeps, fresh starts and force homotopy rely on that failure to try the next start.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["NewtonResult", "damped_newton"]


@dataclass(frozen=True, eq=False)
class NewtonResult:
    """Last iterate ``x`` with its evaluation ``state``, ``iterations``, ``error`` and whether it
    ``converged`` (``error < tol``); ``reason`` says why not."""

    x: np.ndarray
    state: object
    iterations: int
    error: float
    converged: bool
    reason: str = ""


def damped_newton(x, residual, tol, max_iter, *, admissible=None, min_step=1e-3) -> NewtonResult:
    """Newton with step halving on ``|R|``.

    Parameters
    ----------
    x : ndarray
        Start.
    residual : callable
        ``residual(x) -> (R, J, error, state)``: the residual, its Jacobian ``dR/dx``, the
        convergence measure (compared with ``tol``) and anything the caller wants back.
    tol : float
    max_iter : int
    admissible : callable, optional
        ``admissible(x) -> bool``: trial points where it is false are not evaluated (the step
        is halved; below ``min_step`` the iteration fails).
    min_step : float
        Smallest step fraction; a step this short is taken even without decrease.
    """
    R, J, err, state = residual(x)
    it = 0
    while err >= tol and it < max_iter:
        it += 1
        try:
            step = np.linalg.solve(J, -R)
        except np.linalg.LinAlgError:
            return NewtonResult(x, state, it, err, False, "singular Jacobian")
        lam = 1.0
        while True:
            xn = x + lam * step
            if admissible is None or admissible(xn):
                Rn, Jn, errn, staten = residual(xn)
                if np.linalg.norm(Rn) < np.linalg.norm(R) or lam < min_step:
                    break
            elif lam < min_step:
                return NewtonResult(x, state, it, err, False, "no admissible step")
            lam *= 0.5
        x, R, J, err, state = xn, Rn, Jn, errn, staten
    ok = err < tol and math.isfinite(err)
    return NewtonResult(x, state, it, err, ok, "" if ok else "iteration limit reached")
