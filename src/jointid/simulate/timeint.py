"""Time integration of the single-mode model, to cross-check harmonic balance.

:func:`integrate` integrates ``q'' + h(q, q'; theta) = F sin(omega t)`` with
``scipy.integrate.solve_ivp`` (DOP853, tight tolerances) for a frozen ``theta``.

:func:`periodic_orbit` finds the periodic steady state by shooting (Newton on the
period map, Jacobian from the variational equations or finite differences) inside an
outer secant loop on the amplitude closure ``q_max = max |q(t)|`` -- the seed paper's
"iterative approach" (section 4: guess ``q_max``, get the steady state, update
``q_max``), with a secant update because plain fixed-point iteration diverges near
resonance when the damping grows with amplitude.

Both are independent of the harmonic-balance solver in :mod:`jointid.simulate.hbm`:
only its first-order (single-harmonic, describing-function) estimate is borrowed as a
default starting point, which selects the lowest-amplitude branch but does not enter
the converged result.

Examples
--------
>>> from jointid.simulate.model import seed_model
>>> orbit = periodic_orbit(seed_model(), 165.0, 1.0)
>>> round(orbit.q_max * 1e4, 6)
5.974455
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize
from scipy.integrate import solve_ivp

from ..errors import ConvergenceError, RecordError
from .hbm import SteadyState, _linear_closure_amplitude, _Problem, linear_frf
from .model import SingleModeModel

__all__ = ["Trajectory", "PeriodicOrbit", "integrate", "periodic_orbit"]


def _readonly(a):
    a = np.ascontiguousarray(a)
    a.flags.writeable = False
    return a


def _theta_for(model, q_max, theta=None):
    if theta is not None:
        return np.asarray(theta, float)
    if model.depends_on_amplitude:
        if q_max is None:
            raise RecordError(
                "this model has amplitude laws: give the amplitude q_max at which its coefficients are "
                "frozen for the integration (integrate(..., q_max=...))"
            )
        return model.coefficients_at(float(q_max))
    return np.array(model.coefficients, float)


def _rhs_functions(model, theta, omega, F):
    """Scalar right-hand sides (plain and with variational equations)."""
    terms = [(float(c), t) for t, c in zip(model.terms.terms, theta) if c != 0.0]
    funcs = [(c, t.func) for c, t in terms]
    sin = math.sin

    def rhs(t, y):
        q, v = y[0], y[1]
        h = 0.0
        for c, f in funcs:
            h += c * f(q, v)
        return np.array([v, F * sin(omega * t) - h])

    def rhs_var(t, y):
        q, v = y[0], y[1]
        h = gq = gv = 0.0
        for c, term in terms:
            h += c * term.func(q, v)
            if term.dq is not None and term.dv is not None:
                a, b = term.dq(q, v), term.dv(q, v)
            else:
                a, b = term.derivatives(np.asarray(q), np.asarray(v))
            gq += c * a
            gv += c * b
        # sensitivities S = d(q, v)/d(q0, v0), stored column-wise in y[2:6]
        s = y[2:6]
        return np.array(
            [
                v, F * sin(omega * t) - h,
                s[1], -gq * s[0] - gv * s[1],
                s[3], -gq * s[2] - gv * s[3],
            ]
        )

    return rhs, rhs_var


@dataclass(frozen=True, eq=False)
class Trajectory:
    """Result of :func:`integrate`: arrays on the requested time grid.

    Attributes
    ----------
    t, q, velocity, acceleration, force : ndarray
        Time [s], displacement, velocity, acceleration and applied force
        ``F sin(omega t)``.
    theta : ndarray
        Coefficients used (frozen during the integration).
    q_max : float or None
        The amplitude the coefficients were evaluated at (``None`` without laws).
    omega, force_amplitude : float
    nfev : int
        Right-hand-side evaluations.
    """

    t: np.ndarray
    q: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    force: np.ndarray
    theta: np.ndarray
    q_max: float | None
    omega: float
    force_amplitude: float
    nfev: int

    def summary(self) -> dict:
        return {
            "omega": self.omega,
            "force_amplitude": self.force_amplitude,
            "q_max": self.q_max,
            "theta": [float(v) for v in self.theta],
            "n_samples": int(self.t.size),
            "t_span": [float(self.t[0]), float(self.t[-1])] if self.t.size else None,
            "max_abs_q": float(np.max(np.abs(self.q))) if self.t.size else None,
            "nfev": self.nfev,
        }


def integrate(
    model,
    omega,
    force_amplitude,
    t,
    q0=0.0,
    v0=0.0,
    q_max=None,
    *,
    theta=None,
    rtol=1e-12,
    atol=None,
    method="DOP853",
) -> Trajectory:
    """Integrate ``q'' + h(q, q'; theta) = F sin(omega t)`` from ``(q0, v0)`` at ``t[0]``.

    Parameters
    ----------
    model : SingleModeModel
    omega : float
        Excitation frequency [rad/s].
    force_amplitude : float
        ``F``.
    t : array_like
        Increasing output times [s]; the integration starts at ``t[0]``.
    q0, v0 : float
        Initial displacement and velocity (default: at rest).
    q_max : float, optional
        Amplitude at which the amplitude laws are evaluated; required when the model has
        laws (the coefficients are frozen during one integration, as in the seed's
        iterative approach).
    theta : array_like, optional
        Explicit coefficients, overriding the model's.
    rtol, atol : float
        ``solve_ivp`` tolerances; ``atol`` defaults to ``rtol`` times the static
        deflection ``F / omega1^2`` (and ``omega`` times that for the velocity).
    method : str
        ``solve_ivp`` method (default DOP853).

    Returns
    -------
    Trajectory
    """
    if not isinstance(model, SingleModeModel):
        raise TypeError(f"model must be a SingleModeModel, got {type(model).__name__}")
    omega, F = float(omega), float(force_amplitude)
    if not (np.isfinite(omega) and omega > 0):
        raise RecordError(f"omega must be a positive finite frequency in rad/s, got {omega!r}")
    t = np.atleast_1d(np.asarray(t, float))
    if t.ndim != 1 or t.size < 2 or np.any(np.diff(t) <= 0):
        raise RecordError(f"t must be a strictly increasing 1-D array of at least 2 times, got shape {t.shape}")
    th = _theta_for(model, q_max, theta)
    rhs, _ = _rhs_functions(model, th, omega, F)
    if atol is None:
        atol = _default_atol(model, th, omega, F, rtol)
    sol = solve_ivp(rhs, (t[0], t[-1]), [float(q0), float(v0)], method=method, t_eval=t, rtol=rtol, atol=atol)
    if not sol.success:
        raise ConvergenceError(f"time integration failed at omega={omega:.6g} rad/s: {sol.message}")
    q, v = sol.y
    h = model.terms.restoring_force(q, v, th)
    force = F * np.sin(omega * t)
    return Trajectory(
        t=_readonly(t), q=_readonly(q), velocity=_readonly(v), acceleration=_readonly(force - h),
        force=_readonly(force), theta=_readonly(th), q_max=None if q_max is None else float(q_max),
        omega=omega, force_amplitude=F, nfev=int(sol.nfev),
    )


def _default_atol(model, theta, omega, F, rtol):
    names = model.terms.names
    k = abs(theta[names.index("q")]) if "q" in names else omega**2
    qs = abs(F) / max(k, omega**2, 1e-300)
    if qs == 0.0:
        qs = 1.0
    return rtol * np.array([qs, omega * qs])


@dataclass(frozen=True, eq=False)
class PeriodicOrbit:
    """Periodic steady state found by shooting (see :func:`periodic_orbit`).

    Attributes
    ----------
    omega, force_amplitude : float
    q_max : float
        ``max_t |q(t)|`` measured on the integrated orbit; the coefficients ``theta``
        were evaluated at the closure's last iterate, within ``closure_residual``.
    q0, v0 : float
        State at ``t = 0`` (phase of ``sin(omega t)`` zero) on the orbit.
    theta : ndarray
        Coefficients at ``q_max``.
    monodromy : ndarray
        2x2 period map Jacobian (closure frozen).
    floquet_multipliers : ndarray
        Its eigenvalues; the orbit is ``stable`` when all have modulus below one.
    stable : bool
    closure_iterations : int
        Outer iterations on ``q_max`` (1 without amplitude laws).
    shooting_iterations : int
        Newton iterations on the period map, summed over the outer loop.
    closure_residual : float
        ``|q_max - max|q|| / q_max`` at the end.
    """

    omega: float
    force_amplitude: float
    q_max: float
    q0: float
    v0: float
    theta: np.ndarray
    monodromy: np.ndarray
    floquet_multipliers: np.ndarray
    stable: bool
    closure_iterations: int
    shooting_iterations: int
    closure_residual: float
    model: SingleModeModel | None = None

    @property
    def period(self) -> float:
        return 2.0 * np.pi / self.omega

    def trajectory(self, n_samples=512, n_periods=1, rtol=1e-12) -> Trajectory:
        """Integrate the orbit over ``n_periods`` periods from ``t = 0``."""
        t = np.linspace(0.0, n_periods * self.period, int(n_samples) + 1)
        return integrate(self.model, self.omega, self.force_amplitude, t, self.q0, self.v0,
                         theta=self.theta, q_max=self.q_max, rtol=rtol)

    def summary(self) -> dict:
        return {
            "omega": self.omega,
            "force_amplitude": self.force_amplitude,
            "q_max": self.q_max,
            "q0": self.q0,
            "v0": self.v0,
            "theta": [float(v) for v in self.theta],
            "floquet_multipliers": [[float(m.real), float(m.imag)] for m in self.floquet_multipliers],
            "stable": self.stable,
            "closure_iterations": self.closure_iterations,
            "shooting_iterations": self.shooting_iterations,
            "closure_residual": self.closure_residual,
        }


class _BlowUp(Exception):
    """A trial initial state left the region of plausible amplitudes."""


class _Shooter:
    def __init__(self, model, omega, F, rtol, jacobian):
        self.model, self.omega, self.F = model, omega, F
        self.T = 2.0 * np.pi / omega
        self.rtol = rtol
        self.jacobian = jacobian
        self.nit = 0
        self.scale = np.array([1.0, 1.0 / omega])  # state (q, v) -> displacement units
        self.bound = np.inf

    def period_map(self, z, theta, variational):
        rhs, rhs_var = _rhs_functions(self.model, theta, self.omega, self.F)
        atol = _default_atol(self.model, theta, self.omega, self.F, self.rtol)
        bound = self.bound

        def escape(t, y):  # stop integrations that run away (stiff and endless otherwise)
            return bound - abs(y[0])

        escape.terminal = True
        if variational:
            y0 = np.array([z[0], z[1], 1.0, 0.0, 0.0, 1.0])
            atol = np.concatenate([atol, [self.rtol * 1e-3] * 4])
            sol = solve_ivp(rhs_var, (0.0, self.T), y0, method="DOP853", rtol=self.rtol, atol=atol,
                            events=escape)
        else:
            sol = solve_ivp(rhs, (0.0, self.T), z, method="DOP853", rtol=self.rtol, atol=atol,
                            dense_output=True, events=escape)
        if sol.status == 1:
            raise _BlowUp()
        if not sol.success:
            raise ConvergenceError(f"time integration failed at omega={self.omega:.6g} rad/s: {sol.message}")
        return sol

    def _map_and_jacobian(self, z, theta):
        if self.jacobian == "variational":
            y = self.period_map(z, theta, True).y[:, -1]
            return y[:2], y[2:].reshape(2, 2).T
        phi = self.period_map(z, theta, False).y[:, -1]
        M = np.empty((2, 2))
        for j in range(2):
            dz = np.zeros(2)
            dz[j] = 1e-6 * max(abs(z[j]), abs(z[0]) * (self.omega if j else 1.0), 1e-12)
            M[:, j] = (self.period_map(z + dz, theta, False).y[:, -1] - phi) / dz[j]
        return phi, M

    def orbit(self, z, theta, tol, max_iter):
        """Damped Newton on ``phi_T(z) - z = 0``; returns ``(z, M)``.

        Steps are limited to twice the current amplitude and halved when the trial
        integration runs away (beyond 100 times the amplitude scale).
        """
        z = np.array(z, float)
        size0 = max(float(np.max(np.abs(z * self.scale))), abs(self.F) / max(self.omega**2, 1e-300))
        self.bound = 100.0 * size0
        self.nit += 1
        try:
            phi, M = self._map_and_jacobian(z, theta)
        except _BlowUp:
            raise ConvergenceError(
                f"shooting at omega={self.omega:.6g} rad/s, F={self.F:.6g}: the initial guess runs away"
            ) from None
        for _ in range(max_iter):
            step = np.linalg.solve(M - np.eye(2), z - phi)
            size = float(np.max(np.abs(z * self.scale)))
            step_size = float(np.max(np.abs(step * self.scale)))
            if not np.isfinite(step_size):
                break
            if step_size <= tol * max(size, 1e-300):
                return z + step, M
            lam = min(1.0, 2.0 * max(size, size0) / step_size)
            while True:
                self.nit += 1
                try:
                    z_try = z + lam * step
                    phi, M = self._map_and_jacobian(z_try, theta)
                    break
                except _BlowUp:
                    lam *= 0.25
                    if lam < 1e-4:
                        raise ConvergenceError(
                            f"shooting at omega={self.omega:.6g} rad/s, F={self.F:.6g}: every damped Newton "
                            "step runs away; give a closer guess"
                        ) from None
            z = z_try
        raise ConvergenceError(
            f"shooting did not converge at omega={self.omega:.6g} rad/s, F={self.F:.6g} after {max_iter} "
            "Newton iterations on the period map; give a closer guess (e.g. a harmonic-balance SteadyState)"
        )

    def amplitude(self, z, theta):
        """``max |q|`` over one period of the orbit through ``z``, to integration accuracy."""
        sol = self.period_map(z, theta, False)
        n = 512
        tt = np.linspace(0.0, self.T, n + 1)
        q = sol.sol(tt)[0]
        i = int(np.argmax(np.abs(q[:-1])))
        lo, hi = tt[i - 1] if i > 0 else tt[-2] - self.T, tt[i + 1]

        def vel(s):
            return sol.sol(s % self.T if s < 0 else s)[1]

        try:
            ts = optimize.brentq(vel, lo, hi, xtol=1e-15 * self.T, rtol=1e-15)
            val = abs(float(sol.sol(ts % self.T)[0]))
        except ValueError:
            val = float(np.abs(q[i]))
        return max(val, float(np.abs(q[i])))


def periodic_orbit(
    model,
    omega,
    force_amplitude,
    *,
    guess=None,
    q_max_guess=None,
    tol=1e-10,
    closure_tol=1e-10,
    max_iter=30,
    rtol=1e-12,
    jacobian="variational",
) -> PeriodicOrbit:
    """Periodic steady state by shooting, with the seed's iteration on ``q_max``.

    Inner loop: Newton on the period map ``phi_T(q0, v0) = (q0, v0)`` with the
    coefficients frozen at ``theta = model.coefficients_at(s)``; its Jacobian (the
    monodromy matrix) comes from the variational equations (or finite differences).
    Outer loop (only with amplitude laws): ``s <- max_t |q(t)|`` of that orbit, solved
    as ``g(s) = max|q|(s) - s = 0`` by the secant method started from one fixed-point
    step (the seed's iterative approach, made convergent).

    Parameters
    ----------
    model : SingleModeModel
    omega : float
        Excitation frequency [rad/s].
    force_amplitude : float
    guess : (q0, v0) or SteadyState, optional
        Initial state at ``t = 0`` (a harmonic-balance state selects a branch).  Default:
        the first-order single-harmonic (describing-function) solution, lowest amplitude
        first or the one nearest ``q_max_guess``.
    q_max_guess : float, optional
        Initial amplitude for the closure (default: from ``guess`` or the first-order
        solution).
    tol : float
        Relative step tolerance of the shooting Newton.
    closure_tol : float
        Relative tolerance on ``|max|q| - q_max|``.
    max_iter : int
        Iteration limit of each loop.
    rtol : float
        ``solve_ivp`` relative tolerance.
    jacobian : {"variational", "fd"}

    Returns
    -------
    PeriodicOrbit

    Raises
    ------
    jointid.errors.ConvergenceError
    """
    if not isinstance(model, SingleModeModel):
        raise TypeError(f"model must be a SingleModeModel, got {type(model).__name__}")
    if jacobian not in ("variational", "fd"):
        raise RecordError(f"jacobian must be 'variational' or 'fd', got {jacobian!r}")
    omega, F = float(omega), float(force_amplitude)
    if not (np.isfinite(omega) and omega > 0):
        raise RecordError(f"omega must be a positive finite frequency in rad/s, got {omega!r}")
    sh = _Shooter(model, omega, F, rtol, jacobian)

    if isinstance(guess, SteadyState):
        z = np.array([guess.q(0.0), guess.velocity(0.0)], float)
        if q_max_guess is None:
            q_max_guess = guess.q_max
    elif guess is not None:
        z = np.asarray(guess, float).reshape(2)
    else:
        z = None
    if z is None:
        # first-order (single-harmonic, describing-function) estimate; only a start
        first_order = _Problem(model, F, 1)
        cands = [first_order.full(c[: first_order.active.size]) for c in first_order.describing_guesses(omega)]
        if cands:
            amps = np.array([np.hypot(c[1], c[2]) for c in cands])
            k = 0 if q_max_guess is None else int(np.argmin(np.abs(amps - q_max_guess)))
            a1, b1 = cands[k][1], cands[k][2]
            z = np.array([a1, omega * b1])  # q = a1 cos + b1 sin at t = 0
            if q_max_guess is None:
                q_max_guess = float(amps[k])
    if q_max_guess is None:
        q_max_guess = _linear_closure_amplitude(model, omega, F)
    if z is None:
        X = linear_frf(model, omega, F, q_max=q_max_guess)
        z = np.array([X.imag, omega * X.real])  # q = Im(X e^{i omega t})

    def solve_at(s, z_start):
        th = model.coefficients_at(s) if model.depends_on_amplitude else np.array(model.coefficients, float)
        z_orb, M = sh.orbit(z_start, th, tol, max_iter)
        return z_orb, M, th, sh.amplitude(z_orb, th)

    if not model.depends_on_amplitude:
        z, M, th, A = solve_at(0.0, z)
        s, n_outer, res = A, 1, 0.0
    else:
        s0 = float(q_max_guess)
        z, M, th, A0 = solve_at(s0, z)
        g0 = A0 - s0
        s1 = A0  # one fixed-point step (the seed's update)
        n_outer = 1
        s, A = s0, A0
        converged = abs(g0) <= closure_tol * abs(A0)
        while not converged:
            if n_outer >= max_iter:
                raise ConvergenceError(
                    f"q_max closure did not converge at omega={omega:.6g} rad/s, F={F:.6g} after {n_outer} "
                    f"outer iterations (last q_max={s:.6g}, max|q|={A:.6g})"
                )
            z, M, th, A1 = solve_at(s1, z)
            n_outer += 1
            g1 = A1 - s1
            s, A = s1, A1
            if abs(g1) <= closure_tol * abs(A1):
                break
            if g1 == g0:
                raise ConvergenceError(f"q_max closure stalled at omega={omega:.6g} rad/s (secant slope zero)")
            s_next = s1 - g1 * (s1 - s0) / (g1 - g0)
            if not np.isfinite(s_next) or s_next <= 0:
                s_next = 0.5 * s1
            s0, g0, s1 = s1, g1, s_next
        res = abs(A - s) / max(abs(s), 1e-300)
    mult = np.linalg.eigvals(M)
    return PeriodicOrbit(
        omega=omega,
        force_amplitude=F,
        q_max=float(A),  # measured on the time-integrated orbit (|A - s| <= closure_tol A)
        q0=float(z[0]),
        v0=float(z[1]),
        theta=_readonly(th),
        monodromy=_readonly(M),
        floquet_multipliers=_readonly(mult),
        stable=bool(np.max(np.abs(mult)) < 1.0),
        closure_iterations=n_outer,
        shooting_iterations=sh.nit,
        closure_residual=float(res),
        model=model,
    )
