"""Measured-looking steady-state records synthesised from a harmonic-balance solution.

The seed paper's identification (section 4) uses, at each excitation frequency, the
steady-state acceleration and the applied force over the same time interval.
:func:`synthesize_record` samples both from a :class:`~jointid.simulate.hbm.SteadyState`
at any start time and for any duration (a non-integer number of periods is allowed),
optionally with independent white Gaussian noise on each channel.

Examples
--------
>>> from jointid.simulate.model import seed_model
>>> from jointid.simulate.hbm import steady_state
>>> s = steady_state(seed_model(), 168.0, 1.0)
>>> t, Q, qdd = synthesize_record(s, fs=5000.0, duration=0.1, noise=0.01, rng=1)
>>> t.shape == Q.shape == qdd.shape == (500,)
True
"""

from __future__ import annotations

import numpy as np

from ..errors import RecordError

__all__ = ["synthesize_record"]


def _rms(x):
    return float(np.sqrt(np.mean(np.square(x)))) if x.size else 0.0


def synthesize_record(state, fs, duration, t0=0.0, noise=0.0, rng=None):
    """Sample the force and acceleration of a steady state, optionally with noise.

    Parameters
    ----------
    state : SteadyState
        Periodic solution (its ``force(t)`` and ``acceleration(t)`` are sampled).
    fs : float
        Sampling frequency [Hz].
    duration : float
        Record length [s]; ``round(duration * fs)`` samples are taken (need not be a
        whole number of periods).
    t0 : float, default 0
        Time of the first sample [s] (the force is ``F sin(omega t)`` in absolute time,
        so ``t0`` sets the phase at which the record starts).
    noise : float, default 0
        Standard deviation of white Gaussian noise added to each channel, as a fraction
        of that channel's RMS value; force and acceleration get independent draws.
    rng : numpy.random.Generator, int or None
        Source of the noise (passed to :func:`numpy.random.default_rng`); give a seed or
        a seeded generator for reproducible records.

    Returns
    -------
    t : ndarray
        Sample times ``t0 + n / fs`` [s].
    Q : ndarray
        Applied force.
    qdd : ndarray
        Modal acceleration.

    Raises
    ------
    jointid.errors.RecordError
        On a non-positive sampling frequency or duration, a negative noise level, or a
        record shorter than two samples.
    """
    for name, value in (("fs", fs), ("duration", duration)):
        if not (np.isfinite(value) and value > 0):
            raise RecordError(f"{name} must be a positive finite number, got {value!r}")
    if not (np.isfinite(t0)):
        raise RecordError(f"t0 must be finite, got {t0!r}")
    if not (np.isfinite(noise) and noise >= 0):
        raise RecordError(f"noise must be a non-negative fraction of the RMS, got {noise!r}")
    n = int(round(float(duration) * float(fs)))
    if n < 2:
        raise RecordError(f"duration * fs gives {n} samples; at least 2 are needed (duration={duration}, fs={fs})")
    t = float(t0) + np.arange(n) / float(fs)
    Q = np.asarray(state.force(t), float)
    qdd = np.asarray(state.acceleration(t), float)
    if noise > 0:
        gen = np.random.default_rng(rng)
        Q = Q + noise * _rms(Q) * gen.standard_normal(n)
        qdd = qdd + noise * _rms(qdd) * gen.standard_normal(n)
    return t, Q, qdd
