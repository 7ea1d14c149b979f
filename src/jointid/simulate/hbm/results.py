"""Result classes of the harmonic balance (:class:`SteadyState`, :class:`FrequencyResponse`)
and the linear part's receptance :func:`linear_frf`."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...errors import RecordError
from ..model import SingleModeModel


@dataclass(frozen=True, eq=False)
class SteadyState:
    """A periodic steady state found by harmonic balance.

    Attributes
    ----------
    omega : float
        Excitation frequency [rad/s].
    force_amplitude : float
        ``F`` in ``Q(t) = F sin(omega t)``.
    coefficients : ndarray
        Harmonic vector of ``q``, ``[a0, a1, b1, ..., aH, bH]`` (conventions.py).
    n_harmonics : int
    q_max : float
        ``max_t |q(t)|`` of the harmonic series (machine precision).
    theta : ndarray
        Coefficients of the restoring force used, ``model.coefficients_at(q_max)``.
    residual_norm : float
        Scaled norm of the harmonic-balance residual at the solution.
    stable : bool or None
        Floquet stability from the monodromy matrix (``None`` when not computed).  With
        an amplitude closure the coefficients are frozen at ``theta`` for the stability
        analysis.
    iterations : int
        Newton iterations used.
    model : SingleModeModel
    floquet_exponents : ndarray or None
        The two Floquet exponents, imaginary parts within ``omega / 2`` (largest real
        part first).
    """

    omega: float
    force_amplitude: float
    coefficients: np.ndarray
    n_harmonics: int
    q_max: float
    theta: np.ndarray
    residual_norm: float
    stable: bool | None
    iterations: int
    model: SingleModeModel | None = None
    floquet_exponents: np.ndarray | None = None

    # time functions ------------------------------------------------------------------

    def _series(self, t, order):
        tau = self.omega * np.asarray(t, float)
        H = self.n_harmonics
        c = self.coefficients
        kt = np.multiply.outer(tau, np.arange(1, H + 1))
        a, b = c[1::2], c[2::2]
        k = np.arange(1, H + 1, dtype=float)
        w = self.omega
        if order == 0:
            return c[0] + np.cos(kt) @ a + np.sin(kt) @ b
        if order == 1:
            return np.cos(kt) @ (w * k * b) - np.sin(kt) @ (w * k * a)
        return -(np.cos(kt) @ ((w * k) ** 2 * a) + np.sin(kt) @ ((w * k) ** 2 * b))

    def q(self, t):
        """Displacement ``q(t)`` of the harmonic series (time ``t`` in seconds)."""
        return self._series(t, 0)

    def velocity(self, t):
        """``dq/dt`` at times ``t``."""
        return self._series(t, 1)

    def acceleration(self, t):
        """``d2q/dt2`` at times ``t``."""
        return self._series(t, 2)

    def force(self, t):
        """Applied force ``Q(t) = F sin(omega t)``."""
        return self.force_amplitude * np.sin(self.omega * np.asarray(t, float))

    def restoring_force(self, t):
        """``h(q, q')`` with the steady state's coefficients ``theta``."""
        if self.model is None:
            raise RecordError("this SteadyState carries no model; restoring_force needs one")
        return self.model.terms.restoring_force(self.q(t), self.velocity(t), self.theta)

    # scalars ---------------------------------------------------------------------------

    @property
    def amplitude(self) -> float:
        """Amplitude of the fundamental harmonic, ``sqrt(a1^2 + b1^2)``."""
        return float(np.hypot(self.coefficients[1], self.coefficients[2]))

    @property
    def phase(self) -> float:
        """Phase ``phi`` of the fundamental, ``q1 = A sin(omega t + phi)`` (lag < 0)."""
        return float(np.arctan2(self.coefficients[1], self.coefficients[2]))

    @property
    def period(self) -> float:
        return 2.0 * np.pi / self.omega

    def summary(self) -> dict:
        """JSON-safe dictionary of the steady state."""
        names = self.model.terms.coefficient_names if self.model is not None else range(len(self.theta))
        return {
            "omega": self.omega,
            "force_amplitude": self.force_amplitude,
            "n_harmonics": self.n_harmonics,
            "q_max": self.q_max,
            "amplitude": self.amplitude,
            "phase": self.phase,
            "theta": {str(k): float(v) for k, v in zip(names, self.theta)},
            "coefficients": [float(c) for c in self.coefficients],
            "residual_norm": self.residual_norm,
            "stable": self.stable,
            "iterations": self.iterations,
        }

    def report(self) -> str:
        s = self.summary()
        stab = {None: "not computed", True: "stable", False: "unstable"}[self.stable]
        return (
            f"SteadyState at omega = {self.omega:.6g} rad/s, F = {self.force_amplitude:.6g}\n"
            f"  q_max = {self.q_max:.10g}, fundamental amplitude = {self.amplitude:.10g}, "
            f"phase = {self.phase:.6g} rad\n"
            f"  theta = {s['theta']}\n"
            f"  {stab}; residual {self.residual_norm:.2g} after {self.iterations} Newton iterations "
            f"(H = {self.n_harmonics})"
        )

    def _repr_html_(self):
        return "<pre>" + self.report().replace("&", "&amp;").replace("<", "&lt;") + "</pre>"


@dataclass(frozen=True, eq=False)
class FrequencyResponse:
    """Steady states of a frequency sweep or continuation.

    Attributes
    ----------
    omega : ndarray
        Frequencies [rad/s] in the order computed (not monotonic past a fold).
    q_max : ndarray
        ``max |q|`` of each steady state.
    amplitude, phase : ndarray
        Fundamental amplitude and phase (``q1 = A sin(omega t + phi)``).
    stable : ndarray of bool or None
        Floquet stability (closure frozen), ``None`` when not computed.
    folds : tuple of int
        Indices of fold (turning) points found by continuation (empty for sweeps).
    coefficients : ndarray
        ``(n_points, 2H + 1)`` harmonic vectors of ``q``.
    theta : ndarray
        ``(n_points, n_terms)`` coefficients used at each point.
    force_amplitude : float
    n_harmonics : int
    method : {"sweep", "continuation"}
    residual_norm, iterations : ndarray
    floquet_exponents : ndarray or None
        ``(n_points, 2)`` complex.
    model : SingleModeModel
    """

    omega: np.ndarray
    q_max: np.ndarray
    amplitude: np.ndarray
    phase: np.ndarray
    stable: np.ndarray | None
    folds: tuple
    coefficients: np.ndarray
    theta: np.ndarray
    force_amplitude: float
    n_harmonics: int
    method: str
    residual_norm: np.ndarray
    iterations: np.ndarray
    floquet_exponents: np.ndarray | None = None
    model: SingleModeModel | None = None

    def __len__(self):
        return int(self.omega.size)

    def state(self, i: int) -> SteadyState:
        """The :class:`SteadyState` of point ``i``."""
        i = range(len(self))[i]
        return SteadyState(
            omega=float(self.omega[i]),
            force_amplitude=self.force_amplitude,
            coefficients=self.coefficients[i],
            n_harmonics=self.n_harmonics,
            q_max=float(self.q_max[i]),
            theta=self.theta[i],
            residual_norm=float(self.residual_norm[i]),
            stable=None if self.stable is None else bool(self.stable[i]),
            iterations=int(self.iterations[i]),
            model=self.model,
            floquet_exponents=None if self.floquet_exponents is None else self.floquet_exponents[i],
        )

    @property
    def states(self) -> list:
        """All points as a list of :class:`SteadyState`."""
        return [self.state(i) for i in range(len(self))]

    @property
    def fold_omegas(self) -> np.ndarray:
        return self.omega[list(self.folds)]

    def linear(self, q_max=0.0) -> np.ndarray:
        """Complex linear-part FRF at this response's frequencies (see :func:`linear_frf`)."""
        return linear_frf(self.model, self.omega, self.force_amplitude, q_max=q_max)

    def summary(self) -> dict:
        """JSON-safe dictionary (arrays as lists)."""
        i_peak = int(np.argmax(self.q_max)) if len(self) else None
        return {
            "method": self.method,
            "force_amplitude": self.force_amplitude,
            "n_harmonics": self.n_harmonics,
            "n_points": len(self),
            "omega_range": [float(np.min(self.omega)), float(np.max(self.omega))] if len(self) else None,
            "peak": None if i_peak is None else {"omega": float(self.omega[i_peak]), "q_max": float(self.q_max[i_peak])},
            "folds": [{"index": int(i), "omega": float(self.omega[i]), "q_max": float(self.q_max[i])} for i in self.folds],
            "n_unstable": None if self.stable is None else int(np.count_nonzero(~self.stable)),
            "max_residual": float(np.max(self.residual_norm)) if len(self) else None,
            "omega": self.omega.tolist(),
            "q_max_values": self.q_max.tolist(),
            "amplitude": self.amplitude.tolist(),
            "phase": self.phase.tolist(),
            "stable": None if self.stable is None else self.stable.tolist(),
        }

    def report(self) -> str:
        s = self.summary()
        lines = [
            f"FrequencyResponse ({self.method}) of {len(self)} points, F = {self.force_amplitude:.6g}, "
            f"H = {self.n_harmonics}",
        ]
        if len(self):
            lines.append(
                f"  omega {s['omega_range'][0]:.6g} .. {s['omega_range'][1]:.6g} rad/s; "
                f"peak q_max {s['peak']['q_max']:.6g} at {s['peak']['omega']:.6g} rad/s"
            )
        for f in s["folds"]:
            lines.append(f"  fold at omega = {f['omega']:.8g} rad/s, q_max = {f['q_max']:.6g}")
        if s["n_unstable"] is not None:
            lines.append(f"  {s['n_unstable']} unstable points (Floquet, closure frozen)")
        return "\n".join(lines)

    def _repr_html_(self):
        return "<pre>" + self.report().replace("&", "&amp;").replace("<", "&lt;") + "</pre>"

    def plot(self, ax=None, **kwargs):
        """Plot with :func:`jointid.report.frf_plots.plot_frequency_response`; returns ``(fig, ax)``."""
        from ... import plotting

        return plotting.draw("frf_plots.plot_frequency_response", self, ax=ax, **kwargs)


# ----------------------------------------------------------------------------------------
# The linear part
# ----------------------------------------------------------------------------------------


def linear_frf(model, omega, force_amplitude=1.0, q_max=0.0):
    """Complex response of the model's linear part, ``F / (k - omega^2 + i c omega)``.

    ``k`` is the coefficient of the term ``q`` (``omega1^2``) and ``c`` that of ``q'``,
    both evaluated at ``q_max`` (so an amplitude-dependent damping can be frozen at a
    chosen amplitude); every other term is dropped.  With ``Q = F sin(omega t)`` the
    response is ``q(t) = |X| sin(omega t + angle(X))``.

    Parameters
    ----------
    model : SingleModeModel
    omega : float or array_like
        Frequencies [rad/s].
    force_amplitude : float
    q_max : float or array_like
        Amplitude at which amplitude laws are evaluated (broadcast with ``omega``).

    Returns
    -------
    complex ndarray (or complex scalar)

    Examples
    --------
    >>> from jointid.simulate.model import seed_model
    >>> X = linear_frf(seed_model(), 170.0)
    >>> round(float(abs(X)), 6)       # 1 / (c0 * omega1)
    0.073529
    """
    omega = np.asarray(omega, float)
    qm = np.asarray(q_max, float)
    names = model.terms.names
    i_q = names.index("q") if "q" in names else None
    i_v = names.index("q'") if "q'" in names else None
    if qm.ndim == 0:
        theta = model.coefficients_at(float(qm))
        k = theta[i_q] if i_q is not None else 0.0
        c = theta[i_v] if i_v is not None else 0.0
    else:
        thetas = np.array([model.coefficients_at(float(a)) for a in qm.ravel()]).reshape(qm.shape + (len(names),))
        k = thetas[..., i_q] if i_q is not None else 0.0
        c = thetas[..., i_v] if i_v is not None else 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        out = force_amplitude / (k - omega**2 + 1j * c * omega)
    return out[()] if np.ndim(out) == 0 else out
