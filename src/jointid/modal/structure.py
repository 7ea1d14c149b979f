"""The structure description of a campaign: sensors, force point, first mode shape.

A :class:`Structure` turns measured force and accelerations (columns of a record) into
the first modal force ``Q = phi_1(x_f) F`` and modal acceleration ``qdd`` (seed Eq 11,
A6; see :mod:`jointid.modal.coordinates`).  It is built from a plain dict, the
``[structure]`` table of ``campaign.toml`` as parsed by :mod:`tomllib`, with
:meth:`Structure.from_mapping`.  Either a finite element model gives the mode shapes,
or their values are given explicitly.

Schema (FE model)
-----------------
::

    [structure]
    model = "seed-bolted-beam"   # optional base model (the seed's geometry and steel)
    preload = 120                # optional, with the seed model: Table 4 updated parameters
    force_position = 0.05        # m; default 0.05 with the seed model, else required
    force_column = "force"       # optional, the force column of the records
    basis_modes = 1              # optional, modes in the least-squares basis
    n_modes = 6                  # optional, modes computed
    beam = { length = 0.42, width = 0.0254, thickness = 0.00636,
             youngs_modulus = 210e9, density = 7850.0,
             n_elements = 35, clamp_stiffness = 4.3e3 }     # overrides; without
             # a model: length, width, thickness, youngs_modulus, density required
    joint = { position = 0.21, k_w = 2.9e6, k_t = 2.8e3,
              mass = 0.0, inertia = 0.0 }   # without a model and joint: a continuous beam
    update_to_hz = [26.4, 157.6, 471.8]        # optional: update the model first
    update_parameters = ["k_w", "k_t", "k_c"]  # optional (this default)

    [structure.sensors]          # record column -> sensor position [m]
    accel_30 = 0.30
    accel_42 = 0.42

``clamp_stiffness = "inf"`` (or absent) is an ideal clamp.  All values are SI.

Schema (explicit mode shape)
----------------------------
::

    [structure]
    force_column = "force"
    mode_shape = { force = 0.0213, accel_30 = 1.234, accel_42 = 2.065 }

    [structure.sensors]          # optional: positions for the record; the sensor
    accel_30 = 0.30              # names must be those of mode_shape
    accel_42 = 0.42

``mode_shape`` holds the mass-normalised first mode (1/sqrt(kg)) at the force point
(key ``force``) and at each sensor; a list per key gives several modes
(``basis_modes`` = list length).

The whole campaign dict, with a ``structure`` key, is accepted too.  Unknown keys,
non-positive lengths, sensors outside the beam, a mode shape that is (nearly) zero at
the force point and unknown column names raise :class:`~jointid.errors.StructureError`
naming the item.
"""

from __future__ import annotations

import dataclasses
import html
import math
import numbers
import warnings
from dataclasses import dataclass
from types import MappingProxyType
from typing import Mapping

import numpy as np

from ..conventions import STRUCTURE_KEYS
from ..errors import JointidWarning, RecordError, StructureError, unknown_key_message
from ..rounding import format_value
from .analysis import ModalModel, modal_analysis
from .beam import SEED_GEOMETRY, BeamSection, JointedBeam, seed_bolted_beam
from .coordinates import ModalAcceleration, modal_acceleration, sensor_shapes
from .joint import SpringJoint
from .updating import UpdateResult, update_to_frequencies

__all__ = ["Structure", "MODELS"]

#: Ready-made base models for ``model = ...``.
MODELS = ("seed-bolted-beam",)

#: |phi_1(x_f)| below this fraction of max |phi_1| counts as zero.
_ZERO_SHAPE = 1e-3

_TOP_KEYS = STRUCTURE_KEYS  # the keys of one [structure] table, shared with the campaign loader
_BEAM_KEYS = {"length", "width", "thickness", "youngs_modulus", "density", "n_elements", "clamp_stiffness"}
_JOINT_KEYS = {"position", "k_w", "k_t", "c_w", "c_t", "mass", "inertia"}


def _number(ctx: str, value, *, positive=False, nonneg=False, allow_inf=False) -> float:
    if isinstance(value, str) and value.strip().lower() in ("inf", "infinity") and allow_inf:
        return math.inf
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise StructureError(f"{ctx}: expected a number, got {value!r}")
    v = float(value)
    if math.isnan(v) or (math.isinf(v) and not allow_inf):
        raise StructureError(f"{ctx}: expected a finite number, got {value!r}")
    if positive and v <= 0:
        raise StructureError(f"{ctx}: expected a positive value, got {value!r}")
    if nonneg and v < 0:
        raise StructureError(f"{ctx}: expected a value >= 0, got {value!r}")
    return v


def _integer(ctx: str, value, minimum: int = 1) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < minimum:
        raise StructureError(f"{ctx}: expected an integer >= {minimum}, got {value!r}")
    return int(value)


def _table(ctx: str, value, allowed: set | None = None) -> dict:
    if not isinstance(value, Mapping):
        raise StructureError(f"{ctx}: expected a table, got {value!r}")
    if allowed is not None:
        unknown = sorted(set(value) - allowed)
        if unknown:
            raise StructureError(f"{ctx}.{unknown[0]}: {unknown_key_message(unknown[0], allowed)}")
    return dict(value)


@dataclass(frozen=True, eq=False)
class Structure:
    """Sensors, force point and mode shapes turning records into modal coordinates.

    Attributes
    ----------
    sensors : mapping str -> float or None
        Record column name -> sensor position [m] (``None`` if not given).
    phi_sensors : ndarray, shape (n_sensors, n_basis)
        Mass-normalised mode shapes at the sensors, rows in ``sensors`` order.
    phi_force : ndarray, shape (n_basis,)
        Mode shapes at the force point.
    force_position : float or None
        Force position [m].
    force_column : str
        Column of the force in a record.
    modes : ModalModel or None
        The FE modes, when the structure has an FE model.
    update : UpdateResult or None
        The model updating, when ``update_to_hz`` was given.
    source : str
        Where the description came from (for messages).
    """

    sensors: Mapping[str, float | None]
    phi_sensors: np.ndarray
    phi_force: np.ndarray
    force_position: float | None = None
    force_column: str = "force"
    modes: ModalModel | None = None
    update: UpdateResult | None = None
    source: str = "<structure>"

    def __post_init__(self):
        object.__setattr__(self, "sensors", MappingProxyType(dict(self.sensors)))
        P = np.array(self.phi_sensors, dtype=float)
        if P.ndim == 1:
            P = P[:, None]
        pf = np.atleast_1d(np.array(self.phi_force, dtype=float))
        pre = f"{self.source}: " if self.source else ""
        if P.shape[0] != len(self.sensors) or P.shape[0] == 0:
            raise StructureError(f"{pre}expected one mode-shape row per sensor ({len(self.sensors)}), got {P.shape}")
        if pf.shape != (P.shape[1],):
            raise StructureError(f"{pre}phi_force: expected {P.shape[1]} values, got {pf.shape}")
        if P.shape[1] > P.shape[0]:
            raise StructureError(f"{pre}basis_modes = {P.shape[1]} exceeds the number of sensors ({P.shape[0]})")
        if self.force_column in self.sensors:
            raise StructureError(f"{pre}force column {self.force_column!r} is also a sensor column")
        for a in (P, pf):
            a.setflags(write=False)
        object.__setattr__(self, "phi_sensors", P)
        object.__setattr__(self, "phi_force", pf)

    # --- construction ---------------------------------------------------------------
    @classmethod
    def from_modal_model(
        cls,
        modes: ModalModel,
        sensors: Mapping[str, float],
        force_position: float,
        *,
        basis_modes: int = 1,
        force_column: str = "force",
        update: UpdateResult | None = None,
        source: str = "<structure>",
    ) -> "Structure":
        """A structure from FE modes, sensor positions and the force position.

        Raises
        ------
        StructureError
            A sensor or the force outside the beam, or ``phi_1(x_f)`` ~ 0.
        """
        pre = f"{source}: " if source else ""
        L = modes.fe.length
        names = list(sensors)
        if not names:
            raise StructureError(f"{pre}structure.sensors: at least one sensor is needed")
        pos = []
        for n in names:
            x = _number(f"{pre}structure.sensors.{n}", sensors[n])
            if not 0.0 <= x <= L:
                raise StructureError(f"{pre}structure.sensors.{n}: position {x!r} m is outside the beam [0, {L}] m")
            pos.append(x)
        xf = _number(f"{pre}structure.force_position", force_position)
        if not 0.0 <= xf <= L:
            raise StructureError(f"{pre}structure.force_position: {xf!r} m is outside the beam [0, {L}] m")
        n_basis = _integer(f"{pre}structure.basis_modes", basis_modes)
        if n_basis > modes.n_modes:
            raise StructureError(f"{pre}structure.basis_modes: {n_basis} exceeds the {modes.n_modes} computed modes")
        P = sensor_shapes(modes, pos, n_basis)
        pf = modes.shape_at([xf], list(range(n_basis)))[0]
        x_dense = np.linspace(0.0, L, 201)
        ref = float(np.max(np.abs(modes.shape_at(x_dense, 0))))
        if abs(pf[0]) < _ZERO_SHAPE * ref:
            raise StructureError(
                f"{pre}structure.force_position: the first mode shape is ~0 at x = {xf} m "
                f"(phi_1 = {pf[0]:.3g}, max |phi_1| = {ref:.3g}); the force cannot excite mode 1"
            )
        if np.max(np.abs(P[:, 0])) < _ZERO_SHAPE * ref:
            raise StructureError(f"{pre}structure.sensors: the first mode shape is ~0 at every sensor {names}")
        return cls(dict(zip(names, pos)), P, pf, xf, force_column, modes, update, source)

    @classmethod
    def from_mapping(cls, d: Mapping, source: str = "<mapping>") -> "Structure":
        """Build a structure from a plain dict (the ``[structure]`` table of a TOML file).

        Parameters
        ----------
        d : mapping
            The ``[structure]`` table, or a whole campaign dict with a ``structure`` key.
            Schema in the module docstring.
        source : str
            File name (or other origin) used in error messages.

        Raises
        ------
        StructureError
            Naming the offending item.
        """
        pre = f"{source}: " if source else ""
        if isinstance(d, Mapping) and "structure" in d and isinstance(d["structure"], Mapping):
            d = d["structure"]
        d = _table(f"{pre}structure", d, _TOP_KEYS)
        force_column = d.get("force_column", "force")
        if not isinstance(force_column, str) or not force_column:
            raise StructureError(f"{pre}structure.force_column: expected a column name, got {force_column!r}")
        sensors = _table(f"{pre}structure.sensors", d.get("sensors", {}))

        if "mode_shape" in d:
            fe_only = {"model", "preload", "beam", "joint", "update_to_hz", "update_parameters", "n_modes"}
            fe_keys = sorted(set(d) & fe_only)
            if fe_keys:
                raise StructureError(
                    f"{pre}structure.{fe_keys[0]}: give either an FE model or mode_shape values, not both"
                )
            return cls._from_shapes(d, sensors, force_column, source)

        beam = cls._beam_from_mapping(d, source)
        n_modes = _integer(f"{pre}structure.n_modes", d.get("n_modes", 6))
        update = None
        if "update_to_hz" in d:
            hz = d["update_to_hz"]
            if not isinstance(hz, (list, tuple)) or not hz:
                raise StructureError(f"{pre}structure.update_to_hz: expected a list of frequencies in Hz, got {hz!r}")
            hz = [_number(f"{pre}structure.update_to_hz[{i}]", v, positive=True) for i, v in enumerate(hz)]
            params = d.get("update_parameters", ["k_w", "k_t", "k_c"])
            if not isinstance(params, (list, tuple)) or not all(isinstance(p, str) for p in params):
                raise StructureError(f"{pre}structure.update_parameters: expected a list of names, got {params!r}")
            try:
                update = update_to_frequencies(beam, hz, tuple(params))
            except StructureError as exc:
                raise StructureError(f"{pre}structure.update_to_hz: {exc}") from None
            if update.max_abs_relative_residual > 0.005:
                warnings.warn(
                    f"{pre}structure.update_to_hz: the updated model is off by up to "
                    f"{100 * update.max_abs_relative_residual:.2f} %\n{update.report()}",
                    JointidWarning,
                    stacklevel=2,
                )
            beam = update.beam
            n_modes = max(n_modes, len(hz))
        modes = modal_analysis(beam, n_modes)
        if "force_position" in d:
            xf = d["force_position"]
        elif d.get("model") is not None:
            xf = SEED_GEOMETRY["force_position"]
        else:
            raise StructureError(f"{pre}structure.force_position: required (force position in m)")
        return cls.from_modal_model(
            modes, sensors, xf, basis_modes=d.get("basis_modes", 1), force_column=force_column,
            update=update, source=source,
        )

    @staticmethod
    def _beam_from_mapping(d: dict, source: str) -> JointedBeam:
        pre = f"{source}: " if source else ""
        model = d.get("model")
        beam_t = _table(f"{pre}structure.beam", d.get("beam", {}), _BEAM_KEYS)
        joint_t = d.get("joint")
        if model is not None:
            if model not in MODELS:
                raise StructureError(f"{pre}structure.model: unknown model {model!r}; expected one of {list(MODELS)}")
            preload = d.get("preload")
            if preload is not None:
                preload = _number(f"{pre}structure.preload", preload, positive=True)
                try:
                    base = seed_bolted_beam(int(preload) if preload == int(preload) else preload)
                except StructureError as exc:
                    raise StructureError(f"{pre}structure.preload: {exc}") from None
            else:
                base = seed_bolted_beam()
        else:
            if "preload" in d:
                raise StructureError(f"{pre}structure.preload: only meaningful with model = {MODELS[0]!r}")
            missing = [k for k in ("length", "width", "thickness", "youngs_modulus", "density") if k not in beam_t]
            if missing:
                raise StructureError(f"{pre}structure.beam.{missing[0]}: required when no model is given")
            base = None

        def val(key, default, **kw):
            if key in beam_t:
                return _number(f"{pre}structure.beam.{key}", beam_t[key], **kw)
            return default

        s0 = base.section if base is not None else None
        section = BeamSection(
            youngs_modulus=val("youngs_modulus", s0.youngs_modulus if s0 else None, positive=True),
            density=val("density", s0.density if s0 else None, positive=True),
            width=val("width", s0.width if s0 else None, positive=True),
            thickness=val("thickness", s0.thickness if s0 else None, positive=True),
        )
        length = val("length", base.length if base else None, positive=True)
        clamp = val("clamp_stiffness", base.clamp_stiffness if base else math.inf, positive=True, allow_inf=True)
        n_el = _integer(f"{pre}structure.beam.n_elements", beam_t.get("n_elements", base.n_elements if base else 35), 2)

        joint = base.joint if base is not None else None
        xj = base.joint_position if base is not None else None
        if joint_t is not None:
            joint_t = _table(f"{pre}structure.joint", joint_t, _JOINT_KEYS)
            fields = {}
            for key in ("k_w", "k_t", "c_w", "c_t", "mass", "inertia"):
                if key in joint_t:
                    fields[key] = _number(f"{pre}structure.joint.{key}", joint_t[key], nonneg=True)
            if joint is None:
                for key in ("k_w", "k_t"):
                    if key not in fields:
                        raise StructureError(f"{pre}structure.joint.{key}: required (joint stiffness)")
                joint = SpringJoint(**fields)
            else:
                joint = dataclasses.replace(joint, **fields)
            if "position" in joint_t:
                xj = _number(f"{pre}structure.joint.position", joint_t["position"], positive=True)
        if base is not None and "length" in beam_t and "position" not in (joint_t or {}):
            xj = None  # keep the joint at mid-span of the new length
        if xj is not None and not 0.0 < xj < length:
            raise StructureError(f"{pre}structure.joint.position: {xj!r} m is not inside the beam (0, {length}) m")
        try:
            return JointedBeam(length, section, joint, xj, n_el, clamp)
        except StructureError as exc:
            raise StructureError(f"{pre}structure: {exc}") from None

    @classmethod
    def _from_shapes(cls, d: dict, sensors: dict, force_column: str, source: str) -> "Structure":
        pre = f"{source}: " if source else ""
        shapes = _table(f"{pre}structure.mode_shape", d["mode_shape"])
        if "force" not in shapes:
            raise StructureError(f"{pre}structure.mode_shape.force: required (mode shape at the force point)")
        names = [k for k in shapes if k != "force"]
        if not names:
            raise StructureError(f"{pre}structure.mode_shape: no sensor values given")
        if sensors:
            for n in names:
                if n not in sensors:
                    raise StructureError(
                        f"{pre}structure.mode_shape.{n}: unknown column name, "
                        f"not in structure.sensors {sorted(sensors)}"
                    )
            for n in sensors:
                if n not in shapes:
                    raise StructureError(f"{pre}structure.sensors.{n}: no mode_shape value for this sensor")
        vals = {}
        n_basis = None
        for k in ["force"] + names:
            v = shapes[k]
            v = list(v) if isinstance(v, (list, tuple)) else [v]
            vals[k] = [_number(f"{pre}structure.mode_shape.{k}", x) for x in v]
            if n_basis is None:
                n_basis = len(vals[k])
            elif len(vals[k]) != n_basis:
                raise StructureError(
                    f"{pre}structure.mode_shape.{k}: expected {n_basis} values (one per mode), got {len(vals[k])}"
                )
        if "basis_modes" in d and _integer(f"{pre}structure.basis_modes", d["basis_modes"]) != n_basis:
            raise StructureError(
                f"{pre}structure.basis_modes: {d['basis_modes']} given, mode_shape has {n_basis} modes"
            )
        P = np.array([vals[n] for n in names])
        pf = np.array(vals["force"])
        ref = float(np.max(np.abs(np.r_[P[:, 0], pf[0]])))
        if abs(pf[0]) <= _ZERO_SHAPE * ref:
            raise StructureError(
                f"{pre}structure.mode_shape.force: the first mode shape is ~0 at the force point "
                f"({pf[0]!r}, max |phi_1| = {ref:.3g}); the force cannot excite mode 1"
            )
        pos = {}
        for n in names:
            pos[n] = _number(f"{pre}structure.sensors.{n}", sensors[n], nonneg=True) if n in sensors else None
        xf = d.get("force_position")
        xf = None if xf is None else _number(f"{pre}structure.force_position", xf, nonneg=True)
        return cls(pos, P, pf, xf, force_column, None, None, source)

    # --- use ------------------------------------------------------------------------
    @property
    def required_columns(self) -> tuple[str, ...]:
        """Record columns needed: the force column, then the sensor columns."""
        return (self.force_column,) + tuple(self.sensors)

    @property
    def n_basis(self) -> int:
        return self.phi_sensors.shape[1]

    def _accel_matrix(self, accels: Mapping, strict: bool) -> np.ndarray:
        pre = f"{self.source}: " if self.source else ""
        if not isinstance(accels, Mapping):
            raise StructureError(f"{pre}accels: expected a dict of column name -> signal, got {type(accels).__name__}")
        if strict:
            for name in accels:
                if name not in self.sensors:
                    raise StructureError(
                        f"{pre}column {name!r}: unknown column name, not a sensor of the structure "
                        f"(known: {list(self.sensors)})"
                    )
        rows = []
        for name in self.sensors:
            if name not in accels:
                raise StructureError(f"{pre}column {name!r}: sensor signal missing (given: {list(accels)})")
            rows.append(np.asarray(accels[name], dtype=float))
        n = {r.shape for r in rows}
        if len(n) != 1 or rows[0].ndim != 1:
            raise RecordError(
                f"{pre}sensor signals must be 1-D and of equal length, got "
                + ", ".join(f"{k}: {np.shape(accels[k])}" for k in self.sensors)
            )
        return np.vstack(rows)

    def project(self, accels: Mapping) -> ModalAcceleration:
        """Least-squares modal accelerations of a record (all basis modes, with residual)."""
        a = self._accel_matrix(accels, strict=True)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", JointidWarning)  # n_sensors == n_basis is the user's choice
            return modal_acceleration(a, self.phi_sensors)

    def to_modal(self, force, accels: Mapping | None = None):
        """First-mode modal force, modal acceleration and relative residual of a record.

        Parameters
        ----------
        force : array_like, shape (n_t,) or mapping
            Force [N].  A mapping is a record's channel dict holding the force column and
            the sensor columns (other columns are ignored); ``accels`` must then be omitted.
        accels : mapping str -> array_like, shape (n_t,)
            Sensor accelerations [m/s^2] keyed by column name.

        Returns
        -------
        Q : ndarray, shape (n_t,)
            ``phi_1(x_f) F``.
        qdd : ndarray, shape (n_t,)
            First-mode modal acceleration.
        residual : float
            Relative residual ``||a - Phi_s qdd|| / ||a||`` (contamination by other modes).

        Raises
        ------
        StructureError
            An unknown or missing sensor column.
        RecordError
            Signals of different lengths.
        """
        pre = f"{self.source}: " if self.source else ""
        if isinstance(force, Mapping):
            if accels is not None:
                raise TypeError("give either a channel dict or force and accels, not both")
            if self.force_column not in force:
                raise StructureError(f"{pre}column {self.force_column!r}: force signal missing (given: {list(force)})")
            channels = force
            F = np.asarray(channels[self.force_column], dtype=float)
            a = self._accel_matrix({k: channels[k] for k in self.sensors if k in channels}, strict=False)
        else:
            if accels is None:
                raise TypeError("accels (dict of column name -> signal) is required")
            F = np.asarray(force, dtype=float)
            a = self._accel_matrix(accels, strict=True)
        if F.ndim != 1 or F.shape[0] != a.shape[1]:
            raise RecordError(f"{pre}force has shape {F.shape}, the sensor signals have {a.shape[1]} samples")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", JointidWarning)
            m = modal_acceleration(a, self.phi_sensors)
        return self.phi_force[0] * F, m.qdd[0], m.relative_residual

    # --- reporting ------------------------------------------------------------------
    def summary(self) -> dict:
        out = {
            "source": self.source,
            "force_column": self.force_column,
            "force_position": self.force_position,
            "sensors": dict(self.sensors),
            "phi_force": [float(v) for v in self.phi_force],
            "phi_sensors": {n: [float(v) for v in row] for n, row in zip(self.sensors, self.phi_sensors)},
        }
        if self.modes is not None:
            out["frequencies_hz"] = [float(f) for f in self.modes.frequencies_hz]
        if self.update is not None:
            out["update"] = self.update.summary()
        return out

    def report(self) -> str:
        lines = [f"Structure from {self.source}: {self.n_basis} basis mode(s), force column {self.force_column!r}"]
        xf = "" if self.force_position is None else f" at x = {self.force_position} m"
        lines.append(f"  force{xf}: phi = {', '.join(format_value(v, 5) for v in self.phi_force)} 1/√kg")
        for n, row in zip(self.sensors, self.phi_sensors):
            x = self.sensors[n]
            where_ = "" if x is None else f" at x = {x} m"
            lines.append(f"  {n}{where_}: phi = {', '.join(format_value(v, 5) for v in row)} 1/√kg")
        if self.modes is not None:
            lines.append("  FE frequencies [Hz]: " + ", ".join(format_value(f, 6) for f in self.modes.frequencies_hz))
        if self.update is not None:
            lines.append(self.update.report())
        return "\n".join(lines)

    def _repr_html_(self) -> str:
        return f"<pre>{html.escape(self.report())}</pre>"
