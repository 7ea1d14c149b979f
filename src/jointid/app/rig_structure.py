"""A campaign's beam as a multi-mode structure model with a joint element.

A test engineer with a stepped-sine campaign of a jointed beam has its ``[structure]`` table:
the finite element beam updated to the random test's natural frequencies (the joint stuck,
its springs holding the joint's small-amplitude stiffness), the force and sensor positions
and the transformation of the records into the first modal coordinate
(:class:`jointid.modal.structure.Structure`).  This module turns that into

* a :class:`jointid.simulate.structure.StructureModel` (:func:`beam_structure_model`): the
  beam's lowest modes at named DOFs -- the force column, each sensor column and the joint's
  relative rotation ``joint_rotation`` and deflection ``joint_deflection`` -- with modal
  damping ratios of the engineer's choice (the random test's) and one joint element whose
  law the engineer chooses, acting on the relative rotation (or deflection); the law's
  stuck stiffness is subtracted (``k_model``) because the updated beam holds it;
* the first harmonics of the records' sensor displacements against the force
  (:func:`record_first_harmonics`), the measured points of :mod:`jointid.app.update_joint`;
* the predicted steady state seen through the records' own transformation
  (:func:`predicted_modal_loop`): the model's accelerations at the sensors and force turned
  into ``Q``, ``q''`` and ``q`` exactly as the records are, and the loop
  ``Q - q'' - K0 q`` compared over one period with the measured one of the same dwell;
* the peak of the predicted acceleration FRF at a sensor (:func:`predicted_peak`), the
  dwells solved in sweep order and the intervals beside the largest refined by
  :func:`jointid.numerics.peaks.refine_peak`.

Conventions: harmonic coefficients ``x = a0 + sum a_k cos(k w t) + b_k sin(k w t)``, complex
``X_k = a_k - i b_k`` (:mod:`jointid.conventions`); the model's force is ``F sin(w t)``, so
``X_F = -i F``.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import StructureError
from ..io.campaign import read_record
from ..numerics.peaks import parabolic_peak, refine_peak
from ..signal.harmonics import fit_harmonics
from ..simulate.structure import JointElement, ModalModel, StructureModel
from ..simulate.structure_hb import to_complex, warm_sweep
from .update_joint import MeasuredFRF

__all__ = [
    "JOINT_DOFS",
    "beam_structure_model",
    "joint_start_from_modal",
    "predicted_modal_loop",
    "predicted_peak",
    "predicted_sweep",
    "record_first_harmonics",
    "sensor_acceleration",
]

#: DOF names of the joint's relative motions in :func:`beam_structure_model`.
JOINT_DOFS = {"rotation": "joint_rotation", "transverse": "joint_deflection"}


def beam_structure_model(structure, law, zeta, *, direction="rotation", n_modes=None, k_model=None,
                         name="joint") -> StructureModel:
    """The structure model of a beam :class:`~jointid.modal.structure.Structure` with one joint element.

    Parameters
    ----------
    structure : jointid.modal.structure.Structure
        With FE modes (``structure.modes``: a ``[structure]`` table with a beam).
    law : joint law (:mod:`jointid.joints`)
        On the joint's relative ``direction`` motion.
    zeta : float or sequence
        Modal damping ratios (one for all modes, or one per mode from the lowest; a shorter
        list is continued with its last value).
    n_modes : int, optional
        Modes kept (default: all of ``structure.modes``).
    k_model : float, optional
        The joint stiffness already in the beam, subtracted from the law; default the law's
        stuck stiffness ``K_T`` (``kt`` for a Jenkins law), as the updated beam holds the
        joint stuck.
    """
    modes = structure.modes
    if modes is None:
        raise StructureError(f"{structure.source}: the structure has no FE beam (mode_shape values only): "
                             "no joint DOFs to put a joint element on")
    if direction not in JOINT_DOFS:
        raise StructureError(f"joint direction {direction!r}: expected one of {sorted(JOINT_DOFS)}")
    n = modes.n_modes if n_modes is None else int(n_modes)
    if not 1 <= n <= modes.n_modes:
        raise StructureError(f"{structure.source}: n_modes = {n_modes} outside 1..{modes.n_modes}")
    z = np.atleast_1d(np.asarray(zeta, float))
    z = np.concatenate([z, np.full(max(n - z.size, 0), z[-1])])[:n]
    dw, dth = modes.fe.relative_motion(modes.shapes)
    names = [structure.force_column, *structure.sensors, JOINT_DOFS["transverse"], JOINT_DOFS["rotation"]]
    rows = [modes.shape_at([structure.force_position])[0],
            *modes.shape_at([structure.sensors[s] for s in structure.sensors]), dw, dth]
    modal = ModalModel(modes.omega[:n], z, names, np.array(rows)[:, :n])
    if k_model is None:
        pars = law.parameters
        k_model = pars.get("K_T", pars.get("kt", 0.0))
    joint = JointElement(name, None, JOINT_DOFS[direction], law, float(k_model))
    return StructureModel(modal, [joint], {structure.force_column: 1.0})


def joint_start_from_modal(modal_law, modal_k3, psi, K_T, beta=0.0) -> dict:
    """Start values ``{F_S, K_T, chi, beta, k3}`` on the joint of an Iwan4 + cubic law identified in a modal coordinate.

    With the joint's motion ``u = psi q`` the modal force ``psi f(psi q)`` of an Iwan joint is
    an Iwan law in ``q`` with the same ``chi`` and the density coefficient
    ``R_q = psi^(chi + 3) R_u``, and a cubic ``k3_q = psi^4 k3_u``.  The micro-slip force
    (all the records can show below macro-slip) depends on ``R`` and ``chi`` only, so with
    the engineer's ``K_T`` and ``beta`` the joint's ``F_S`` is the one giving ``R_u``:
    ``F_S = ((chi + 1) (K_T d / (1 + beta))^(chi + 2) / (d R_u))^(1 / (chi + 1))``,
    ``d = beta + (chi + 1) / (chi + 2)``.
    """
    p = abs(float(psi))
    chi = float(modal_law.chi)
    R = float(modal_law.R) / p ** (chi + 3.0)
    d = beta + (chi + 1.0) / (chi + 2.0)
    F_S = ((chi + 1.0) * (K_T * d / (1.0 + beta)) ** (chi + 2.0) / (d * R)) ** (1.0 / (chi + 1.0))
    return {"F_S": F_S, "K_T": float(K_T), "chi": chi, "beta": float(beta), "k3": float(modal_k3) / p**4}


def record_first_harmonics(outcomes, sensors, force_levels, *, force_column="force") -> MeasuredFRF:
    """First harmonics of the sensor displacements of stepped-sine records, per unit of the model's force.

    For each record (``outcomes``: the usable record outcomes of a campaign run, in sweep
    order) at one of ``force_levels``: the fundamentals ``A`` of each sensor acceleration and
    ``C_F`` of the force by least squares over the whole record; the displacement's first
    harmonic under the nominal force ``F sin(w t)`` is ``X = (A / C_F) (-i F) / (-w^2)``.
    ``se``: the fits' residual rms times ``sqrt(2 / n)`` (the standard error of a sine
    coefficient in white noise), propagated to ``X`` with the force's share added in
    quadrature.  One row per record and sensor (the DOF named by the sensor column).
    """
    levels = {float(x) for x in force_levels}
    lv, fr, dof, X, se = [], [], [], [], []
    for o in outcomes:
        F = float(o.spec.force_level)
        if F not in levels:
            continue
        data = read_record(o.spec, required=("time", force_column, *sensors))
        w = o.signals.omega
        t = data.time
        sf, rf = fit_harmonics(t, data.channels[force_column], w, 1, channel=force_column)
        cf = sf.coefficients[1] - 1j * sf.coefficients[2]
        g = math.sqrt(2.0 / t.size)
        for s in sensors:
            sa, ra = fit_harmonics(t, data.channels[s], w, 1, channel=s, t0=sf.t0)
            ca = sa.coefficients[1] - 1j * sa.coefficients[2]
            x = (ca / cf) * (-1j * F) / (-(w**2))
            lv.append(F)
            fr.append(o.signals.frequency_hz)
            dof.append(s)
            X.append(x)
            se.append(abs(x) * math.hypot(g * ra / abs(ca), g * rf / abs(cf)))
    if not X:
        raise StructureError(f"no usable record at force level(s) {sorted(levels)}")
    return MeasuredFRF("<records>", np.array(lv), np.array(fr), tuple(dof), np.array(X), np.array(se))


def sensor_acceleration(model: StructureModel, point, dof) -> complex:
    """First harmonic of the acceleration at a named DOF of a steady state (complex, ``a1 - i b1``)."""
    return -(point.omega**2) * to_complex(model.modal.shape(dof) @ point.modal[:, :3])[1]


def predicted_sweep(model: StructureModel, frequencies_hz, force_amplitude, *, n_harmonics=9, n_time=None,
                    start=None) -> list:
    """Steady states of a stepped sweep, in the given order, each started from its predecessors (secant,
    :func:`jointid.simulate.structure_hb.warm_sweep`); the first from ``start`` (joint coefficients), else
    from the linear response."""
    force = [0.0, 0.0, float(force_amplitude)]  # F sin(w t), as StructureModel.solve
    return warm_sweep(lambda w, guess: model.engine.solve(w, force, n_harmonics, n_time=n_time, guess=guess),
                      2 * np.pi * np.asarray(frequencies_hz, float), start=start)


def predicted_peak(model: StructureModel, frequencies_hz, force_amplitude, dof, *, n_harmonics=9, n_time=None,
                   rtol=1e-5, sweep=None) -> tuple:
    """``(frequency [Hz], |acceleration fundamental| / F)`` of the model's FRF peak at ``dof``.

    The frequencies (a stepped sweep, in order; or the steady states ``sweep`` of
    :func:`predicted_sweep` at them) are solved each from its predecessors; the intervals
    beside the largest are halved down to ``rtol`` of its frequency
    (:func:`~jointid.numerics.peaks.refine_peak`, each new point started from the nearest
    solved one) and :func:`~jointid.numerics.peaks.parabolic_peak` locates the peak.
    """
    f = np.asarray(frequencies_hz, float)
    pts = list(sweep) if sweep is not None else predicted_sweep(model, f, force_amplitude, n_harmonics=n_harmonics,
                                                                  n_time=n_time)
    solved = dict(zip(f.tolist(), pts))

    def amp(p):
        return abs(sensor_acceleration(model, p, dof)) / force_amplitude

    def more(fn):
        out = []
        for x in np.asarray(fn, float):
            near = solved[min(solved, key=lambda g: abs(g - x))]
            p = predicted_sweep(model, [x], force_amplitude, n_harmonics=near.n_harmonics, n_time=n_time,
                                start=near.joint)[0]
            solved[float(x)] = p
            out.append(amp(p))
        return out

    y = np.array([amp(p) for p in pts])
    k = int(np.argmax(y))
    xs, ys = refine_peak(more, f, y, rtol * f[k])
    return parabolic_peak(xs, ys)


def _rotate(c, phase):
    """Harmonic coefficients of ``x(t + phase / w)``: harmonic k turned by ``k phase``."""
    X = to_complex(c)
    X = X * np.exp(1j * phase * np.arange(X.size))
    out = np.empty_like(np.asarray(c, float))
    out[0] = X[0].real
    out[1::2], out[2::2] = X[1:].real, -X[1:].imag
    return out


def _modal_series(Qc, ac, omega, K0, n_time):
    """``q(t)`` and ``Q - q'' - K0 q`` over one period from the coefficients of ``Q`` and ``q''`` (force phase 0)."""
    H = (ac.size - 1) // 2
    k = np.repeat(np.arange(1, H + 1), 2) * omega
    qc = np.zeros_like(ac)
    qc[1:] = -ac[1:] / k**2
    t = np.arange(int(n_time)) / int(n_time) * 2 * np.pi / omega
    E = np.ones((t.size, ac.size))
    for j in range(1, H + 1):
        E[:, 2 * j - 1], E[:, 2 * j] = np.cos(j * omega * t), np.sin(j * omega * t)
    q = E[:, 1:] @ qc[1:]
    y = E[:, 1:] @ (Qc[1:] - ac[1:] - K0 * qc[1:])
    return q, y


def predicted_modal_loop(model: StructureModel, point, structure, signals, K0, *, n_time=512) -> dict:
    """A dwell's loop ``Q - q'' - K0 q`` predicted and measured, and their relative rms difference.

    Predicted: the model's force ``F sin(w t)`` and sensor accelerations (harmonics ``1..H``
    of the record's own harmonic fit) turned into ``Q`` and ``q''`` by
    ``structure.to_modal`` -- the records' transformation, linear and sample by sample, so
    applied to the harmonic coefficients -- and ``q`` by integrating each harmonic.
    Measured: the record's ``Q`` (least-squares harmonics ``1..H`` over the record) and its
    filtered ``q''`` (``signals.acceleration``), turned so that the force's fundamental has
    phase zero as in the model.  ``K0`` is the same linear stiffness for both (the linear
    part left out of the loop).  The difference is compared sample by sample over one
    period: ``rms(measured - predicted) / rms(measured)``.
    """
    acc = signals.acceleration
    H = acc.n_harmonics
    w = signals.omega
    if abs(point.omega - w) > 1e-9 * w:
        raise StructureError(f"the steady state is at {point.frequency_hz:.6g} Hz, the record at "
                             f"{signals.frequency_hz:.6g} Hz")
    sq, _ = fit_harmonics(signals.t, signals.force, w, H, channel="force", t0=acc.t0)
    Qm, am = sq.coefficients, np.asarray(acc.coefficients, float)
    phase = math.atan2(Qm[1], Qm[2])  # Q ~ sin(w t + phase)
    if structure.phi_force[0] < 0:  # Q = phi_f F: the force itself has the opposite phase
        phase += math.pi
    Qm, am = _rotate(Qm, -phase), _rotate(am, -phase)
    Hp = min(H, point.n_harmonics)
    m = 2 * Hp + 1
    force = np.zeros(2 * H + 1)
    force[: min(point.force.size, m)] = point.force[: min(point.force.size, m)]
    k = np.repeat(np.arange(1, H + 1), 2) * w
    accels = {}
    for s in structure.sensors:
        x = np.zeros(2 * H + 1)
        x[:m] = model.modal.shape(s) @ point.modal[:, :m]
        x[1:] *= -(k**2)
        x[0] = 0.0
        accels[s] = x
    Qp, ap, _ = structure.to_modal(force, accels)
    qm, ym = _modal_series(np.asarray(Qm, float), am, w, K0, n_time)
    qp, yp = _modal_series(np.asarray(Qp, float), np.asarray(ap, float), w, K0, n_time)
    rms = float(np.sqrt(np.mean((ym - yp) ** 2)) / np.sqrt(np.mean(ym**2)))
    return {"frequency_hz": float(signals.frequency_hz), "q_measured": qm, "loop_measured": ym, "q_predicted": qp,
            "loop_predicted": yp, "rms_difference": rms}
