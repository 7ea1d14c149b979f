"""Jenkins elements (spring in series with a Coulomb slider) and their parallel (discrete Iwan) sets.

Element ``i`` has stiffness ``k_i`` and slip force ``F_i`` (slip displacement
``phi_i = F_i / k_i``).  Its slider position ``x_i`` is the state; the element carries
``k_i (u - x_i)`` with ``|u - x_i| <= phi_i``, and one step of the motion to ``u`` moves the
slider by the play operator ``x_i <- clip(x_i, u - phi_i, u + phi_i)``.  The laws are rate
independent and exact for any sampled motion (the sliders only move at the samples' extremes
of each monotone stretch, which the play operator sees exactly).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from ..errors import StructureError
from ._core import JointLaw, _number, _scalar_out

__all__ = ["Jenkins", "DiscreteIwan", "jenkins_harmonic_stiffness", "play_block", "BLOCK_ELEMENTS"]


def jenkins_harmonic_stiffness(s):
    """First-harmonic stiffness of a unit Jenkins element whose slip displacement is ``s`` times
    the amplitude (Caughey's bilinear hysteresis): ``(t - sin(2 t) / 2) / pi`` with
    ``cos t = 1 - 2 s`` for ``s < 1``, one for ``s >= 1`` (stuck)."""
    s = np.clip(np.asarray(s, float), 0.0, 1.0)
    t = np.arccos(1.0 - 2.0 * s)
    return (t - 0.5 * np.sin(2.0 * t)) / np.pi


#: Elements (samples x batch x sliders) evaluated at once by :func:`_slider_aft`: longer motions and
#: larger batches go in blocks of samples (bounded memory; past ~1e5 elements larger blocks got slower).
BLOCK_ELEMENTS = 1 << 16


def _knot_states(s, x, phi):
    """The states after each knot of ``s`` (B, T) from ``x`` (B, m), for :func:`play_block`.

    Returns ``S`` (q + 1, B, m) (``S[0] = x``, ``S[i + 1]`` after the ``i``-th knot; a batch with
    fewer knots repeats its last one, a no-op), the knots' samples ``pos`` (B, q) and the number
    of knots strictly before each sample ``before`` (B, T).
    """
    B, T = s.shape
    kn = np.zeros((B, T), dtype=bool)
    kn[:, 0] = True
    if T > 2:
        sg = np.sign(np.diff(s, axis=1))
        kn[:, 1:-1] = sg[:, :-1] != sg[:, 1:]
    nk = kn.sum(axis=1)
    q = int(nk.max()) if B else 0
    order = np.argsort(~kn, axis=1, kind="stable")[:, :q]  # knot samples first, in time order
    rows = np.arange(B)
    pos = np.where(np.arange(q)[None, :] < nk[:, None], order, order[rows, nk - 1][:, None])  # pad: last knot again
    sk = np.ascontiguousarray(s[rows[:, None], pos].T)[:, :, None]  # (q, B, 1): the knots' samples
    lo = np.subtract(sk, phi)  # the bounds of every knot's step at once (the same elementwise values)
    hi = np.add(sk, phi)
    S = np.empty((q + 1,) + x.shape)
    S[0] = x
    for i in range(q):  # a repeated knot is the same step again (a no-op)
        np.maximum(S[i], lo[i], out=S[i + 1])
        np.minimum(S[i + 1], hi[i], out=S[i + 1])
    before = np.cumsum(kn, axis=1) - kn  # knots strictly before each sample: the stretch's start state
    return S, pos, before


def play_block(s, x, phi, end_only=False):
    """Slider positions after each sample of ``s`` (batch ``B``, ``T`` samples), starting from ``x`` (B, m).

    Exactly the step ``x <- min(max(x, s_t - phi), s_t + phi)`` repeated over the samples, without
    a loop over them: on a stretch where ``s`` is monotone the steps compose to one step from the
    stretch's start (increasing: ``max(x_start, s_t - phi)``, the ``min`` a no-op; decreasing
    alike), and ``max``/``min`` only select, so the values are the loop's to the bit.  The loop
    runs over the knots only (the first sample and every sample where the sign of the
    difference changes; a flat step counts as its own sign, so equal samples only add knots,
    and a NaN makes every neighbouring sample a knot).  Returns ``(T, B, m)``, or with
    ``end_only`` the state after the last sample ``(B, m)``.
    """
    B, T = s.shape
    m = x.shape[-1]
    S, _, before = _knot_states(s, x, phi)
    rows = np.arange(B)
    if end_only:
        st = s[:, -1:]
        return np.minimum(np.maximum(S[before[:, -1], rows], st - phi), st + phi)
    X = np.take(S.reshape(-1, m), (before.T * B + rows[None, :]).ravel(), axis=0).reshape(T, B, m)
    st = np.ascontiguousarray(s.T)[:, :, None]
    bound = np.subtract(st, phi)
    np.maximum(X, bound, out=X)
    np.add(st, phi, out=bound)
    return np.minimum(X, bound, out=X)


def _first_sweep(s, x, phi):
    """End state of one sweep over ``s`` (B, T) from ``x`` (B, m) and each element's latest slip step.

    For finite ``s`` and ``x`` only.  An element moves monotonically over a stretch between
    knots (and over the open stretch after the last knot), so it moved there exactly when the
    stretch's end state differs from its start state; its latest slip lies in the last such
    stretch, at the latest sample whose state differs from the one before (usually the
    stretch's last sample: the walk back only continues past samples where the rounded bound
    did not change).  The states are :func:`play_block`'s (one step from the stretch's start),
    so the steps found are those of the sample loop.  Returns ``(x_end (B, m), last (B, m))``
    (``last`` -1: the element never moved).
    """
    B, T = s.shape
    m = x.shape[-1]
    S, pos, before = _knot_states(s, x, phi)
    q = S.shape[0] - 1
    rows = np.arange(B)
    st = s[:, -1:]
    x_end = np.minimum(np.maximum(S[before[:, -1], rows], st - phi), st + phi)
    ends = np.concatenate([S[1:], x_end[None]])  # (q + 1, B, m): stretch i from S[i] to ends[i]
    end_at = np.concatenate([pos.T, np.full((1, B), T - 1)])  # (q + 1, B): the stretch's last sample
    start_at = np.concatenate([np.full((1, B), -1), pos.T])  # sample of the start state (-1: before the sweep)
    moved = ends != S
    last = np.full((B, m), -1, dtype=np.intp)
    anym = moved.any(axis=0)
    if not anym.any():
        return x_end, last
    istar = q - np.argmax(moved[::-1], axis=0)  # the last stretch where each element moved
    b, i = np.nonzero(anym)
    j = istar[b, i]
    t = end_at[j, b]
    lim = start_at[j, b]
    x_start = S[j, b, i]
    cur = ends[j, b, i]
    p = phi[i]
    while b.size:
        tp = t - 1
        inner = tp > lim
        sp = s[b, np.where(inner, tp, 0)]
        prev = np.where(inner, np.minimum(np.maximum(x_start, sp - p), sp + p), x_start)
        done = prev != cur
        last[b[done], i[done]] = t[done]
        keep = ~done
        b, i, t, lim, x_start, cur, p = b[keep], i[keep], tp[keep], lim[keep], x_start[keep], cur[keep], p[keep]
    return x_end, last


def _slider_aft(u, k, phi, x0, jacobian, centre=False):
    """Periodic force of parallel Jenkins elements over one sampled period (two sweeps).

    The first sweep starts from ``x0`` (the state at sample 0 before the period) and ends in
    the periodic state of every element that slipped: once the motion has passed its
    largest and its smallest sample, an element that slipped holds a state independent of
    where it started (Masing).  The second sweep gives the force.  An element that never
    slips keeps ``x0`` (with ``centre=True``, ``x0`` is the centre of the range of ``u`` and
    depends on it).  The Jacobian follows the same sweep: the play operator returns
    either the old slider position or ``u_j -+ phi``, so ``d x_i(t_j) / d u`` is the unit
    vector of the sample where element ``i`` last slipped (zero if it never did).

    The sweeps are evaluated a monotone stretch of ``u`` at a time (:func:`play_block`), the
    values bit-identical to the sample-by-sample play operator; the force's ``x @ k`` is the
    same matrix product per sample as the sample loop's (one ``dot`` or ``gemv`` per sample
    over the same batch), stacked in one call.  Without the Jacobian the first sweep gives its
    end state only; with it (finite motion and start, one block) its end state and each
    element's latest slip (:func:`_first_sweep`), not every state.
    """
    u = np.asarray(u, float)
    n = u.shape[-1]
    batch = u.shape[:-1]
    m = k.size
    nb = int(np.prod(batch, dtype=int))
    x = np.array(np.broadcast_to(x0, batch + (m,)), dtype=float).reshape(nb, m)
    ktot = float(k.sum())
    ub = u.reshape(nb, n)
    ext = np.concatenate([ub, ub], axis=1)  # the two sweeps
    fT = np.empty((n, nb))
    last = np.full((nb, m), -1, dtype=np.intp)  # step of each element's latest slip so far
    lasts = np.empty((n, nb, m), dtype=np.intp) if jacobian else None
    stack = (batch if batch else (1,)) + (m,)  # per sample: the sample loop's operand shape
    tb = max(2, BLOCK_ELEMENTS // max(nb * m, 1))
    if jacobian and n <= tb and nb and np.isfinite(ub).all() and np.isfinite(x).all():
        x, last = _first_sweep(ub, x, phi)  # the first sweep's end state and latest slips, without its states
        starts = [n]
    elif jacobian:  # both sweeps in blocks of samples
        starts = list(range(0, 2 * n, tb))
    else:  # the first sweep apart: only its end state counts
        starts = list(range(0, n, tb)) + list(range(n, 2 * n, tb))
    for t0 in starts:
        t1 = min(n if t0 < n and not jacobian else 2 * n, t0 + tb)
        if t1 <= n and not jacobian:  # first sweep without the Jacobian: only its end state counts
            x = play_block(ext[:, t0:t1], x, phi, end_only=True)
            continue
        X = play_block(ext[:, t0:t1], x, phi)
        a = max(t0, n)  # the block's first sample of the second sweep
        if jacobian:
            C = np.empty(X.shape, dtype=bool)  # the element moved at this step
            np.not_equal(X[0], x, out=C[0])
            np.not_equal(X[1:], X[:-1], out=C[1:])
            e1 = min(a, t1)  # first sweep up to here: only each element's latest step of slip counts
            if e1 > t0:
                C1 = C[: e1 - t0]
                last = np.where(C1.any(axis=0), e1 - 1 - np.argmax(C1[::-1], axis=0), last)
        if a < t1:
            X2 = X[a - t0 :]
            fT[a - n : t1 - n] = ktot * ext[:, a:t1].T - np.matmul(X2.reshape((t1 - a,) + stack), k).reshape(t1 - a, nb)
            if jacobian:
                dest = lasts[a - n : t1 - n]  # step of the latest slip at each sample, then its sample
                dest[...] = -1  # written in place: fresh pages cost more than the arithmetic here
                np.copyto(dest, np.arange(a, t1)[:, None, None], where=C[a - t0 :])
                np.maximum(dest[0], last, out=dest[0])
                np.maximum.accumulate(dest, axis=0, out=dest)
                last = dest[-1].copy()
                np.subtract(dest, n, out=dest, where=dest >= n)
        x = X[-1].copy()
    f = fT.T.reshape(u.shape)
    if not jacobian:
        return f, None
    L = lasts
    seen = L >= 0
    if centre:  # the same elements at every sample (summed as a subset)
        k_never = np.array([k[row < 0].sum() for row in L[0]])
    np.add(L, np.arange(nb)[None, :, None] * (n * n) + np.arange(n)[:, None, None] * n, out=L)  # the bins, in place
    flat = L.ravel() if seen.all() else L[seen]
    # the weights summed per bin in the order of (sample, batch, element), as before: the same bits
    D = np.bincount(flat, weights=np.broadcast_to(k, L.shape)[seen], minlength=nb * n * n)
    D = np.asarray(D, dtype=float).reshape(nb, n, n)  # (integer when nothing slipped)
    np.negative(D, out=D)
    D[:, np.arange(n), np.arange(n)] += ktot
    if centre:
        ub = u.reshape(nb, n)
        imax, imin = np.argmax(ub, axis=-1), np.argmin(ub, axis=-1)
        D[np.arange(nb), :, imax] -= 0.5 * k_never[:, None]
        D[np.arange(nb), :, imin] -= 0.5 * k_never[:, None]
    return f, D.reshape(batch + (n, n))


def _stretches(u, du):
    """Monotone stretches of one sampled period ``u`` (n,) with steps ``du = diff(u)``, as
    ``(start, end, direction)`` (inclusive samples; direction +1, -1, 0 for flat, None for the
    lone sample 0, which steps from the state before the period): :func:`_knot_states`'s knots."""
    out = [(0, 0, None)]
    if u.size < 2:
        return out
    sg = np.sign(du)
    a = 1
    for e in ((sg[:-1] != sg[1:]).nonzero()[0] + 1).tolist() + [u.size - 1]:
        if e >= a:
            out.append((a, e, int(sg[a - 1])))
        a = e + 1
    return out


def _fast_ok(u, du, x, phi_max):
    """Whether :func:`_slider_aft_projected` may take its per-stretch path: finite motion and start,
    and every non-zero step ``du`` of ``u`` larger than the rounding of ``u -+ phi`` (then a
    slipping element moves at every sample of a monotone stretch, as in the sample loop, and the
    rounded thresholds below are off by at most one sample)."""
    adu = np.abs(du)
    hi = float(adu.max(initial=0.0))
    if not (math.isfinite(hi) and math.isfinite(float(u[0])) and math.isfinite(float(x.sum()))):
        return False  # (a non-finite sample makes a non-finite step)
    small = float(adu.min(where=adu > 0, initial=np.inf))
    return small > _EPS8 * (abs(float(u[0])) + hi * u.size + phi_max)


_EPS8 = 8.0 * float(np.finfo(float).eps)
_CP = (None, None)  # the last projection and its cumulative column sums


def _cum_projection(P):
    """``CPT[j] = sum_{t < j} P[:, t]`` (n + 1, c), rows contiguous; cached for the last ``P`` (one
    tuple read and one rebinding: threads of one process never get another projection's sums)."""
    global _CP
    last = _CP
    if last[0] is P:
        return last[1]
    CPT = np.zeros((P.shape[1] + 1, P.shape[0]))
    np.cumsum(P.T, axis=0, out=CPT[1:])
    _CP = (P, CPT)
    return CPT


def _onsets(us, S, phi, sgn):
    """First slipping sample (index into the monotone stretch ``us``, ``len(us)``: never) of each
    element from the states ``S`` at the stretch's start: the first ``t`` with
    ``u_t - phi > S`` (increasing; decreasing ``u_t + phi < S``) as the sample loop rounds it,
    found by ``searchsorted`` on ``S +- phi`` and corrected by one sample where rounding differs."""
    pad = np.empty(us.size + 2)  # the stretch between sentinels: "slipping" after its end, not before its start
    pad[1:-1] = us
    if sgn > 0:
        pad[0], pad[-1] = -np.inf, np.inf
        o = us.searchsorted(S + phi, side="right")
        at = pad.take(o + 1) - phi > S  # slipping at o
        before = pad.take(o) - phi > S  # slipping one sample earlier
    else:
        pad[0], pad[-1] = np.inf, -np.inf
        o = (-us).searchsorted(phi - S, side="right")
        at = pad.take(o + 1) + phi < S
        before = pad.take(o) + phi < S
    # the rounded threshold is at most one sample early (not slipping at o) or late (slipping at o - 1)
    return o + ~at - before


def _slider_aft_projected(u, k, phi, x0, P, E, centre=False, lazy=False, consts=None):
    """Force samples and the projected Jacobian ``P (df/du) E`` of :func:`_slider_aft` for one
    finite motion ``u`` (n,), without the ``n x m`` states or the dense ``n x n`` Jacobian;
    ``None`` where :func:`_fast_ok` fails (the caller then takes :func:`_slider_aft`).

    The sweeps go a monotone stretch at a time: on an increasing stretch from the states ``S``
    at its start, element ``i`` holds ``max(S_i, u_t - phi_i)`` (decreasing:
    ``min(S_i, u_t + phi_i)``), so it sticks up to its onset sample (:func:`_onsets`) and slips
    from there to the stretch's end.  The first sweep keeps only each stretch's end state and
    which elements moved (their latest slip is the stretch's last sample).  In the second sweep
    the force at ``t`` is ``sigma sum_slipping F_i + sum_stuck k_i (u_t - S_i)`` (sums over onset
    bins), a stuck element depends on the sample ``L_i`` of its latest slip before the stretch
    and a slipping one on ``u_t`` alone (its terms cancel on the diagonal): ``df/du = diag(d) -
    sum k_i e_t e_{L_i}^T`` over the stuck ones, ``d_t`` their stiffness, and ``P (df/du) E =
    (P d) E - sum_i k_i (sum_{t stuck} P[:, t]) E[L_i]`` with the column sums from a cumulative
    sum of ``P``.  Force and Jacobian agree with :func:`_slider_aft` to rounding.  With ``lazy``
    the Jacobian is returned as a function that projects it when called.  ``consts``: the law's
    ``(k phi, sum k, max phi)`` if known.
    """
    n = u.size
    kphi, ktot, phi_max = (k * phi, float(k.sum()), float(phi.max())) if consts is None else consts
    du = u[1:] - u[:-1]
    x = np.asarray(x0, dtype=float)  # (never written: every step makes a new array)
    if not _fast_ok(u, du, x, phi_max):
        return None
    m = k.size
    last = np.empty(m, dtype=np.intp)
    last.fill(-1)
    parts = _stretches(u, du)
    for a, e, sgn in parts:  # first sweep: end states and latest slips only
        ue = u[e]
        if sgn is None:
            xn = np.minimum(np.maximum(x, ue - phi), ue + phi)
        elif sgn > 0:
            xn = np.maximum(x, ue - phi)
        elif sgn < 0:
            xn = np.minimum(x, ue + phi)
        else:
            continue
        last[xn != x] = e
        x = xn
    never = last < 0
    f = np.empty(n)
    d = np.empty(n)
    CP = _cum_projection(P)
    starts, ons, rows, wts = [], [], [], []
    for a, e, sgn in parts:  # second sweep: force, stuck stiffness and the stuck elements' columns
        L = e + 1 - a
        us = u[a : e + 1]
        if sgn is None:  # one sample from the state after the period's last sample
            xn = np.minimum(np.maximum(x, us[0] - phi), us[0] + phi)
            mv = xn != x
            o = np.where(mv, 0, 1)
            d[a] = ktot - float(k[mv].sum())
            f[a] = ktot * us[0] - float(xn @ k)
        elif sgn == 0:  # flat: nothing moves
            o = np.empty(m, dtype=np.intp)
            o.fill(L)
            d[a : e + 1] = ktot
            f[a : e + 1] = ktot * us - float(x @ k)
            xn, mv = x, o < L
        else:
            o = _onsets(us, x, phi, sgn)
            # per onset bin: k, k S, k phi; suffix sums over o > t (the stuck), prefix over o <= t (slipping)
            bins = np.empty((3, L + 1))
            bins[0] = np.bincount(o, weights=k, minlength=L + 1)
            bins[1] = np.bincount(o, weights=k * x, minlength=L + 1)
            bins[2] = np.bincount(o, weights=kphi, minlength=L + 1)
            stuck = bins[:2, :0:-1].cumsum(axis=1)[:, ::-1]  # (2, L): k and k S of the elements stuck at t
            kst = stuck[0]
            d[a : e + 1] = kst
            f[a : e + 1] = sgn * bins[2, :-1].cumsum() + kst * us - stuck[1]
            mv = o < L
            xn = np.where(mv, us[-1] - sgn * phi, x)
        st = ((o > 0) & (last >= 0)).nonzero()[0]  # stuck at the stretch's first sample, with a latest slip
        ons.append(a + o[st])
        starts.append((a, st.size))
        rows.append(last[st])
        wts.append(k[st])
        last[mv] = e
        x = xn

    def project():
        J = (P * d) @ E
        on = np.concatenate(ons)
        if on.size:
            a0, cnt = zip(*starts)
            C = (CP[on] - CP[np.array(a0).repeat(cnt)]) * np.concatenate(wts)[:, None]  # (K, c)
            J -= C.T @ E[np.concatenate(rows)]
        if centre and never.any():
            kn = float(k[never].sum())
            J -= np.multiply.outer(0.5 * kn * CP[n], E[int(np.argmax(u))] + E[int(np.argmin(u))])
        return J

    return f, (project if lazy else project())

@dataclass(frozen=True, eq=False)
class DiscreteIwan(JointLaw):
    """``N`` Jenkins elements in parallel (a discrete Iwan model).

    Parameters
    ----------
    stiffness : array (N,)
        Element stiffnesses ``k_i`` [N/m] (> 0).
    slip_force : array (N,)
        Element slip forces ``F_i`` [N] (> 0).

    State: the slider positions ``x_i`` [m], shape ``(..., N)``.
    """

    stiffness: np.ndarray
    slip_force: np.ndarray
    UNITS: ClassVar[dict] = {"stiffness": "N/m", "slip_force": "N"}
    masing: ClassVar[bool] = True
    name: ClassVar[str] = "discrete Iwan"

    def __post_init__(self):
        k = np.array(self.stiffness, dtype=float).ravel()
        F = np.array(self.slip_force, dtype=float).ravel()
        if k.shape != F.shape or k.size == 0:
            raise StructureError(
                f"{self.name}: stiffness ({k.size} values) and slip_force ({F.size} values) must have the same, "
                "non-zero length"
            )
        if not (np.all(np.isfinite(k)) and np.all(k > 0) and np.all(np.isfinite(F)) and np.all(F > 0)):
            raise StructureError(f"{self.name}: element stiffnesses and slip forces must be positive and finite")
        for nm, a in (("stiffness", k), ("slip_force", F)):
            a.setflags(write=False)
            object.__setattr__(self, nm, a)

    # --- parameters ---------------------------------------------------------------
    @property
    def parameters(self) -> dict:
        return {"stiffness": self.stiffness.tolist(), "slip_force": self.slip_force.tolist()}

    @property
    def slip_displacement(self) -> np.ndarray:
        """``phi_i = F_i / k_i`` [m]."""
        return self.slip_force / self.stiffness

    @property
    def n_elements(self) -> int:
        return int(self.stiffness.size)

    @property
    def n_state(self) -> int:
        return self.n_elements

    @property
    def total_stiffness(self) -> float:
        """Stiffness with every element stuck [N/m]."""
        return float(self.stiffness.sum())

    @property
    def total_slip_force(self) -> float:
        """Force with every element slipping (macro-slip) [N]."""
        return float(self.slip_force.sum())

    def derived(self) -> dict:
        return {
            "n_elements": self.n_elements,
            "total_stiffness": self.total_stiffness,
            "total_slip_force": self.total_slip_force,
        }

    # --- protocol -----------------------------------------------------------------
    def force(self, u, v, state):
        """One step to relative motion ``u`` (any shape): ``(f, new_state)``; ``v`` is unused."""
        u = np.asarray(u, float)
        uu = u[..., None]
        phi = self.slip_displacement
        x = np.minimum(np.maximum(np.asarray(state, float), uu - phi), uu + phi)
        return self.total_stiffness * u - x @ self.stiffness, x

    @functools.cached_property
    def _projection_constants(self):
        """``(phi, k phi, sum k, max phi, zeros)`` for :meth:`aft_projected` (the law is immutable)."""
        phi = self.slip_displacement
        zeros = np.zeros(self.n_elements)
        zeros.setflags(write=False)
        return phi, self.stiffness * phi, float(self.stiffness.sum()), float(phi.max()), zeros

    def _start(self, u, state0):
        """Slider positions before the period (see :meth:`aft`'s ``state0``)."""
        if isinstance(state0, str):
            if state0 != "centre":
                raise StructureError(f"{self.name}: state0 must be an array or 'centre', got {state0!r}")
            return np.broadcast_to((0.5 * (u.max(axis=-1) + u.min(axis=-1)))[..., None], u.shape[:-1] + (self.n_elements,))
        return self.initial_state(u.shape[:-1]) if state0 is None else np.asarray(state0, float)

    def aft(self, u_t, v_t=None, *, velocity_jacobian=False, jacobian=True, state0=None):
        """Periodic force over one sampled period and its exact Jacobian.

        Parameters
        ----------
        u_t : array (..., n)
            Relative motion at ``n`` equispaced instants of one period.
        v_t : ignored (rate independent).
        velocity_jacobian : bool
            Also return ``df_dv`` (zeros).
        jacobian : bool
            ``False``: skip the Jacobians (returned as ``None``), for long periods.
        state0 : array (..., N) or "centre", optional
            Slider positions before the period (default: the virgin state, sliders at 0);
            only elements that never slip over the period keep it.  ``"centre"``: they sit
            at the centre of the motion's range (the state a vibration growing from rest
            about its mean reaches; a stuck element then carries no mean force), and the
            Jacobian includes that dependence on the largest and smallest samples.

        Returns
        -------
        f_t : array (..., n)
        df_du : array (..., n, n)
            Dense; ``df_du[..., j, m] = d f_j / d u_m``.  At most ``N + 1`` non-zeros per row
            (the diagonal and the sample where each element last slipped, which may lie
            later in the period: the slip history wraps round).
        """
        u = np.asarray(u_t, float)
        centre = isinstance(state0, str)
        x0 = self._start(u, state0)
        f, D = _slider_aft(u, self.stiffness, self.slip_displacement, x0, jacobian, centre)
        if velocity_jacobian:
            return f, D, None if D is None else np.zeros_like(D)
        return f, D

    def aft_projected(self, u_t, P, E, *, state0=None, lazy=False):
        """Periodic force of one motion and its Jacobian projected on a harmonic basis.

        The optional companion of :meth:`aft` that :class:`jointid.simulate.structure_hb.CondensedHB`
        uses when a law offers it: ``u_t`` (n,) one period (no batch), ``P`` (c, n) and ``E``
        (n, c) the projection and time basis; returns ``(f_t (n,), P @ df_du @ E (c, c))`` equal
        to :meth:`aft`'s to rounding, without forming the dense ``n x n`` Jacobian (it has the
        diagonal and a few knot columns: :func:`_slider_aft_projected`).  Non-finite motions,
        steps below the rounding of ``u -+ phi`` and batches take :meth:`aft` and the product.
        ``lazy``: the Jacobian comes as a function that returns it (for a caller that may not need it).
        """
        u = np.asarray(u_t, float)
        phi, kphi, ktot, phi_max, zeros = self._projection_constants
        x0 = zeros if state0 is None and u.ndim == 1 else self._start(u, state0)
        centre = isinstance(state0, str)
        out = (_slider_aft_projected(u, self.stiffness, phi, x0, P, E, centre, lazy, (kphi, ktot, phi_max))
               if u.ndim == 1 and u.size else None)
        if out is not None:
            return out
        f, D = _slider_aft(u, self.stiffness, phi, x0, True, centre)
        return f, ((lambda: P @ D @ E) if lazy else P @ D @ E)

    def backbone(self, a):
        """Initial-loading force at displacement ``a`` (odd): ``sum_i min(k_i |a|, F_i) sign(a)``."""
        a = np.asarray(a, float)
        f = np.minimum(self.stiffness * np.abs(a)[..., None], self.slip_force).sum(axis=-1)
        return _scalar_out(np.sign(a) * f)

    def dissipation(self, a, omega=None):
        """Energy per symmetric cycle ``u = +-a``: ``sum_i 4 F_i (|a| - phi_i)`` over slipping elements."""
        a = np.abs(np.asarray(a, float))[..., None]
        return _scalar_out((4.0 * self.slip_force * np.maximum(a - self.slip_displacement, 0.0)).sum(axis=-1))

    def first_harmonic(self, a, omega=None, n=None):
        """``(k_eq, k_loss)`` at amplitude ``a`` in closed form (sum of the elements' own)."""
        a = np.abs(np.asarray(a, float))
        with np.errstate(invalid="ignore", divide="ignore"):
            g = jenkins_harmonic_stiffness(self.slip_displacement / a[..., None])
            k = (self.stiffness * g).sum(axis=-1)
            kl = self.dissipation(a) / (np.pi * a**2)
        return _scalar_out(k), _scalar_out(kl)


@dataclass(frozen=True, eq=False)
class Jenkins(JointLaw):
    """One Jenkins element: spring ``kt`` in series with a Coulomb slider of slip force ``Fs``.

    Closed forms (amplitude ``a``, slip displacement ``a_s = Fs / kt``): backbone
    ``f = kt a`` for ``a <= a_s``, ``Fs`` beyond; dissipation per symmetric cycle
    ``D = 4 Fs (a - a_s)`` for ``a > a_s``, zero below.

    State: the slider position [m], shape ``(..., 1)``.
    """

    kt: float
    Fs: float
    UNITS: ClassVar[dict] = {"kt": "N/m", "Fs": "N"}
    masing: ClassVar[bool] = True
    name: ClassVar[str] = "Jenkins"
    _elements: DiscreteIwan = field(init=False, repr=False, compare=False, default=None)

    def __post_init__(self):
        object.__setattr__(self, "kt", _number(self.name, "kt", self.kt, positive=True))
        object.__setattr__(self, "Fs", _number(self.name, "Fs", self.Fs, positive=True))
        object.__setattr__(self, "_elements", DiscreteIwan([self.kt], [self.Fs]))

    @property
    def slip_displacement(self) -> float:
        return self.Fs / self.kt

    @property
    def n_state(self) -> int:
        return 1

    def derived(self) -> dict:
        return {"slip_displacement": self.slip_displacement}

    def force(self, u, v, state):
        return self._elements.force(u, v, state)

    def aft(self, u_t, v_t=None, *, velocity_jacobian=False, jacobian=True, state0=None):
        """As :meth:`DiscreteIwan.aft` with one element."""
        return self._elements.aft(u_t, v_t, velocity_jacobian=velocity_jacobian, jacobian=jacobian, state0=state0)

    def aft_projected(self, u_t, P, E, *, state0=None, lazy=False):
        """As :meth:`DiscreteIwan.aft_projected` with one element."""
        return self._elements.aft_projected(u_t, P, E, state0=state0, lazy=lazy)

    def backbone(self, a):
        a = np.asarray(a, float)
        return _scalar_out(np.sign(a) * np.minimum(self.kt * np.abs(a), self.Fs))

    def dissipation(self, a, omega=None):
        a = np.abs(np.asarray(a, float))
        return _scalar_out(4.0 * self.Fs * np.maximum(a - self.slip_displacement, 0.0))

    def first_harmonic(self, a, omega=None, n=None):
        """``(kt g(a_s / a), D / (pi a^2))``: Caughey's equivalent stiffness and loss stiffness."""
        return self._elements.first_harmonic(a)
