"""Conventions shared by the whole package (read this first).

Units
    SI throughout: seconds, newtons, metres, kilograms.  Modal quantities use the
    mass-normalised first mode, so the modal mass is one and ``omega1`` is in rad/s.
    Frequencies named ``*_hz`` are in hertz, everything named ``omega*`` is in rad/s.

Time axis
    Time is the last axis of every signal array (scipy.signal's ``axis=-1``).

Single-mode equation of motion (seed paper Eq 14, 19, 25)
    ``q'' + h(q, q') = Q(t)`` where the restoring force ``h`` is a sum of named terms
    times coefficients.  With the seed's terms
    ``h(q, q') = omega1^2 q - k3 q^3 + c q'`` so ``k3 > 0`` is softening.

Excitation
    The simulated single-frequency force is ``Q(t) = F sin(omega t)`` (seed Eq 19).

Harmonic coefficients
    A periodic signal truncated to ``H`` harmonics is stored as the real vector
    ``[a0, a1, b1, a2, b2, ..., aH, bH]`` with
    ``x(t) = a0 + sum_k a_k cos(k omega t) + b_k sin(k omega t)``.

Regression matrices
    ``(n_samples, n_terms)``; coefficient vectors follow the order of the term library.

Amplitude ``q_max``
    The largest ``|q(t)|`` over one steady-state period of the reconstructed
    (harmonic-series) displacement, found to machine precision, not on the sample grid.
"""

from __future__ import annotations

import numpy as np

__all__ = ["harmonic_index", "n_coefficients"]


def n_coefficients(n_harmonics: int) -> int:
    """Length of a harmonic coefficient vector with ``n_harmonics`` harmonics."""
    return 2 * n_harmonics + 1


def harmonic_index(n_harmonics: int) -> np.ndarray:
    """Harmonic number ``k`` of each entry of a coefficient vector (0, 1, 1, 2, 2, ...)."""
    k = np.zeros(n_coefficients(n_harmonics), dtype=int)
    k[1::2] = np.arange(1, n_harmonics + 1)
    k[2::2] = np.arange(1, n_harmonics + 1)
    return k
