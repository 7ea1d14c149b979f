"""The sequential sweep: a polynomial predictor through the last solutions, runs of well
predicted frequencies solved together.

The knobs (``BATCH_GUESS``, ``HISTORY``, ``BATCH_MAX``, ``SAME_BRANCH``) are read at each
call from :mod:`jointid.simulate.hbm`, where they are re-exported: set them there.
"""

from __future__ import annotations

import math
import sys

import numpy as np

from ...errors import ConvergenceError
from .kernels import _TINY, _extrapolate, _extrapolate_one


def _block(pts):
    """Points ``(omega, z, evaluation, iterations)`` as one block of arrays ``(omegas, Z,
    residual norms, peak values (NaN where not evaluated), iterations)``."""
    return (
        np.array([p[0] for p in pts], float),
        np.array([p[1] for p in pts], float),
        np.array([p[2]["err"] for p in pts], float),
        np.array([np.nan if p[2].get("peak") is None else p[2]["peak"][0] for p in pts], float),
        np.array([p[3] for p in pts], int),
    )


#: Predictor error (relative) up to which frequencies are solved together in a sweep: four
#: full Newton steps take such a start below the tolerance (5e-2 -> 2.5e-3 -> 6e-6 -> 4e-11 ->
#: ...); a point that does not converge, or lands off the branch, is solved alone.  On the
#: tests' sweeps the batched solutions differ from the point-by-point ones by at most 8e-11
#: of the largest coefficient, as with 1e-2 (the Newton tolerance's footprint).
BATCH_GUESS = 5e-2
#: Solutions the sweep's predictor extrapolates through (polynomial of degree HISTORY - 1).
HISTORY = 4
#: Longest batch of a sweep.
BATCH_MAX = 64
#: Relative distance from the one-step predictor within which a batched solution is the
#: one the point-by-point sweep reaches (another branch lies much farther away).
SAME_BRANCH = 0.02


def _sweep(problem, omegas, tol):
    """Sequential solutions at ``omegas``; predictor: polynomial extrapolation through the
    last ``HISTORY`` solutions (secant, quadratic, then cubic: on the seed's sweep the
    cubic's one-step error is 25 times the quadratic's smaller), falling back to the
    previous solution and to a fresh start.

    Where the response is smooth the predictor stays accurate many points ahead: the
    last one-step predictor error ``e`` grows about as ``binomial(k + HISTORY, HISTORY) e``
    over ``k`` steps, and while that stays below ``BATCH_GUESS`` the next points are solved together by
    :meth:`_Problem.newton_batch`.  A batched solution is kept while it converged with
    full steps and lies within ``SAME_BRANCH`` of the one-step predictor (the branch the
    point-by-point sweep follows); the first other point is solved alone as before,
    jumps included.  Returns the points as consecutive blocks of arrays (see
    :func:`_block`): a batch stays one block, without a Python object per point.
    """
    omegas = [float(w) for w in omegas]
    blocks = []  # consecutive points as arrays (see _block)
    hist_w, hist_z = [], []
    err1 = np.inf  # relative error of the last one-step prediction
    i, n = 0, len(omegas)
    knobs = sys.modules[__package__]  # the knobs as set on jointid.simulate.hbm
    BATCH_GUESS, BATCH_MAX, SAME_BRANCH, nh = knobs.BATCH_GUESS, knobs.BATCH_MAX, knobs.SAME_BRANCH, knobs.HISTORY
    while i < n:
        k = 0
        while len(hist_z) == nh and k < min(BATCH_MAX, n - i) and err1 * math.comb(k + nh, nh) <= BATCH_GUESS:
            k += 1
        if k >= 4:
            ws = np.array(omegas[i : i + k])
            Hz = np.array(hist_z)
            Z0 = _extrapolate(np.broadcast_to(hist_w, (k, nh)), Hz[None], ws)
            Z, err, its, ok, peaks = problem.newton_batch(Z0, ws, tol)
            # each point's one-step predictor from the points before it (history, then batch)
            allw, allz = np.concatenate([hist_w, ws]), np.concatenate([Hz, Z])
            win = np.arange(k)[:, None] + np.arange(nh)
            d = Z - _extrapolate(allw[win], allz[win], ws)
            dist = np.sqrt(np.einsum("ij,ij->i", d, d)) / np.maximum(np.sqrt(np.einsum("ij,ij->i", Z, Z)), _TINY)
            bad = ~ok | ~(dist <= SAME_BRANCH)
            taken = int(np.argmax(bad)) if bad.any() else k
            if taken:
                peak = np.full(taken, np.nan) if peaks is None else peaks[0][:taken]
                blocks.append((ws[:taken], Z[:taken], err[:taken], peak, its[:taken]))
                hist_w, hist_z = [float(w) for w in allw[taken : taken + nh]], list(allz[taken : taken + nh])
                err1 = float(dist[taken - 1])
            i += taken
            if taken == k:
                continue
        w = omegas[i]
        if not hist_z:
            z, ev, it = problem.fresh(w, tol)
            jumped = False
        else:
            guess = _extrapolate_one(hist_w, hist_z, w)
            jumped = False
            try:
                z, ev, it = problem.newton(guess, w, tol)
            except ConvergenceError:
                try:
                    z, ev, it = problem.newton(hist_z[-1], w, tol)
                except ConvergenceError:
                    z, ev, it = problem.fresh(w, tol)
                jumped = True
            d = z - guess
            err1 = np.inf if jumped else math.sqrt(d @ d) / max(math.sqrt(z @ z), _TINY)
        blocks.append(_block([(w, z, ev, it)]))
        if jumped:
            hist_w, hist_z = [], []  # a jump: restart the predictor
        hist_w = (hist_w + [w])[-nh:]
        hist_z = (hist_z + [z])[-nh:]
        i += 1
    return blocks
