"""Campaign identification: records -> state signals -> force-state mapping -> laws.

:func:`identify_campaign` runs the whole chain on a campaign folder (or a parsed
:class:`~jointid.io.campaign.Campaign`) and returns a frozen :class:`CampaignResult`.
A record that cannot be used is reported as failed with the reason, and the other
records still finish.

The chain: the records are processed (:mod:`jointid.app.records`) and corrected for a
channel delay (:mod:`jointid.app.channel_delay`); every pooled fit is made by
:func:`jointid.app.campaign_fit.fit_campaign`; adequacy, re-prediction, backbones and the
broadband records follow, and the :class:`CampaignResult` is built once from all of it.
With ``terms="auto"`` the records are first processed with the seed's terms, the model of
each preload is selected from them (:func:`jointid.app.model_checks.preload_selections`),
and the chain runs once with the selected terms.
"""

from __future__ import annotations

import warnings
from dataclasses import replace

from .._blas import single_threaded
from ..errors import IdentificationError, JointidWarning
from ..identify.terms import SEED_TERMS, library
from ..io.campaign import Campaign, load_campaign
from .campaign_fit import fit_campaign, pooled_mask
from .campaign_result import CampaignResult, GroupResult
from .records import IdentifySettings, RecordOutcome, flag_group_outliers, process_all, process_record

__all__ = ["IdentifySettings", "RecordOutcome", "GroupResult", "CampaignResult", "identify_campaign", "process_record"]


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
    from .model_checks import is_auto

    if is_first_harmonic_campaign(campaign):  # stepped-sine controller exports: one line per frequency
        return identify_first_harmonic_campaign(campaign, settings)
    if is_auto(settings.terms):  # the model chosen by the data (jointid.identify.selection)
        settings, selections, selection_errors = _select_terms(campaign, settings)
    else:
        selections = selection_errors = None
    _check_terms(settings.terms)
    return _identify_stepped_sine(campaign, settings, selections, selection_errors, stacklevel=_CALLER + 1)


def _check_terms(terms) -> None:
    if "q" not in library(terms).names:  # fails early on unknown terms too
        raise IdentificationError(
            f"terms {terms!r} have no linear stiffness term 'q': omega1 (and every law built on it) "
            "is its coefficient; add it, e.g. \"q + q'\" or \"q - q^3 + q'\"")


def _records(campaign, settings):
    """The stepped-sine records processed and corrected for a channel delay.

    Returns ``(outcomes, ChannelDelay or None, delay error, {preload: Structure}, broadband specs)``.
    """
    to_modal, structures = None, {}
    if campaign.coordinates == "physical":
        from ..modal.structure import Structure

        to_modal, structures = _record_structures(campaign, Structure)
    from .broadband_records import split_broadband
    from .channel_delay import correct_channel_delay

    sine_specs, to_modal, broadband_specs = split_broadband(campaign.records, to_modal)
    outcomes = flag_group_outliers(process_all(sine_specs, settings, to_modal))
    outcomes, delay, delay_error = correct_channel_delay(outcomes, settings, pooled_mask(outcomes, settings))
    return outcomes, delay, delay_error, structures, broadband_specs


def _select_terms(campaign, settings):
    """``terms="auto"``: the records processed with the seed's terms, the candidate models of each preload
    ranked on them, and the settings with the selected terms (their union over the preloads).

    Returns ``(settings, {preload: SelectionResult or None}, {preload: error})``.
    """
    from .model_checks import preload_selections, union_terms

    seed = replace(settings, terms=" + ".join(SEED_TERMS))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", JointidWarning)
        first = _records(campaign, seed)[0]
    selections, errors = preload_selections(first, seed)
    for e in errors.values():
        warnings.warn(e, JointidWarning, stacklevel=_CALLER + 1)  # past _select_terms
    return replace(settings, terms=union_terms(selections)), selections, errors


def _record_notes(outcomes, settings) -> list:
    """Every message of the records, failures and flags: ``(message, category)``."""
    notes = [(w, category) for o in outcomes for w, category in zip(o.warnings, o.warning_types)]
    notes += [(f"record failed: {o.error}", JointidWarning) for o in outcomes if not o.ok]
    kept = "kept in" if settings.keep_flagged else "left out of"
    notes += [(f"{o.spec.file} [record {o.spec.index}]: flagged ({kept} the pooled fits): "
               + "; ".join(f.report() for f in o.flags), JointidWarning) for o in outcomes if o.ok and o.flags]
    return notes


def _identify_stepped_sine(campaign, settings, selections=None, selection_errors=None, *, stacklevel):
    """The chain of :func:`identify_campaign` with ``settings.terms`` fixed (module docstring); with
    ``selections`` each preload's model is its selected one (adequacy and re-prediction use it)."""
    outcomes, delay, delay_error, structures, broadband_specs = _records(campaign, settings)
    if delay_error:
        warnings.warn(f"channel delay not estimated: {delay_error}", JointidWarning, stacklevel=stacklevel)
    fit = fit_campaign(outcomes, settings, name=campaign.name, root=str(campaign.root), structures=structures,
                       channel_delay=delay)
    # every message is kept on its record (results.json); the call ends with one summary warning
    summary_warning(_record_notes(fit.records, settings) + fit.notes, len(fit.records), stacklevel=stacklevel)
    from .backbones import campaign_backbones
    from .broadband_records import identify_broadband
    from .model_checks import campaign_adequacy

    broadband = identify_broadband(broadband_specs, settings)
    backbones = campaign_backbones(fit, campaign)  # of the fitted preload models
    if selections is not None:  # each preload's model is its selected one
        fit.models = {**fit.models, **{p: s.model for p, s in selections.items() if s is not None and s.model is not None}}
        fit.selections = selections
    adequacy, adequacy_errors = campaign_adequacy(fit)
    for a in adequacy.values():
        if a is not None and a.adequate is False:
            warnings.warn(f"preload {a.preload}: {a.verdict}", JointidWarning, stacklevel=stacklevel)
    from .fit_checks import fit_checks
    from .reprediction import campaign_loops, loop_errors, repredict_campaign

    hysteresis = campaign_loops(fit)  # each group's measured and identified loops, formed once (the report draws them)
    repredictions, loops = (), ()
    if settings.repredict:
        repredictions, loops = repredict_campaign(fit), tuple(loop_errors(hysteresis))
    return CampaignResult(
        campaign.name, str(campaign.root), settings, fit.records, fit.groups, fit.damping_laws, fit.damping_law_errors,
        repredictions=repredictions, loops=loops, structures=fit.structures, channel_delay=delay,
        channel_delay_error=delay_error, broadband=broadband, models=fit.models, model_errors=fit.model_errors,
        backbones=backbones, adequacy=adequacy, adequacy_errors=adequacy_errors, selections=selections or {},
        selection_errors=selection_errors or {}, fit_checks=tuple(fit_checks(fit)), hysteresis_loops=hysteresis,
    )
