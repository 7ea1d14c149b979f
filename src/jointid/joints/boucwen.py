"""A smooth hysteretic law: Bouc-Wen with exponent one, integrated exactly between samples.

``f = k_inf u + z`` with the hysteretic force ``z`` [N] following

``dz/du = k_z - (beta sign(z du) + gamma) |z|``

(``k_z`` [N/m]: initial stiffness of the hysteretic part; ``beta``, ``gamma`` [1/m] with
``-beta < gamma <= beta``).  The law is rate independent: between two samples the motion is
taken as monotone and the equation, linear in ``z`` on each side of ``z = 0``, is solved
exactly, so the sampled law has no step-size error and its Jacobian is exact.  Writing
``w = s z`` and ``xi = |du|`` with ``s = sign(du)``: ``dw/dxi = k_z - b w`` (``w >= 0``,
``b = beta + gamma``) and ``dw/dxi = k_z + c w`` (``w < 0``, ``c = gamma - beta <= 0``).

Closed forms: backbone ``f(a) = k_inf a + z_s (1 - exp(-b a))`` with ``z_s = k_z / b`` the
slip (saturation) force; dissipation per symmetric cycle of amplitude ``a``,
``D = 2 [(z_a - k_z xi*) / c + (k_z (2a - xi*) - z_a) / b]`` (``c -> 0``:
``2 [-z_a xi* + k_z xi*^2 / 2 + (k_z (2a - xi*) - z_a) / b]``), where the loop tip force
``z_a`` solves ``z_a = z_s (1 - exp(-b (2a - xi*)))`` with
``xi* = -log(1 - c z_a / k_z) / c`` the travel over which ``z`` returns to zero after a
reversal: one scalar root, found to machine precision.  Unlike Jenkins and Iwan, Bouc-Wen
does not obey Masing's rule (its unloading runs at rate ``c`` until ``z`` changes sign).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import math

import numpy as np
from scipy import optimize

from ..errors import ConvergenceError, StructureError
from ._core import JointLaw, _number, _scalar_out

__all__ = ["BoucWen"]


def _expm1_over(x):
    """``(exp(x) - 1) / x``, one at ``x = 0``."""
    x = np.asarray(x, float)
    safe = np.where(x == 0.0, 1.0, x)
    return np.where(x == 0.0, 1.0, np.expm1(safe) / safe)


@dataclass(frozen=True, eq=False)
class BoucWen(JointLaw):
    """Bouc-Wen hysteresis (exponent 1) in parallel with a linear spring.

    Parameters
    ----------
    k_z : float
        Initial stiffness of the hysteretic part [N/m] (> 0).
    beta, gamma : float
        Shape parameters [1/m]: ``beta > 0``, ``-beta < gamma <= beta``; the hysteretic force
        saturates at ``z_s = k_z / (beta + gamma)``.
    k_inf : float
        Stiffness in parallel [N/m] (``>= 0``); the initial stiffness is ``k_inf + k_z``.

    State: ``(u_prev, z)``, shape ``(..., 2)``: the motion at the last step and the hysteretic
    force there (the virgin state is the joint at rest at ``u = 0``).
    """

    k_z: float
    beta: float
    gamma: float = 0.0
    k_inf: float = 0.0
    UNITS: ClassVar[dict] = {"k_z": "N/m", "beta": "1/m", "gamma": "1/m", "k_inf": "N/m"}
    name: ClassVar[str] = "Bouc-Wen"

    def __post_init__(self):
        nm = self.name
        object.__setattr__(self, "k_z", _number(nm, "k_z", self.k_z, positive=True))
        object.__setattr__(self, "beta", _number(nm, "beta", self.beta, positive=True))
        g = _number(nm, "gamma", self.gamma)
        if not -self.beta < g <= self.beta:
            raise StructureError(f"{nm} parameter gamma: expected -beta < gamma <= beta (beta = {self.beta}), got {g}")
        object.__setattr__(self, "gamma", g)
        object.__setattr__(self, "k_inf", _number(nm, "k_inf", self.k_inf, nonneg=True))

    @property
    def z_s(self) -> float:
        """Saturation (slip) force of the hysteretic part [N]."""
        return self.k_z / (self.beta + self.gamma)

    @property
    def n_state(self) -> int:
        return 2

    def derived(self) -> dict:
        return {"z_s": self.z_s, "initial_stiffness": self.k_z + self.k_inf}

    # --- one exact step -------------------------------------------------------------
    def _step(self, z, du):
        """``z`` after a monotone step ``du``: ``(z_new, dz_new/dz, dz_new/d du)``."""
        z = np.asarray(z, float)
        du = np.asarray(du, float)
        kz, b, c = self.k_z, self.beta + self.gamma, self.gamma - self.beta
        s = np.where(du >= 0, 1.0, -1.0)
        xi = np.abs(du)
        w0 = s * z
        neg = w0 < 0
        # w0 >= 0: relaxation towards z_s at rate b
        eb = np.exp(-b * xi)
        w_pos = self.z_s + (w0 - self.z_s) * eb
        # w0 < 0: rate c until w = 0 (travel xi*), then as above
        w0n = np.where(neg, w0, 0.0)
        xstar = np.where(c != 0.0, -np.log1p(c * w0n / kz) / (c if c != 0.0 else 1.0), -w0n / kz)
        before = xi <= xstar
        w_b = w0n * np.exp(c * xi) + kz * xi * _expm1_over(c * xi)
        rest = np.maximum(xi - xstar, 0.0)
        w_a = self.z_s * -np.expm1(-b * rest)
        w = np.where(neg, np.where(before, w_b, w_a), w_pos)
        dw0 = np.where(neg, np.where(before, np.exp(c * xi), kz * np.exp(-b * rest) / (kz + c * w0n)), eb)
        rhs = kz - np.where(w >= 0, b * w, -c * w)  # dw/dxi at the end of the step
        return s * w, dw0, rhs

    def _step_scalar(self, z, du):
        """:meth:`_step` for one motion, in plain floats (the same formulas, for speed)."""
        kz, b, c = self.k_z, self.beta + self.gamma, self.gamma - self.beta
        s = 1.0 if du >= 0 else -1.0
        xi = abs(du)
        w0 = s * z
        if w0 >= 0:
            eb = math.exp(-b * xi)
            w, dw0 = self.z_s + (w0 - self.z_s) * eb, eb
        else:
            xstar = -math.log1p(c * w0 / kz) / c if c != 0.0 else -w0 / kz
            if xi <= xstar:
                cx = c * xi
                w = w0 * math.exp(cx) + kz * xi * (math.expm1(cx) / cx if cx != 0.0 else 1.0)
                dw0 = math.exp(cx)
            else:
                e = math.exp(-b * (xi - xstar))
                w, dw0 = self.z_s * (1.0 - e), kz * e / (kz + c * w0)
        rhs = kz - (b * w if w >= 0 else -c * w)
        return s * w, dw0, rhs

    # --- protocol -----------------------------------------------------------------
    def force(self, u, v, state):
        """One step to ``u``: ``(f, new_state)`` with ``state = (u_prev, z)``; ``v`` unused."""
        u = np.asarray(u, float)
        state = np.asarray(state, float)
        z, _, _ = self._step(state[..., 1], u - state[..., 0])
        return self.k_inf * u + z, np.stack(np.broadcast_arrays(u, z), axis=-1)

    def _period(self, u, z0):
        """One sweep of the closed period from ``z0`` at sample 0: states and derivatives."""
        n = u.shape[-1]
        zs = np.empty(u.shape)
        gz = np.empty(u.shape)  # gz[..., j] = d z_j / d z_{j-1} (j = 0: closing step n-1 -> 0)
        gd = np.empty(u.shape)  # gd[..., j] = d z_j / d (u_j - u_{j-1})
        if u.ndim == 1:  # one motion: plain floats
            ul, z = u.tolist(), float(z0)
            for j in range(1, n + 1):
                z, gz[j % n], gd[j % n] = self._step_scalar(z, ul[j % n] - ul[j - 1])
                if j < n:
                    zs[j] = z
            return np.float64(z), zs, gz, gd
        z = z0
        for j in range(1, n + 1):
            z, gz[..., j % n], gd[..., j % n] = self._step(z, u[..., j % n] - u[..., j - 1])
            if j < n:
                zs[..., j] = z
        return z, zs, gz, gd

    def aft(self, u_t, v_t=None, *, velocity_jacobian=False, jacobian=True):
        """Periodic force over one sampled period and its exact Jacobian.

        The hysteretic force at sample 0 is the fixed point of the period map (Newton on one
        scalar per motion, the map being a contraction); ``d z / d u`` follows by the chain
        rule along the period and the implicit function theorem at the fixed point.  A
        constant motion has no unique periodic state: it keeps the state reached by loading
        from rest to it.

        Returns ``(f_t, df_du)`` (and ``df_dv``, zeros, with ``velocity_jacobian=True``);
        ``df_du`` is dense ``(..., n, n)`` (``None`` with ``jacobian=False``).
        """
        u = np.asarray(u_t, float)
        n = u.shape[-1]
        z0 = self._step(np.zeros(u.shape[:-1]), u[..., 0])[0]  # from rest at u = 0 to the first sample
        for _ in range(100):
            zn, _, gz, _ = self._period(u, z0)
            P = np.prod(gz, axis=-1)
            r = zn - z0
            z0 = z0 + np.divide(r, 1.0 - P, out=np.zeros_like(r), where=P < 1.0)  # P = 1: u constant, any z0
            if np.all(np.abs(r) <= 1e-14 * self.z_s):
                break
        else:
            raise ConvergenceError(f"{self.name}: the periodic hysteretic force did not converge in 100 Newton steps")
        _, zs, gz, gd = self._period(u, z0)
        zs[..., 0] = z0
        if not jacobian:
            f = self.k_inf * u + zs
            return (f, None, None) if velocity_jacobian else (f, None)
        # J[..., j, :] = d z_j / d u; start from J_0 = 0, close the period, restart from the true J_0
        eye = np.eye(n)

        def sweep(J0):
            J = np.empty(u.shape[:-1] + (n, n))
            J[..., 0, :] = J0
            Jp = J0
            for j in range(1, n + 1):
                Jp = gz[..., j % n, None] * Jp + gd[..., j % n, None] * (eye[j % n] - eye[j - 1])
                if j < n:
                    J[..., j, :] = Jp
            return J, Jp

        _, Jn = sweep(np.zeros(u.shape[:-1] + (n,)))
        P = np.prod(gz, axis=-1)
        J, _ = sweep(np.divide(Jn, (1.0 - P)[..., None], out=np.zeros_like(Jn), where=(P < 1.0)[..., None]))
        f = self.k_inf * u + zs
        D = J + self.k_inf * eye
        return (f, D, np.zeros_like(D)) if velocity_jacobian else (f, D)

    # --- closed forms ---------------------------------------------------------------
    def backbone(self, a):
        """Initial loading from rest: ``k_inf a + z_s (1 - exp(-b |a|)) sign(a)``."""
        a = np.asarray(a, float)
        b = self.beta + self.gamma
        return _scalar_out(self.k_inf * a + np.sign(a) * self.z_s * -np.expm1(-b * np.abs(a)))

    def _loop_tip(self, a):
        """``(z_a, xi*)`` of the steady symmetric loop of amplitude ``a > 0``."""
        kz, b, c = self.k_z, self.beta + self.gamma, self.gamma - self.beta

        def xstar(za):
            return za / kz if c == 0.0 else -np.log1p(-c * za / kz) / c

        def g(za):
            return self.z_s * -np.expm1(-b * (2.0 * a - xstar(za))) - za

        hi = self.z_s * -np.expm1(-b * 2.0 * a)
        za = optimize.brentq(g, 0.0, hi, xtol=1e-300, rtol=4 * np.finfo(float).eps, maxiter=500) if hi > 0 else 0.0
        return za, xstar(za)

    def dissipation(self, a, omega=None):
        """Energy per symmetric cycle of amplitude ``a`` (closed form up to one scalar root)."""
        a_arr = np.abs(np.asarray(a, float))
        kz, b, c = self.k_z, self.beta + self.gamma, self.gamma - self.beta
        out = np.empty(a_arr.shape)
        for idx, ai in np.ndenumerate(a_arr):
            if ai == 0.0:
                out[idx] = 0.0
                continue
            za, xs = self._loop_tip(float(ai))
            first = (za - kz * xs) / c if c != 0.0 else -za * xs + 0.5 * kz * xs**2
            out[idx] = 2.0 * (first + (kz * (2.0 * ai - xs) - za) / b)
        return _scalar_out(out)
