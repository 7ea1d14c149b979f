"""The linear modal dynamics in the frequency domain, written once.

A mass-normalised mode of natural frequency ``Omega`` and damping ratio ``zeta`` obeys
``q'' + 2 zeta Omega q' + Omega^2 q = f``; at angular frequency ``w`` its receptance is
``1 / d`` with the denominator ``d = Omega^2 - w^2 + 2 i zeta Omega w``
(:func:`modal_denominator`).  The FRFs and modal fits of :mod:`jointid.signal.frf`, its
periodic (FFT) steady state and the receptances of the harmonic-balance engines use it.
"""

from __future__ import annotations

__all__ = ["modal_denominator"]


def modal_denominator(omega, zeta, w, xi=0.0):
    """``Omega^2 - w^2 + i (2 zeta Omega - xi) w``, broadcast over the arguments (numpy arrays or floats).

    ``xi``: a self-excitation ``-xi q'`` (the nonlinear modes of :mod:`jointid.simulate.nlmodes`);
    with ``xi = 0`` the values are those of ``Omega^2 - w^2 + 2 i zeta Omega w`` to the bit.

    Parameters
    ----------
    omega : float or ndarray
        Natural frequencies [rad/s].
    zeta : float or ndarray
        Damping ratios.
    w : float or ndarray
        Angular frequencies [rad/s].
    xi : float, optional
        Self-excitation coefficient [1/s].

    Examples
    --------
    >>> complex(modal_denominator(2.0, 0.05, 1.0))
    (3+0.2j)
    """
    return omega**2 - w**2 + 1j * (2 * zeta * omega - xi) * w
