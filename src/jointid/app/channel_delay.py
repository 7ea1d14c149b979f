"""The channel-delay step of a campaign identification (:mod:`jointid.identify.delay`).

With ``IdentifySettings.channel_delay = "estimate"`` the delay of the response channel
behind the excitation channel is estimated from the stepped-sine records with the same
pooled fits the identification uses (one damping law per preload, the delay shared by
every record); with a number it is taken as known.  Every record is then corrected (its
response series re-timed) and its single-record fit repeated, before the groups and laws
are identified.  The delay and its standard error are reported in ``results.json``
(``channel_delay``).
"""

from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np

from ..errors import IdentificationError, JointidWarning
from ..identify.delay import ChannelDelay, ChannelDelayEstimator, shift_response
from ..identify.fsm import ForceStateMapping, PooledForceStateMapping
from ..identify.gain import PooledGainForceStateMapping

__all__ = ["correct_channel_delay"]

#: The plausibility flag a channel delay explains (:mod:`jointid.signal.checks`): a record that
#: carries it is used for the estimate, and loses it when its corrected input power is positive.
DELAY_FLAG = "negative_input_power"


def _pooled(signals, settings):
    """The group's pooled fit as the workflow makes it (gain-free when the gain is unknown)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", JointidWarning)
        if settings.force_gain == "known":
            return PooledForceStateMapping(settings.terms, weighting=settings.weighting).fit(signals).result_
        from .workflow import _gain_free

        gain = PooledGainForceStateMapping(settings.terms, weighting=settings.weighting).fit(signals).result_
        return _gain_free(gain, settings.terms)


def correct_channel_delay(outcomes, settings, use=None):
    """Estimate (or take) the channel delay and correct every identified record by it.

    Parameters
    ----------
    outcomes : sequence of RecordOutcome
    settings : IdentifySettings
        ``channel_delay``: ``None`` (nothing done), ``"estimate"`` or a delay in seconds.
    use : sequence of bool, optional
        Records the estimate may use (default: every identified record).

    Returns
    -------
    (list of RecordOutcome, ChannelDelay or None, str or None)
        The corrected outcomes, the delay, and the reason when it could not be estimated
        (the outcomes are then returned unchanged).  A record flagged for a negative input
        power is used for the estimate, and its flag is cleared when the corrected record
        takes power in.
    """
    mode = settings.channel_delay
    outcomes = list(outcomes)
    if mode is None:
        return outcomes, None, None
    use = [o.ok for o in outcomes] if use is None else list(use)
    if isinstance(mode, str):
        if mode != "estimate":
            raise IdentificationError(f"channel_delay must be 'estimate', a number of seconds or None, got {mode!r}")
        by_group = {}
        for i, o in enumerate(outcomes):
            # a negative input power is what a channel delay causes: such records are kept
            delay_only = o.ok and all(f.name == DELAY_FLAG for f in getattr(o, "flags", ()))
            if o.ok and (use[i] or delay_only):
                by_group.setdefault(o.spec.group, []).append(o.signals)
        by_group = {k: v for k, v in by_group.items() if len(v) >= 2}

        def fit_groups(current):
            out = {}
            for key, sigs in current.items():
                pooled = _pooled(sigs, settings)
                if "c" not in pooled.own_names or not np.isfinite(pooled.omega1):
                    raise IdentificationError("channel delay: the terms need a per-record damping term q'")
                out[key] = (pooled.get("c"), pooled.get_stderr("c"), 2 * np.pi * np.asarray(pooled.frequency_hz),
                            pooled.omega1, np.asarray(pooled.q_max))
            return out

        try:
            per_law = {}
            for key, sigs in by_group.items():
                per_law[key[0]] = per_law.get(key[0], 0) + len(sigs)
            # the damping law's order, lowered until the regression keeps a degree of freedom
            order = max(0, min([settings.damping_order] + [n - 3 for n in per_law.values()]))
            est = ChannelDelayEstimator(fit_groups, law_order=order,
                                        law_of=lambda key: key[0]).fit(by_group)
        except IdentificationError as exc:
            return outcomes, None, str(exc)
        delay = est.result_
    else:
        delay = ChannelDelay(float(mode), 0.0, source="given")
    fixed = []
    for o in outcomes:
        if not o.ok:
            fixed.append(o)
            continue
        sig = shift_response(o.signals, delay.delay_s)
        try:
            fit = ForceStateMapping(settings.terms).fit(sig, context=f"{o.spec.file} [record {o.spec.index}]: ").result_
        except IdentificationError as exc:
            fixed.append(replace(o, status="failed", error=f"after the channel-delay correction: {exc}"))
            continue
        changes = {"signals": sig, "fit": fit}
        flags = tuple(getattr(o, "flags", ()))
        if any(f.name == DELAY_FLAG for f in flags) and _input_power(sig) > 0:
            changes["flags"] = tuple(f for f in flags if f.name != DELAY_FLAG)  # explained by the delay
        fixed.append(replace(o, **changes))
    return fixed, delay, None


def _input_power(signals) -> float:
    """Mean input power ``<Q q'>`` with the (corrected) velocity series."""
    return float(np.mean(np.asarray(signals.force) * signals.velocity(signals.t)))
