"""Time integration of a modal structure with joint laws, started on a harmonic-balance orbit.

The check of :mod:`jointid.simulate.structure_hb` by an independent method: the same model

``eta'' + 2 zeta Omega eta' + Omega^2 eta + Psi^T (f(u; history) - k u) = p F(t)``,  ``u = Psi eta``

(the fields of a :class:`~jointid.simulate.structure_hb.CondensedHB`) integrated by scipy's
DOP853 (no truncation to harmonics, no AFT).  Each joint law is evaluated through its
time-step protocol ``force(u, v, state)``: the hysteretic state is held over a step and
updated at its end (the play operator is exact between reversals); where a joint's velocity
changes sign inside a step, the state first passes through the extremum (located on the
step's dense output).  The run starts at ``t = 0`` on the harmonic-balance point: modal
displacements and velocities from its harmonics, the joint states those its motion leaves
(two passes of a finely sampled period from the virgin state).  The harmonics of the last
period are Fourier sums over a uniform grid of that period (dense output).

A settled run reproduces the harmonic balance's periodic orbit up to its truncation to
harmonics; ``relative_difference`` measures the fundamental's change at the response DOFs.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
from scipy.integrate import DOP853
from scipy.optimize import brentq

from ..errors import ConvergenceError
from ..numerics.aft import to_complex
from .structure_hb import HBPoint

__all__ = ["TimeIntegration", "TooStiffError", "integrate_from_point", "integrate_structure"]


class TooStiffError(ConvergenceError):
    """The model needs more steps of the explicit integrator than the bound (its highest modes): the
    check is not done, which says nothing against the harmonic balance."""


@dataclass(frozen=True, eq=False)
class TimeIntegration:
    """Harmonics of the last integrated period (coefficients ``[a0, a1, b1, ...]``, :mod:`jointid.conventions`).

    Attributes
    ----------
    omega : float
        Excitation frequency [rad/s].
    modal, joint : ndarray (n_modes | n_joints, 2H + 1)
        Modal coordinates and joint relative motions.
    response : ndarray (n_response, 2H + 1)
        Displacements at the response DOFs (``shapes @ modal``; the modal coordinates when no shapes).
    relative_difference : float
        ``max |X1_ti - X1_hb| / max |X1_hb|`` of the fundamental's complex amplitudes at the response DOFs.
    periods, n_steps : int
        Periods integrated; accepted DOP853 steps.
    cost_s : float
        Processor time of the run [s].
    """

    omega: float
    modal: np.ndarray
    joint: np.ndarray
    response: np.ndarray
    relative_difference: float
    periods: int
    n_steps: int
    cost_s: float

    @property
    def frequency_hz(self) -> float:
        return self.omega / (2 * np.pi)


def _series(coef, w, t):
    """Values of harmonic coefficient rows ``(m, 2H + 1)`` at times ``t``."""
    coef = np.atleast_2d(coef)
    k = np.arange(1, (coef.shape[1] - 1) // 2 + 1)
    return coef[:, :1] + coef[:, 1::2] @ np.cos(np.outer(k, w * t)) + coef[:, 2::2] @ np.sin(np.outer(k, w * t))


def _orbit_state(law, u_samples):
    """Joint state at the end of two passes of a sampled period from the virgin state (the orbit's at t = 0)."""
    s = law.initial_state()
    for _ in range(2):
        for uu in u_samples:
            _, s = law.force(uu, 0.0, s)
    return s


def _harmonics(y, w, t, H):
    """Fourier sums over one uniformly sampled period: rows of ``y`` -> ``(m, 2H + 1)``."""
    out = np.empty((y.shape[0], 2 * H + 1))
    out[:, 0] = np.mean(y, axis=1)
    for k in range(1, H + 1):
        out[:, 2 * k - 1] = 2 * np.mean(y * np.cos(k * w * t), axis=1)
        out[:, 2 * k] = 2 * np.mean(y * np.sin(k * w * t), axis=1)
    return out


#: Default bound on the DOP853 steps of one run, per period and largest step (``max_steps``).
STEPS_PER_MAX_STEP = 40


def integrate_from_point(engine, point: HBPoint, n_periods=25, steps_per_period=60, *, shapes=None,
                         n_harmonics=None, n_grid=4096, rtol=1e-11, atol=1e-14, max_steps=None) -> TimeIntegration:
    """Integrate ``engine``'s model (a :class:`~jointid.simulate.structure_hb.CondensedHB`) from ``point``.

    Parameters
    ----------
    engine : CondensedHB
    point : HBPoint
        The starting orbit; its ``force`` harmonics are the excitation ``F(t)``.
    n_periods : int
        Periods integrated; the harmonics are those of the last.
    steps_per_period : int
        Largest step ``T / steps_per_period`` of DOP853.
    shapes : array (n_response, n_modes), optional
        Response DOFs' mode shapes (default: the modal coordinates).
    n_harmonics : int, optional
        Harmonics returned (default: the point's).
    n_grid : int
        Samples of the last period for the Fourier sums.
    max_steps : int, optional
        Most DOP853 steps of the run (default ``STEPS_PER_MAX_STEP n_periods steps_per_period``). An
        explicit integrator's step is bounded by the fastest mode: a run whose highest natural
        frequency alone needs more steps is refused before it starts, and a run that reaches the
        bound (stiff joints) is stopped.

    Raises
    ------
    ConvergenceError
        The integrator failed, the motion left the finite numbers, or the run needs more than
        ``max_steps`` steps (the model is too stiff for an explicit integration).
    """
    t0 = time.process_time()
    n_periods, spp = int(n_periods), int(steps_per_period)
    if n_periods < 1 or spp < 1:
        raise ValueError(f"n_periods and steps_per_period must be positive, got {n_periods}, {spp}")
    w = float(point.omega)
    T = 2 * np.pi / w
    Psi, pf, Om, ze, km = engine.joint_shapes, engine.force_shape, engine.omega, engine.zeta, engine.k_model
    max_steps = STEPS_PER_MAX_STEP * n_periods * spp if max_steps is None else int(max_steps)
    # DOP853 is stable for h Omega up to about 4 on an undamped mode, and at rtol 1e-7 its steps on the
    # fastest mode were measured at h Omega ~ 1.3: that mode alone needs ~ Omega T / 2 steps a period
    need = n_periods * float(Om.max()) * T / 2.0
    if not need <= max_steps:
        raise TooStiffError(f"time integration at {w / (2 * np.pi):.6g} Hz not done: the highest mode "
                            f"({Om.max() / (2 * np.pi):.3g} Hz) needs about {need:.2g} steps of an explicit "
                            f"integrator over {n_periods} periods, more than the bound {max_steps}")
    laws = engine.laws
    H = point.n_harmonics if n_harmonics is None else int(n_harmonics)
    Fc = np.asarray(point.force, float)
    kf = np.arange(1, (Fc.size - 1) // 2 + 1)
    S = np.eye(Om.size) if shapes is None else np.atleast_2d(np.asarray(shapes, float))
    n = Om.size
    # joint states at t = 0 from the harmonic-balance motion (as a run settled on that orbit has them)
    u_hb = _series(point.joint, w, np.linspace(0, T, 2049)[1:])
    states = [_orbit_state(law, u_hb[i]) for i, law in enumerate(laws)]

    live = [(k, float(Fc[2 * k - 1]), float(Fc[2 * k])) for k in kf if Fc[2 * k - 1] != 0 or Fc[2 * k] != 0]
    F0 = float(Fc[0])

    def excitation(t):
        return F0 + sum(a * math.cos(k * w * t) + b * math.sin(k * w * t) for k, a, b in live)

    c2, Om2, PsiT, idx = 2 * ze * Om, Om**2, Psi.T.copy(), range(len(laws))

    def rhs(t, y):
        eta, etad = y[:n], y[n:]
        u, v = Psi @ eta, Psi @ etad
        f = np.array([float(laws[i].force(u[i], v[i], states[i])[0]) for i in idx]) - km * u
        return np.concatenate([etad, pf * excitation(t) - c2 * etad - Om2 * eta - PsiT @ f])

    m = np.asarray(point.modal, float)
    km_ = np.arange(1, (m.shape[1] - 1) // 2 + 1)
    y0 = np.concatenate([m[:, 0] + m[:, 1::2].sum(1), (m[:, 2::2] * km_ * w).sum(1)])
    solver = DOP853(rhs, 0.0, y0, n_periods * T, rtol=rtol, atol=atol, max_step=T / spp)
    tg = np.linspace(n_periods * T - T, n_periods * T, int(n_grid) + 1)[:-1]  # the last period, uniform
    etag = np.full((n, tg.size), np.nan)
    n_steps = 0
    with np.errstate(over="raise", invalid="raise"):
        try:
            while solver.status == "running":
                if n_steps >= max_steps:
                    raise TooStiffError(f"time integration at {w / (2 * np.pi):.6g} Hz stopped after {n_steps} "
                                        f"steps at t = {solver.t / T:.3g} of {n_periods} periods (the bound): the "
                                        "model is too stiff for an explicit integration")
                t_old, y_old = solver.t, solver.y.copy()
                solver.step()
                if solver.status == "failed":
                    break
                n_steps += 1
                v_old, v_new = Psi @ y_old[n:], Psi @ solver.y[n:]
                reversal = v_old * v_new < 0
                inside = (tg >= t_old) & (tg <= solver.t) if solver.t > tg[0] else None
                # the step's dense output (three more evaluations of rhs, with the states still those held over
                # the step: before any update): only where a reversal or the last period needs it
                sol = solver.dense_output() if reversal.any() or (inside is not None and inside.any()) else None
                for i, law in enumerate(laws):
                    if reversal[i]:  # a reversal inside the step: pass through its extreme first
                        tr = brentq(lambda s, r=Psi[i], d=sol: float(r @ d(s)[n:]), t_old, solver.t, xtol=1e-14)
                        _, states[i] = law.force(float(Psi[i] @ sol(tr)[:n]), 0.0, states[i])
                    _, states[i] = law.force(float(Psi[i] @ solver.y[:n]), float(v_new[i]), states[i])
                if inside is not None and inside.any():  # the dense output at the grid instants the step covers
                    etag[:, inside] = sol(tg[inside])[:n]
        except FloatingPointError as exc:
            raise ConvergenceError(f"time integration at {w / (2 * np.pi):.6g} Hz: the motion overflowed "
                                   f"({exc})") from None
    if solver.status == "failed" or not np.all(np.isfinite(etag)):
        raise ConvergenceError(f"time integration at {w / (2 * np.pi):.6g} Hz failed after {n_steps} steps"
                               + (f" ({solver.message})" if solver.status == "failed" else ""))
    modal = _harmonics(etag, w, tg, H)
    response = S @ modal
    X_hb = S @ to_complex(m)[:, 1]
    X_ti = to_complex(response)[:, 1]
    rel = float(np.max(np.abs(X_ti - X_hb)) / np.max(np.abs(X_hb)))
    return TimeIntegration(w, modal, Psi @ modal, response, rel, n_periods, n_steps, time.process_time() - t0)


def integrate_structure(structure, point: HBPoint, dofs=None, n_periods=25, steps_per_period=60,
                        **kw) -> TimeIntegration:
    """:func:`integrate_from_point` of a :class:`~jointid.simulate.structure.StructureModel`; the response at
    the named ``dofs`` (default: every DOF of its modal model)."""
    modal = structure.modal
    shapes = modal.shapes if dofs is None else np.array([modal.shape(d) for d in dofs])
    return integrate_from_point(structure.engine, point, n_periods, steps_per_period, shapes=shapes, **kw)
