"""Multi-mode harmonic balance condensed onto the joint coordinates.

A linear structure in ``n_modes`` mass-normalised modal coordinates ``eta`` with modal
damping carries ``n_joints`` nonlinear joint elements, each acting on one relative motion
``u_j = Psi_j . eta`` (the difference of two degrees of freedom, a translation or a
rotation):

``eta'' + 2 zeta Omega eta' + Omega^2 eta + Psi^T f_nl(u, u') = p F(t)``

with ``f_nl,j = f_j(u_j; history) - k_j u_j``: the joint law's force less the stiffness
``k_j`` of the joint already in the linear model (zero when the linear model leaves the
joint out).  ``p`` is the load distribution in modal coordinates.

Harmonic balance with the force evaluated in time over one period (alternating
frequency/time, :mod:`jointid.numerics.aft`).  The nonlinearity acts only through ``u``, so
the modal unknowns are condensed exactly onto the joint coordinates: per harmonic ``k``
(complex amplitudes, ``X_k = a_k - i b_k``)

``u_k = Psi H_k p F_k - Psi H_k Psi^T f_k``,
``H_k = diag(1 / (Omega^2 - (k w)^2 + 2 i zeta Omega k w))``,

and Newton runs on the ``n_joints (2H + 1)`` real joint coefficients with the exact
Jacobian of each law's AFT map (``law.aft``).  Modes with ``Omega = 0`` (rigid-body modes of
a free structure) take no part in the joint motion (checked) and carry no constant part.
The condensed size does not grow with the number of modes: a model of hundreds of modes
with one joint solves a ``(2H + 1)`` system per Newton step.

A frequency response is followed by pseudo-arclength continuation in ``(u, omega)``
through folds (the predictor, corrector and fold location of :mod:`jointid.simulate.hbm`).

Joint laws follow the protocol of :mod:`jointid.joints`: ``aft(u_t, v_t=None, *,
velocity_jacobian=False, jacobian=True)``; rate-dependent laws (``law.rate_dependent``)
get the velocity samples and return ``df_dv`` too.

Harmonic coefficient vectors follow :mod:`jointid.conventions`:
``x(t) = a0 + sum_k a_k cos(k w t) + b_k sin(k w t)`` stored ``[a0, a1, b1, ...]``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._blas import single_threaded
from ..conventions import n_coefficients
from ..errors import ConvergenceError, StructureError
from ..numerics.aft import aft_basis, aft_samples, resize_harmonics, to_complex, to_real
from ..numerics.receptance import modal_denominator
from .hbm.continuation import _Arclength, _follow
from .hbm.kernels import hill_companion
from .newton import damped_newton

__all__ = [
    "CondensedHB", "HBPoint", "HBCurve", "JointMotion", "JointMotionCurve", "warm_sweep", "to_complex", "to_real",
    "default_n_time",
]


def default_n_time(n_harmonics: int) -> int:
    """The power of two at or above ``4 (H + 1)``: time samples per period of the AFT.

    Half the single-mode solver's oversampling (:func:`jointid.simulate.hbm.default_n_time`,
    ``8 (H + 1)``, alias-free for its polynomial terms up to degree 7): the joint laws here are
    non-smooth sliders, whose aliasing does not vanish at any finite rate.
    """
    return aft_samples(n_harmonics, 4)


class JointMotion:
    """What every periodic solution of the condensed engine shares (:class:`HBPoint`, the
    nonlinear modes' :class:`~jointid.simulate.nlmodes.NonlinearModePoint`): the fields ``omega``
    [rad/s], ``modal``, ``joint`` and ``joint_force`` (harmonic coefficients), ``iterations`` and
    ``residual_norm`` of the subclass, and these properties."""

    __slots__ = ()

    @property
    def frequency_hz(self) -> float:
        return self.omega / (2 * np.pi)

    @property
    def n_harmonics(self) -> int:
        return (self.joint.shape[-1] - 1) // 2


class JointMotionCurve:
    """What a sequence of :class:`JointMotion` points shares (:class:`HBCurve`,
    :class:`~jointid.simulate.nlmodes.NonlinearModeBackbone`): the field ``points`` and these."""

    __slots__ = ()

    @property
    def omega(self) -> np.ndarray:
        return np.array([p.omega for p in self.points])

    @property
    def frequency_hz(self) -> np.ndarray:
        return self.omega / (2 * np.pi)

    def __len__(self):
        return len(self.points)


@dataclass(frozen=True, eq=False)
class HBPoint(JointMotion):
    """A periodic steady state found by :class:`CondensedHB`.

    Attributes
    ----------
    omega : float
        Excitation frequency [rad/s].
    force : ndarray (2H + 1,)
        Harmonic coefficients of the excitation ``F(t)``.
    modal : ndarray (n_modes, 2H + 1)
        Harmonic coefficients of the modal coordinates.
    joint : ndarray (n_joints, 2H + 1)
        Harmonic coefficients of the joint relative motions ``u``.
    joint_force : ndarray (n_joints, 2H + 1)
        Harmonic coefficients of the nonlinear joint forces ``f - k u``.
    iterations : int
        Newton iterations.
    residual_norm : float
        ``|residual| / |u|`` at the solution.
    """

    omega: float
    force: np.ndarray
    modal: np.ndarray
    joint: np.ndarray
    joint_force: np.ndarray
    iterations: int
    residual_norm: float


@dataclass(frozen=True, eq=False)
class HBCurve(JointMotionCurve):
    """Points of a continued frequency response, in the order of the curve.

    ``folds`` are the indices of the located turning points (where ``d omega / ds = 0``).
    """

    points: tuple
    folds: tuple


def warm_sweep(solve, frequencies, frequency=lambda p: p.omega, start=None) -> list:
    """``solve(f, guess)`` at each frequency ``f`` in turn: the first point starts from ``start``
    (``None``: the solver's own start), the second from the first, every later one from the secant
    through the joint coefficients of the two before it (in the harmonics both carry).

    ``frequency(point)`` gives a point's frequency in the units of ``frequencies`` (rad/s by
    default).  The sequential sweep of the condensed engine, the rig's reduced model and the
    virtual rig (in Hz); the single-mode solver's sweep (:mod:`jointid.simulate.hbm.sweep`)
    extrapolates through four points and solves well-predicted runs together.
    """
    out = []
    for f in np.asarray(frequencies, float):
        guess = None if out else start
        if len(out) >= 2:
            p0, p1 = out[-2], out[-1]
            f0, f1 = frequency(p0), frequency(p1)
            n = min(p0.joint.shape[-1], p1.joint.shape[-1])
            s = (f - f1) / (f1 - f0) if f1 != f0 else 0.0
            guess = p1.joint[:, :n] + s * (p1.joint[:, :n] - p0.joint[:, :n])
        elif out:
            guess = out[-1]
        out.append(solve(f, guess))
    return out


class _Evaluation(dict):
    """One evaluation of :meth:`CondensedHB.evaluate` (``R``, ``F``, ... and, when asked, ``J``, ``Jw``)."""

    _complete = None

    def complete(self):
        """Add the derivatives that ``evaluate(..., lazy=True)`` deferred; returns the dict."""
        if self._complete is not None:
            fn, self._complete = self._complete, None
            fn()
        return self


_REAL_BLOCK_INDEX = {}  # (H, n_j) -> flat positions of CondensedHB._real_blocks' entries


class CondensedHB:
    """Harmonic balance of a modal model with joint elements, condensed on the joint coordinates.

    Parameters
    ----------
    omega : array (n_modes,)
        Natural frequencies [rad/s] of the linear model (zero for rigid-body modes).
    zeta : array (n_modes,) or float
        Modal damping ratios.
    joint_shapes : array (n_joints, n_modes)
        Relative motion of each joint element per unit modal coordinate.
    force_shape : array (n_modes,)
        Load distribution in modal coordinates (``Phi^T f`` of the force vector per newton).
    laws : sequence
        One joint law per element (the :mod:`jointid.joints` protocol).
    k_model : array (n_joints,) or float, optional
        Stiffness of each joint already in the linear model (subtracted from the law).
    """

    def __init__(self, omega, zeta, joint_shapes, force_shape, laws, k_model=0.0):
        om = np.array(omega, float).ravel()
        n = om.size
        if n == 0:
            raise StructureError("harmonic balance: the model has no modes")
        try:
            ze = np.broadcast_to(np.asarray(zeta, float), (n,)).copy()
        except ValueError:
            raise StructureError(f"zeta: expected one damping ratio or {n}, got {np.size(zeta)}") from None
        ps = np.array(joint_shapes, float)
        if ps.ndim == 1:
            ps = ps[None, :]
        if ps.ndim != 2 or ps.shape[1] != n:
            raise StructureError(f"joint_shapes: expected shape (n_joints, {n}), got {np.shape(joint_shapes)}")
        pf = np.array(force_shape, float).ravel()
        if pf.size != n:
            raise StructureError(f"force_shape: expected {n} values, got {pf.size}")
        laws = tuple(laws)
        if len(laws) != ps.shape[0]:
            raise StructureError(f"{ps.shape[0]} joint elements need as many laws, got {len(laws)}")
        for law in laws:
            if not callable(getattr(law, "aft", None)):
                raise StructureError(f"joint law {law!r} has no aft method (the jointid.joints protocol)")
        km = np.broadcast_to(np.asarray(k_model, float), (ps.shape[0],)).copy()
        bad = ~np.isfinite(om) | (om < 0) | ~np.isfinite(ze) | (ze < 0)
        if np.any(bad) or not np.all(np.isfinite(ps)) or not np.all(np.isfinite(pf)) or not np.all(np.isfinite(km)):
            raise StructureError("natural frequencies and damping ratios must be finite and non-negative, shapes finite")
        rigid = om <= 1e-9 * max(float(om.max()), 1e-300)
        if np.any(rigid):
            scale = max(float(np.abs(ps[:, ~rigid]).max()) if np.any(~rigid) else 0.0, 1e-300)
            if np.any(np.abs(ps[:, rigid]) > 1e-8 * scale):
                raise StructureError(
                    "a joint element moves in a rigid-body mode of the linear model (the joint is a mechanism): "
                    "include the joint's stiffness in the linear model and give it as k_model"
                )
        self.omega, self.zeta, self.joint_shapes, self.force_shape, self.k_model = om, ze, ps, pf, km
        self.laws = laws
        self._rigid = rigid
        self._cache = None  # (omega, H, G, Hm) of the last evaluation
        self._pe = {}  # (H, n_time) -> P @ E (the identity to rounding), for k_model with projected laws
        self._fcache = None  # (force as given, a copy, H, Fc, Xf) of the last evaluation
        self._rate = any(bool(getattr(law, "rate_dependent", False)) for law in laws)
        self._omega_sq, self._i2zo = om**2, 1j * (2 * ze * om - 0.0)  # modal_denominator's Omega^2, i (2 zeta Omega - xi)
        # psi_jm psi_lm (m, n_j^2) and psi_jm phi_m (m, n_j), complex: the receptances' contractions as one product
        self._shape_products = (ps[:, None, :] * ps[None, :, :]).reshape(-1, ps.shape[1]).T.astype(complex)
        self._force_products = (ps * pf).T.astype(complex)

    @property
    def n_modes(self) -> int:
        return self.omega.size

    @property
    def n_joints(self) -> int:
        return self.joint_shapes.shape[0]

    # --- linear pieces ---------------------------------------------------------------
    def receptance(self, w, xi=0.0):
        """Modal receptances ``1 / (Omega^2 - w^2 + 2 i zeta Omega w)``, shape ``w.shape + (n_modes,)``.

        A rigid-body mode at ``w = 0`` gives 0 (no constant rigid-body motion).  ``xi``: a
        self-excitation ``-xi eta'`` (the nonlinear modes of :mod:`jointid.simulate.nlmodes`),
        ``2 zeta Omega`` becomes ``2 zeta Omega - xi``.
        """
        w = np.asarray(w, float)[..., None]
        if xi == 0.0:  # modal_denominator's operations with its constant factors kept: the same values to the bit
            den = self._omega_sq - w**2 + self._i2zo * w
        else:
            den = modal_denominator(self.omega, self.zeta, w, xi)
        zero = den == 0
        if not zero.any():
            return 1.0 / den
        out = 1.0 / np.where(zero, 1.0, den)
        out[zero] = 0.0
        return out

    def _d_receptance(self, w, H=None):
        """``d H / d w`` of :meth:`receptance` at harmonic frequencies ``w`` (``H``: its receptances, if known)."""
        H = self.receptance(w) if H is None else H
        w = np.asarray(w, float)[..., None]
        return -(H**2) * (-2.0 * w + 2j * self.zeta * self.omega)

    @staticmethod
    def _real_blocks(Gk, H, nj):
        """Real form (n_j n, n_j n) of the complex harmonic blocks ``Gk`` (H+1, n_j, n_j): per harmonic
        ``[[Re, Im], [-Im, Re]]`` on its cos/sin rows, the constant's real part; one scatter of
        ``[Re G_0, Re G_k, Im G_k, -Im G_k, Re G_k]`` at positions cached per ``(H, n_j)``."""
        tgt = _REAL_BLOCK_INDEX.get((H, nj))
        if tgt is None:
            n = n_coefficients(H)
            j, l = np.arange(nj)[:, None], np.arange(nj)[None, :]
            a = np.arange(1, 2 * H, 2)[:, None, None]  # cos rows of harmonics 1..H; sin rows a + 1
            at = lambda r, c: ((j * n + r) * nj + l) * n + c  # noqa: E731 (flat index of G[j, r, l, c])
            z = np.zeros((1, 1, 1), dtype=np.intp)
            tgt = np.concatenate([np.broadcast_to(at(r, c), (r.shape[0], nj, nj)).ravel()
                                  for r, c in ((z, z), (a, a), (a, a + 1), (a + 1, a), (a + 1, a + 1))])
            _REAL_BLOCK_INDEX[H, nj] = tgt
        Gr, Gi = Gk.real, Gk[1:].imag
        n = nj * n_coefficients(H)
        G = np.zeros(n * n)
        G[tgt] = np.concatenate((Gr, Gi, -Gi, Gr[1:]), axis=None)
        return G.reshape(n, n)

    def condensed(self, omega, H):
        """Real condensed receptance ``G`` (n_j n, n_j n) and the complex modal receptances (H+1, n_modes)."""
        k = np.arange(H + 1)
        Hm = self.receptance(k * omega)
        nj = self.n_joints
        Gk = (Hm @ self._shape_products).reshape(H + 1, nj, nj)  # sum_m psi_jm H_km psi_lm
        return self._real_blocks(Gk, H, nj), Hm

    def _linear_part(self, omega, H, Xf, Hm):
        return to_real((Hm @ self._force_products).T * Xf).reshape(-1)  # sum_m psi_jm H_km phi_m X_k

    # --- nonlinear pieces -------------------------------------------------------------
    def aft(self, U, omega, H, n_time, jacobian=True, domega=False, lazy=False):
        """Nonlinear joint force coefficients ``F (n_j, n)`` of joint motions ``U (n_j, n)``.

        With ``jacobian``: also the block-diagonal ``dF/dU`` (n_j n, n_j n); with ``domega``
        also ``dF/domega`` (n_j n,) (non-zero only for rate-dependent laws).  With ``lazy``:
        ``(F, finish)``, ``finish()`` returning the two derivatives (the projections that laws
        offering ``aft_projected`` defer are done only then).
        """
        E, Dm, P = aft_basis(H, int(n_time), "F")
        nj, n = U.shape
        F = np.empty_like(U)
        J = np.zeros((nj, n, nj, n)) if jacobian else None
        Jw = np.zeros((nj, n)) if domega else None
        deferred = []
        for j, uj, vj, f, D, Dv, Jp in self._laws_on(U, omega, H, n_time, jacobian, projection=P, lazy=lazy):
            if Jp is not None:  # the law projects its own Jacobian (now or when called)
                deferred.append((j, Jp))
            elif jacobian:
                Jj = P @ D @ E
                if Dv is not None:
                    Jj = Jj + omega * (P @ Dv @ E @ Dm)
                J[j, :, j, :] = Jj
                if domega and Dv is not None:
                    Jw[j] = P @ (Dv @ (vj / omega))
            F[j] = (f - self.k_model[j] * uj) @ P.T

        def finish():
            for j, Jp in deferred:
                Jj = Jp() if callable(Jp) else Jp
                if self.k_model[j]:
                    PE = self._pe.get((H, int(n_time)))
                    if PE is None:
                        PE = self._pe[H, int(n_time)] = P @ E
                    Jj = Jj - self.k_model[j] * PE
                J[j, :, j, :] = Jj
            return (None if J is None else J.reshape(nj * n, nj * n)), (None if Jw is None else Jw.reshape(-1))

        return (F, finish) if lazy else (F, *finish())

    def _laws_on(self, U, omega, H, n_time, jacobian, projection=None, lazy=False):
        """Each joint law on the samples of one period of ``U``: ``(j, u_j, v_j, f, D, Dv, Jp)`` with
        the force samples ``f``, ``D = df/du - k_model`` and ``Dv = df/dv`` (rate-dependent laws;
        else None), the derivatives only with ``jacobian``.  Shared by :meth:`aft` and
        :meth:`hill_eigenvalues`.

        With a ``projection`` ``P`` and a rate-independent law that offers the optional
        ``aft_projected(u_t, P, E)`` (the slider laws: their time Jacobian is a diagonal and a
        few columns), ``D`` is None and ``Jp = P (df/du) E`` comes from the law, without the
        dense ``n_time x n_time`` Jacobian (and without ``k_model``; with ``lazy`` a function
        returning it); otherwise ``Jp`` is None.
        """
        E, Dm, _ = aft_basis(H, int(n_time), "F")
        u = U @ E.T  # (n_j, N)
        v = None
        if self._rate:
            Ud = U @ Dm.T  # d/dtau coefficients
            v = omega * (Ud @ E.T)
        for j, law in enumerate(self.laws):
            Dv = D = Jp = None
            if projection is not None and not getattr(law, "rate_dependent", False) and hasattr(law, "aft_projected"):
                # the same force with or without the Jacobian (its projection deferred, unused without)
                f, Jp = law.aft_projected(u[j], projection, E, lazy=lazy or not jacobian)
                yield j, u[j], None, f, None, None, (Jp if jacobian else None)
                continue
            if getattr(law, "rate_dependent", False):
                f, Du, Dv = law.aft(u[j], v[j], velocity_jacobian=True, jacobian=jacobian)
                Dv = None if Dv is None or not jacobian else np.asarray(Dv)
            else:
                f, Du = law.aft(u[j], jacobian=jacobian)
            if jacobian:
                D = np.array(Du, float)
                D[np.diag_indices_from(D)] -= self.k_model[j]
            yield j, u[j], (None if v is None else v[j]), f, D, Dv, Jp

    def _force_vector(self, force, H):
        return resize_harmonics(np.ravel(force), H)

    def evaluate(self, U, omega, force, H, n_time, jacobian=True, domega=False, lazy=False):
        """Residual ``R = U - b + G F(U)`` of the condensed balance, with its derivatives.

        Returns a dict with ``R``, ``F`` (joint force coefficients) and, as asked, ``J = dR/dU``
        and ``Jw = dR/domega``; with ``lazy`` those two only after the dict's ``complete()``
        (for Newton's last residual, whose derivatives nobody uses).
        """
        nj = self.n_joints
        n = n_coefficients(H)
        fc = self._fcache
        if fc is None or fc[0] is not force or fc[2] != H or not np.array_equal(fc[1], force):
            Fc = self._force_vector(force, H)
            Xf = to_complex(Fc)
            Fc.setflags(write=False)
            Xf.setflags(write=False)
            fc = self._fcache = (force, np.array(force, float), H, Fc, Xf)
        Fc, Xf = fc[3], fc[4]
        cached = self._cache
        if cached is not None and cached[0] == omega and cached[1] == H:
            G, Hm = cached[2], cached[3]
        else:
            G, Hm = self.condensed(omega, H)
            self._cache = (omega, H, G, Hm)
        b = self._linear_part(omega, H, Xf, Hm)
        want = jacobian or domega
        F, finish = self.aft(U.reshape(nj, n), omega, H, n_time, jacobian=want, domega=domega, lazy=True)
        Fv = F.reshape(-1)
        ev = _Evaluation(R=U - b + G @ Fv, F=F, b=b, G=G, Hm=Hm, Xf=Xf)

        def derivatives():
            JF, JFw = finish()
            if want:
                J = G @ JF
                J.flat[:: U.size + 1] += 1.0  # I + G dF/dU
                ev["J"] = J
            if domega:
                # d/dw of G F - b, harmonic by harmonic in complex form: the joint shapes times
                # dH_k (psi^T F_k - phi_f X_k) (the real blocks of dG and db applied without forming them)
                k = np.arange(H + 1)
                dH = self._d_receptance(k * omega, Hm) * k[:, None]  # chain rule of (k w)
                ps = self.joint_shapes
                Z = dH * (to_complex(F).T @ ps - Xf[:, None] * self.force_shape)
                Jw = to_real((Z @ ps.T).T).reshape(-1)
                ev["Jw"] = Jw + G @ JFw if self._rate else Jw

        if want and lazy:
            ev._complete = derivatives
        elif want:
            derivatives()
        return ev

    def point(self, U, omega, force, H, n_time, ev=None, iterations=0, residual_norm=0.0) -> HBPoint:
        """The :class:`HBPoint` of joint coefficients ``U`` (flattened or (n_j, n))."""
        nj = self.n_joints
        n = n_coefficients(H)
        Uv = np.asarray(U, float).reshape(-1)
        if ev is None:
            ev = self.evaluate(Uv, omega, force, H, n_time, jacobian=False)
        Fj = ev["F"]
        Xm = ev["Hm"].T * (self.force_shape[:, None] * ev["Xf"][None, :] - self.joint_shapes.T @ to_complex(Fj))
        return HBPoint(float(omega), self._force_vector(force, H), to_real(Xm), Uv.reshape(nj, n).copy(), Fj,
                       int(iterations), float(residual_norm))

    # --- stability -------------------------------------------------------------------
    def hill_eigenvalues(self, point: HBPoint, n_time=None):
        """Floquet exponents of a periodic solution by Hill's method: ``(eigenvalues, harmonic index)``.

        The motion linearised about the orbit, ``d_eta = exp(lambda t) sum_k x_k (harmonics)``,
        gives the quadratic eigenproblem ``(lambda^2 I + lambda C1 + K0) x = 0`` on the modal
        coefficients, with ``C1 = 2 Dt + C + Psi^T Jv Psi`` and
        ``K0 = Dt^2 + C Dt + Omega^2 + Psi^T (Ju + Jv Dt) Psi`` (``Dt = omega d/dtau``; ``Ju``,
        ``Jv``: the AFT Jacobians of the joint forces in coefficient space; for a hysteretic law
        the derivative of its periodic force map, the usual linearisation of Hill's method).
        Each exponent appears once per harmonic (``lambda + i k omega``); of the
        ``2 n_modes (2H + 1)`` eigenvalues the ``2 n_modes`` whose eigenvectors sit lowest in
        the harmonics are the exponents themselves (for a linear model, ``-zeta Omega +- i Omega_d``);
        copies of one exponent share its real part.  Returns all eigenvalues and the mean
        harmonic index of their eigenvectors (large: an eigenvalue of the truncation).  Rigid-body
        modes, which the joints do not move, are left out (their exponents are zero).

        Checked against time integrations on a chain with a cubic spring and a Jenkins joint that
        barely slips (stable and unstable points of the upper branch, the branch between folds).
        Where sliders slip much (the same chain with ``Fs`` halved; the Iwan lap joint of
        docs/formats.md) it reports positive growth rates over whole branches that no time
        integration has confirmed: the periodic-map Jacobian of a slider law is not the
        linearisation of the transient motion.  For slipping slider laws the result is not
        trustworthy yet.
        """
        H = point.n_harmonics
        n = n_coefficients(H)
        N = default_n_time(H) if n_time is None else int(n_time)
        w = point.omega
        E, Dm, P = aft_basis(H, N, "F")
        nm, nj = self.n_modes, self.n_joints
        Ju = np.zeros((nj * n, nj * n))
        Jv = np.zeros((nj * n, nj * n))
        for j, _, _, _, D, Dv, _ in self._laws_on(point.joint, w, H, N, True):
            if Dv is not None:
                Jv[j * n:(j + 1) * n, j * n:(j + 1) * n] = P @ Dv @ E
            Ju[j * n:(j + 1) * n, j * n:(j + 1) * n] = P @ D @ E
        flex = ~self._rigid  # rigid-body modes carry no joint motion: they decouple (exponents 0)
        nm = int(flex.sum())
        T = np.kron(self.joint_shapes[:, flex], np.eye(n))  # modal coefficients -> joint coefficients
        I_n = np.eye(n)
        Dt = np.kron(np.eye(nm), w * Dm)
        C = np.kron(np.diag(2 * self.zeta[flex] * self.omega[flex]), I_n)
        K = np.kron(np.diag(self.omega[flex] ** 2), I_n)
        C1 = 2 * Dt + C + T.T @ Jv @ T
        K0 = Dt @ Dt + C @ Dt + K + T.T @ (Ju @ T + Jv @ T @ Dt)
        m = nm * n
        lam, vec = np.linalg.eig(hill_companion(K0, C1))
        # every exponent appears once per harmonic (lambda + i k omega, its vector shifted by k
        # harmonics); keep the copy whose vector sits lowest in the harmonics
        kidx = np.tile(np.concatenate([[0.0], np.repeat(np.arange(1.0, H + 1), 2)]), nm)
        wgt = np.abs(vec[:m]) ** 2
        score = (kidx @ wgt) / np.maximum(wgt.sum(axis=0), 1e-300)
        return lam, score

    def growth_rate(self, point: HBPoint, n_time=None) -> float:
        """Largest real part [1/s] of the well-resolved Hill eigenvalues (eigenvector's mean harmonic
        index at most ``H / 2``): negative for an asymptotically stable orbit."""
        lam, score = self.hill_eigenvalues(point, n_time)
        return float(np.max(lam.real[score <= 0.5 * point.n_harmonics]))

    def is_stable(self, point: HBPoint, n_time=None, tol=1e-9) -> bool:
        """True when :meth:`growth_rate` is below ``tol * omega``."""
        return self.growth_rate(point, n_time) < tol * point.omega

    # --- fixed frequency -------------------------------------------------------------
    @single_threaded
    def solve(self, omega, force, n_harmonics=9, *, n_time=None, guess=None, tol=1e-10, max_iter=40):
        """Periodic steady state at ``omega`` (Newton with step halving on the residual norm).

        Parameters
        ----------
        omega : float
            Excitation frequency [rad/s].
        force : array_like
            Harmonic coefficients of ``F(t)`` (``[0, 0, F]`` for ``F sin(omega t)``); harmonics
            above ``n_harmonics`` are ignored.
        n_harmonics : int
            Harmonics 0..H.
        n_time : int, optional
            AFT samples per period (default :func:`default_n_time`); must exceed ``2 H``.
        guess : HBPoint or array, optional
            Starting joint coefficients.
        tol : float
            On ``|residual| / |u|``.

        Raises
        ------
        ConvergenceError
        """
        H = int(n_harmonics)
        n = n_coefficients(H)
        nj = self.n_joints
        w = float(omega)
        if not (math.isfinite(w) and w > 0):
            raise StructureError(f"harmonic balance: omega must be a positive number, got {omega!r}")
        N = default_n_time(H) if n_time is None else int(n_time)
        if N <= 2 * H:
            raise StructureError(f"harmonic balance: n_time = {N} must exceed 2 H = {2 * H}")
        Fc = self._force_vector(force, H)
        ev = self.evaluate(np.zeros(nj * n), w, Fc, H, N, jacobian=False)
        b = ev["b"]
        if guess is None:
            U = b.copy()
        else:
            g = guess.joint if isinstance(guess, HBPoint) else np.asarray(guess, float).reshape(nj, -1)
            U = resize_harmonics(g, H).reshape(-1)
        scale = max(np.linalg.norm(b), 1e-300)

        def error(r, Uv):
            return np.linalg.norm(r) / max(np.linalg.norm(Uv), scale * 1e-6)

        def residual(Uv):
            ev = self.evaluate(Uv, w, Fc, H, N, lazy=True)
            return ev["R"], None, error(ev["R"], Uv), ev

        out = damped_newton(U, residual, tol, max_iter, jacobian=lambda ev: ev.complete()["J"])
        U, ev, it, err = out.x, out.state, out.iterations, out.error
        if not out.converged:
            raise ConvergenceError(
                f"harmonic balance at {w / (2 * np.pi):.6g} Hz did not converge: relative residual {err:.3g} "
                f"> {tol:g} after {it} Newton iterations ({out.reason})"
            )
        return self.point(U, w, Fc, H, N, ev, it, err)

    @single_threaded
    def sweep(self, omegas, force, n_harmonics=9, **kw):
        """:meth:`solve` at each frequency in turn, each started from a secant predictor (:func:`warm_sweep`)."""
        return warm_sweep(lambda w, guess: self.solve(w, force, n_harmonics, guess=guess, **kw), omegas)

    # --- continuation ---------------------------------------------------------------
    @single_threaded
    def continuation(self, omega_start, omega_end, force, n_harmonics=9, *, n_time=None, tol=1e-9, ds=0.02,
                     ds_max=0.1, max_steps=2000):
        """Frequency response from ``omega_start`` to ``omega_end`` by pseudo-arclength continuation.

        The curve passes folds (turning points, located where ``d omega / ds`` changes sign and
        added to the curve).  Steps are in a metric where the frequency range and the
        largest linear joint response are of size one.

        Returns
        -------
        HBCurve
        """
        H = int(n_harmonics)
        N = default_n_time(H) if n_time is None else int(n_time)
        w0, w1 = float(omega_start), float(omega_end)
        if not (w0 > 0 and w1 > 0 and w0 != w1 and math.isfinite(w0) and math.isfinite(w1)):
            raise StructureError(f"continuation: need two different positive frequencies, got {w0!r}, {w1!r}")
        Fc = self._force_vector(force, H)
        prob = _Problem(self, Fc, H, N)
        zs = prob.scale(w0, w1)
        prob.F = zs
        arc = _Arclength(prob, w0, w1, zs, tol)
        first = self.solve(w0, Fc, H, n_time=N, tol=tol)
        pts, folds = _follow(
            arc, first, first.joint.reshape(-1), w0, w1, ds, ds_max, max_steps,
            extrapolate=True,
            point=lambda z, w, ev, its: self.point(z, w, Fc, H, N, ev["ev"], its, ev["err"]),
            land=lambda z, w: self.solve(w, Fc, H, n_time=N, guess=z, tol=tol),
            stopped=lambda last: (f"continuation stopped after {max_steps} steps at {last.frequency_hz:.6g} Hz "
                                  "before the end of the range; returning the partial curve"),
            stalled=lambda last, ds_min: (f"continuation stalled at {last.frequency_hz:.6g} Hz: step size fell "
                                          f"below {ds_min:g}; try more harmonics or a smaller range"),
            stacklevel=4,
        )
        return HBCurve(tuple(pts), tuple(folds))


class _Problem:
    """The interface :class:`jointid.simulate.hbm.continuation._Arclength` expects."""

    closure = False

    def __init__(self, engine: CondensedHB, Fc, H, N):
        self.e, self.Fc, self.H, self.N = engine, Fc, H, N
        self.m = engine.n_joints * n_coefficients(H)
        self.active = np.arange(self.m)
        self.F = 1.0

    def scale(self, w0, w1):
        """Largest joint response of the linear model over the range (its ends and resonances inside)."""
        e = self.e
        ws = [w0, w1] + [w for w in e.omega if min(w0, w1) < w < max(w0, w1)]
        amp = 0.0
        for w in ws:
            b = e._linear_part(w, self.H, to_complex(self.Fc), e.receptance(np.arange(self.H + 1) * w))
            amp = max(amp, float(np.max(np.abs(b))))
        return amp if amp > 0 else 1.0

    def evaluate(self, z, w, jacobian=False):
        ev = self.e.evaluate(z, w, self.Fc, self.H, self.N, jacobian=True, domega=True, lazy=True)
        R = ev["R"]
        err = math.sqrt(float(R @ R)) / max(math.sqrt(float(z @ z)), 1e-300)  # np.linalg.norm's sqrt(x . x)
        return {"R": R, "err": err, "z": z, "w": w, "ev": ev}

    def jacobian(self, ev, domega=True):
        ev["ev"].complete()
        ev["J"] = ev["ev"]["J"]
        ev["Jw"] = ev["ev"]["Jw"]
