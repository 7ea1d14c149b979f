"""Nonlinear modes by the extended periodic motion concept, condensed on the joint coordinates.

The extended periodic motion concept (EPMC, Krack 2015) makes a damped nonlinear mode a
periodic motion by adding a self-excitation ``-xi M x'`` that balances the dissipation.  In
the mass-normalised modal coordinates of :class:`jointid.simulate.structure_hb.CondensedHB`,
with no external force:

``eta'' + (2 zeta Omega - xi) eta' + Omega^2 eta + Psi^T f_nl(Psi eta) = 0``.

The unknowns are the harmonics of the motion, the frequency ``omega`` and ``xi``; the
mode's amplitude is the continuation parameter.  Normalisation: the first harmonic of the
chosen mode's modal coordinate is ``eta_r = a cos(omega t)`` (amplitude ``a``, its sine part
zero fixes the phase); the damping ratio of the nonlinear mode is ``xi / (2 omega)``.  For a
linear structure this gives the natural frequency ``Omega_r`` and the modal damping ratio
``zeta_r``.

Condensation.  Every modal harmonic except the mode's own first harmonic is a receptance
times the joint forces, ``eta_mk = -Hx_mk Psi_m^T F_k`` with
``Hx_mk = 1 / (Omega_m^2 - (k w)^2 + i k w (2 zeta_m Omega_m - xi))``.  The joint coefficients
``U`` then satisfy ``U - Psi_r a e_1 + G'(w, xi) F(U) = 0`` (``G'`` the condensed receptance
without the mode's first harmonic), closed by the mode's own first-harmonic balance
``(Omega_r^2 - w^2 + i w (2 zeta_r Omega_r - xi)) a + Psi_r^T F_1(U) = 0`` (two real
equations for ``w`` and ``xi``).  Newton runs on the ``n_joints (2H + 1) + 2`` unknowns with
the exact Jacobian of each law's AFT map.  This is the same solution as the rig's
uncondensed backbone (:meth:`jointid.rig.VirtualRig.backbone`) at a size that does not grow
with the number of modes.  An internal resonance (another mode's ``Omega_m`` at a multiple
``k omega``) makes a receptance singular; it is not treated.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._blas import single_threaded
from ..conventions import n_coefficients
from ..errors import ConvergenceError, StructureError
from ..numerics.aft import resize_harmonics, to_complex, to_real
from .newton import damped_newton
from .structure_hb import CondensedHB, JointMotion, JointMotionCurve, default_n_time

__all__ = ["NonlinearModePoint", "NonlinearModeBackbone", "epmc_point", "epmc_backbone"]


@dataclass(frozen=True, eq=False)
class NonlinearModePoint(JointMotion):
    """One point of a damped nonlinear mode (``frequency_hz`` and ``n_harmonics`` as
    :class:`~jointid.simulate.structure_hb.HBPoint`).

    Attributes
    ----------
    amplitude : float
        First-harmonic amplitude of the mode's modal coordinate (mass-normalised, m kg^0.5).
    omega : float
        Frequency [rad/s].
    xi : float
        Self-excitation coefficient [1/s] that makes the motion periodic.
    modal : ndarray (n_modes, 2H + 1)
        Harmonic coefficients of the modal coordinates.
    joint : ndarray (n_joints, 2H + 1)
        Harmonic coefficients of the joint relative motions.
    joint_force : ndarray (n_joints, 2H + 1)
        Harmonic coefficients of the nonlinear joint forces ``f - k_model u``.
    iterations : int
    residual_norm : float
    """

    amplitude: float
    omega: float
    xi: float
    modal: np.ndarray
    joint: np.ndarray
    joint_force: np.ndarray
    iterations: int
    residual_norm: float

    @property
    def damping_ratio(self) -> float:
        return self.xi / (2 * self.omega)


@dataclass(frozen=True, eq=False)
class NonlinearModeBackbone(JointMotionCurve):
    """Backbone of one mode: frequency and damping ratio against amplitude (``omega``,
    ``frequency_hz`` and ``len`` as :class:`~jointid.simulate.structure_hb.HBCurve`)."""

    mode: int
    points: tuple
    error: str = ""  # why the backbone stops early (``epmc_backbone(..., partial=True)``)

    @property
    def amplitude(self) -> np.ndarray:
        return np.array([p.amplitude for p in self.points])

    @property
    def damping_ratio(self) -> np.ndarray:
        return np.array([p.damping_ratio for p in self.points])

    @property
    def joint_amplitude(self) -> np.ndarray:
        """First-harmonic amplitude of each joint's relative motion, (n_points, n_joints)."""
        return np.array([np.abs(to_complex(p.joint)[:, 1]) for p in self.points])


class _Epmc:
    """The condensed EPMC residual of one mode of a :class:`CondensedHB` engine."""

    def __init__(self, engine: CondensedHB, mode: int, H: int, N: int):
        if not isinstance(engine, CondensedHB):
            raise StructureError(f"nonlinear modes: expected a CondensedHB engine, got {type(engine).__name__}")
        r = int(mode)
        if not 0 <= r < engine.n_modes:
            raise StructureError(f"nonlinear modes: mode {mode} out of range (the model has {engine.n_modes} modes, "
                                 "counted from 0)")
        if engine._rigid[r]:
            raise StructureError(f"nonlinear modes: mode {r} is a rigid-body mode (natural frequency 0)")
        if N <= 2 * H:
            raise StructureError(f"nonlinear modes: n_time = {N} must exceed 2 H = {2 * H}")
        self.e, self.r, self.H, self.N = engine, r, H, N
        self.n = n_coefficients(H)
        self.psi_r = engine.joint_shapes[:, r]
        self.Or = float(engine.omega[r])
        self.dr = 2.0 * float(engine.zeta[r]) * self.Or
        self.k = np.arange(H + 1)

    def receptances(self, w, xi):
        """``Hx (H+1, n_modes)`` without the mode's first harmonic and its derivatives in w and xi."""
        e, k = self.e, self.k
        Hx = e.receptance(k * w, xi=xi)
        Hx[1, self.r] = 0.0
        kk = k[:, None].astype(float)
        d = 2 * e.zeta * e.omega - xi
        dD_dw = -2.0 * kk**2 * w + 1j * kk * d
        dD_dxi = -1j * kk * w * np.ones_like(d)
        return Hx, -(Hx**2) * dD_dw, -(Hx**2) * dD_dxi

    def _cond(self, Hk):
        ps = self.e.joint_shapes
        return self.e._real_blocks(np.einsum("jm,km,lm->kjl", ps, Hk, ps), self.H, self.e.n_joints)

    def evaluate(self, U, w, xi, a, jacobian=True):
        e, n, nj = self.e, self.n, self.e.n_joints
        Hx, dHw, dHxi = self.receptances(w, xi)
        F, JF, JFw = e.aft(U.reshape(nj, n), w, self.H, self.N, jacobian=jacobian, domega=jacobian)
        Fv = F.reshape(-1)
        G = self._cond(Hx)
        b = np.zeros((nj, n))
        b[:, 1] = self.psi_r * a
        RU = U - b.reshape(-1) + G @ Fv
        F1 = to_complex(F)[:, 1]
        c = (self.Or**2 - w**2 + 1j * w * (self.dr - xi)) * a + self.psi_r @ F1
        out = {"RU": RU, "c": c, "F": F, "Hx": Hx}
        if not jacobian:
            return out
        m = nj * n
        J = np.zeros((m + 2, m + 2))
        J[:m, :m] = np.eye(m) + G @ JF
        J[:m, m] = self._cond(dHw) @ Fv + G @ JFw
        J[:m, m + 1] = self._cond(dHxi) @ Fv
        rows1 = np.arange(nj) * n + 1
        dc_dU = self.psi_r @ (JF[rows1] - 1j * JF[rows1 + 1])
        dc_dw = (-2.0 * w + 1j * (self.dr - xi)) * a + self.psi_r @ (JFw[rows1] - 1j * JFw[rows1 + 1])
        dc_dxi = -1j * w * a
        J[m, :m], J[m + 1, :m] = dc_dU.real, dc_dU.imag
        J[m, m], J[m + 1, m] = dc_dw.real, dc_dw.imag
        J[m, m + 1], J[m + 1, m + 1] = dc_dxi.real, dc_dxi.imag
        out["J"] = J
        return out

    def scales(self, a):
        """Row scale of the mode's own balance (joint units) and the residual's reference size."""
        pr = float(np.linalg.norm(self.psi_r))
        ref = max(pr, 1e-12 * float(np.abs(self.e.joint_shapes).max()), 1e-300)
        return ref / self.Or**2, ref * a

    def error(self, ev, U, a):
        s, ref = self.scales(a)
        R = np.concatenate([ev["RU"], s * np.array([ev["c"].real, ev["c"].imag])])
        return R, float(np.linalg.norm(R) / max(np.linalg.norm(U), ref))

    def point(self, U, w, xi, a, ev, it, err) -> NonlinearModePoint:
        e, nj, n = self.e, self.e.n_joints, self.n
        F = ev["F"]
        X = -ev["Hx"].T * (e.joint_shapes.T @ to_complex(F))
        X[self.r, 1] += a
        return NonlinearModePoint(float(a), float(w), float(xi), to_real(X), U.reshape(nj, n).copy(), F,
                                  int(it), float(err))


def _newton(prob: _Epmc, a, U, w, xi, tol, max_iter):
    """Newton with step halving on the scaled residual (:func:`jointid.simulate.newton.damped_newton`)
    on ``(U, omega, xi)``, ``omega`` kept positive; None when it does not converge."""
    m = U.size
    s, _ = prob.scales(a)

    def residual(x):
        ev = prob.evaluate(x[:m], x[m], x[m + 1], a)
        R, err = prob.error(ev, x[:m], a)
        J = ev["J"].copy()
        J[m:] *= s
        return R, J, err, ev

    out = damped_newton(np.concatenate([U, [w, xi]]), residual, tol, max_iter, admissible=lambda x: x[m] > 0)
    if not out.converged:
        return None
    x = out.x
    return x[:m], x[m], x[m + 1], out.state, out.iterations, out.error


@single_threaded
def epmc_point(engine: CondensedHB, mode: int, amplitude: float, n_harmonics: int = 9, *, n_time=None,
               guess=None, tol: float = 1e-10, max_iter: int = 40) -> NonlinearModePoint:
    """The damped nonlinear mode ``mode`` of ``engine`` at one modal amplitude.

    ``guess`` (a :class:`NonlinearModePoint`) starts Newton; by default the linear mode.

    Raises
    ------
    ConvergenceError
    """
    H = int(n_harmonics)
    N = default_n_time(H) if n_time is None else int(n_time)
    prob = _Epmc(engine, mode, H, N)
    a = float(amplitude)
    if not (math.isfinite(a) and a > 0):
        raise StructureError(f"nonlinear modes: the amplitude must be a positive number, got {amplitude!r}")
    U, w, xi = _start(prob, a, guess)
    out = _newton(prob, a, U, w, xi, tol, max_iter)
    if out is None:
        raise ConvergenceError(f"nonlinear mode {prob.r} at amplitude {a:.4g}: Newton did not converge "
                               f"to {tol:g} in {max_iter} iterations")
    return prob.point(out[0], out[1], out[2], a, out[3], out[4], out[5])


def _start(prob: _Epmc, a, guess):
    if guess is None:
        U = np.zeros((prob.e.n_joints, prob.n))
        U[:, 1] = prob.psi_r * a
        return U.reshape(-1), prob.Or, prob.dr
    U = resize_harmonics(np.asarray(guess.joint, float) * (a / guess.amplitude), prob.H)
    return U.reshape(-1), float(guess.omega), float(guess.xi)


@single_threaded
def epmc_backbone(engine: CondensedHB, mode: int, amplitudes, n_harmonics: int = 9, *, n_time=None,
                  tol: float = 1e-10, max_iter: int = 40, max_halvings: int = 8,
                  partial: bool = False) -> NonlinearModeBackbone:
    """Backbone of one mode: :func:`epmc_point` continued over the amplitudes in the given order.

    Each point starts from a secant predictor in log amplitude through the two previous
    solutions (the joint coefficients scaled with the amplitude); where Newton fails the step
    is halved (intermediate amplitudes are solved, not returned) up to ``max_halvings`` times.

    Parameters
    ----------
    engine : CondensedHB
    mode : int
        Index of the linear mode the nonlinear mode grows from (0: the lowest).
    amplitudes : array_like
        First-harmonic modal amplitudes, positive (increasing order recommended).
    n_harmonics, n_time : int
        Harmonics 0..H and AFT samples per period (default :func:`default_n_time`).
    partial : bool
        When a point cannot be reached, return the points before it with the reason in
        ``error`` instead of raising.

    Raises
    ------
    ConvergenceError
        When a point cannot be reached (and not ``partial``); the message names the amplitude.
    """
    H = int(n_harmonics)
    N = default_n_time(H) if n_time is None else int(n_time)
    prob = _Epmc(engine, mode, H, N)
    amps = np.atleast_1d(np.asarray(amplitudes, float))
    if amps.size == 0 or not np.all(np.isfinite(amps)) or np.any(amps <= 0):
        raise StructureError("nonlinear modes: amplitudes must be positive finite numbers")
    hist = []  # (a, U/a, w, xi)
    pts = []
    for target in amps:
        a_done = hist[-1][0] if hist else None
        todo = [float(target)]
        halvings = 0
        while todo:
            a = todo[-1]
            U, w, xi = _predict(prob, hist, a)
            out = _newton(prob, a, U, w, xi, tol, max_iter)
            if out is None:
                if a_done is None or halvings >= max_halvings:
                    msg = (f"nonlinear mode {prob.r}: no solution at amplitude {a:.4g} (Newton did not converge to "
                           f"{tol:g} after {halvings} step halvings)")
                    if partial:
                        return NonlinearModeBackbone(prob.r, tuple(pts), msg)
                    raise ConvergenceError(msg)
                halvings += 1
                todo.append(0.5 * (a_done + a))
                continue
            todo.pop()
            hist.append((a, out[0] / a, out[1], out[2]))
            hist = hist[-2:]
            a_done = a
            if not todo:
                pts.append(prob.point(out[0], out[1], out[2], a, out[3], out[4], out[5]))
    return NonlinearModeBackbone(prob.r, tuple(pts))


def _predict(prob: _Epmc, hist, a):
    if not hist:
        return _start(prob, a, None)
    a1, u1, w1, x1 = hist[-1]
    if len(hist) < 2 or hist[-2][0] == a1:
        return u1 * a, w1, x1
    a0, u0, w0, x0 = hist[-2]
    s = math.log(a / a1) / math.log(a1 / a0)  # secant in log amplitude
    return (u1 + s * (u1 - u0)) * a, w1 + s * (w1 - w0), x1 + s * (x1 - x0)
