"""One record through the chain: read, reduce to state signals, fit; and all records of a campaign.

:func:`process_record` never raises for a bad record: it returns a failed
:class:`RecordOutcome` with the reason, so one record never loses the campaign.
:func:`process_all` runs it over the records of a campaign.

Each record also goes through the plausibility checks of :mod:`jointid.signal.checks`;
a flagged record keeps its fit but is not :attr:`~RecordOutcome.usable`, so the pooled
fits leave it out unless :attr:`IdentifySettings.keep_flagged` is set.
:func:`flag_group_outliers` adds the checks that compare a record with its group.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field, replace

import numpy as np

from ..errors import IdentificationError, JointidError, JointidWarning, where
from ..identify.fsm import ForceStateMapping, RecordFit
from ..identify.terms import library
from ..io.campaign import RecordSpec, read_record
from ..signal.checks import (Z_LIMIT, Flag, check_live, clipping_flag, equivalent_damping, monotone_outliers,
                             record_flags, scale_outliers, trend_outliers)
from ..signal.harmonics import StateSignals, steady_state_signals

__all__ = ["IdentifySettings", "RecordOutcome", "process_record", "process_all", "flag_group_outliers", "Flag"]


@dataclass(frozen=True)
class IdentifySettings:
    """Choices of an identification run (all recorded in ``results.json``).

    Parameters
    ----------
    terms : str
        Restoring-force terms, e.g. ``"q + -q^3 + q'"``.
    n_harmonics : int
        Harmonics fitted to the acceleration (seed: 4).
    damping_order : int
        Order of the ``c(q_max)`` polynomial.
    weighting : {"noise", "none"}
        Record weights in the pooled regression.
    force_gain : {"known", "unknown"}
        ``"unknown"`` when the force column is proportional to the force with an unknown
        factor (a shaker voltage): each group's pooled regression then includes the
        inertia term and identifies the gain; ``omega1``, ``k3`` and ``c`` are gain-free
        (divided by the fitted inertia coefficient), the single-record ``omega1`` is the
        record's own with the shared inertia and cubic held, and single-record ``k3`` is
        not reported (inertia and stiffness separate only across frequencies).
    refine_frequency : bool
        Check a manifest's ``frequency_hz`` on the force and replace a value that would
        drift the phase by more than 0.01 rad over the record (a rounded log), with a warning.
    jobs : int
        Worker processes for the records: ``1``, in this process; ``N``, a local dask
        cluster of ``N`` workers; ``0``, one per core.  Results do not depend on it.
    scheduler : str, optional
        Address of an existing dask scheduler to run the records on (overrides ``jobs``).
    progress : bool
        Show a progress bar.
    channel_delay : None, "estimate" or float
        Delay [s] of the response channel behind the excitation channel: ``None``, no
        correction; a number, a known delay; ``"estimate"``, estimated with its standard
        error from the dwells' damping (:mod:`jointid.identify.delay`).  The records are
        corrected before the groups are identified.
    repredict : bool
        Re-predict every group's measured FRF with its identified model by harmonic
        balance and compare the measured and identified hysteresis loops
        (:mod:`jointid.app.reprediction`; ``reprediction`` in ``results.json``).
    keep_flagged : bool
        Keep records flagged by the plausibility checks in the pooled fits (by default
        they are left out and listed under ``flagged`` in ``results.json``).
    """

    terms: str = "q + -q^3 + q'"
    n_harmonics: int = 5
    damping_order: int = 2
    weighting: str = "noise"
    force_gain: str = "known"
    refine_frequency: bool = True
    jobs: int = 1
    scheduler: str | None = None
    progress: bool = False
    repredict: bool = True
    channel_delay: float | str | None = None
    keep_flagged: bool = False

    def __post_init__(self):
        if self.force_gain not in ("known", "unknown"):
            raise IdentificationError(f"force_gain must be 'known' or 'unknown', got {self.force_gain!r}")
        for name, low, high in (("n_harmonics", 1, 200), ("damping_order", 0, 10), ("jobs", 0, 4096)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not low <= v <= high:
                raise IdentificationError(f"{name} must be an integer from {low} to {high}, got {v!r}")
        if self.weighting not in ("noise", "none"):
            raise IdentificationError(f"weighting must be 'noise' or 'none', got {self.weighting!r}")

    def summary(self) -> dict:
        return {
            "terms": list(library(self.terms).names),
            "n_harmonics": self.n_harmonics,
            "damping_order": self.damping_order,
            "weighting": self.weighting,
            "force_gain": self.force_gain,
            "refine_frequency": self.refine_frequency,
            "channel_delay": self.channel_delay,
            "keep_flagged": self.keep_flagged,
        }  # jobs, scheduler and progress do not change results

@dataclass(frozen=True)
class RecordOutcome:
    """What became of one record."""

    spec: RecordSpec
    status: str
    error: str | None = None
    signals: StateSignals | None = field(default=None, repr=False)
    fit: RecordFit | None = None
    c_pooled: float | None = None
    c_pooled_stderr: float | None = None
    energy: float | None = None
    joint_force: float | None = None
    modal_residual: float | None = None
    warnings: tuple = ()
    omega1_own: float | None = None  # with an unknown force gain: the record's omega1, shared inertia held
    warning_types: tuple = field(default=(), repr=False, compare=False)  # category of each warning
    flags: tuple = ()  # Flag of each failed plausibility check
    energy_measured: float | None = None  # energy per cycle of the recorded force (jointid.app.campaign_fit)

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    @property
    def usable(self) -> bool:
        """Identified and not flagged by a plausibility check: enters the pooled fits by default."""
        return self.ok and not self.flags

    def summary(self) -> dict:
        s = self.spec
        d = {
            "index": s.index,
            "file": s.file,
            "preload": s.preload,
            "force_level": s.force_level,
            "frequency_hz": self.signals.frequency_hz if self.signals is not None else s.frequency_hz,
            "frequency_given": s.frequency_hz is not None,
            "status": self.status,
            "error": self.error,
            "q_max": None,
            "omega1": None,
            "k3": None,
            "c": None,
        }
        if self.fit is not None:
            d.update(
                q_max=self.fit.q_max,
                omega1=self.fit.omega1,
                f1_hz=self.fit.omega1 / (2 * np.pi),
                k3=self.fit.k3,
                c=self.fit.c,
                c_pooled=self.c_pooled,
                c_pooled_stderr=self.c_pooled_stderr,
                energy_per_cycle=self.energy,
                joint_force_amplitude=self.joint_force,
                coefficients=self.fit.summary()["coefficients"],
                stderr=self.fit.summary()["stderr"],
                condition_number=self.fit.condition_number,
                accel_residual_rms=self.signals.accel_residual_rms,
            )
            if self.omega1_own is not None:  # force gain unknown: the single-record fit is in excitation units
                d.update(omega1=self.omega1_own, f1_hz=self.omega1_own / (2 * np.pi), k3=None, c=self.c_pooled,
                         coefficients=None, stderr=None)
        if self.modal_residual is not None:
            d["modal_residual"] = self.modal_residual
        d["warnings"] = list(self.warnings)
        d["flags"] = [f.summary() for f in self.flags]
        d["excitation"] = s.excitation
        return d

def _context(spec: RecordSpec) -> str:
    return where(spec.file, spec.index)


def process_record(spec: RecordSpec, settings: IdentifySettings, to_modal=None) -> RecordOutcome:
    """Read, reduce, check and fit one record; any :class:`JointidError` becomes a failed outcome.

    The plausibility checks (:func:`jointid.signal.checks.record_flags`, and clipping of
    every raw channel) attach their flags to the outcome; a constant channel fails it.
    """
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", JointidWarning)
        try:
            if spec.excitation != "stepped-sine":
                raise IdentificationError(
                    f"excitation {spec.excitation!r} is not supported yet; only 'stepped-sine' records are identified"
                )
            if to_modal is None:
                data = read_record(spec)
                Q, qdd, resid = data.channels["force"], data.channels["accel"], None
                names = ("time", "force", "accel")
            else:
                data = read_record(spec, required=("time",) + tuple(to_modal.required_columns))
                Q, qdd, resid = to_modal.to_modal(data.channels)
                names = ("time", "force (modal)", "accel (modal)")
            for name, x in data.channels.items():
                check_live(x, name)
            flags = [f for f in (clipping_flag(x, name) for name, x in data.channels.items()) if f is not None]
            signals = steady_state_signals(
                data.time, Q, qdd, frequency_hz=spec.frequency_hz, n_harmonics=settings.n_harmonics, channels=names,
                refine_frequency=settings.refine_frequency,
            )
            flags += [f for f in record_flags(signals, channels=names[1:]) if f.name != "clipping"]
            if resid is not None and resid > MODAL_RESIDUAL_LIMIT:
                flags.append(Flag("modal_residual", f"{100 * resid:.3g} % of the accelerations is not explained by "
                                                    f"the mode shape at the sensors (at most "
                                                    f"{100 * MODAL_RESIDUAL_LIMIT:g} %): swapped, mislocated, "
                                                    "flipped or mis-scaled sensors, or another mode",
                                  {"relative_residual": float(resid)}))
            fit = ForceStateMapping(settings.terms).fit(signals, context=_context(spec)).result_
            if not np.all(np.isfinite(fit.coefficients)):
                raise IdentificationError("the regression gave non-finite coefficients; the record carries no "
                                          "usable information")
            w2 = fit.get("omega1^2") if "omega1^2" in fit.coefficient_names else None
            if w2 is not None and not w2 > 0:
                flags.append(Flag("negative_stiffness", f"the linear stiffness omega1^2 = {w2:.4g} is not "
                                                        f"positive; a flipped or mis-scaled channel",
                                  {"omega1^2": w2}))
        except JointidError as exc:
            msg = str(exc)
            if not msg.startswith(str(spec.file)):
                msg = _context(spec) + msg
            return RecordOutcome(spec, "failed", msg, **_caught(caught))
        except Exception as exc:  # noqa: BLE001 - one record must never lose the campaign
            msg = f"{_context(spec)}unexpected {type(exc).__name__}: {exc}"
            return RecordOutcome(spec, "failed", msg, **_caught(caught))
    return RecordOutcome(spec, "ok", None, signals, fit, modal_residual=resid, flags=tuple(flags), **_caught(caught))


def flag_group_outliers(outcomes) -> list:
    """Flag records whose scale is off from their group's: the checks that compare records.

    Within each (preload, force level) group of identified records: an excitation frequency
    off from the group's median by a factor of 3 or more (``time_unit``: time in ms instead
    of s), an ``omega1`` off by a factor of 1.5 or more, or an equivalent viscous damping
    ``c_eq = <Q q'> / <q'^2>`` off the group's trend of ``c_eq`` against ``q_max`` (3 times below it
    or 8 times above: a damping law growing faster than a power law lies above the line of a few
    records) and by more than 6 of its standard errors (``scale_outlier``:
    acceleration in g instead of m/s^2 scales the identified damping by about 9.81 and leaves
    ``omega1`` nearly unchanged near resonance; a wrong channel), unless it lies below the trend at the
    group's smaller amplitudes in a way no factor on the acceleration explains and a sticking friction joint does
    (:func:`_damping_outliers`); and a record whose energy dissipated per cycle over ``q_max`` is that of records
    3 times larger or smaller in ``q_max``, the wrong way round (``scale_outlier`` with ``amplitude_ratio``: an
    acceleration unit moves ``q_max`` and leaves that energy as it was).  Each limit is also at least 6 robust standard deviations of the group's
    log values, so only a record far outside the group's own spread is flagged.  Outliers of the pooled fits themselves (records
    the group model does not explain) are to be added here, after the pooled fit.

    When at least half of a group's records show negative input power, the others get
    ``group_sign``: one test setup per group, and a flipped sign is visible only near resonance.

    Returns
    -------
    list of RecordOutcome
        The outcomes, with the new flags appended.
    """
    outcomes = list(outcomes)
    groups = {}
    for i, o in enumerate(outcomes):
        if o.ok:
            groups.setdefault(_group_id(o.spec.group), []).append(i)
    sign_flags = ("negative_input_power", "channel_swap")
    for members in groups.values():
        # one test setup per group: when most of its records show negative input power, the others
        # (off resonance, where the power is within the noise) have the same channels and are suspect too
        wrong = [i for i in members if any(f.name in sign_flags for f in outcomes[i].flags)]
        if 2 * len(wrong) >= len(members):
            for i in members:
                if i not in wrong:
                    f = Flag("group_sign", f"{len(wrong)} of the {len(members)} records of this group show negative "
                                           f"input power; this record shares their channels (a flipped sign or "
                                           f"swapped channels are not visible off resonance)",
                             {"records_with_negative_power": len(wrong), "records_in_group": len(members)})
                    outcomes[i] = replace(outcomes[i], flags=outcomes[i].flags + (f,))
        freq = scale_outliers({i: outcomes[i].signals.frequency_hz for i in members}, factor=3.0)
        omega = scale_outliers({i: outcomes[i].fit.omega1 for i in members}, factor=1.5)
        damping = _damping_outliers(outcomes, members)
        for i, (ratio, median) in freq.items():
            f = Flag("time_unit", f"excitation frequency {outcomes[i].signals.frequency_hz:.6g} Hz is {ratio:.4g} "
                                  f"times the group's median {median:.6g} Hz; time in ms instead of s?",
                     {"frequency_hz": outcomes[i].signals.frequency_hz, "group_median_hz": median, "ratio": ratio})
            outcomes[i] = replace(outcomes[i], flags=outcomes[i].flags + (f,))
        for i, (ratio, median) in omega.items():
            f = Flag("scale_outlier", f"omega1 = {outcomes[i].fit.omega1:.6g} rad/s is {ratio:.4g} times the "
                                      f"group's median {median:.6g} rad/s; acceleration in g instead of m/s^2, "
                                      f"a wrong channel or another structure?",
                     {"omega1": outcomes[i].fit.omega1, "group_median_omega1": median, "ratio": ratio})
            outcomes[i] = replace(outcomes[i], flags=outcomes[i].flags + (f,))
        for i, (c, se, ratio, median, scale, broken, moved) in damping.items():
            pm = f" (± {se:.2g})" if se is not None and np.isfinite(se) else ""
            off = (f"is {ratio:.4g} times the group's trend of c_eq against q_max ({median:.6g} there)"
                   if ratio is not None else "is not off the group's trend of c_eq against q_max by the trend check's limits")
            why = "".join([f"; the acceleration times {1 / scale:.3g} would put the record on it" if scale else "",
                           f"; its energy dissipated per cycle over q_max is {broken:.3g} times off that of a record "
                           f"with {'a smaller' if ratio is None or ratio < 1 else 'a larger'} q_max (a joint's does "
                           f"not fall as q_max grows)" if broken else "",
                           f"; its energy dissipated per cycle over q_max (q_max = {outcomes[i].fit.q_max:.4g}) "
                           f"breaks the rule that it does not fall as q_max grows against records with a q_max "
                           f"{max(moved, 1 / moved):.3g} times {'larger' if moved < 1 else 'smaller'} (an "
                           f"acceleration unit moves q_max and leaves it as it was)" if moved else ""])
            f = Flag("scale_outlier", f"equivalent viscous damping c_eq = {c:.6g}{pm} {off}{why}: acceleration "
                                      f"or force in g instead of m/s^2 or N, or a mis-scaled channel?",
                     {"c": outcomes[i].fit.c, "c_equivalent": c, "c_equivalent_stderr": se, "group_trend_c": median,
                      "ratio": ratio, "acceleration_scale": scale, "dissipation_ratio": broken,
                      "amplitude_ratio": moved})
            outcomes[i] = replace(outcomes[i], flags=outcomes[i].flags + (f,))
    return outcomes


def _damping_outliers(outcomes, members) -> dict:
    """Records of a group off its trend of ``c_eq`` against ``q_max``, less those a joint's physics explains.

    A record off the group's power-law trend of ``c_eq`` against ``q_max`` (:func:`trend_outliers`:
    3 times below it or 8 times above, by 6 standard errors) is a scale outlier, except one *below*
    the trend at the group's smaller amplitudes (``q_max`` at most the group's median) when

    - no factor of 3 or more on its acceleration puts it on the trend (such a factor multiplies
      ``q_max`` by itself and ``c_eq`` by its inverse: ``invariant=-1``) while keeping its ``omega1``
      among the group's (:func:`_stiffness_agrees`), and
    - its energy dissipated per cycle over its amplitude, ``W / (pi q_max) = c_eq omega q_max``, is
      not 3 times below that of a record with a smaller amplitude (:func:`monotone_outliers`: for
      viscous, polynomial and friction damping it does not fall as the amplitude grows).

    That record is what a friction joint does as it starts to slip: it dissipates far less at
    the group's smallest amplitudes than the slipping records' power law says (a Jenkins joint:
    nothing beyond the viscous damping below its slip amplitude).  A force wrong by a factor on
    such a record is not told from it.

    A record is also a scale outlier, on or off the trend, when its ``W / q_max`` is that of
    records whose amplitudes are 3 times larger or smaller than its own, the wrong way round
    (:func:`monotone_outliers` along ``q_max``, by 6 standard errors of the dissipation): an
    acceleration in other units leaves ``W / q_max`` as it was and moves ``q_max`` by the factor.
    The resonant dwell with its acceleration in g lands at a tenth of the group's amplitudes,
    where the extrapolated trend is too uncertain to call its ``c_eq`` off, yet it dissipates per
    unit amplitude as much as the records 8 times larger.

    Returns ``{index: (c_eq, stderr, ratio to the trend or None, trend value or None, acceleration
    scale or None, dissipation ratio or None, amplitude ratio or None)}``; the amplitude ratio is
    the factor along ``q_max`` (below 1: the record's ``q_max`` is too small).
    """
    ceq = {i: _equivalent_damping(outcomes[i]) for i in members}
    q = {i: outcomes[i].fit.q_max for i in members}
    c = {i: v[0] for i, v in ceq.items()}
    se = {i: v[1] for i, v in ceq.items()}
    kw = {"factor": (3.0, 8.0), "stderr": se}
    vertical = trend_outliers(q, c, **kw)
    w = {i: outcomes[i].signals.omega * q[i] for i in members}
    wq = {i: c[i] * w[i] if c[i] is not None else None for i in members}  # W / (pi q_max)
    wq_se = {i: se[i] * w[i] if se[i] is not None else None for i in members}
    scaled = trend_outliers(q, c, invariant=-1.0, **kw) if vertical else {}
    dissipation = monotone_outliers(q, wq, stderr=wq_se, factor=(3.0, 8.0)) if vertical else {}
    small = float(np.median([v for v in q.values() if v is not None and np.isfinite(v)]))
    sticking = set()
    for i, (ratio, _, _) in vertical.items():
        unit = i in scaled and _stiffness_agrees(outcomes, members, i, scaled[i][2])
        if ratio < 1 and q[i] <= small and not unit and i not in dissipation:
            sticking.add(i)  # a joint that sticks at the smaller amplitudes, unless its q_max is moved (below)
    # the rule along q_max among the records not already off the trend (one of those would break it with others)
    rest = [i for i in members if i not in vertical or i in sticking]
    moved = monotone_outliers({i: q[i] for i in rest}, {i: wq[i] for i in rest}, stderr=wq_se, factor=3.0,
                              along="x")
    for i, r in moved.items():  # below 1: the record's q_max is too small for its dissipation
        lo = any(q[j] > q[i] and wq[j] is not None and wq[j] < wq[i] for j in rest if j != i)
        moved[i] = 1.0 / r if lo else r
    out = {}
    for i, (ratio, trend, _) in vertical.items():
        if i in sticking and i not in moved:
            continue
        out[i] = (c[i], se[i], ratio, trend, scaled[i][2] if i in scaled else None, dissipation.get(i), moved.get(i))
    for i, r in moved.items():
        if i not in out:
            out[i] = (c[i], se[i], None, None, None, dissipation.get(i), r)
    return out


def _stiffness_agrees(outcomes, members, i, scale) -> bool:
    """Whether record ``i`` with its acceleration divided by ``scale`` keeps an ``omega1`` within its group's.

    A factor ``s`` on the acceleration multiplies ``omega1^2 - omega^2`` by ``1 / s`` (the fit keeps
    the unit modal mass): undone, the record's ``omega1`` is ``sqrt(omega^2 + s (omega1^2 - omega^2))``.
    A unit error undone brings it among the others' (or leaves it where it was, at resonance); a
    record that was right moves off them (a sticking joint's dwell well below resonance, by its
    stiffness and damping ratio together).  Agreement: not farther from the others' median ``omega1``
    (in log) than the record itself by more than ``Z_LIMIT`` robust standard deviations of theirs.
    """
    o = outcomes[i]
    others = np.log([outcomes[j].fit.omega1 for j in members if j != i and outcomes[j].fit.omega1 > 0])
    if others.size < 2 or not o.fit.omega1 > 0:
        return True
    w2 = o.signals.omega ** 2
    k = w2 + scale * (o.fit.omega1 ** 2 - w2)
    if not k > 0:
        return False
    med = float(np.median(others))
    spread = 1.4826 * float(np.median(np.abs(others - med)))
    return abs(0.5 * np.log(k) - med) <= abs(np.log(o.fit.omega1) - med) + Z_LIMIT * spread


def _equivalent_damping(outcome):
    """``(c_eq, stderr)`` of an identified record (:func:`~jointid.signal.checks.equivalent_damping`)."""
    sc = outcome.fit.scores
    if sc is None or sc.force_coefficients is None:
        return None, None
    s = outcome.signals
    return equivalent_damping(sc.force_coefficients, s.velocity.coefficients, s.omega, sc.sigma_force, sc.sigma_accel,
                              sc.n_samples)


def _group_id(key):
    return tuple(("num", float(v)) if isinstance(v, (int, float)) and not isinstance(v, bool) else
                 (type(v).__name__, str(v)) for v in key)


def _caught(caught) -> dict:
    return {"warnings": tuple(str(w.message) for w in caught), "warning_types": tuple(w.category for w in caught)}


def process_all(specs, settings, to_modal) -> list:
    """:func:`process_record` over all records, on dask workers when ``settings.jobs != 1`` or a
    ``settings.scheduler`` is given (see :mod:`jointid.app.parallel`); outcomes in the records' order.

    ``to_modal`` is one structure for every record, or a list with one per record (per-preload
    structures)."""
    from .parallel import map_tasks

    specs = list(specs)
    per_record = to_modal if isinstance(to_modal, (list, tuple)) else [to_modal] * len(specs)

    def lost(i, message):  # a record that took its workers down fails alone
        return RecordOutcome(specs[i], "failed", f"{_context(specs[i])}lost on the workers: {message}")

    return map_tasks(process_record, [(spec, settings, tm) for spec, tm in zip(specs, per_record)], jobs=settings.jobs,
                     scheduler=settings.scheduler, progress=settings.progress, desc="records", on_lost=lost,
                     files=[spec.path for spec in specs],  # on an existing cluster: do its workers see the records?
                     min_items=MIN_PARALLEL_RECORDS)


#: Fewer records than this are identified in this process even with ``jobs > 1``: a record takes
#: tens of milliseconds, a local cluster seconds to start (the results are the same).
MIN_PARALLEL_RECORDS = 100

#: A physical record whose accelerations the first mode's shape at the sensors leaves more than this share
#: unexplained (relative residual) is flagged: near the first mode the other modes leave well under a per cent
#: (0.3 % on the virtual rig), two swapped sensors 60 %, a flipped one 80 %.
MODAL_RESIDUAL_LIMIT = 0.3
