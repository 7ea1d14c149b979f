"""One record through the chain: read, reduce to state signals, fit; and all records of a campaign.

:func:`process_record` never raises for a bad record: it returns a failed
:class:`RecordOutcome` with the reason, so one record never loses the campaign.
:func:`process_all` runs it over the records of a campaign.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from ..errors import IdentificationError, JointidError, JointidWarning, where
from ..identify.fsm import ForceStateMapping, RecordFit
from ..identify.terms import library
from ..io.campaign import RecordSpec, read_record
from ..signal.harmonics import StateSignals, steady_state_signals

__all__ = ["IdentifySettings", "RecordOutcome", "process_record", "process_all"]


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
    repredict : bool
        Re-predict every group's measured FRF with its identified model by harmonic
        balance and compare the measured and identified hysteresis loops
        (:mod:`jointid.app.reprediction`; ``reprediction`` in ``results.json``).
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

    def __post_init__(self):
        if self.force_gain not in ("known", "unknown"):
            raise IdentificationError(f"force_gain must be 'known' or 'unknown', got {self.force_gain!r}")

    def summary(self) -> dict:
        return {
            "terms": list(library(self.terms).names),
            "n_harmonics": self.n_harmonics,
            "damping_order": self.damping_order,
            "weighting": self.weighting,
            "force_gain": self.force_gain,
            "refine_frequency": self.refine_frequency,
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

    @property
    def ok(self) -> bool:
        return self.status == "ok"

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
        return d

def _context(spec: RecordSpec) -> str:
    return where(spec.file, spec.index)


def process_record(spec: RecordSpec, settings: IdentifySettings, to_modal=None) -> RecordOutcome:
    """Read, reduce and fit one record; any :class:`JointidError` becomes a failed outcome."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", JointidWarning)
        try:
            if to_modal is None:
                data = read_record(spec)
                Q, qdd, resid = data.channels["force"], data.channels["accel"], None
                names = ("time", "force", "accel")
            else:
                data = read_record(spec, required=("time",) + tuple(to_modal.required_columns))
                Q, qdd, resid = to_modal.to_modal(data.channels)
                names = ("time", "force (modal)", "accel (modal)")
            signals = steady_state_signals(
                data.time, Q, qdd, frequency_hz=spec.frequency_hz, n_harmonics=settings.n_harmonics, channels=names,
                refine_frequency=settings.refine_frequency,
            )
            fit = ForceStateMapping(settings.terms).fit(signals, context=_context(spec)).result_
        except JointidError as exc:
            msg = str(exc)
            if not msg.startswith(str(spec.file)):
                msg = _context(spec) + msg
            return RecordOutcome(spec, "failed", msg, **_caught(caught))
        except Exception as exc:  # noqa: BLE001 - one record must never lose the campaign
            msg = f"{_context(spec)}unexpected {type(exc).__name__}: {exc}"
            return RecordOutcome(spec, "failed", msg, **_caught(caught))
    return RecordOutcome(spec, "ok", None, signals, fit, modal_residual=resid, **_caught(caught))


def _caught(caught) -> dict:
    return {"warnings": tuple(str(w.message) for w in caught), "warning_types": tuple(w.category for w in caught)}


def process_all(specs, settings, to_modal) -> list:
    """:func:`process_record` over all records, on dask workers when ``settings.jobs != 1`` or a
    ``settings.scheduler`` is given (see :mod:`jointid.app.parallel`); outcomes in the records' order."""
    from .parallel import map_tasks

    return map_tasks(process_record, [(spec, settings, to_modal) for spec in specs], jobs=settings.jobs,
                     scheduler=settings.scheduler, progress=settings.progress, desc="records")
