"""Backbones of an identified campaign: model, stepped-sine points, ring-downs and the joint law, per preload.

:func:`backbone_from_campaign` takes a :class:`~jointid.app.workflow.CampaignResult` (and
its campaign, for the ring-down records) and returns a :class:`CampaignBackbones`:

* the backbone of each preload's identified model (``result.models``) over the measured
  amplitude range with 95 % bands from the model's covariance
  (:func:`preload_model_backbone`, also usable on a saved ``results.json`` entry);
* the equivalent linearisation of every stepped-sine record (its force times the
  identified gain when the force column has an unknown gain, its response corrected by the
  channel delay) and the phase-resonance point of every force level;
* the free-decay backbone of every ``excitation = "ringdown"`` record (windowed fit of
  the modal acceleration, windows below the noise floor left out);
* with an FE structure, the Iwan and cubic + viscous joint laws fitted to the measured
  points through the joint's linear modes.

A record or a preload that cannot be used is reported in ``errors`` and the rest goes on.
"""

from __future__ import annotations

import html
import warnings
from dataclasses import dataclass, field

import numpy as np

from ..errors import JointidError, JointidWarning, ManifestError, RecordError, where
from ..identify.backbone import Backbone, equivalent_linearisation, model_backbone, phase_resonance_points
from ..identify.jointlaw import JointModes, fit_joint_laws
from ..signal.ringdown import fit_decay

__all__ = ["PreloadBackbones", "CampaignBackbones", "preload_model_backbone", "ringdown_decay",
           "backbone_from_campaign", "campaign_backbones", "backbones_from_results", "check_results_for_backbones",
           "write_backbone_figures"]


def preload_model_backbone(model, amplitudes=None, n_points=40, n_harmonics=1, label="") -> Backbone:
    """Backbone of a preload's identified model with 95 % bands.

    Parameters
    ----------
    model : PreloadModel or dict
        The model, or its ``summary()`` (a ``results.json`` ``models`` entry): ``terms``,
        ``amplitude_laws`` (orders), ``parameter_names``, ``parameters``, ``covariance``,
        ``q_max_range``.
    amplitudes : array_like, optional
        Default: ``n_points`` log-spaced over the model's ``q_max`` range.
    n_harmonics : int
        See :func:`jointid.identify.backbone.model_backbone`.
    """
    s = model if isinstance(model, dict) else model.summary()
    from ..identify.model import law_size
    from ..identify.powerlaw import PowerLaw, is_power
    from ..identify.terms import library

    lib = library(s["terms"])
    # a law's order, or "power" for the micro-slip law c0 + c1 q_max^p (three parameters)
    orders = {lib[k].coefficient: (v if isinstance(v, str) else int(v))
              for k, v in (s.get("amplitude_laws") or {}).items()}
    params = np.asarray(s["parameters"], float)
    cov = None if s.get("covariance") is None else np.asarray(s["covariance"], float)
    # the model's parameters run term by term (laws expanded in place); the backbone's
    # vector holds the constant coefficients first, then the laws (parameter_vector)
    coefs, laws, pos_const, pos_law = [], {}, [], {}
    i = 0
    for t in lib:
        L = orders.get(t.coefficient, 0)
        n = law_size(L)
        if n == 1:
            coefs.append(params[i])
            pos_const.append(i)
        else:
            coefs.append(0.0)
            laws[t.coefficient] = PowerLaw(*params[i:i + 3]) if is_power(L) else params[i:i + n]
            pos_law[t.coefficient] = list(range(i, i + n))
        i += n
    perm = pos_const + [j for t in lib if t.coefficient in pos_law for j in pos_law[t.coefficient]]
    if amplitudes is None:
        lo, hi = s.get("q_max_range") or (None, None)
        if not (lo and hi and hi > lo > 0):
            raise RecordError("the model has no amplitude range; give the amplitudes")
        amplitudes = np.geomspace(lo, hi, int(n_points))
    return model_backbone(lib, coefs, amplitudes, amplitude_laws=laws,
                          covariance=None if cov is None else cov[np.ix_(perm, perm)], n_harmonics=n_harmonics,
                          label=label or f"preload {s.get('preload')}")


def ringdown_decay(spec, structure=None, **fit_options):
    """Read one ring-down record, project it on mode 1 and fit its free decay.

    Parameters
    ----------
    spec : RecordSpec
        An ``excitation = "ringdown"`` record (the force column may be absent).
    structure : Structure, optional
        Physical campaign: the sensor columns are projected on mode 1.  Without it the
        record holds the modal acceleration in column ``accel``.
    **fit_options
        Passed to :func:`jointid.signal.ringdown.fit_decay`.

    Returns
    -------
    DecayFit

    Raises
    ------
    JointidError
        Naming the file and record.
    """
    from ..io.campaign import read_record

    loc = where(spec.file, spec.index)
    if structure is None:
        data = read_record(spec, required=("time", "accel"))
        qdd = data.channels["accel"]
        channel = "accel"
    else:
        data = read_record(spec, required=("time",) + tuple(structure.sensors))
        qdd = structure.project({k: data.channels[k] for k in structure.sensors}).qdd[0]
        channel = "accel (modal)"
    try:
        decay = fit_decay(data.time, qdd, channel=channel, **fit_options)
    except RecordError as exc:
        raise RecordError(f"{loc}{exc}") from None
    from ..signal.ringdown_checks import ringdown_flags

    flags = ringdown_flags(decay, channel)  # noise, growth, no decay, too few windows: no backbone from it
    if flags:
        raise RecordError(loc + "not a usable free decay: " + "; ".join(f.report() for f in flags))
    return decay


@dataclass(frozen=True, eq=False)
class PreloadBackbones:
    """The backbones of one preload and the joint laws fitted to its measured points."""

    preload: object
    model: Backbone | None = None
    stepped: Backbone | None = None
    phase_resonance: Backbone | None = None
    ringdown: tuple = ()
    joint_laws: dict = field(default_factory=dict)
    errors: dict = field(default_factory=dict)

    def measured(self) -> Backbone | None:
        """Stepped-sine and ring-down points together (the joint laws are fitted to them)."""
        parts = [b for b in (self.stepped,) + tuple(self.ringdown) if b is not None and len(b)]
        if not parts:
            return None
        cat = {k: np.concatenate([getattr(b, k) for b in parts])
               for k in ("amplitude", "omega", "zeta", "omega_stderr", "zeta_stderr", "amplitude_stderr")}
        ok = np.isfinite(cat["omega"]) & np.isfinite(cat["zeta"])
        return Backbone(cat["amplitude"][ok], cat["omega"][ok], cat["zeta"][ok], cat["omega_stderr"][ok],
                        cat["zeta_stderr"][ok], "+".join(sorted({b.source for b in parts})),
                        cat["amplitude_stderr"][ok], f"preload {self.preload}")

    def summary(self) -> dict:
        return {
            "preload": self.preload,
            "model": None if self.model is None else self.model.summary(),
            "stepped_sine": None if self.stepped is None else self.stepped.summary(),
            "phase_resonance": None if self.phase_resonance is None else self.phase_resonance.summary(),
            "ringdown": [b.summary() for b in self.ringdown],
            "joint_laws": {k: f.summary() for k, f in self.joint_laws.items()},
            "errors": dict(self.errors),
        }

    def report(self) -> str:
        from ..report.summary import backbone_lines

        lines = [f"Preload {self.preload}:"]
        for b in (self.model, self.stepped, self.phase_resonance) + tuple(self.ringdown):
            if b is not None:
                lines += ["  " + line for line in backbone_lines(b)]
        for f in self.joint_laws.values():
            lines.append("  " + f.report().replace("\n", "\n  "))
        for k, e in self.errors.items():
            lines.append(f"  {k}: {e}")
        return "\n".join(lines)

    def plot(self, ax=None):
        from ..report.backbone_plots import plot_backbones

        curves = [b for b in (self.model, self.stepped, self.phase_resonance) + tuple(self.ringdown) if b is not None]
        curves += [f.backbone(self.model.amplitude if self.model is not None else np.geomspace(
            *sorted((f.amplitude.min(), f.amplitude.max())), 40), label=f"{f.law} law") for f in self.joint_laws.values()]
        return plot_backbones(curves, ax=ax, title=f"preload {self.preload}")


@dataclass(frozen=True, eq=False)
class CampaignBackbones:
    """:class:`PreloadBackbones` of every preload of a campaign (``results.json`` key ``backbones``)."""

    preloads: tuple
    error: str | None = None

    def __getitem__(self, preload) -> PreloadBackbones:
        for p in self.preloads:
            if p.preload == preload:
                return p
        raise KeyError(preload)

    def summary(self) -> dict:
        return {"preloads": [p.summary() for p in self.preloads], "error": self.error}

    def report(self) -> str:
        text = "\n\n".join(p.report() for p in self.preloads) or "no backbones"
        return text + (f"\nbackbones: {self.error}" if self.error else "")

    def _repr_html_(self) -> str:
        return f"<pre>{html.escape(self.report())}</pre>"


def campaign_backbones(result, campaign=None) -> CampaignBackbones:
    """:func:`backbone_from_campaign` that never raises: a failure is kept in ``error``."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            return backbone_from_campaign(result, campaign)
    except (JointidError, ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
        return CampaignBackbones((), f"{type(exc).__name__}: {exc}")


def _structure_of(campaign, preload, result=None):
    known = getattr(result, "structures", None) or {}
    if preload in known:
        return known[preload]
    if campaign is None or getattr(campaign, "structure", None) is None and getattr(campaign, "structures", None) is None:
        return None
    from ..modal.structure import Structure

    table = campaign.structure_for(preload) if getattr(campaign, "structures", None) else campaign.structure
    return Structure.from_mapping(table, source=str(campaign.root / "campaign.toml"))


def _record_gains(result, outcomes):
    """The force gain and its standard error for each record (1, 0 with a known gain).

    With an unknown gain (``settings.force_gain != "known"``) a record takes the gain of the
    pooled fit of its (preload, force level) group; ``None`` where that group has none.
    """
    settings = getattr(result, "settings", None)
    if getattr(settings, "force_gain", "known") == "known":
        return [1.0] * len(outcomes), [0.0] * len(outcomes)
    by_group = {}
    for g in getattr(result, "groups", ()) or ():
        if getattr(g, "gain", None) is not None:
            value, se = g.gain.derived()["gain"]
            if np.isfinite(value) and value > 0:
                by_group[(g.preload, g.force_level)] = (float(value), float(se) if np.isfinite(se) else 0.0)
    out = [by_group.get(o.spec.group, (None, None)) for o in outcomes]
    return [v for v, _ in out], [s for _, s in out]


def _delay_stderr(result) -> float:
    """Standard error of the channel delay the records were corrected by (0 when none or given)."""
    d = getattr(result, "channel_delay", None)
    se = getattr(d, "stderr_s", 0.0) if d is not None else 0.0
    return float(se) if se is not None and np.isfinite(se) else 0.0


def backbone_from_campaign(result, campaign=None, *, joint_laws=True, direction="rotation", n_points=40,
                           **fit_options) -> CampaignBackbones:
    """All backbones of an identified campaign (module docstring).

    Parameters
    ----------
    result : CampaignResult
    campaign : Campaign or path, optional
        Needed for the ring-down records and the FE modes; default ``result.root``.
    joint_laws : bool
        Fit the joint laws when the structure has an FE model.
    direction : {"rotation", "transverse"}
        The joint's loaded direction.
    n_points : int
        Points of the model backbone.
    **fit_options
        Passed to :func:`jointid.signal.ringdown.fit_decay`.
    """
    from ..io.campaign import Campaign, load_campaign

    if campaign is None and getattr(result, "root", None):
        campaign = result.root
    if campaign is not None and not isinstance(campaign, Campaign):
        campaign = load_campaign(campaign)
    models = getattr(result, "models", {}) or {}
    specs = list(campaign.records) if campaign is not None else [r.spec for r in result.records]
    preloads = []
    for p in dict.fromkeys([s.preload for s in specs] + list(models)):
        errors = {}
        structure = None
        try:
            structure = _structure_of(campaign, p, result)
        except JointidError as exc:
            errors["structure"] = str(exc)
        model_bb = None
        if models.get(p) is not None:
            try:
                model_bb = preload_model_backbone(models[p], n_points=n_points, label=f"preload {p}")
            except JointidError as exc:
                errors["model"] = str(exc)
        ok = [r for r in result.records if r.ok and r.spec.preload == p and r.signals is not None
              and getattr(r.spec, "excitation", "stepped-sine") == "stepped-sine"]
        stepped = res = None
        gains, gain_se = _record_gains(result, ok)
        if any(g is None for g in gains):
            errors["stepped_sine"] = (f"{sum(g is None for g in gains)} record(s) without an identified force gain "
                                      "(unknown gain, no pooled fit of their group) left out of the stepped-sine points")
            keep = [i for i, g in enumerate(gains) if g is not None]
            ok, gains, gain_se = [ok[i] for i in keep], [gains[i] for i in keep], [gain_se[i] for i in keep]
        if ok:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                stepped = equivalent_linearisation([r.signals for r in ok], force_level=[r.spec.force_level for r in ok],
                                                   force_gain=gains, force_gain_stderr=gain_se,
                                                   delay_stderr=_delay_stderr(result), label=f"preload {p}")
                res = phase_resonance_points(stepped, label=f"preload {p}")
        rds = []
        for s in specs:
            if s.preload != p or getattr(s, "excitation", "") != "ringdown":
                continue
            try:
                d = ringdown_decay(s, structure, **fit_options)
                rd = d.backbone(label=f"{s.file}")
                off = _off_the_mode(rd, model_bb if model_bb is not None else stepped)
                if off:
                    errors[f"record {s.index}"] = f"{where(s.file, s.index)}{off}"
                    continue
                rds.append(rd)
            except JointidError as exc:
                errors[f"record {s.index}"] = str(exc)
            except (np.linalg.LinAlgError, ValueError, ArithmeticError) as exc:  # fails this record only
                errors[f"record {s.index}"] = (f"{where(s.file, s.index)}not a usable free decay: the decay fit "
                                               f"failed ({type(exc).__name__}: {exc})")
        pb = PreloadBackbones(p, model_bb, stepped, res, tuple(rds), {}, errors)
        if joint_laws and structure is not None and structure.modes is not None:
            meas = pb.measured()
            if meas is not None and len(meas) >= 4:
                try:
                    z0 = float(np.nanmedian(meas.zeta[np.argsort(meas.amplitude)[:3]]))
                    modes = JointModes.from_modal_model(structure.modes, direction, z0)
                    pb = PreloadBackbones(p, model_bb, stepped, res, tuple(rds), fit_joint_laws(meas, modes, direction=direction),
                                          errors)
                except (JointidError, np.linalg.LinAlgError, ValueError) as exc:
                    errors["joint_laws"] = str(exc)
                    warnings.warn(f"preload {p}: joint laws not fitted ({exc})", JointidWarning, stacklevel=2)
        preloads.append(pb)
    return CampaignBackbones(tuple(preloads))


#: A ring-down whose frequency is further than this factor from its preload's identified mode is not used.
RINGDOWN_FREQUENCY_FACTOR = 1.5


def _off_the_mode(rd, reference) -> str:
    """Why a ring-down's backbone ``rd`` is not of the mode ``reference`` (the preload's model or stepped-sine
    backbone) identifies: its median frequency further than :data:`RINGDOWN_FREQUENCY_FACTOR` from the mode's
    (another mode, or a time column in another unit); ``""`` when it is near, or nothing to compare with."""
    if reference is None or not len(rd) or not len(reference):
        return ""
    f_rd = np.nanmedian(np.asarray(rd.omega, float)) / (2 * np.pi)
    f_ref = np.nanmedian(np.asarray(reference.omega, float)) / (2 * np.pi)
    if not (np.isfinite(f_rd) and np.isfinite(f_ref) and f_rd > 0 and f_ref > 0):
        return ""
    ratio = f_rd / f_ref
    if 1 / RINGDOWN_FREQUENCY_FACTOR <= ratio <= RINGDOWN_FREQUENCY_FACTOR:
        return ""
    hint = " (1000 times off: a time column in ms?)" if abs(np.log10(ratio) + 3) < 0.1 or abs(np.log10(ratio) - 3) < 0.1 \
        else ""
    return (f"the free decay rings at {f_rd:.4g} Hz, {ratio:.3g} times the frequency of the mode the preload's "
            f"records identify ({f_ref:.4g} Hz){hint}: another mode or another time unit, not a backbone of this "
            "mode; left out")


MAX_LAW_ORDER = 10  # the largest damping order identify fits (IdentifySettings.damping_order)
MAX_TERMS = 50
MAX_POINTS = 100_000  # points of a saved backbone


def _shown(v) -> str:
    r = repr(v)
    return r if len(r) <= 80 else r[:77] + "..."


def _is_num(v, allow_null=False) -> bool:
    if v is None:
        return allow_null
    return isinstance(v, (int, float)) and not isinstance(v, bool) and bool(np.isfinite(v))


def _check_saved_backbone(d, at):
    """A saved backbone (``Backbone.summary()``): equal-length lists of numbers (null: not measured)."""
    if not isinstance(d, dict):
        raise ManifestError(f"{at}: a backbone (JSON object) expected, got {_shown(d)}")
    n = None
    for k in ("amplitude", "omega", "zeta", "omega_stderr", "zeta_stderr", "amplitude_stderr"):
        v = d.get(k)
        if v is None and k in ("amplitude_stderr", "omega_stderr", "zeta_stderr"):
            continue
        if not isinstance(v, list) or len(v) > MAX_POINTS or not all(_is_num(x, allow_null=True) for x in v):
            raise ManifestError(f"{at}.{k}: a list of numbers (null: none) expected, got {_shown(v)}")
        if n is not None and len(v) != n and v:
            raise ManifestError(f"{at}.{k}: {len(v)} values, but the backbone has {n} points")
        n = len(v) if n is None else n
    for k in ("label", "source"):
        if k in d and not isinstance(d[k], str):
            raise ManifestError(f"{at}.{k}: a string expected, got {_shown(d[k])}")
    if d.get("meta") is not None and not isinstance(d["meta"], dict):
        raise ManifestError(f"{at}.meta: a JSON object expected, got {_shown(d['meta'])}")


def _check_model_entry(m, at):
    """A ``models`` entry that gives a backbone: terms, laws, parameters and covariance that fit together."""
    from ..identify.model import law_size
    from ..identify.powerlaw import is_power
    from ..identify.terms import library

    terms = m.get("terms")
    if not (isinstance(terms, str) or (isinstance(terms, list) and terms and all(isinstance(t, str) for t in terms))) \
            or (isinstance(terms, list) and len(terms) > MAX_TERMS):
        raise ManifestError(f"{at}.terms: a list of up to {MAX_TERMS} term names expected, got {_shown(terms)}")
    try:
        lib = library(terms)
    except Exception as exc:  # noqa: BLE001 - any parse failure of user data is a bad entry
        raise ManifestError(f"{at}.terms: not a term library: {exc}") from None
    laws = m.get("amplitude_laws") or {}
    if not isinstance(laws, dict):
        raise ManifestError(f"{at}.amplitude_laws: a JSON object of term -> order expected, got {_shown(laws)}")
    orders = {}
    for k, v in laws.items():
        try:
            coefficient = lib[k].coefficient
        except (KeyError, IndexError, TypeError):
            raise ManifestError(f"{at}.amplitude_laws: {k!r} is no term of the model "
                                f"({', '.join(t.name for t in lib)})") from None
        if not (is_power(v) or (isinstance(v, int) and not isinstance(v, bool) and 0 <= v <= MAX_LAW_ORDER)):
            raise ManifestError(f"{at}.amplitude_laws.{k}: an order from 0 to {MAX_LAW_ORDER} or \"power\" "
                                f"expected, got {_shown(v)}")
        orders[coefficient] = v
    n = sum(law_size(orders.get(t.coefficient, 0)) for t in lib)
    params = m.get("parameters")
    if not isinstance(params, list) or not all(_is_num(x) for x in params):
        raise ManifestError(f"{at}.parameters: a list of finite numbers expected, got {_shown(params)}")
    if len(params) != n:
        raise ManifestError(f"{at}.parameters: {len(params)} values, but terms and amplitude_laws give {n}")
    cov = m.get("covariance")
    if cov is not None and not (isinstance(cov, list) and len(cov) == n and all(
            isinstance(row, list) and len(row) == n and all(_is_num(x, allow_null=True) for x in row) for row in cov)):
        shape = f"{len(cov)} rows" if isinstance(cov, list) else type(cov).__name__
        raise ManifestError(f"{at}.covariance: a {n} x {n} matrix of numbers (or null) expected, got {shape}")
    if cov is not None:
        _check_covariance(cov, f"{at}.covariance", m.get("parameter_names"))
    rng = m.get("q_max_range")
    if rng is not None and not (isinstance(rng, list) and len(rng) == 2 and all(_is_num(x, allow_null=True) for x in rng)
                                and (None in rng or 0 < rng[0] <= rng[1])):
        raise ManifestError(f"{at}.q_max_range: a pair [low, high] of amplitudes with 0 < low <= high expected, "
                            f"got {_shown(rng)}")


def _check_covariance(cov, at, names=None) -> None:
    """A covariance matrix (its defined part): symmetric, no negative variance, positive semi-definite
    to rounding; otherwise :class:`ManifestError` (its standard errors would be made up)."""
    C = np.array([[np.nan if x is None else x for x in row] for row in cov], float)
    if C.size == 0 or not np.all(np.isfinite(C)):
        return  # undefined entries: the prediction gives no standard error (said there)
    d = np.diag(C)
    if np.any(d < 0):
        k = int(np.argmin(d))
        name = names[k] if isinstance(names, list) and k < len(names) else f"parameter {k}"
        raise ManifestError(f"{at}: the variance of {name} is negative ({d[k]:.3g}): not a covariance matrix")
    scale = max(float(d.max()), np.finfo(float).tiny)
    if not np.allclose(C, C.T, rtol=1e-6, atol=1e-9 * scale):
        raise ManifestError(f"{at}: not symmetric: not a covariance matrix")
    s = np.sqrt(d)
    s = np.where(s > 0, s, 1.0)
    lam = np.linalg.eigvalsh(C / np.outer(s, s))  # the correlation matrix: a negative eigenvalue beyond rounding
    if lam.min() < -1e-6 * max(lam.max(), 1.0):
        raise ManifestError(f"{at}: not positive semi-definite (an eigenvalue of its correlation matrix is "
                            f"{lam.min():.3g}): not a covariance matrix")


def _check_label(v, at):
    if not (v is None or isinstance(v, str) or _is_num(v)):
        raise ManifestError(f"{at}: a preload label (string or number) expected, got {_shown(v)}")


def check_results_for_backbones(results, source="results.json") -> None:
    """The parts of a ``results.json`` that :func:`backbones_from_results` reads, checked like a manifest.

    Raises
    ------
    jointid.errors.ManifestError
        Naming the file and the JSON path of the bad entry (``models[0].parameters``).
    """
    if not isinstance(results, dict):
        raise ManifestError(f"{source}: not a results.json of jointid: a JSON object expected, got "
                            f"{type(results).__name__ if results is not None else 'null'}")
    models = results.get("models")
    if models is not None and not isinstance(models, list):
        raise ManifestError(f"{source}: models: a list expected, got {_shown(models)}")
    for j, m in enumerate(models or []):
        at = f"{source}: models[{j}]"
        if not isinstance(m, dict):
            raise ManifestError(f"{at}: a model (JSON object) expected, got {_shown(m)}")
        _check_label(m.get("preload"), f"{at}.preload")
        if m.get("parameters") is None:
            continue  # a preload that was not identified
        if "terms" not in m:
            continue  # a first-harmonic model: its backbone is the saved one (checked below)
        _check_model_entry(m, at)
    bb = results.get("backbones")
    if bb is not None and not isinstance(bb, dict):
        raise ManifestError(f"{source}: backbones: a JSON object expected, got {_shown(bb)}")
    preloads = (bb or {}).get("preloads")
    if preloads is not None and not isinstance(preloads, list):
        raise ManifestError(f"{source}: backbones.preloads: a list expected, got {_shown(preloads)}")
    for j, e in enumerate(preloads or []):
        at = f"{source}: backbones.preloads[{j}]"
        if not isinstance(e, dict):
            raise ManifestError(f"{at}: a JSON object expected, got {_shown(e)}")
        _check_label(e.get("preload"), f"{at}.preload")
        for k in ("model", "stepped_sine", "phase_resonance"):
            if e.get(k):
                _check_saved_backbone(e[k], f"{at}.{k}")
        ring = e.get("ringdown")
        if ring is not None and not isinstance(ring, list):
            raise ManifestError(f"{at}.ringdown: a list expected, got {_shown(ring)}")
        for i, d in enumerate(ring or []):
            _check_saved_backbone(d, f"{at}.ringdown[{i}]")
    for j, m in enumerate(models or []):
        if isinstance(m, dict) and m.get("parameters") is not None and "terms" not in m and not any(
                isinstance(e, dict) and e.get("preload") == m.get("preload") and e.get("model")
                for e in preloads or []):
            raise ManifestError(f"{source}: models[{j}]: no 'terms' and no saved model backbone of preload "
                                f"{m.get('preload')!r} under backbones.preloads")


def backbones_from_results(results, n_points=40, n_harmonics=1) -> CampaignBackbones:
    """The backbones of a saved identification (``results.json`` path or its parsed dict).

    Each preload's model (``models``) gives its backbone with bands; the measured points
    and joint laws saved under ``backbones`` are drawn alongside (joint laws as their
    parameter tables).
    """
    import json
    from pathlib import Path

    if not isinstance(results, dict):
        path = Path(results)
        try:
            results = json.loads(path.read_text())
        except FileNotFoundError:
            from ..errors import RecordFileNotFoundError

            raise RecordFileNotFoundError(f"{path}: no such results file") from None
        except (OSError, ValueError, RecursionError) as exc:
            raise RecordError(f"{path}: not a readable results.json ({exc})") from None
        check_results_for_backbones(results, str(path))
    else:
        check_results_for_backbones(results, "results")
    saved = {}
    for entry in ((results.get("backbones") or {}).get("preloads") or []):
        saved[entry.get("preload")] = entry
    out = []
    models = [m for m in results.get("models") or [] if m.get("parameters") is not None]
    for p in dict.fromkeys([m.get("preload") for m in models] + list(saved)):
        errors = {}
        model_bb = None
        m = next((m for m in models if m.get("preload") == p), None)
        e = saved.get(p) or {}
        if m is not None and "terms" not in m and e.get("model"):  # a model kept as its backbone (first harmonics)
            model_bb = Backbone.from_summary(e["model"])
        elif m is not None:
            try:
                model_bb = preload_model_backbone(m, n_points=n_points, n_harmonics=n_harmonics, label=f"preload {p}")
            except JointidError as exc:
                errors["model"] = str(exc)
        neg = _negative_damping(model_bb)
        if neg:
            errors["model damping"] = neg
        e = saved.get(p) or {}
        pick = (lambda d: None if not d else Backbone.from_summary(d))
        out.append(PreloadBackbones(p, model_bb, pick(e.get("stepped_sine")), pick(e.get("phase_resonance")),
                                    tuple(Backbone.from_summary(d) for d in e.get("ringdown") or []), {}, errors))
    if not out:
        raise RecordError("the results hold no identified model and no backbone")
    return CampaignBackbones(tuple(out))


def _negative_damping(bb) -> str | None:
    """What is wrong with a model backbone whose damping ratio is negative somewhere, or None."""
    if bb is None or not len(bb):
        return None
    z = np.asarray(bb.zeta, float)
    neg = np.isfinite(z) & (z < 0)
    if not neg.any():
        return None
    a = np.asarray(bb.amplitude, float)[neg]
    return (f"the model's damping ratio is negative at {int(neg.sum())} of {z.size} amplitudes ({a.min():.4g} to "
            f"{a.max():.4g}, down to {100 * z[neg].min():.3g} %): a joint dissipates energy, so the model does "
            "not hold there")


def write_backbone_figures(backbones: CampaignBackbones, out_dir, inputs=()) -> list:
    """The backbones of a saved identification as one output set in ``out_dir``: one PNG per preload
    (``backbone_<preload>.png``) and ``backbones.json`` (:meth:`CampaignBackbones.summary`); returns
    the figures' paths.

    The folder is replaced as a whole (:func:`jointid.io.outputset.output_set`, kind ``backbone``):
    never a mix with an earlier run, never a folder holding anything else or one of ``inputs``.
    """
    from pathlib import Path

    from ..io.outputset import output_set
    from ..io.results import write_json
    from ..report.formatting import slug

    out = Path(out_dir)
    names = []
    with output_set(out, kind="backbone", inputs=inputs) as tmp:
        write_json(tmp / "backbones.json", backbones.summary())
        for p in backbones.preloads:
            fig, _ = p.plot()
            name = f"backbone_{slug(p.preload)}.png"
            fig.savefig(tmp / name, dpi=120)
            names.append(name)
    return [out / n for n in names]
