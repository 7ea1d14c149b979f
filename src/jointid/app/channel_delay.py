"""The channel-delay step of a campaign identification (:mod:`jointid.identify.delay`).

With ``IdentifySettings.channel_delay = "estimate"`` the delay of the response channel
behind the excitation channel is estimated from the stepped-sine records with the same
pooled fits the identification uses (:func:`jointid.app.campaign_fit.pooled_fit`; one damping
law per preload, the delay shared by every record); with a number it is taken as known.  Every record is then corrected (its
response series re-timed) and its single-record fit repeated, before the groups and laws
are identified.  The delay and its standard error are reported in ``results.json``
(``channel_delay``).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..errors import IdentificationError
from ..identify.delay import (ChannelDelay, ChannelDelayEstimator, check_delay_plausible, delay_c_stderr,
                              delay_refusal, shift_response)
from ..identify.fsm import ForceStateMapping
from ..signal.checks import Z_LIMIT, Flag
from .campaign_fit import pooled_fit

__all__ = ["correct_channel_delay"]

#: The plausibility flag a channel delay explains (:mod:`jointid.signal.checks`): a record that
#: carries it is used for the estimate, and loses it when its corrected input power is positive.
DELAY_FLAG = "negative_input_power"


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
                pooled = pooled_fit(sigs, settings)[0]  # as the campaign fit makes it
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
        refused = delay_refusal(delay)
        if refused:
            return outcomes, None, refused
        try:  # an estimate beyond a channel delay's size is reported, not applied
            _check_plausible(outcomes, delay)
        except IdentificationError as exc:
            return outcomes, None, str(exc)
    else:
        delay = ChannelDelay(float(mode), 0.0, source="given")
        _check_plausible(outcomes, delay)  # a given delay that cannot be one is refused (exit 2)
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
    return _passive_flags(outcomes, _with_delay_stderr(fixed, delay), delay), delay, None


def _check_plausible(outcomes, delay) -> None:
    """Refuse a delay longer than a fraction of the dwells' period or records (IdentificationError)."""
    ok = [o for o in outcomes if o.ok]
    freqs = [o.signals.frequency_hz for o in ok]
    durations = [o.signals.n_periods / o.signals.frequency_hz for o in ok]
    check_delay_plausible(delay.delay_s, freqs, durations, source=delay.source)


def _with_delay_stderr(outcomes, delay):
    """The estimated delay's standard error carried into each corrected record's damping ``c``."""
    if delay.source != "estimated" or not delay.stderr_s > 0:
        return outcomes
    out = []
    for o in outcomes:
        fit = getattr(o, "fit", None)
        names = tuple(getattr(fit, "coefficient_names", ()))
        if not o.ok or "c" not in names or not np.isfinite(fit.omega1):
            out.append(o)
            continue
        j = names.index("c")
        extra = float(delay_c_stderr(delay, fit.omega1, o.signals.omega))
        stderr = np.array(fit.stderr, float)
        stderr[j] = float(np.hypot(stderr[j], extra))
        cov = None
        if fit.covariance is not None:
            cov = np.array(fit.covariance, float)
            cov[j, j] += extra**2
        out.append(replace(o, fit=replace(fit, stderr=stderr, covariance=cov)))
    return out


#: Flags of a record whose damping is negative after a channel-delay correction.
NEGATIVE_DAMPING = "negative_damping"
DELAY_IMPLAUSIBLE = "channel_delay_implausible"
_SIGN_FLAGS = (DELAY_FLAG, "channel_swap")


def _negative_damping(o, delay):
    """``negative_damping`` flag of a corrected record, or None: its damping coefficient ``c`` negative
    beyond ``Z_LIMIT`` standard errors, or (terms without ``q'``) its mean input power ``<Q q'>``."""
    c = getattr(o.fit, "c", None)
    where_ = f"after the channel-delay correction of {1e3 * delay.delay_s:.4g} ms ({delay.source})"
    if c is not None:
        se = o.fit.c_stderr
        if se is None or not np.isfinite(c) or not (c < 0 and -c > Z_LIMIT * max(se, 0.0)):
            return None
        return Flag(NEGATIVE_DAMPING, f"damping c = {c:.4g} ± {se:.2g} {where_}: negative, and a passive joint "
                                      "dissipates", {"c": c, "c_stderr": se, "delay_s": delay.delay_s})
    from ..signal.checks import record_flags

    sign = [f for f in record_flags(o.signals) if f.name in _SIGN_FLAGS]
    if not sign:
        return None
    p, se = sign[0].values.get("input_power"), sign[0].values.get("input_power_stderr")
    return Flag(NEGATIVE_DAMPING, f"mean input power <Q q'> = {p:.4g} ± {se:.2g} {where_}: negative, and a passive "
                                  "joint dissipates", {"input_power": p, "input_power_stderr": se,
                                                       "delay_s": delay.delay_s})


def _passive_flags(before, after, delay):
    """Flag records whose corrected damping is negative beyond its noise (a passive joint dissipates).

    Each such record gets ``negative_damping``; when the correction turned a record's damping negative
    that had no sign flag before it, the delay itself is implausible for the campaign and every
    corrected record gets ``channel_delay_implausible`` (the delay is one number for all of them).
    """
    after = list(after)
    caused = 0
    for i, (old, o) in enumerate(zip(before, after)):
        f = _negative_damping(o, delay) if o.ok else None
        if f is None:
            continue
        after[i] = replace(o, flags=tuple(o.flags) + (f,))
        if not any(g.name in _SIGN_FLAGS for g in getattr(old, "flags", ())):
            caused += 1
    if caused:
        n_ok = sum(o.ok for o in after)
        f = Flag(DELAY_IMPLAUSIBLE, f"the channel delay {1e3 * delay.delay_s:.4g} ms ({delay.source}) makes the "
                                    f"damping negative at {caused} of {n_ok} records that were not negative "
                                    "without it: the delay does not fit these data",
                 {"delay_s": delay.delay_s, "records_negative": caused, "records": n_ok})
        after = [replace(o, flags=tuple(o.flags) + (f,)) if o.ok else o for o in after]
    return after


def _input_power(signals) -> float:
    """Mean input power ``<Q q'>`` with the (corrected) velocity series."""
    return float(np.mean(np.asarray(signals.force) * signals.velocity(signals.t)))
