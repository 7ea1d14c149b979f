"""The campaign fit: identified records -> groups, damping laws, preload models and power laws.

One module holds every pooled fit of a campaign identification, whatever asks for it:
the plain identification and ``--terms auto`` (:mod:`jointid.app.workflow`) and the
channel-delay estimate (:mod:`jointid.app.channel_delay`, which fits the groups the same
way while it searches the delay).

* :func:`in_pooled_fits` says which records enter the pooled fits (identified, and not
  flagged unless ``settings.keep_flagged``);
* :func:`pooled_fit` is one group's pooled regression (omega1 and k3 shared, one ``c`` per
  record), gain-free (:func:`gain_free`) when the force gain is identified with it;
* :func:`fit_campaign` runs the stages in the paper's order: the pooled fit and band
  average per (preload, force level) group, the damping law per preload over the pooled
  per-record ``c`` with their full covariance, one preload model per preload, and the
  energy per cycle with the power law per group.

Nothing here reads files or writes results: it takes the records' outcomes and returns a
:class:`CampaignFit`.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field, replace

import numpy as np
from scipy import linalg

from ..errors import IdentificationError, IllConditionedWarning, JointidWarning
from ..identify.fsm import PooledFit, PooledForceStateMapping, band_average
from ..identify.gain import PooledGainForceStateMapping
from ..identify.laws import (
    cycle_energy,
    dissipated_energy,
    elastic_force_amplitude,
    fit_damping_law,
    fit_power_law,
    model_power_law,
)
from ..identify.model import PreloadForceStateMapping
from ..identify.terms import library
from ..identify.uncertainty import LowRankCovariance
from ..numerics.intervals import band_mean_resolution
from .campaign_result import GroupResult, group_key

__all__ = ["CampaignFit", "in_pooled_fits", "pooled_mask", "gain_free", "pooled_fit", "with_measured_energy",
           "fit_campaign"]


def in_pooled_fits(outcome, settings) -> bool:
    """Does this record enter the pooled fits?  Identified, and not flagged by a plausibility
    check unless ``settings.keep_flagged``."""
    return outcome.ok if settings.keep_flagged else outcome.usable


def pooled_mask(outcomes, settings) -> list:
    """:func:`in_pooled_fits` of every record."""
    return [in_pooled_fits(o, settings) for o in outcomes]


def gain_free(gain, terms) -> PooledFit:
    """A :class:`PooledFit` of the gain-free coefficients (``theta / m``) of a gain fit."""
    d = gain.derived()
    names = tuple(n for n in gain.shared_names if n != "m")
    vals, errs = [], []
    for n in names:
        if n == "omega1^2":
            w, sw = d["omega1"]
            vals.append(w**2)
            errs.append(2 * w * sw)
        else:
            v, e = d[f"{n}/m"]
            vals.append(v)
            errs.append(e)
    own = np.empty_like(gain.own)
    own_se = np.empty_like(gain.own)
    for j, n in enumerate(gain.own_names):
        own[:, j], own_se[:, j] = gain.per_record(n)
    return PooledFit(library(terms).names, names, np.array(vals), np.array(errs), gain.own_names, own, own_se,
                     gain.q_max, gain.frequency_hz, gain.condition_number, gain.weights, gain.n_samples, gain.warnings)


def pooled_fit(signals, settings, *, context="", fits=None):
    """One group's pooled regression with ``settings`` (terms, weighting, force gain).

    Returns ``(PooledFit, GainFit or None)``: with a known force gain the pooled fit of
    :class:`~jointid.identify.fsm.PooledForceStateMapping` (``fits``: the records' own fits,
    optional); otherwise the gain is identified with the group
    (:class:`~jointid.identify.gain.PooledGainForceStateMapping`) and the pooled fit holds its
    gain-free coefficients.  The fit's own warnings are kept in ``PooledFit.warnings``.
    """
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", JointidWarning)
        if settings.force_gain == "known":
            fsm = PooledForceStateMapping(settings.terms, weighting=settings.weighting)
            return fsm.fit(signals, context=context, fits=fits).result_, None
        gain = PooledGainForceStateMapping(settings.terms, weighting=settings.weighting).fit(
            signals, context=context).result_
        return gain_free(gain, settings.terms), gain


def with_measured_energy(outcomes) -> list:
    """Each identified record with the energy per cycle of its recorded force over its velocity
    (``RecordOutcome.energy_measured``; results.json ``records[].energy_measured``)."""
    out = []
    for o in outcomes:
        sc = o.fit.scores if o.fit is not None else None
        if sc is not None and sc.force_coefficients is not None and o.signals is not None:
            o = replace(o, energy_measured=cycle_energy(sc.force_coefficients, o.signals.velocity.coefficients,
                                                        o.signals.omega))
        out.append(o)
    return out


@dataclass
class CampaignFit:
    """The pooled fits of a campaign (:func:`fit_campaign`), with what the later steps
    (adequacy, re-prediction, backbones) read of the campaign."""

    name: str
    root: str
    settings: object
    records: tuple
    groups: tuple
    damping_laws: dict
    damping_law_errors: dict
    models: dict
    model_errors: dict
    notes: list = field(default_factory=list)  # (message, category) of the fits, for the campaign's warning
    structures: dict = field(default_factory=dict)
    channel_delay: object = None
    selections: dict = field(default_factory=dict)


def _group_fits(outcomes, use, settings):
    """Pooled fit and band average per (preload, force level) group (groups without a usable
    record have none).  Returns ``(groups, outcomes, notes)``; the records of a group get
    their pooled ``c`` (and, with an unknown gain, their own ``omega1``)."""
    keys = sorted({o.spec.group for o in outcomes}, key=lambda k: (group_key(k[0]), group_key(k[1])))
    groups, notes = [], []
    outcomes = list(outcomes)
    for key in keys:
        members = [i for i, o in enumerate(outcomes) if o.spec.group == key and use[i]]
        pooled = band = gain = resolution = None
        if members:
            ctx = f"group preload={key[0]}, force_level={key[1]}: "
            pooled, gain = pooled_fit([outcomes[i].signals for i in members], settings, context=ctx,
                                      fits=[outcomes[i].fit for i in members])
            notes += [(w, IllConditionedWarning) for w in pooled.warnings]  # resolution and conditioning
            if gain is None:
                fits = [outcomes[i].fit for i in members]
                band = band_average(fits)
                if band.get("k3") is not None:
                    resolution = band_mean_resolution([f.k3 for f in fits], band["k3"], pooled.k3,
                                                      pooled.get_stderr("k3") if pooled.k3 is not None else None)
            else:
                band = {"omega1": float(np.mean(gain.omega1_per_record)), "k3": None, "n_records": len(members)}
                for j, i in enumerate(members):
                    outcomes[i] = replace(outcomes[i], omega1_own=float(gain.omega1_per_record[j]))
            if "c" in pooled.own_names:
                for j, i in enumerate(members):
                    outcomes[i] = replace(outcomes[i], c_pooled=float(pooled.get("c")[j]),
                                          c_pooled_stderr=float(pooled.get_stderr("c")[j]))
        groups.append(GroupResult(key[0], key[1], tuple(outcomes[i].spec.index for i in members), pooled, band,
                                  gain=gain, band_resolution=resolution))
    return groups, outcomes, notes


def _c_covariance(groups, members_of, idx, delay_term=None):
    """Covariance of the pooled per-record ``c`` of the records ``idx`` (one preload), low-rank per group,
    with each record's ``var(q_max)`` and ``cov(c, q_max)``: keyword arguments of :func:`fit_damping_law`.

    ``delay_term``: ``(d c / d tau per record of idx, var(tau))`` of an estimated channel delay, one number
    shared by every record: its rank-one term ``var(tau) g g^T`` is added (the records were corrected by the
    estimate, so its error moves every ``c`` at once; :func:`delay_sensitivity`).
    """
    parts, order, qv, cq = [], [], [], []
    for g in groups:
        members = members_of[(g.preload, g.force_level)]
        sel = [j for j, i in enumerate(members) if i in idx]
        if not sel:
            continue
        pf = g.pooled
        if pf is None or pf.covariance is None or "c" not in pf.own_names:
            return {}
        jc = pf.own_names.index("c")
        parts.append(pf.covariance.own_factor(jc, sel))
        qv += list(pf.covariance.q_max_variance[sel])
        cq += list(pf.covariance.own_q_max[sel, jc])
        order += [members[j] for j in sel]
    if not parts or sorted(order) != sorted(idx):  # no usable record: no covariance to build
        return {}
    C = LowRankCovariance.stack(parts)
    pos = [order.index(i) for i in idx]
    C = LowRankCovariance(C.d[pos], C.U[pos], C.W, C.W_inv)
    if delay_term is not None:
        g, var = np.asarray(delay_term[0], float), float(delay_term[1])
        if var > 0 and np.all(np.isfinite(g)):
            W_inv = None if C.W_inv is None else linalg.block_diag(C.W_inv, [[1.0 / var]])
            C = LowRankCovariance(C.d, np.column_stack([C.U, g]), linalg.block_diag(C.W, [[var]]), W_inv)
    return {"c_covariance": C, "q_max_variance": np.array(qv)[pos], "c_q_max_covariance": np.array(cq)[pos]}


def delay_sensitivity(omega1, omega):
    """``d c / d tau`` of a dwell at ``omega`` of a mode at ``omega1``: a response channel late by ``tau``
    adds ``tau (omega1^2 - omega^2)`` to the damping ``c`` (first-order model of :mod:`jointid.identify.delay`)."""
    return np.asarray(omega1, float) ** 2 - np.asarray(omega, float) ** 2


def _delay_term(delay, outcomes, groups, idx):
    """``(d c / d tau, var(tau))`` of the records ``idx`` for an estimated delay, else None; each record's
    ``omega1`` is its group's pooled one."""
    if delay is None or getattr(delay, "source", None) != "estimated":
        return None
    se = getattr(delay, "stderr_s", None)
    if se is None or not np.isfinite(se) or not se > 0:
        return None
    w1 = {(g.preload, g.force_level): g.pooled.omega1 for g in groups if g.pooled is not None}
    try:
        g = [delay_sensitivity(w1[outcomes[i].spec.group], outcomes[i].signals.omega) for i in idx]
    except KeyError:
        return None
    return np.array(g, float), float(se) ** 2


def _damping_laws(outcomes, use, groups, preloads, settings, delay=None):
    """The damping law per preload over all its records' pooled ``c``: the paper's two-step method, with
    the full covariance of the per-record ``c`` (correlated through each group's shared coefficients and,
    with an estimated channel delay, through the delay's error)."""
    index_of = {o.spec.index: i for i, o in enumerate(outcomes)}
    members_of = {(g.preload, g.force_level): [index_of[x] for x in g.record_indices] for g in groups}
    laws, errors = {}, {}
    for preload in preloads:
        idx = [i for i, o in enumerate(outcomes) if use[i] and o.spec.preload == preload and o.c_pooled is not None]
        try:
            laws[preload] = fit_damping_law(
                [outcomes[i].fit.q_max for i in idx],
                [outcomes[i].c_pooled for i in idx],
                [outcomes[i].c_pooled_stderr for i in idx],
                order=settings.damping_order,
                **_c_covariance([g for g in groups if g.preload == preload], members_of, idx,
                                _delay_term(delay, outcomes, groups, idx)),
            )
        except IdentificationError as exc:
            laws[preload] = None
            errors[preload] = f"preload {preload}: {exc}"
    return laws, errors


def _preload_models(outcomes, use, preloads, settings):
    """One model per preload: a single regression over all its records with the damping law inside."""
    models, errors, notes = {}, {}, []
    for preload in preloads:
        idx = [i for i, o in enumerate(outcomes) if use[i] and o.spec.preload == preload]
        if not idx:
            continue
        if settings.force_gain != "known":
            models[preload] = None
            errors[preload] = f"preload {preload}: the preload model needs a known force gain"
            continue
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", JointidWarning)
                models[preload] = PreloadForceStateMapping(
                    settings.terms, damping_order=settings.damping_order, weighting=settings.weighting,
                    preload=preload,
                ).fit([outcomes[i].signals for i in idx], fits=[outcomes[i].fit for i in idx],
                      context=f"preload {preload}: ").result_
            notes += [(w, IllConditionedWarning) for w in models[preload].warnings]
        except IdentificationError as exc:
            models[preload] = None
            text = str(exc)  # the fit's context already names the preload
            errors[preload] = text if text.startswith(f"preload {preload}: ") else f"preload {preload}: {text}"
    return models, errors, notes


def _power_law(g, outcomes, use, law, model):
    """Energy per cycle and elastic force of a group's records, and its power law ``U = alpha F^n``.

    Returns ``(PowerLaw or None, error or None)``; the records get their ``energy`` and
    ``joint_force`` (``outcomes`` is updated in place).  With a preload model the energy and
    force are the model's, with ``n``'s interval propagated from its covariance.
    """
    idx = [i for i, o in enumerate(outcomes) if use[i] and o.spec.group == (g.preload, g.force_level)]
    F, U = [], []
    if g.pooled is not None and idx:
        w1 = g.pooled.omega1
        k3 = g.pooled.k3 or 0.0
        for i in idx:
            o = outcomes[i]
            c = float(law(o.fit.q_max)) if law is not None else o.c_pooled
            if c is None or not np.isfinite(w1):
                continue
            u = dissipated_energy(o.signals.velocity.coefficients, o.signals.omega, lambda v, c=c: c * v)
            f = elastic_force_amplitude(o.signals.displacement.coefficients, w1, k3)
            outcomes[i] = replace(o, energy=u, joint_force=f)
            F.append(f)
            U.append(u)
    power, perr = None, None
    try:
        power = fit_power_law(F, U)
    except IdentificationError as exc:
        perr = f"preload {g.preload}, force level {g.force_level}: {exc}"
    if model is not None and len(idx) >= 2:
        states = [(outcomes[i].signals.displacement.coefficients, outcomes[i].signals.velocity.coefficients,
                   outcomes[i].signals.omega, outcomes[i].fit.q_max) for i in idx]
        measured = [outcomes[i].energy_measured for i in idx]
        try:
            power = model_power_law(model, states, [np.nan if m is None else m for m in measured])
            perr = None
            for j, i in enumerate(idx):
                outcomes[i] = replace(outcomes[i], energy=float(power.energy[j]), joint_force=float(power.force[j]))
        except IdentificationError as exc:
            perr = perr or f"preload {g.preload}, force level {g.force_level}: {exc}"
    return power, perr


def fit_campaign(outcomes, settings, *, name="", root="", structures=None, channel_delay=None) -> CampaignFit:
    """Every pooled fit of a campaign from its records' outcomes (module docstring).

    Parameters
    ----------
    outcomes : sequence of RecordOutcome
        The stepped-sine records, processed (and corrected for a channel delay).
    settings : IdentifySettings
    name, root, structures, channel_delay
        Carried into the :class:`CampaignFit` for the later steps.
    """
    outcomes = with_measured_energy(outcomes)
    use = pooled_mask(outcomes, settings)
    groups, outcomes, notes = _group_fits(outcomes, use, settings)
    preloads = sorted({g.preload for g in groups}, key=group_key)
    laws, law_errors = _damping_laws(outcomes, use, groups, preloads, settings, channel_delay)
    models, model_errors, model_notes = _preload_models(outcomes, use, preloads, settings)
    final = []
    for g in groups:
        power, perr = _power_law(g, outcomes, use, laws.get(g.preload), models.get(g.preload))
        final.append(replace(g, power_law=power, power_law_error=perr))
    return CampaignFit(name, root, settings, tuple(outcomes), tuple(final), laws, law_errors, models, model_errors,
                       notes + model_notes, dict(structures or {}), channel_delay)
