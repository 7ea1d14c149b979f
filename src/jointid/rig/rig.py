"""The virtual bolted-beam test rig of the seed paper (section 5, Figs 7-8, Table 4).

A :class:`VirtualRig` is one bolt preload of the seed's jointed cantilever:

* the finite element beam of :mod:`jointid.modal` whose joint springs and clamp were
  updated to the Table 4 frequencies of that preload (the joint stuck, so its springs
  include the small-amplitude stiffness ``K_T`` of the joint law);
* a physical nonlinear joint law (:class:`~jointid.rig.iwan.JointLaw`: Iwan micro-slip
  plus cubic stiffness) on the relative rotation and/or deflection of the joint nodes;
* modal damping of the beam (material and clamp), ``n_modes`` modes kept;
* a shaker force at 5 cm measured by a force cell, accelerometers at 30 and 42 cm,
  white sensor noise, an ideal anti-aliasing filter and an optional harmonic
  distortion of the shaker force.

Tests (seed section 5): :meth:`VirtualRig.random_test` (low-level random excitation,
linear FRFs) and :meth:`VirtualRig.stepped_sine` (dwells at constant force amplitude
around mode 1, each recorded after a settle check).  The steady states come from
multi-harmonic balance of the reduced model (:mod:`jointid.rig.reduced`) and the
records are sampled from them; ``docs/demo.md`` gives the measurements behind that
choice.  :func:`seed_rig` builds the two preloads of the paper.
"""

from __future__ import annotations

import html
import math
import warnings
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Mapping

import numpy as np
import scipy.signal

from ..errors import ConvergenceError, ConvergenceWarning, StructureError
from ..io.channels import Channels
from ..modal.analysis import ModalModel, modal_analysis
from ..modal.beam import SEED_GEOMETRY, JointedBeam, seed_bolted_beam
from ..numerics.peaks import parabolic_peak, refine_peak  # noqa: F401 (refine_peak re-exported: jointid.rig.rig.refine_peak)
from ..simulate.nlmodes import epmc_backbone
from ..simulate.structure_hb import warm_sweep
from .iwan import IwanParameters, JointLaw
from .reduced import JOINT_DIRECTIONS, ReducedModel, RigSteadyState, sample_series, settle_check

__all__ = [
    "Acquisition",
    "RandomTest",
    "Dwell",
    "RigFRF",
    "VirtualRig",
    "SEED_RIG_JOINTS",
    "SEED_SENSORS",
    "SEED_RIG_DAMPING",
    "seed_rig",
]

#: Accelerometer columns and positions [m] of the seed (section 5, Fig 8).
SEED_SENSORS: Mapping[str, float] = MappingProxyType({"accel_30": 0.30, "accel_42": 0.42})

#: Joint laws of the seed rig per preload [N]: on the relative rotation, a moment [N m]
#: of the relative rotation [rad].  ``K_T`` is the fraction ``stuck_fraction`` of the
#: updated rotational joint stiffness (the rest is the elastic bolt and plates).  The
#: macro-slip moment grows with the preload (Coulomb: ``F_S ~ mu N r``) so the 120 N
#: joint is the more nonlinear one.
SEED_RIG_JOINTS: Mapping[int, Mapping[str, float]] = MappingProxyType(
    {
        120: MappingProxyType({"F_S": 16.0, "stuck_fraction": 0.8, "chi": -0.3, "beta": 0.4, "k3": 1.5e7}),
        540: MappingProxyType({"F_S": 40.0, "stuck_fraction": 0.8, "chi": -0.3, "beta": 0.4, "k3": 0.4e7}),
    }
)

#: Modal damping ratio of the beam (material and clamp) in the seed rig.
SEED_RIG_DAMPING = 0.0015


@dataclass(frozen=True)
class Acquisition:
    """How the rig samples its channels.

    Parameters
    ----------
    fs : float
        Sample rate [Hz].
    duration : float
        Length of a stepped-sine record [s].
    force_noise : float
        RMS of the force-cell noise [N].
    accel_noise : float
        RMS of each accelerometer's noise [m/s^2].
    antialias : float
        Cut-off of the ideal anti-aliasing filter as a fraction of ``fs`` (harmonics of a
        steady state above it are not recorded).
    distortion : tuple of (int, float, float)
        Shaker force distortion: ``(harmonic k, amplitude relative to F, phase [rad])``
        added to ``F sin(omega t)`` as ``F a sin(k omega t + phase)``; the force cell
        measures the distorted force.
    settle_periods : int
        Periods integrated in time from each harmonic-balance orbit by the settle check.
    settle_tol : float
        Largest relative deviation of the settle check.
    """

    fs: float = 2048.0
    duration: float = 2.0
    force_noise: float = 0.005
    accel_noise: float = 0.1
    antialias: float = 0.45
    distortion: tuple = ()
    settle_periods: int = 6
    settle_tol: float = 5e-3

    def __post_init__(self):
        for name in ("fs", "duration"):
            v = float(getattr(self, name))
            if not (math.isfinite(v) and v > 0):
                raise StructureError(f"acquisition {name}: expected a positive number, got {getattr(self, name)!r}")
            object.__setattr__(self, name, v)
        for name in ("force_noise", "accel_noise"):
            v = float(getattr(self, name))
            if not (math.isfinite(v) and v >= 0):
                raise StructureError(f"acquisition {name}: expected a number >= 0, got {getattr(self, name)!r}")
            object.__setattr__(self, name, v)
        if not 0 < self.antialias <= 0.5:
            raise StructureError(f"acquisition antialias: expected a fraction in (0, 0.5], got {self.antialias!r}")
        object.__setattr__(self, "distortion", tuple(tuple(d) for d in self.distortion))
        for d in self.distortion:
            if len(d) != 3 or int(d[0]) < 2:
                raise StructureError(f"acquisition distortion: expected (harmonic >= 2, amplitude, phase), got {d!r}")

    def summary(self) -> dict:
        return {
            "fs": self.fs,
            "duration": self.duration,
            "force_noise": self.force_noise,
            "accel_noise": self.accel_noise,
            "antialias_hz": self.antialias * self.fs,
            "distortion": [list(d) for d in self.distortion],
            "settle_periods": self.settle_periods,
            "settle_tol": self.settle_tol,
        }


@dataclass(frozen=True)
class RandomTest:
    """Low-level random excitation (seed section 5, first stage).

    Parameters
    ----------
    force_rms : float
        RMS of the shaker force [N].
    band_hz : float
        Upper edge of the flat force spectrum [Hz].
    duration : float
        Record length [s].
    fs : float
        Sample rate of the record [Hz] (simulated 2x faster and decimated).
    nperseg : int
        Welch segment of the H1 estimate.
    """

    force_rms: float = 0.1
    band_hz: float = 700.0
    duration: float = 128.0
    fs: float = 2048.0
    nperseg: int = 65536

    def summary(self) -> dict:
        return {"force_rms": self.force_rms, "band_hz": self.band_hz, "duration": self.duration, "fs": self.fs,
                "nperseg": self.nperseg}


@dataclass(frozen=True, eq=False)
class Dwell:
    """One stepped-sine dwell: the steady state, the record and its settle check."""

    frequency_hz: float
    force_level: float
    state: RigSteadyState | None = field(repr=False)
    record: Channels = field(repr=False)
    settle_deviation: float
    settled: bool

    def summary(self) -> dict:
        return {
            "frequency_hz": self.frequency_hz,
            "force_level": self.force_level,
            "settle_deviation": self.settle_deviation,
            "settled": self.settled,
            "hbm_iterations": None if self.state is None else self.state.iterations,
            "hbm_residual": None if self.state is None else self.state.residual_norm,
        }


@dataclass(frozen=True, eq=False)
class RigFRF:
    """Steady-state (fundamental) response of the rig at a sensor per unit force amplitude.

    Attributes
    ----------
    frequency_hz : ndarray
    H : ndarray, complex
        Fundamental of the sensor acceleration divided by the force amplitude
        [(m/s^2)/N], ``a1 = |H| F sin(omega t + angle)`` convention of the harmonics.
    force_level : float
    sensor : str
    joint_amplitude : ndarray
        Largest joint relative motion of each steady state.
    """

    frequency_hz: np.ndarray
    H: np.ndarray
    force_level: float
    sensor: str
    joint_amplitude: np.ndarray

    def peak(self) -> tuple[float, float]:
        """``(frequency [Hz], |H|)`` of the peak, refined by a parabola through the 3 top points."""
        return parabolic_peak(self.frequency_hz, np.abs(self.H))

    def summary(self) -> dict:
        fp, hp = self.peak()
        return {"force_level": self.force_level, "sensor": self.sensor, "peak_frequency_hz": fp, "peak_magnitude": hp,
                "frequency_hz": self.frequency_hz.tolist(), "magnitude": np.abs(self.H).tolist()}


@dataclass(frozen=True, eq=False)
class VirtualRig:
    """One bolt preload of the virtual bolted-beam rig.

    Parameters
    ----------
    preload : float
        Bolt preload [N] (a label; the physics is in ``beam`` and ``joint_laws``).
    beam : JointedBeam
        Linear structure with the joint stuck: its joint springs include the ``K_T`` of
        every joint law.
    joint_laws : mapping str -> JointLaw
        ``{"rotation": law}`` and/or ``{"transverse": law}`` (relative rotation or
        deflection of the joint nodes, right minus left).
    damping_ratio : float or sequence
        Modal damping ratio(s) of the beam (material and clamp).
    n_modes : int
        Modes kept in the reduced model.
    force_position : float
        Shaker position [m].
    sensors : mapping str -> float
        Accelerometer column names and positions [m].
    harmonics_to_hz : float
        Harmonic balance keeps harmonics up to this frequency (default 1.5 x the highest
        kept mode) so that the higher modes' response to the joint's harmonics is in the
        records.

    Attributes
    ----------
    modes : ModalModel
        Modes of the stuck-joint beam.
    model : ReducedModel
    """

    preload: float
    beam: JointedBeam
    joint_laws: Mapping[str, JointLaw]
    damping_ratio: float | tuple = SEED_RIG_DAMPING
    n_modes: int = 4
    force_position: float = SEED_GEOMETRY["force_position"]
    sensors: Mapping[str, float] = field(default_factory=lambda: dict(SEED_SENSORS))
    harmonics_to_hz: float | None = None
    modes: ModalModel = field(init=False, repr=False, default=None)
    model: ReducedModel = field(init=False, repr=False, default=None)

    def __post_init__(self):
        laws = dict(self.joint_laws)
        if not laws:
            raise StructureError("joint_laws: at least one joint law is needed")
        for d, law in laws.items():
            if d not in JOINT_DIRECTIONS:
                raise StructureError(f"joint_laws: unknown direction {d!r}; expected {sorted(JOINT_DIRECTIONS)}")
            if not isinstance(law, JointLaw):
                raise StructureError(f"joint_laws[{d!r}]: expected a JointLaw, got {type(law).__name__}")
        object.__setattr__(self, "joint_laws", MappingProxyType(laws))
        object.__setattr__(self, "sensors", MappingProxyType(dict(self.sensors)))
        modes = modal_analysis(self.beam, int(self.n_modes))
        dw, dth = modes.fe.relative_motion(modes.shapes)
        rel = {"transverse": dw, "rotation": dth}
        dirs = tuple(laws)
        zeta = np.broadcast_to(np.asarray(self.damping_ratio, float), (modes.n_modes,))
        names = tuple(self.sensors)
        model = ReducedModel(
            omega=modes.omega,
            zeta=zeta,
            force_shape=modes.shape_at([self.force_position])[0],
            joint_shapes=np.array([rel[d] for d in dirs]),
            sensor_shapes=modes.shape_at([self.sensors[n] for n in names]),
            sensor_names=names,
            laws=tuple(laws[d] for d in dirs),
            directions=dirs,
        )
        object.__setattr__(self, "modes", modes)
        object.__setattr__(self, "model", model)

    # --- properties -------------------------------------------------------------------
    @property
    def linear_frequencies_hz(self) -> np.ndarray:
        """Natural frequencies of the stuck (small-amplitude) rig [Hz]."""
        return self.modes.frequencies_hz

    @property
    def modal_cubic_coefficient(self) -> float:
        """``k3`` of the first mode due to the joint laws' cubic parts (seed sign, per unit q)."""
        psi = self.model.joint_shapes[:, 0]
        return float(sum(law.k3 * p**4 for law, p in zip(self.model.laws, psi)))

    def n_harmonics_for(self, frequency_hz: float) -> int:
        """Harmonics kept by harmonic balance at an excitation frequency."""
        top = self.harmonics_to_hz or 1.5 * float(self.linear_frequencies_hz[-1])
        return int(max(9, math.ceil(top / float(frequency_hz))))

    def force_coefficients(self, force_amplitude, distortion=()) -> np.ndarray:
        """Harmonic coefficients of ``F sin(w t) + sum F a_k sin(k w t + p_k)``."""
        H = max([1] + [int(d[0]) for d in distortion])
        c = np.zeros(2 * H + 1)
        c[2] = force_amplitude
        for k, a, p in distortion:
            k = int(k)
            c[2 * k - 1] += force_amplitude * a * np.sin(p)
            c[2 * k] += force_amplitude * a * np.cos(p)
        return c

    # --- simulation -------------------------------------------------------------------
    def steady_state(self, frequency_hz, force_amplitude, *, distortion=(), guess=None) -> RigSteadyState:
        """Periodic steady state at one excitation frequency (multi-harmonic balance)."""
        return self.model.harmonic_balance(
            2 * np.pi * float(frequency_hz), self.force_coefficients(force_amplitude, distortion),
            self.n_harmonics_for(frequency_hz), guess=guess,
        )

    def sweep(self, frequencies_hz, force_amplitude, *, distortion=()) -> list:
        """Steady states over a frequency list, each started from its neighbours (secant,
        :func:`jointid.simulate.structure_hb.warm_sweep`)."""
        return warm_sweep(lambda f, guess: self.steady_state(f, force_amplitude, distortion=distortion, guess=guess),
                          frequencies_hz, lambda p: p.frequency_hz)

    def record(self, state: RigSteadyState, acquisition: Acquisition, rng, source: str = "") -> Channels:
        """Sample the force cell and accelerometers of a steady state (``t = 0 .. duration``).

        Harmonics above the anti-aliasing cut-off are left out, then white noise is added.
        """
        rng = np.random.default_rng(rng)
        fs = acquisition.fs
        n = int(round(acquisition.duration * fs))
        dt = 1.0 / fs
        keep = harmonic_mask(state.n_harmonics, state.frequency_hz, acquisition.antialias * fs)
        last = int(np.flatnonzero(keep)[-1]) + 1  # the coefficients below the cut-off: [:last]
        force = sample_series(state.force[:last], state.omega, n, dt)
        acc = sample_series(self.model.sensor_shapes @ state.modal[:, :last], state.omega, n, dt, derivative=2)
        force = force + acquisition.force_noise * rng.standard_normal(n)
        acc = acc + acquisition.accel_noise * rng.standard_normal(acc.shape)
        data = {"force": force}
        data.update({name: acc[i] for i, name in enumerate(self.model.sensor_names)})
        units = {"force": "N", **{name: "m/s^2" for name in self.model.sensor_names}}
        return Channels.from_arrays(data, fs=fs, units=units, source=source,
                                    meta={"preload": self.preload, "frequency_hz": state.frequency_hz})

    def stepped_sine(self, frequencies_hz, force_amplitude, acquisition: Acquisition | None = None, rng=None,
                     *, settle: bool = True, method: str = "hbm", **time_options) -> tuple:
        """Stepped-sine dwells at constant force amplitude (seed section 5, second stage).

        Parameters
        ----------
        frequencies_hz : array_like
            Dwell frequencies, in the order of the sweep.
        force_amplitude : float
            ``F`` [N] of the shaker force ``F sin(omega t)`` (plus any distortion).
        acquisition : Acquisition, optional
        rng : seed or numpy Generator
            Source of the sensor noise.
        settle : bool
            Run the settle check (``method="hbm"``).
        method : {"hbm", "time"}
            ``"hbm"`` (default): each dwell is the harmonic-balance steady state (swept in
            the given order), checked for settling by a time integration of
            ``acquisition.settle_periods`` periods started on its orbit, then sampled.
            ``"time"``: every dwell is integrated in time from rest (vectorised over the
            dwells) until its response stops changing, then recorded; see
            :meth:`stepped_sine_time` (slow: kept to measure the choice, docs/demo.md).

        Returns
        -------
        tuple of Dwell
        """
        acquisition = acquisition or Acquisition()
        rng = np.random.default_rng(rng)
        if method == "time":
            return self.stepped_sine_time(frequencies_hz, force_amplitude, acquisition, rng, **time_options)
        if method != "hbm":
            raise StructureError(f"stepped_sine method: expected 'hbm' or 'time', got {method!r}")
        states = self.sweep(frequencies_hz, force_amplitude, distortion=acquisition.distortion)
        if settle:
            dev = settle_check(self.model, states, n_periods=acquisition.settle_periods,
                               steps_per_period=1024)
        else:
            dev = np.full(len(states), np.nan)
        bad = np.flatnonzero(dev > acquisition.settle_tol)
        if bad.size:
            warnings.warn(
                f"preload {self.preload}, F = {force_amplitude}: {bad.size} dwell(s) did not pass the settle check "
                f"(largest deviation {100 * np.nanmax(dev):.3g} % > {100 * acquisition.settle_tol:g} %)",
                ConvergenceWarning, stacklevel=2,
            )
        return tuple(
            Dwell(s.frequency_hz, float(force_amplitude), s, self.record(s, acquisition, rng),
                  float(d), bool(not settle or d <= acquisition.settle_tol))
            for s, d in zip(states, dev)
        )

    def stepped_sine_time(self, frequencies_hz, force_amplitude, acquisition: Acquisition | None = None, rng=None,
                          *, substeps: int = 8, chunk: float = 1.0, max_time: float = 120.0) -> tuple:
        """Stepped sine by time integration from rest (the alternative to harmonic balance).

        All dwells are integrated at once (:func:`jointid.rig.reduced.integrate`, step
        ``1 / (fs * substeps)``) in chunks of ``chunk`` seconds; a dwell has settled when the
        largest ``|accel|`` at the last sensor changes by less than ``acquisition.settle_tol``
        (relative) from one chunk to the next.  Then ``acquisition.duration`` seconds are
        recorded.  Dwells carry ``state=None``.
        """
        from .reduced import integrate

        acquisition = acquisition or Acquisition()
        rng = np.random.default_rng(rng)
        f = np.asarray(frequencies_hz, float)
        w = 2 * np.pi * f
        fc = self.force_coefficients(force_amplitude, acquisition.distortion)
        forces = np.tile(fc, (f.size, 1))
        dt = 1.0 / (acquisition.fs * int(substeps))
        init, t, prev = None, 0.0, None
        change = np.full(f.size, np.inf)
        while t < max_time:
            traj = integrate(self.model, w, forces, t + chunk, dt, initial=init, sample_every=int(substeps))
            peak = np.max(np.abs(traj.accel[:, -1, :]), axis=-1)
            if prev is not None:
                change = np.abs(peak - prev) / peak
            prev, init, t = peak, traj.final, t + chunk
            if np.all(change < acquisition.settle_tol):
                break
        traj = integrate(self.model, w, forces, t + acquisition.duration, dt, initial=init,
                         sample_every=int(substeps))
        n = int(round(acquisition.duration * acquisition.fs))
        out = []
        for i in range(f.size):
            data = {"force": traj.force[i, :n] + acquisition.force_noise * rng.standard_normal(n)}
            for j, name in enumerate(self.model.sensor_names):
                data[name] = traj.accel[i, j, :n] + acquisition.accel_noise * rng.standard_normal(n)
            units = {"force": "N", **{name: "m/s^2" for name in self.model.sensor_names}}
            rec = Channels.from_arrays(data, fs=acquisition.fs, units=units,
                                       meta={"preload": self.preload, "frequency_hz": float(f[i]), "settle_time": t})
            out.append(Dwell(float(f[i]), float(force_amplitude), None, rec, float(change[i]),
                             bool(change[i] < acquisition.settle_tol)))
        return tuple(out)

    def nonlinear_frf(self, frequencies_hz, force_amplitude, sensor="accel_42", *, distortion=()) -> RigFRF:
        """The rig's exact steady-state FRF (fundamental) at a sensor over a frequency grid."""
        states = self.sweep(frequencies_hz, force_amplitude, distortion=distortion)
        i = self.model.sensor_names.index(sensor)
        H = np.array([-(s.omega**2) * (self.model.sensor_shapes[i] @ (s.modal[:, 1] - 1j * s.modal[:, 2]))
                      for s in states]) / force_amplitude
        amp = np.array([np.max(np.abs(s.joint_at(np.linspace(0, 1 / s.frequency_hz, 257)))) for s in states])
        return RigFRF(np.asarray(frequencies_hz, float), H, float(force_amplitude), sensor, amp)

    # --- backbone and ring-down ----------------------------------------------------------
    def backbone(self, amplitudes, n_harmonics: int = 9, n_time: int = 256, tol: float = 1e-11):
        """The rig's exact backbone of mode 1: damped nonlinear modes of the reduced model.

        For each first-harmonic amplitude ``a`` of the modal coordinate ``eta_1`` the periodic
        motion of ``eta'' + (2 zeta Omega - xi) eta' + Omega^2 eta + Psi^T f_nl(Psi eta) = 0``
        (all ``n_modes`` modes, ``n_harmonics`` harmonics, joint force by AFT with its exact
        Jacobian) is solved for the harmonics, the frequency ``omega`` and the damping ``xi``
        that makes it periodic (the extended periodic motion concept, Krack 2015), with
        ``eta_1 = a cos(omega t) + higher harmonics``; ``zeta = xi / (2 omega)``.  The solver
        is the engine's, :func:`jointid.simulate.nlmodes.epmc_backbone` on
        :meth:`ReducedModel.engine` (condensed on the joint coordinates, continued over the
        amplitudes in the given order).

        Parameters
        ----------
        amplitudes : array_like
            First-harmonic amplitudes of ``eta_1``, positive (continued in the given order).
        n_harmonics, n_time : int
        tol : float
            On the relative residual of the condensed equations.

        Returns
        -------
        Backbone
            ``source = "rig"``, zero standard errors.

        Raises
        ------
        ConvergenceError
            When an amplitude cannot be reached (the message names it).
        """
        from ..identify.backbone import Backbone

        a_list = np.atleast_1d(np.asarray(amplitudes, float))
        try:
            bb = epmc_backbone(self.model.engine(), 0, a_list, int(n_harmonics), n_time=int(n_time), tol=tol,
                               max_iter=60)
        except ConvergenceError as exc:
            raise ConvergenceError(f"rig backbone: {exc}") from None
        return Backbone(a_list, bb.omega, bb.damping_ratio, 0.0, 0.0, "rig", 0.0,
                        f"virtual rig, preload {self.preload:g} N",
                        {"n_harmonics": int(n_harmonics), "n_modes": self.model.n_modes})

    def phase_resonance(self, force_amplitude, band=(0.97, 1.01)) -> RigSteadyState:
        """The steady state in phase resonance at a force level: ``eta_1`` in quadrature with the force."""
        from scipy import optimize

        f1 = float(self.linear_frequencies_hz[0])

        def g(f):
            return self.steady_state(f, force_amplitude).modal[0, 2]  # sin part of eta_1: zero in quadrature

        f = optimize.brentq(g, band[0] * f1, band[1] * f1, xtol=1e-10)
        return self.steady_state(f, force_amplitude)

    def ringdown(self, force_amplitudes, duration, acquisition: Acquisition | None = None, rng=None, *,
                 substeps: int = 8, source: str = "") -> tuple:
        """Ring-down tests: the shaker drives mode 1 in phase resonance, then is released at ``t = 0``.

        Each free decay starts on the periodic orbit of harmonic balance (the joint's
        hysteretic state included) and is integrated in time (:func:`~jointid.rig.reduced.integrate`,
        ``substeps`` steps per sample, all release levels at once) with no force.  The force
        cell then reads only its noise; the accelerometers get theirs.

        Parameters
        ----------
        force_amplitudes : float or sequence of float
            Shaker force amplitude [N] before each release.
        duration : float
            Record length after the release [s].
        acquisition : Acquisition, optional
        rng : seed or numpy Generator
        substeps : int
        source : str

        Returns
        -------
        tuple of (Channels, RigSteadyState)
            Per release level: the record (``force`` and the accelerometers; ``meta`` has
            the release force and frequency) and the steady state at the release.
        """
        from .reduced import integrate

        acquisition = acquisition or Acquisition()
        rng = np.random.default_rng(rng)
        levels = np.atleast_1d(np.asarray(force_amplitudes, float))
        states = [self.phase_resonance(F) for F in levels]
        fs = acquisition.fs
        n = int(round(float(duration) * fs))
        eta, vel, js = self.model.initial_conditions(states)
        traj = integrate(self.model, [s.omega for s in states], np.zeros((levels.size, 3)), n / fs,
                         1.0 / (fs * int(substeps)), initial=(0.0, eta, vel, js), sample_every=int(substeps))
        units = {"force": "N", **{name: "m/s^2" for name in self.model.sensor_names}}
        out = []
        for i, (F, s) in enumerate(zip(levels, states)):
            data = {"force": acquisition.force_noise * rng.standard_normal(n)}
            for j, name in enumerate(self.model.sensor_names):
                data[name] = traj.accel[i, j, :n] + acquisition.accel_noise * rng.standard_normal(n)
            rec = Channels.from_arrays(data, fs=fs, units=units, source=source,
                                       meta={"preload": self.preload, "test": "ringdown", "release_force": float(F),
                                             "release_frequency_hz": s.frequency_hz})
            out.append((rec, s))
        return tuple(out)

    def random_test(self, test: RandomTest | None = None, acquisition: Acquisition | None = None, rng=None,
                    source: str = "") -> Channels:
        """Low-level random excitation of the stuck structure (seed section 5, Fig 9).

        At the random level the joint stays in its linear range (its largest relative
        motion is printed by :meth:`random_linearity`), so the response is that of the
        stuck modes, simulated exactly (first-order hold) at 2 x the record rate,
        decimated with an anti-aliasing filter, then given the sensor noise.
        """
        from ..signal.frf import simulate_modal_response

        test = test or RandomTest()
        acquisition = acquisition or Acquisition()
        rng = np.random.default_rng(rng)
        q = 2
        fs_sim = q * test.fs
        n = int(round(test.duration * test.fs)) * q
        white = rng.standard_normal(n + 4096)
        b, a = scipy.signal.butter(8, test.band_hz / (fs_sim / 2))
        force = scipy.signal.lfilter(b, a, white)[4096:]
        force *= test.force_rms / np.std(force)
        m = self.model
        keep = m.omega < np.pi * fs_sim
        resp = simulate_modal_response(m.omega[keep], m.zeta[keep], m.force_shape[keep], m.sensor_shapes[:, keep],
                                       force, fs_sim, output="acceleration")
        sig = np.vstack([force, resp.response])
        dec = scipy.signal.decimate(sig, q, ftype="fir", zero_phase=True, axis=-1)
        dec[0] += acquisition.force_noise * rng.standard_normal(dec.shape[1])
        dec[1:] += acquisition.accel_noise * rng.standard_normal(dec[1:].shape)
        # the joint's largest relative motion during the test, for the linearity check
        u = m.joint_shapes[:, keep] @ resp.q
        data = {"force": dec[0]}
        data.update({name: dec[1 + i] for i, name in enumerate(m.sensor_names)})
        units = {"force": "N", **{name: "m/s^2" for name in m.sensor_names}}
        return Channels.from_arrays(data, fs=test.fs, units=units, source=source,
                                    meta={"preload": self.preload, "test": "random",
                                          "joint_max": np.max(np.abs(u), axis=-1).tolist(),
                                          "joint_rms": np.std(u, axis=-1).tolist()})

    def random_linearity(self, joint_max) -> list:
        """Secant stiffness loss of each joint law at the largest random-test motion (fraction of ``K_T``)."""
        out = []
        for law, u in zip(self.model.laws, np.atleast_1d(joint_max)):
            if law.iwan is None:
                out.append(0.0)
                continue
            f = law.iwan.backbone(u) - law.k3 * u**3
            out.append(float(1.0 - f / (law.linear_stiffness * u)))
        return out

    def summary(self) -> dict:
        return {
            "preload": self.preload,
            "linear_frequencies_hz": self.linear_frequencies_hz.tolist(),
            "damping_ratio": np.broadcast_to(np.asarray(self.damping_ratio, float), (self.modes.n_modes,)).tolist(),
            "n_modes": self.modes.n_modes,
            "force_position": self.force_position,
            "sensors": dict(self.sensors),
            "joint": {"k_w": self.beam.joint.k_w, "k_t": self.beam.joint.k_t, "clamp_stiffness": self.beam.clamp_stiffness},
            "joint_laws": {d: law.summary() for d, law in self.joint_laws.items()},
            "modal_cubic_coefficient": self.modal_cubic_coefficient,
            "joint_shape_mode1": self.model.joint_shapes[:, 0].tolist(),
            "force_shape_mode1": float(self.model.force_shape[0]),
        }

    def report(self) -> str:
        lines = [f"Virtual rig, preload {self.preload} N: stuck frequencies "
                 + ", ".join(f"{f:.2f}" for f in self.linear_frequencies_hz) + " Hz"]
        for d, law in self.joint_laws.items():
            lines.append(f"  {d}: {law.report()}")
        return "\n".join(lines)

    def _repr_html_(self) -> str:
        return f"<pre>{html.escape(self.report())}</pre>"


def harmonic_mask(n_harmonics: int, frequency_hz: float, cutoff_hz: float) -> np.ndarray:
    """Coefficient mask (length 2H+1) keeping the constant and the harmonics below ``cutoff_hz``."""
    k = np.zeros(2 * n_harmonics + 1)
    k[1::2] = np.arange(1, n_harmonics + 1)
    k[2::2] = np.arange(1, n_harmonics + 1)
    return (k * frequency_hz < cutoff_hz).astype(float)


def seed_rig(preload: int = 120, *, joint: Mapping[str, float] | None = None, damping_ratio=SEED_RIG_DAMPING,
             n_modes: int = 4, n_elements: int = 100) -> VirtualRig:
    """The virtual rig of the seed paper at bolt preload 120 or 540 N.

    The beam is :func:`~jointid.modal.beam.seed_bolted_beam` updated to the Table 4
    frequencies of the preload (joint ``k_w, k_t`` and clamp ``k_c``); the joint law acts on
    the relative rotation with the parameters of :data:`SEED_RIG_JOINTS` (or ``joint``).

    Parameters
    ----------
    preload : {120, 540}
    joint : mapping, optional
        ``F_S``, ``stuck_fraction`` (``K_T`` as a fraction of the updated ``k_t``), ``chi``,
        ``beta``, ``k3`` overriding :data:`SEED_RIG_JOINTS`.
    damping_ratio : float
        Modal damping of the beam.
    n_modes : int
    n_elements : int
        Jenkins elements of the Iwan joint.

    Examples
    --------
    >>> rig = seed_rig(120)
    >>> np.round(rig.linear_frequencies_hz[:3], 2)
    array([ 26.4, 157.6, 471.8])
    """
    try:
        base = dict(SEED_RIG_JOINTS[int(preload)])
    except (KeyError, TypeError, ValueError):
        raise StructureError(f"seed rig preload: expected one of {sorted(SEED_RIG_JOINTS)} N, got {preload!r}") from None
    base.update(joint or {})
    beam = seed_bolted_beam(int(preload))
    K_T = base["stuck_fraction"] * beam.joint.k_t
    law = JointLaw(IwanParameters(base["F_S"], K_T, base["chi"], base["beta"]), k3=base["k3"], n_elements=n_elements)
    return VirtualRig(float(preload), beam, {"rotation": law}, damping_ratio=damping_ratio, n_modes=n_modes)

