"""Reader of a structure model file (``MODEL.toml``): a linear model with joint elements.

The file names the mass and stiffness matrices (a ``.npz``, a MATLAB ``.mat`` or Matrix
Market ``.mtx`` files, read with numpy / scipy.io) or gives modal data, the damping, the
joint elements between named degrees of freedom with their laws (:mod:`jointid.joints`),
the force DOFs and the response DOFs.  The format is described in ``docs/formats.md``
("Structure model").  :func:`read_structure_model` checks everything a computation needs
and raises :class:`~jointid.errors.ManifestError` naming the file and the key (a missing
matrix file: :class:`~jointid.errors.RecordFileNotFoundError`).

The result is a :class:`StructureSpec` of plain arrays and joint-law objects;
:func:`jointid.simulate.structure.structure_from_spec` turns it into a model.
"""

from __future__ import annotations

import math
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import ManifestError, RecordFileNotFoundError, StructureError, unknown_key_message
from ..joints import BoucWen, DiscreteIwan, Iwan4, Jenkins, PolynomialLaw

__all__ = ["JOINT_LAWS", "JointSpec", "StructureSpec", "read_structure_model", "stuck_stiffness"]

#: law name in MODEL.toml -> joint-law class of :mod:`jointid.joints`.
JOINT_LAWS = {
    "jenkins": Jenkins,
    "iwan4": Iwan4,
    "discrete_iwan": DiscreteIwan,
    "bouc_wen": BoucWen,
    "polynomial": PolynomialLaw,
}

_TOP = {"model", "matrices", "modal", "damping", "joint", "force", "response", "predict"}
_MATRICES = {"file", "mass", "stiffness", "mass_key", "stiffness_key", "dof_names", "dof_names_key"}
_MODAL = {"frequencies_hz", "damping_ratios", "dof_names", "shapes"}
_DAMPING = {"modal", "rayleigh"}
_JOINT = {"name", "dofs", "law", "parameters", "k_model", "motion"}
_PREDICT = {"frequency_range_hz", "force_levels", "n_harmonics", "n_time"}
#: Largest number of DOFs of a ``[matrices]`` model: the matrices are dense and their modes are
#: found by a dense eigensolver (a bigger model: reduce it, or give its modal data).
MAX_DOFS = 5000
#: Bounds of ``[predict] n_harmonics`` (as ``--harmonics``) and ``n_time``.
MAX_HARMONICS, MAX_N_TIME = 50, 65536


@dataclass(frozen=True, eq=False)
class JointSpec:
    """One joint element: law on ``x[dof_b] - x[dof_a]`` (``dof_a`` None: to ground)."""

    name: str
    dof_a: str | None
    dof_b: str
    law: object
    k_model: float
    motion: str = "translation"  # or "rotation": the law's N and m read as N m and rad

    @property
    def units(self) -> dict:
        """Units of the law's parameters for this joint's motion (:func:`motion_units`)."""
        return {k: motion_units(u, self.motion) for k, u in self.law.units.items()}


def motion_units(unit: str, motion: str) -> str:
    """A joint law's parameter unit (written for a translation: force N, displacement m) for a
    rotation: ``N`` -> ``N m`` (a moment), ``m`` -> ``rad`` (``N/m`` -> ``N m/rad``, ``1/m`` -> ``1/rad``)."""
    if motion != "rotation" or not unit:
        return unit
    num, _, den = unit.partition("/")
    num = re.sub(r"\bN\b", "N m", num)
    num = re.sub(r"(?<!N )\bm\b", "rad", num)
    return num + ("/" + re.sub(r"\bm\b", "rad", den) if den else "")


@dataclass(frozen=True, eq=False)
class StructureSpec:
    """The contents of a MODEL.toml, checked.

    Either ``M``, ``K`` (with ``zeta`` or ``rayleigh``) or modal data
    (``frequencies_hz``, ``zeta``, ``shapes``) are set; ``dof_names`` name the matrix rows
    or the shape rows.
    """

    path: str
    name: str
    dof_names: tuple
    joints: tuple
    force: dict
    response: tuple
    M: np.ndarray | None = None
    K: np.ndarray | None = None
    frequencies_hz: np.ndarray | None = None
    shapes: np.ndarray | None = None
    zeta: object = None
    rayleigh: object = None
    n_modes: int | None = None
    predict: dict = field(default_factory=dict)
    response_units: dict = field(default_factory=dict)  # response DOF -> unit of its motion ("m" unless declared)


def _err(path, key, msg):
    return ManifestError(f"{path}: {key}: {msg}")


def _table(path, doc, key, allowed, required=False):
    t = doc.get(key)
    if t is None:
        if required:
            raise _err(path, f"[{key}]", "missing table")
        return None
    if not isinstance(t, dict):
        raise _err(path, key, f"expected a table, got {type(t).__name__}")
    for k in t:
        if k not in allowed:
            raise _err(path, f"[{key}]", unknown_key_message(k, allowed))
    return t


def _number(path, key, v, *, positive=False, nonneg=False, integer=False):
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise _err(path, key, f"expected a number, got {v!r}")
    if integer and not isinstance(v, int):
        raise _err(path, key, f"expected an integer, got {v!r}")
    if not math.isfinite(v) or (positive and v <= 0) or (nonneg and v < 0):
        kind = "positive" if positive else "non-negative" if nonneg else "finite"
        raise _err(path, key, f"expected a {kind} number, got {v!r}")
    return v


def _numbers(path, key, v, **kw):
    if not isinstance(v, list) or not v:
        raise _err(path, key, f"expected a non-empty list of numbers, got {v!r}")
    return np.array([_number(path, f"{key}[{i}]", x, **kw) for i, x in enumerate(v)], float)


def _names(path, key, v):
    if not isinstance(v, list) or not v or not all(isinstance(s, str) and s for s in v):
        raise _err(path, key, "expected a non-empty list of non-empty strings")
    if len(set(v)) != len(v):
        dup = next(s for s in v if v.count(s) > 1)
        raise _err(path, key, f"DOF name {dup!r} appears twice")
    return tuple(v)


def _file(path, key, name):
    if not isinstance(name, str) or not name:
        raise _err(path, key, f"expected a file name, got {name!r}")
    p = Path(name)
    if not p.is_absolute():
        p = Path(path).parent / p
    if not p.is_file():
        raise RecordFileNotFoundError(f"{path}: {key}: file {name!r} not found (looked for {p})")
    return p


def _matrix_from(path, key, file, array_key):
    """A dense float matrix from .npz / .mat (by key) or .mtx (the whole file)."""
    suffix = file.suffix.lower()
    try:
        if suffix == ".npz":
            with np.load(file, allow_pickle=False) as z:
                if array_key not in z.files:
                    raise _err(path, key, f"{file.name} has no array {array_key!r} (it has {', '.join(z.files)})")
                a = z[array_key]
        elif suffix == ".mat":
            import scipy.io

            d = scipy.io.loadmat(file)
            if array_key not in d:
                have = ", ".join(k for k in d if not k.startswith("__"))
                raise _err(path, key, f"{file.name} has no variable {array_key!r} (it has {have})")
            a = d[array_key]
        elif suffix == ".mtx":
            import scipy.io

            rows, cols, _, _, kind, _ = scipy.io.mminfo(file)
            if kind == "pattern":
                raise _err(path, key, f"{file.name}: a Matrix Market \"pattern\" file holds where the entries are, "
                                      "not their values: expected a real matrix")
            _check_size(path, key, file, "the matrix", (rows, cols))
            a = scipy.io.mmread(file)
        else:
            raise _err(path, key, f"{file.name}: expected a .npz, .mat or .mtx file")
    except ManifestError:
        raise
    except Exception as exc:  # a damaged file: say which one
        raise _err(path, key, f"cannot read {file.name}: {exc}") from None
    if hasattr(a, "toarray"):
        _check_size(path, key, file, array_key, a.shape)  # before making it dense
        a = a.toarray()
    a = np.asarray(a)
    _check_size(path, key, file, array_key, a.shape)
    if a.dtype.kind not in "fiu":
        raise _err(path, key, f"{file.name}: {array_key!r} is not a real numeric matrix (dtype {a.dtype})")
    a = a.astype(float)
    if a.ndim != 2 or a.shape[0] != a.shape[1] or a.shape[0] == 0:
        raise _err(path, key, f"{file.name}: {array_key!r} is not a square matrix (shape {a.shape})")
    if not np.all(np.isfinite(a)):
        raise _err(path, key, f"{file.name}: {array_key!r} has NaN or infinite entries")
    if not np.allclose(a, a.T, rtol=1e-9, atol=1e-12 * max(float(np.abs(a).max()), 1e-300)):
        raise _err(path, key, f"{file.name}: {array_key!r} is not symmetric")
    return a


def _check_size(path, key, file, what, shape):
    if len(shape) == 2 and max(int(shape[0]), int(shape[1])) > MAX_DOFS:
        raise _err(path, key, f"{file.name}: {what!s} has {shape[0]} x {shape[1]} entries: at most {MAX_DOFS} DOFs "
                              "(the matrices are dense here; reduce the model or give its modal data in [modal])")


def _law_parameter(path, key, v):
    """A law parameter as written: a TOML number, or a non-empty list of numbers (not a bool, not a string)."""
    if isinstance(v, list):
        if not v:
            raise _err(path, key, "expected a number or a non-empty list of numbers, got []")
        for i, x in enumerate(v):
            if isinstance(x, bool) or not isinstance(x, (int, float)):
                raise _err(path, f"{key}[{i}]", f"expected a number, got {x!r}")
        return v
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise _err(path, key, f"expected a number, got {v!r}")
    return v


def _law(path, key, j):
    name = j.get("law")
    if name not in JOINT_LAWS:
        raise _err(path, f"{key}.law", unknown_key_message(name, JOINT_LAWS, "joint law"))
    params = j.get("parameters", {})
    if not isinstance(params, dict):
        raise _err(path, f"{key}.parameters", "expected a table of parameters")
    cls = JOINT_LAWS[name]
    params = {k: _law_parameter(path, f"{key}.parameters.{k}", v) for k, v in params.items()}
    try:
        if cls is PolynomialLaw:
            return cls(dict(params))
        if cls is DiscreteIwan:
            return cls(**{k: np.asarray(v, float) for k, v in params.items()})
        return cls(**params)
    except TypeError as exc:
        raise _err(path, f"{key}.parameters", f"{name}: {exc}") from None
    except (StructureError, ValueError) as exc:
        raise _err(path, f"{key}.parameters", str(exc)) from None


def _motion_dimension(unit):
    """``"length"`` or ``"angle"`` for a unit of a DOF's motion (:mod:`jointid.io.units`), else None."""
    from .units import ANGLE, LENGTH, UNITS

    dim = UNITS.get(str(unit).strip(), (None, None))[1]  # case-sensitive, as SI prefixes are (mm, Mm)
    return "length" if dim == LENGTH else "angle" if dim == ANGLE else None


def stuck_stiffness(law) -> float:
    """Tangent stiffness of a joint law at rest (every slider stuck): what a linear model holds as the joint."""
    if isinstance(law, Jenkins):
        return float(law.kt)
    if isinstance(law, Iwan4):
        return float(law.K_T)
    if isinstance(law, DiscreteIwan):
        return float(np.sum(law.stiffness))
    if isinstance(law, BoucWen):
        return float(law.k_z + law.k_inf)
    return float(dict(law.terms).get("q", 0.0))


def read_structure_model(path) -> StructureSpec:
    """Read and check a MODEL.toml (see the module docstring and ``docs/formats.md``)."""
    path = Path(path)
    if path.is_dir():
        raise ManifestError(f"{path}: structure model is a folder, not a file (give its .toml file)")
    if not path.is_file():
        raise RecordFileNotFoundError(f"{path}: structure model file not found")
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ManifestError(f"{path}: not a valid TOML file: {exc}") from None
    for k in doc:
        if k not in _TOP:
            raise _err(path, "top level", unknown_key_message(k, _TOP, "table"))
    model = _table(path, doc, "model", {"name", "n_modes"}) or {}
    name = model.get("name", path.stem)
    if not isinstance(name, str):
        raise _err(path, "model.name", "expected a string")
    n_modes = model.get("n_modes")
    if n_modes is not None:
        n_modes = int(_number(path, "model.n_modes", n_modes, positive=True, integer=True))
    mats = _table(path, doc, "matrices", _MATRICES)
    modal = _table(path, doc, "modal", _MODAL)
    if (mats is None) == (modal is None):
        raise _err(path, "[matrices] / [modal]", "give exactly one of the two tables")
    out = {"path": str(path), "name": name, "n_modes": n_modes}
    if mats is not None:
        if "file" in mats:
            if "mass" in mats or "stiffness" in mats:
                raise _err(path, "[matrices]", "give either file or mass and stiffness, not both")
            f = _file(path, "matrices.file", mats["file"])
            M = _matrix_from(path, "matrices.file", f, mats.get("mass_key", "M"))
            K = _matrix_from(path, "matrices.file", f, mats.get("stiffness_key", "K"))
        else:
            for k in ("mass", "stiffness"):
                if k not in mats:
                    raise _err(path, f"matrices.{k}", "missing (or give file)")
            fm, fk = _file(path, "matrices.mass", mats["mass"]), _file(path, "matrices.stiffness", mats["stiffness"])
            M = _matrix_from(path, "matrices.mass", fm, mats.get("mass_key", "M"))
            K = _matrix_from(path, "matrices.stiffness", fk, mats.get("stiffness_key", "K"))
            f = fm
        if M.shape != K.shape:
            raise _err(path, "[matrices]", f"mass {M.shape} and stiffness {K.shape} differ in size")
        if "dof_names" in mats:
            names = _names(path, "matrices.dof_names", mats["dof_names"])
        else:
            nk = mats.get("dof_names_key", "dof_names")
            if f.suffix.lower() != ".npz":
                raise _err(path, "matrices.dof_names", "missing (only a .npz file can hold the DOF names)")
            with np.load(f, allow_pickle=False) as z:
                if nk not in z.files:
                    raise _err(path, "matrices.dof_names", f"missing, and {f.name} has no array {nk!r}")
                names = _names(path, f"{f.name}:{nk}", [str(s) for s in z[nk].tolist()])
        if len(names) != M.shape[0]:
            raise _err(path, "matrices.dof_names", f"{len(names)} names for {M.shape[0]} degrees of freedom")
        out.update(M=M, K=K, dof_names=names)
        if n_modes is not None and n_modes > M.shape[0]:
            raise _err(path, "model.n_modes", f"{n_modes} modes asked of a model of {M.shape[0]} DOFs")
    else:
        for k in _MODAL:
            if k not in modal:
                raise _err(path, f"modal.{k}", "missing")
        fr = _numbers(path, "modal.frequencies_hz", modal["frequencies_hz"], nonneg=True)
        zr = _numbers(path, "modal.damping_ratios", modal["damping_ratios"], nonneg=True)
        names = _names(path, "modal.dof_names", modal["dof_names"])
        sh = modal["shapes"]
        if not isinstance(sh, list) or len(sh) != len(names):
            raise _err(path, "modal.shapes", f"expected {len(names)} rows (one per DOF name)")
        rows = [_numbers(path, f"modal.shapes[{i}]", r) for i, r in enumerate(sh)]
        for i, r in enumerate(rows):
            if r.size != fr.size:
                raise _err(path, f"modal.shapes[{i}]", f"{r.size} values for {fr.size} modes")
        if zr.size != fr.size:
            raise _err(path, "modal.damping_ratios", f"{zr.size} values for {fr.size} modes")
        order = np.argsort(fr, kind="stable")  # the modes from the lowest, each with its shape and damping ratio
        out.update(frequencies_hz=fr[order], zeta=zr[order], shapes=np.array(rows)[:, order], dof_names=names)
    damp = _table(path, doc, "damping", _DAMPING, required=mats is not None)
    if damp is not None:
        if modal is not None:
            raise _err(path, "[damping]", "modal data carry their damping ratios (modal.damping_ratios)")
        if ("modal" in damp) == ("rayleigh" in damp):
            raise _err(path, "[damping]", "give exactly one of modal (ratios) and rayleigh ([alpha, beta])")
        if "modal" in damp:
            v = damp["modal"]
            z = _numbers(path, "damping.modal", v if isinstance(v, list) else [v], nonneg=True)
            out["zeta"] = float(z[0]) if not isinstance(v, list) else z
        else:
            r = _numbers(path, "damping.rayleigh", damp["rayleigh"], nonneg=True)
            if r.size != 2:
                raise _err(path, "damping.rayleigh", f"expected [alpha, beta], got {r.size} values")
            out["rayleigh"] = (float(r[0]), float(r[1]))
    names = out["dof_names"]

    def dof(key, s):
        if s not in names:
            raise _err(path, key, unknown_key_message(s, names, "DOF"))
        return s

    joints_raw = doc.get("joint")
    if not isinstance(joints_raw, list) or not joints_raw or not all(isinstance(j, dict) for j in joints_raw):
        raise _err(path, "[[joint]]", "at least one joint element table is needed")
    joints = []
    for i, j in enumerate(joints_raw):
        key = f"joint[{i}]"
        for k in j:
            if k not in _JOINT:
                raise _err(path, key, unknown_key_message(k, _JOINT))
        jn = j.get("name", f"joint{i + 1}")
        if not isinstance(jn, str) or not jn:
            raise _err(path, f"{key}.name", f"expected a non-empty string, got {jn!r}")
        if any(o.name == jn for o in joints):
            raise _err(path, f"{key}.name", f"joint name {jn!r} appears twice (each joint element needs its own name)")
        d = j.get("dofs")
        if not isinstance(d, list) or len(d) not in (1, 2) or not all(isinstance(s, str) for s in d):
            raise _err(path, f"{key}.dofs", "expected one DOF name (to ground) or two (relative motion b - a)")
        a, b = (None, d[0]) if len(d) == 1 else (d[0], d[1])
        if a is not None:
            dof(f"{key}.dofs", a)
        dof(f"{key}.dofs", b)
        if a == b:
            raise _err(path, f"{key}.dofs", "the two DOFs must differ")
        law = _law(path, key, j)
        km = j.get("k_model", 0.0)
        if km == "stuck":
            km = stuck_stiffness(law)
            if not (math.isfinite(km) and km >= 0):
                raise _err(path, f"{key}.k_model", f"\"stuck\" takes the law's stiffness at rest, here {km:g} (its "
                                                    "\"q\" term) < 0: give k_model as a number (the joint's stiffness "
                                                    "already in the linear model), or a law stiff at rest")
        km = _number(path, f"{key}.k_model", km, nonneg=True)
        motion = j.get("motion", "translation")
        if motion not in ("translation", "rotation"):
            raise _err(path, f"{key}.motion", f"expected \"translation\" or \"rotation\", got {motion!r}")
        joints.append(JointSpec(str(jn), a, b, law, float(km), motion))
    force = _table(path, doc, "force", {"dofs"}, required=True)
    fd = force.get("dofs")
    if not isinstance(fd, dict) or not fd:
        raise _err(path, "force.dofs", "expected a table DOF name -> weight")
    fw = {dof("force.dofs", k): float(_number(path, f"force.dofs.{k}", v)) for k, v in fd.items()}
    if not any(fw.values()):
        raise _err(path, "force.dofs", "every weight is 0: the model has no force")
    resp = _table(path, doc, "response", {"dofs", "units"}, required=True)
    rd = resp.get("dofs")
    if not isinstance(rd, list) or not rd or not all(isinstance(s, str) for s in rd):
        raise _err(path, "response.dofs", "expected a list of DOF names")
    response = tuple(dof("response.dofs", s) for s in rd)
    ru = resp.get("units", {})
    if not isinstance(ru, dict) or not all(isinstance(u, str) and u.strip() for u in ru.values()):
        raise _err(path, "response.units", "expected a table DOF name -> unit, e.g. { \"B.r0\" = \"rad\" }")
    for k in ru:
        if k not in response:
            raise _err(path, f"response.units.{k}", f"not one of the response DOFs {list(response)}")
    for k, u in ru.items():
        if _motion_dimension(u) is None:
            raise _err(path, f"response.units.{k}", f"{u!r} is not a unit of length or angle (e.g. m, mm, rad, deg)")
    units = {d: str(ru.get(d, "m")).strip() for d in response}
    pred = _table(path, doc, "predict", _PREDICT) or {}
    predict = {}
    if "frequency_range_hz" in pred:
        r = _numbers(path, "predict.frequency_range_hz", pred["frequency_range_hz"], positive=True)
        if r.size != 2 or r[0] >= r[1]:
            raise _err(path, "predict.frequency_range_hz", "expected [low, high] with low < high")
        predict["frequency_range_hz"] = (float(r[0]), float(r[1]))
    if "force_levels" in pred:
        predict["force_levels"] = [float(x) for x in _numbers(path, "predict.force_levels", pred["force_levels"],
                                                              positive=True)]
    for k, top in (("n_harmonics", MAX_HARMONICS), ("n_time", MAX_N_TIME)):
        if k in pred:
            predict[k] = int(_number(path, f"predict.{k}", pred[k], positive=True, integer=True))
            if predict[k] > top:
                raise _err(path, f"predict.{k}", f"expected an integer from 1 to {top}, got {predict[k]}")
    if "n_harmonics" in predict and "n_time" in predict and predict["n_time"] <= 2 * predict["n_harmonics"]:
        raise _err(path, "predict.n_time", f"must exceed 2 n_harmonics = {2 * predict['n_harmonics']}")
    out.update(joints=tuple(joints), force=fw, response=response, predict=predict, response_units=units)
    return StructureSpec(**out)
