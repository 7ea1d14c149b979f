"""Campaign identification: records -> state signals -> force-state mapping -> laws.

:func:`identify_campaign` runs the whole chain on a campaign folder (or a parsed
:class:`~jointid.io.campaign.Campaign`) and returns a frozen :class:`CampaignResult`.
A record that cannot be used is reported as failed with the reason, and the other
records still finish.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field, replace

import numpy as np

from .._blas import single_threaded
from ..errors import IdentificationError, IllConditionedWarning, JointidWarning
from ..identify.fsm import PooledFit, PooledForceStateMapping, band_average
from ..identify.gain import PooledGainForceStateMapping
from ..identify.laws import (
    PowerLaw,
    cycle_energy,
    dissipated_energy,
    elastic_force_amplitude,
    fit_damping_law,
    fit_power_law,
    model_power_law,
)
from ..identify.model import PreloadForceStateMapping
from ..identify.uncertainty import LowRankCovariance, ci95
from ..identify.terms import library
from ..io.campaign import Campaign, load_campaign
from .records import IdentifySettings, RecordOutcome, flag_group_outliers, process_all, process_record

__all__ = ["IdentifySettings", "RecordOutcome", "GroupResult", "CampaignResult", "identify_campaign", "process_record"]


@dataclass(frozen=True)
class GroupResult:
    """One (preload, force level) group: pooled fit, band average and power law."""

    preload: object
    force_level: object
    record_indices: tuple
    pooled: PooledFit | None
    band: dict | None
    power_law: PowerLaw | None = None
    power_law_error: str | None = None
    gain: object = None  # GainFit when the force gain was identified

    def summary(self) -> dict:
        d = {"preload": self.preload, "force_level": self.force_level, "records": list(self.record_indices)}
        if self.gain is not None:
            g, se = self.gain.derived()["gain"]
            d.update(force_gain=g, force_gain_stderr=se, force_gain_ci95=ci95(g, se),
                     omega1_per_record=list(self.gain.omega1_per_record))
        if self.pooled is not None:
            d.update(
                omega1=self.pooled.omega1,
                omega1_stderr=self.pooled.omega1_stderr,
                f1_hz=self.pooled.omega1 / (2 * np.pi),
                k3=self.pooled.k3,
                k3_stderr=self.pooled.get_stderr("k3") if "k3" in self.pooled.shared_names else None,
                omega1_ci95=ci95(self.pooled.omega1, self.pooled.omega1_stderr),
                k3_ci95=ci95(self.pooled.k3, self.pooled.get_stderr("k3")) if "k3" in self.pooled.shared_names else None,
                method="paper (Table 5): pooled fit per force level, omega1 and k3 shared, one c per record",
                pooled=self.pooled.summary(),
            )
        if self.band is not None:
            d.update(
                omega1_mean=self.band["omega1"],
                f1_hz_mean=self.band["omega1"] / (2 * np.pi),
                k3_mean=self.band.get("k3"),
                band_average=self.band,
            )
        return d

    def __repr__(self):
        k3 = f", k3={self.pooled.k3:.4g}" if self.pooled is not None and self.pooled.k3 is not None else ""
        w1 = f", omega1={self.pooled.omega1:.6g} rad/s" if self.pooled is not None else ""
        return f"GroupResult(preload={self.preload!r}, force_level={self.force_level!r}: " \
               f"{len(self.record_indices)} records{w1}{k3})"

    def _repr_html_(self):
        from ..report.notebook import result_html

        return result_html(self)


@dataclass(frozen=True)
class CampaignResult:
    """Everything identified from a campaign.

    ``summary()`` is the content of ``results.json``; ``report()`` prints the tables.
    """

    name: str
    root: str
    settings: IdentifySettings
    records: tuple
    groups: tuple
    damping_laws: dict
    damping_law_errors: dict = field(default_factory=dict)
    repredictions: tuple = ()  # Reprediction per group (jointid.app.reprediction)
    loops: tuple = ()  # measured vs identified hysteresis loop errors per group
    structures: dict = field(default_factory=dict)  # preload -> Structure (physical campaigns; Table 4)
    channel_delay: object = None  # ChannelDelay applied to every record (jointid.identify.delay)
    channel_delay_error: str | None = None
    broadband: tuple = ()  # BroadbandGroup per group of multisine / random records (jointid.app.broadband_records)
    models: dict = field(default_factory=dict)  # PreloadModel per preload (one regression over its records)
    model_errors: dict = field(default_factory=dict)
    backbones: object = None  # CampaignBackbones (jointid.app.backbones): omega(a), zeta(a), joint laws
    adequacy: dict = field(default_factory=dict)  # AdequacyResult per preload (jointid.identify.adequacy)
    adequacy_errors: dict = field(default_factory=dict)
    selections: dict = field(default_factory=dict)  # SelectionResult per preload (terms="auto")
    selection_errors: dict = field(default_factory=dict)

    @property
    def failed(self):
        return [r for r in self.records if not r.ok]

    @property
    def flagged(self):
        """Identified records flagged by a plausibility check (left out of the pooled fits unless
        ``settings.keep_flagged``)."""
        return [r for r in self.records if r.ok and r.flags]

    @property
    def misfits(self) -> list:
        """Campaign-level regressions whose model does not fit the data to their errors
        (:mod:`jointid.app.fit_checks`; ``results.json`` key ``fit_checks``)."""
        from .fit_checks import fit_checks, misfits

        return misfits(fit_checks(self))

    def group(self, preload, force_level) -> GroupResult:
        for g in self.groups:
            if g.preload == preload and g.force_level == force_level:
                return g
        raise KeyError((preload, force_level))

    def summary(self) -> dict:
        from .. import __version__

        return {
            "jointid_version": __version__,
            "campaign": {"name": self.name, "folder": self.root},
            "settings": self.settings.summary(),
            "records": [_record_summary(r) for r in self.records],
            "groups": [g.summary() for g in self.groups],
            "damping_law": [
                {"preload": p, **law.summary()} if law is not None else {"preload": p, "coefficients": None,
                                                                          "error": self.damping_law_errors.get(p)}
                for p, law in self.damping_laws.items()
            ],
            "power_law": [
                {"preload": g.preload, "force_level": g.force_level,
                 **(g.power_law.summary() if g.power_law else {"alpha": None, "n": None, "error": g.power_law_error})}
                for g in self.groups
            ],
            "models": [
                self.models[p].summary() if self.models.get(p) is not None
                else {"preload": p, "omega1": None, "error": self.model_errors.get(p)}
                for p in sorted(set(self.models) | set(self.model_errors), key=_group_key)
            ],
            "n_records": len(self.records),
            "n_failed": len(self.failed),
            "reprediction": {"groups": [r.summary() for r in self.repredictions], "loops": list(self.loops)},
            "structures": [{"preload": p, **s.summary()} for p, s in self.structures.items()],
            "channel_delay": (self.channel_delay.summary() if self.channel_delay is not None
                              else {"delay_s": None, "error": self.channel_delay_error}),
            "broadband": [b.summary() for b in self.broadband],
            "flagged": [{"index": r.spec.index, "file": r.spec.file, "flags": [f.name for f in r.flags],
                         "in_pooled_fits": self.settings.keep_flagged} for r in self.flagged],
            "backbones": None if self.backbones is None else self.backbones.summary(),
            "adequacy": [self.adequacy[p].summary() if self.adequacy.get(p) is not None
                         else {"preload": p, "adequate": None, "error": self.adequacy_errors.get(p)}
                         for p in sorted(set(self.adequacy) | set(self.adequacy_errors), key=_group_key)],
            "fit_checks": _fit_checks(self),
            "selection": [self.selections[p].summary() if self.selections.get(p) is not None
                          else {"preload": p, "selected": None, "error": self.selection_errors.get(p)}
                          for p in sorted(set(self.selections) | set(self.selection_errors), key=_group_key)],
        }

    def report(self) -> str:
        from ..report.tables import campaign_report

        return campaign_report(self)

    def __repr__(self):
        preloads = ", ".join(str(p) for p in self.damping_laws)
        return (f"CampaignResult({self.name!r}: {len(self.records)} records, {len(self.failed)} failed, "
                f"{len(self.flagged)} flagged, {len(self.groups)} groups, preloads [{preloads}])")

    def _repr_html_(self):
        from ..report.notebook import result_html

        return result_html(self)


def _fit_checks(result) -> list:
    from .fit_checks import fit_checks

    return fit_checks(result)


def _gain_free(gain, terms) -> PooledFit:
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


def _group_key(value):
    return (0, value) if isinstance(value, (int, float)) else (1, str(value))


def _record_summary(r) -> dict:
    """A record's summary with the 95 % intervals of its estimates and its measured energy per cycle."""
    d = r.summary()
    fit = r.fit
    if fit is None:
        return d
    gain_free = getattr(r, "omega1_own", None) is not None
    c_se = r.c_pooled_stderr if gain_free else fit.c_stderr
    d.update(
        c_stderr=c_se,
        c_ci95=ci95(d.get("c"), c_se),
        c_pooled_ci95=ci95(r.c_pooled, r.c_pooled_stderr),
    )
    if not gain_free:
        d.update(
            omega1_stderr=fit.omega1_stderr,
            omega1_ci95=ci95(fit.omega1, fit.omega1_stderr),
            ci95={n: ci95(v, s) for n, v, s in zip(fit.coefficient_names, fit.coefficients, fit.stderr)},
        )
    sc = fit.scores
    if sc is not None and sc.force_coefficients is not None and r.signals is not None:
        d["energy_measured"] = cycle_energy(sc.force_coefficients, r.signals.velocity.coefficients, r.signals.omega)
    return d


def _c_covariance(groups, members_of, idx):
    """Covariance of the pooled per-record ``c`` of the records ``idx`` (one preload), low-rank per group,
    with each record's ``var(q_max)`` and ``cov(c, q_max)``: keyword arguments of :func:`fit_damping_law`."""
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
    return {"c_covariance": LowRankCovariance(C.d[pos], C.U[pos], C.W, C.W_inv),
            "q_max_variance": np.array(qv)[pos], "c_q_max_covariance": np.array(cq)[pos]}


def _record_structures(campaign, Structure):
    """One :class:`~jointid.modal.structure.Structure` per record of a physical campaign.

    With per-preload ``[structure.<preload>]`` tables each preload's records use their
    own structure (built once per preload); otherwise every record uses ``[structure]``.
    Returns ``(per-record list, {preload: Structure})``.
    """
    manifest = campaign.root / "campaign.toml"
    if getattr(campaign, "structures", None) is None:
        s = Structure.from_mapping(campaign.structure, source=str(manifest))
        return [s] * len(campaign.records), {r.preload: s for r in campaign.records}
    built, per_record = {}, []
    for spec in campaign.records:
        key = str(spec.preload)
        if key not in built:
            built[key] = (spec.preload, Structure.from_mapping(campaign.structure_for(spec.preload),
                                                              source=f"{manifest} [structure.{spec.preload}]"))
        per_record.append(built[key][1])
    return per_record, dict(built.values())


def summary_warning(notes, n_records, stacklevel=2):
    """One warning for a whole campaign: the kinds of message with their counts and one example
    each (every message stays on its record and in ``results.json``).  Its category is the
    messages' common category, or :class:`JointidWarning` when they differ."""
    if not notes:
        return
    from ..report.summary import group_messages

    cats = {c for _, c in notes}
    category = cats.pop() if len(cats) == 1 else JointidWarning
    kinds = group_messages(t for t, _ in notes)
    lines = [example if n == 1 else f"{n} x {kind} (e.g. {example})" for kind, n, example in kinds[:12]]
    if len(kinds) > 12:
        lines.append(f"... and {len(kinds) - 12} more kinds")
    warnings.warn(f"{len(notes)} warnings over {n_records} records (each kept on its record: "
                  f"result.records[i].warnings, results.json):\n  " + "\n  ".join(lines), category,
                  stacklevel=stacklevel + 1)


#: stacklevel of a warning issued in :func:`_identify_campaign` that points at the caller's line:
#: past _identify_campaign, identify_campaign and its single-threaded wrapper
_CALLER = 4


@single_threaded
def identify_campaign(campaign, settings: IdentifySettings | None = None, **kw) -> CampaignResult:
    """Identify every record of a campaign, then the groups and the laws.

    Parameters
    ----------
    campaign : path or Campaign
    settings : IdentifySettings, optional
    **kw
        Overrides of :class:`IdentifySettings` fields (``terms=...``, ``n_harmonics=...``).
    """
    from .provenance import RunClock, attach_provenance

    clock = RunClock()
    return attach_provenance(_identify_campaign(campaign, settings, **kw), clock)


def _identify_campaign(campaign, settings: IdentifySettings | None = None, **kw):
    if settings is None:
        settings = IdentifySettings(**kw)
    elif kw:
        settings = replace(settings, **kw)
    if not isinstance(campaign, Campaign):
        campaign = load_campaign(campaign)
    from .firstharmonic_campaign import identify_first_harmonic_campaign, is_first_harmonic_campaign

    if is_first_harmonic_campaign(campaign):  # stepped-sine controller exports: one line per frequency
        return identify_first_harmonic_campaign(campaign, settings)
    from .model_checks import campaign_adequacy, identify_auto, is_auto

    if is_auto(settings.terms):  # the model chosen by the data (jointid.identify.selection)
        return identify_auto(campaign, settings)
    if "q" not in library(settings.terms).names:  # fails early on unknown terms too
        raise IdentificationError(
            f"terms {settings.terms!r} have no linear stiffness term 'q': omega1 (and every law built on it) "
            "is its coefficient; add it, e.g. \"q + q'\" or \"q - q^3 + q'\"")
    to_modal, structures = None, {}
    if campaign.coordinates == "physical":
        from ..modal.structure import Structure

        to_modal, structures = _record_structures(campaign, Structure)

    from .broadband_records import identify_broadband, split_broadband

    sine_specs, to_modal, broadband_specs = split_broadband(campaign.records, to_modal)
    outcomes = flag_group_outliers(process_all(sine_specs, settings, to_modal))
    use = [o.ok if settings.keep_flagged else o.usable for o in outcomes]  # records of the pooled fits
    from .channel_delay import correct_channel_delay

    outcomes, delay, delay_error = correct_channel_delay(outcomes, settings, use)
    if delay_error:
        warnings.warn(f"channel delay not estimated: {delay_error}", JointidWarning, stacklevel=_CALLER)
    use = [o.ok if settings.keep_flagged else o.usable for o in outcomes]  # after the correction
    # every message is kept on its record (results.json); the call ends with one summary warning
    notes = [(w, category) for o in outcomes for w, category in zip(o.warnings, o.warning_types)]
    notes += [(f"record failed: {o.error}", JointidWarning) for o in outcomes if not o.ok]
    kept = "kept in" if settings.keep_flagged else "left out of"
    notes += [(f"{o.spec.file} [record {o.spec.index}]: flagged ({kept} the pooled fits): "
               + "; ".join(f.report() for f in o.flags), JointidWarning) for o in outcomes if o.ok and o.flags]

    # groups: pooled regression and band average
    keys = sorted({o.spec.group for o in outcomes}, key=lambda k: (_group_key(k[0]), _group_key(k[1])))
    groups = []
    outcomes = list(outcomes)
    for key in keys:
        members = [i for i, o in enumerate(outcomes) if o.spec.group == key and use[i]]
        pooled = band = None
        gain = None
        if members:
            ctx = f"group preload={key[0]}, force_level={key[1]}: "
            sigs = [outcomes[i].signals for i in members]
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", JointidWarning)
                if settings.force_gain == "known":
                    pooled = PooledForceStateMapping(settings.terms, weighting=settings.weighting).fit(
                        sigs, context=ctx, fits=[outcomes[i].fit for i in members]).result_
                else:
                    gain = PooledGainForceStateMapping(settings.terms, weighting=settings.weighting).fit(
                        sigs, context=ctx).result_
                    pooled = _gain_free(gain, settings.terms)
            notes += [(w, IllConditionedWarning) for w in pooled.warnings]  # resolution and conditioning
            if gain is None:
                band = band_average([outcomes[i].fit for i in members])
            else:
                band = {"omega1": float(np.mean(gain.omega1_per_record)), "k3": None, "n_records": len(members)}
                for j, i in enumerate(members):
                    outcomes[i] = replace(outcomes[i], omega1_own=float(gain.omega1_per_record[j]))
            if "c" in pooled.own_names:
                for j, i in enumerate(members):
                    outcomes[i] = replace(outcomes[i], c_pooled=float(pooled.get("c")[j]),
                                           c_pooled_stderr=float(pooled.get_stderr("c")[j]))
        groups.append(GroupResult(key[0], key[1], tuple(outcomes[i].spec.index for i in members), pooled, band,
                                  gain=gain))

    # damping law per preload over all its records (pooled c): the paper's two-step method, with the
    # full covariance of the per-record c (correlated through each group's shared coefficients)
    index_of = {o.spec.index: i for i, o in enumerate(outcomes)}
    members_of = {(g.preload, g.force_level): [index_of[x] for x in g.record_indices] for g in groups}
    preloads = sorted({k[0] for k in keys}, key=_group_key)
    laws, law_errors = {}, {}
    for preload in preloads:
        idx = [i for i, o in enumerate(outcomes) if use[i] and o.spec.preload == preload and o.c_pooled is not None]
        try:
            laws[preload] = fit_damping_law(
                [outcomes[i].fit.q_max for i in idx],
                [outcomes[i].c_pooled for i in idx],
                [outcomes[i].c_pooled_stderr for i in idx],
                order=settings.damping_order,
                **_c_covariance([g for g in groups if g.preload == preload], members_of, idx),
            )
        except IdentificationError as exc:
            laws[preload] = None
            law_errors[preload] = f"preload {preload}: {exc}"

    # one model per preload: a single regression over all its records with the damping law inside
    models, model_errors = {}, {}
    for preload in preloads:
        idx = [i for i, o in enumerate(outcomes) if use[i] and o.spec.preload == preload]
        if not idx:
            continue
        if settings.force_gain != "known":
            models[preload] = None
            model_errors[preload] = f"preload {preload}: the preload model needs a known force gain"
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
            model_errors[preload] = f"preload {preload}: {exc}"

    # energy per cycle and power law per group
    final_groups = []
    for g in groups:
        law = laws.get(g.preload)
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
        model = models.get(g.preload)
        if model is not None and len(idx) >= 2:
            # the preload model's energy and elastic force, n with an interval propagated from its covariance
            sig = [outcomes[i].signals for i in idx]
            states = [(s.displacement.coefficients, s.velocity.coefficients, s.omega, outcomes[i].fit.q_max)
                      for s, i in zip(sig, idx)]
            measured = [_record_summary(outcomes[i]).get("energy_measured") for i in idx]
            try:
                power = model_power_law(model, states, [np.nan if m is None else m for m in measured])
                perr = None
                for j, i in enumerate(idx):
                    outcomes[i] = replace(outcomes[i], energy=float(power.energy[j]),
                                          joint_force=float(power.force[j]))
            except IdentificationError as exc:
                perr = perr or f"preload {g.preload}, force level {g.force_level}: {exc}"
        final_groups.append(replace(g, power_law=power, power_law_error=perr))

    summary_warning(notes, len(outcomes), stacklevel=_CALLER)
    result = CampaignResult(
        campaign.name, str(campaign.root), settings, tuple(outcomes), tuple(final_groups), laws, law_errors,
        models=models, model_errors=model_errors,
    )
    result = replace(result, structures=structures, channel_delay=delay, channel_delay_error=delay_error,
                     broadband=identify_broadband(broadband_specs, settings))
    adequacy, adequacy_errors = campaign_adequacy(result)
    result = replace(result, adequacy=adequacy, adequacy_errors=adequacy_errors)
    for a in adequacy.values():
        if a is not None and a.adequate is False:
            warnings.warn(f"preload {a.preload}: {a.verdict}", JointidWarning, stacklevel=_CALLER)
    if settings.repredict:
        from .reprediction import with_repredictions

        result = with_repredictions(result)
    from .backbones import campaign_backbones

    return replace(result, backbones=campaign_backbones(result, campaign))


