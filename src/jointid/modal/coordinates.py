"""Physical to modal coordinates (seed Eq 11, 12, A6).

The response is assumed to be ``d(x, t) = sum_r phi_r(x) q_r(t)`` with mass-normalised
modes.  With accelerometers at positions ``x_k`` the sampled accelerations are
``a = Phi_s qdd`` where ``Phi_s[k, r] = phi_r(x_k)``; the modal accelerations follow by
least squares, sample by sample:

``qdd = argmin ||a - Phi_s qdd||``

The seed uses the first mode only (``d = phi_1 q``, two accelerometers); more modes can
be put in the basis when there are more sensors than modes.  The part of the
accelerations the basis cannot explain, the *relative residual*
``||a - Phi_s qdd||_F / ||a||_F`` over the record, measures the contamination by modes
outside the basis (with a one-mode basis, mostly mode 2): near the first resonance it
is small, for a record dominated by mode 2 it is of order one.  With as many sensors
as basis modes it is identically zero and carries no information.

The modal force of a point force ``F`` at ``x_f`` is ``Q_r = phi_r(x_f) F`` (seed A6).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from ..errors import JointidWarning, RecordError, StructureError
from .analysis import ModalModel

__all__ = ["ModalAcceleration", "modal_acceleration", "modal_force", "sensor_shapes"]


@dataclass(frozen=True, eq=False)
class ModalAcceleration:
    """Least-squares modal accelerations of one record.

    Attributes
    ----------
    qdd : ndarray, shape (n_basis, n_t)
        Modal accelerations of the basis modes (``qdd[0]`` is the first mode).
    residual : ndarray, shape (n_sensors, n_t)
        ``a - Phi_s qdd``: what the basis does not explain.
    relative_residual : float
        ``||residual||_F / ||a||_F`` over the record (0: the basis explains all).
    condition_number : float
        Of the sensor shape matrix ``Phi_s`` (large: sensors cannot separate the modes).
    """

    qdd: np.ndarray
    residual: np.ndarray
    relative_residual: float
    condition_number: float

    def __post_init__(self):
        for name in ("qdd", "residual"):
            a = np.array(getattr(self, name))
            a.setflags(write=False)
            object.__setattr__(self, name, a)

    def summary(self) -> dict:
        return {
            "n_basis": int(self.qdd.shape[0]),
            "relative_residual": float(self.relative_residual),
            "condition_number": float(self.condition_number),
        }


def modal_acceleration(accels, phi_sensors, weights=None) -> ModalAcceleration:
    """Modal accelerations from sensor accelerations by least squares.

    Parameters
    ----------
    accels : array_like, shape (n_sensors, n_t)
        Accelerations [m/s^2], one row per sensor, time on the last axis.
    phi_sensors : array_like, shape (n_sensors,) or (n_sensors, n_basis)
        Mass-normalised mode shapes at the sensors (a 1-D array: the first mode only).
    weights : array_like, shape (n_sensors,), optional
        Sensor weights (e.g. inverse noise standard deviations); default equal.

    Returns
    -------
    ModalAcceleration

    Examples
    --------
    >>> phi = np.array([0.9, 1.6])
    >>> r = modal_acceleration(np.outer(phi, [1.0, -2.0]), phi)
    >>> np.round(r.qdd, 12), r.relative_residual < 1e-12
    (array([[ 1., -2.]]), True)
    """
    a = np.asarray(accels, dtype=float)
    P = np.asarray(phi_sensors, dtype=float)
    if P.ndim == 1:
        P = P[:, None]
    if a.ndim == 1:
        a = a[:, None]
    if a.ndim != 2 or a.shape[0] != P.shape[0]:
        raise RecordError(f"accels: expected shape ({P.shape[0]}, n_t) (one row per sensor), got {np.shape(accels)}")
    n_s, n_b = P.shape
    if n_b > n_s:
        raise StructureError(f"{n_b} basis modes cannot be resolved from {n_s} sensors")
    if n_b == n_s:
        warnings.warn(
            f"{n_s} sensors and {n_b} basis modes: the residual is identically zero and does not "
            "show contamination by other modes",
            JointidWarning,
            stacklevel=2,
        )
    if not np.all(np.isfinite(a)):
        raise RecordError("accels contain non-finite values")
    wv = np.ones(n_s) if weights is None else np.asarray(weights, dtype=float)
    if wv.shape != (n_s,) or np.any(wv <= 0):
        raise StructureError(f"weights: expected {n_s} positive values, got {weights!r}")
    Pw = P * wv[:, None]
    s = np.linalg.svd(Pw, compute_uv=False)
    if s[-1] <= 1e-12 * s[0]:
        raise StructureError("the mode shapes at the sensors are linearly dependent (or zero)")
    qdd, *_ = np.linalg.lstsq(Pw, a * wv[:, None], rcond=None)
    resid = a - P @ qdd
    norm_a = np.linalg.norm(a)
    rel = float(np.linalg.norm(resid * wv[:, None]) / np.linalg.norm(a * wv[:, None])) if norm_a > 0 else 0.0
    return ModalAcceleration(qdd, resid, rel, float(s[0] / s[-1]))


def modal_force(force, phi_force) -> np.ndarray:
    """Modal force ``Q_r = phi_r(x_f) F`` of a point force.

    Parameters
    ----------
    force : array_like, shape (n_t,)
        Force [N].
    phi_force : float or array_like, shape (n_modes,)
        Mass-normalised mode shape value(s) at the force point.

    Returns
    -------
    ndarray, shape (n_t,) for a scalar ``phi_force``, else (n_modes, n_t)
    """
    F = np.asarray(force, dtype=float)
    p = np.asarray(phi_force, dtype=float)
    if p.ndim == 0:
        return p * F
    return p[:, None] * F[None, :]


def sensor_shapes(modes: ModalModel, positions, n_basis: int = 1) -> np.ndarray:
    """``Phi_s[k, r] = phi_r(x_k)`` for the first ``n_basis`` modes, shape (n_sensors, n_basis)."""
    if not 1 <= n_basis <= modes.n_modes:
        raise StructureError(f"basis_modes: expected 1..{modes.n_modes}, got {n_basis!r}")
    return modes.shape_at(np.atleast_1d(positions), list(range(n_basis)))
