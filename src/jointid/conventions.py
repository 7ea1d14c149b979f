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

Restoring-force terms (:data:`TERMS`)
    Every standard term ``phi(q, q')`` enters ``h = sum theta phi`` with the sign written in
    its name, so its coefficient's sign means the same thing everywhere: ``k3 > 0`` in
    ``-q^3`` softens, ``k5 > 0`` in ``q^5`` hardens, every damping coefficient ``> 0``
    dissipates.  With the modal mass one (kg) ``q`` is in m and ``h``, ``Q`` in m/s^2 (N per
    kg of modal mass); :data:`TERMS` gives each coefficient's unit.  A coefficient that follows
    an amplitude law ``theta(q_max) = theta_0 + theta_1 q_max + ...`` has ``theta_j`` in its
    unit over m^j (:func:`coefficient_unit`).
"""

from __future__ import annotations

import numpy as np

__all__ = ["harmonic_index", "n_coefficients", "TERMS", "coefficient_unit", "STRUCTURE_KEYS"]

#: term name -> (coefficient, unit of the coefficient, what a positive coefficient means).
TERMS = {
    "q": ("omega1^2", "1/s^2", "linear stiffness per unit modal mass; omega1 = sqrt(omega1^2) rad/s"),
    "-q^3": ("k3", "1/(m^2 s^2)", "k3 > 0 softening, k3 < 0 hardening (seed Eq 21)"),
    "q^2": ("k2", "1/(m s^2)", "k2 > 0 stiffer for q > 0 than for q < 0 (asymmetric)"),
    "q^5": ("k5", "1/(m^4 s^2)", "k5 > 0 hardening"),
    "|q|q": ("k_abs", "1/(m s^2)", "k_abs > 0 hardening (symmetric quadratic stiffness)"),
    "q'": ("c", "1/s", "c > 0 dissipates (viscous; 2 zeta omega1 for a linear mode)"),
    "|q'|q'": ("c_quad", "1/m", "c_quad > 0 dissipates (quadratic damping)"),
    "q'^3": ("c_cubic", "s/m^2", "c_cubic > 0 dissipates (cubic damping)"),
    "sign(q')": ("f_c", "m/s^2", "f_c > 0 dissipates (Coulomb friction force per unit modal mass)"),
    "q^2 q'": ("c_qq", "1/(m^2 s)", "c_qq > 0 dissipates more at large displacement"),
}


#: The keys of one ``[structure]`` table of a campaign (docs/formats.md): read by the campaign
#: loader (one table for every preload, or tables keyed by preload) and by
#: :mod:`jointid.modal.structure`, which builds the structure from it.
STRUCTURE_KEYS = frozenset({
    "model", "preload", "force_position", "force_column", "basis_modes", "n_modes", "beam", "joint",
    "update_to_hz", "update_parameters", "sensors", "mode_shape",
})


def coefficient_unit(term: str, power: int = 0) -> str:
    """Unit of a term's coefficient, or of the ``q_max^power`` coefficient of its amplitude law.

    >>> coefficient_unit("-q^3")
    '1/(m^2 s^2)'
    >>> coefficient_unit("q'", 2)
    '1/s per m^2'
    """
    unit = TERMS[term][1]
    return unit if power == 0 else f"{unit} per m" + (f"^{power}" if power > 1 else "")


def n_coefficients(n_harmonics: int) -> int:
    """Length of a harmonic coefficient vector with ``n_harmonics`` harmonics."""
    return 2 * n_harmonics + 1


def harmonic_index(n_harmonics: int) -> np.ndarray:
    """Harmonic number ``k`` of each entry of a coefficient vector (0, 1, 1, 2, 2, ...)."""
    k = np.zeros(n_coefficients(n_harmonics), dtype=int)
    k[1::2] = np.arange(1, n_harmonics + 1)
    k[2::2] = np.arange(1, n_harmonics + 1)
    return k
