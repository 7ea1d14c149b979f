"""Broadband records of a campaign: multisine or random excitation, broadband force-state mapping.

A record with ``excitation = "multisine"`` (and its ``period_s``) or ``"random"`` is not a
stepped-sine dwell: the records of a (preload, force level) group are identified together
by the broadband force-state mapping (:class:`~jointid.identify.broadband.BroadbandForceStateMapping`,
with the inertia term when the force gain is unknown and a static input offset):

* multisine record: its whole periods after the first (a transient) are averaged (one
  period: the last one), and the states come by exact DFT differentiation over the
  force's band (:func:`power_band`; :func:`~jointid.signal.broadband.periodic_states`);
* random record: band-limited states over the force's band
  (:func:`~jointid.signal.broadband.random_states`).

Held-out records
    When a group holds multisine and random records, the model is fitted on the multisines
    and the random records are held out; otherwise, with two records or more, the last one
    is held out.  The identified model is simulated from rest with each held-out record's
    excitation and its free-run simulation error (rms of measured minus simulated
    response) is reported -- the test of a model that predicts, not only fits.

The response column is the campaign's ``accel`` (or, for a modal campaign, ``velocity`` or
``displacement`` when the record has that column instead); a physical campaign's records
are reduced with the structure like the stepped-sine ones.
"""

from __future__ import annotations

import html
import warnings
from dataclasses import dataclass, field

import numpy as np

from ..errors import IdentificationError, JointidError, JointidWarning, RecordError, where
from ..identify.broadband import BroadbandForceStateMapping
from ..io.campaign import read_record
from ..signal.broadband import (
    multisine_flags,
    multisine_transient_flags,
    periodic_states,
    random_flags,
    random_states,
)
from ..signal.checks import Flag

__all__ = ["BROADBAND", "BroadbandGroup", "split_broadband", "identify_broadband", "power_band"]

#: Excitations identified by the broadband force-state mapping.
BROADBAND = ("multisine", "random")
#: Force power left outside the identification band at each end (:func:`power_band`).
POWER_TAIL = 1e-5
_RESPONSES = (("accel", "acceleration"), ("velocity", "velocity"), ("displacement", "displacement"))


def split_broadband(specs, to_modal=None):
    """``(stepped-sine specs, their structures, [(broadband spec, structure), ...])``.

    Ring-down records are in neither list: they are identified with the backbones
    (:mod:`jointid.app.backbones`), which report their errors.
    """
    specs = list(specs)
    per = to_modal if isinstance(to_modal, (list, tuple)) else [to_modal] * len(specs)
    sine, sine_modal, broad = [], [], []
    for spec, tm in zip(specs, per):
        excitation = getattr(spec, "excitation", "stepped-sine")
        if excitation == "ringdown":
            continue
        if excitation in BROADBAND:
            broad.append((spec, tm))
        else:
            sine.append(spec)
            sine_modal.append(tm)
    return sine, (sine_modal if isinstance(to_modal, (list, tuple)) else to_modal), broad


@dataclass(frozen=True, eq=False)
class BroadbandGroup:
    """The broadband identification of one (preload, force level) group.

    Attributes
    ----------
    preload, force_level : object
    fit : BroadbandFit or None
        The model fitted on the estimation records.
    estimation : tuple of str
        Files of the records fitted.
    held_out : tuple of dict
        Per held-out record: ``file``, ``rms_error`` (measured minus free-run simulated
        response, response units), ``rms_response`` and ``relative_error``.
    failed : tuple of str
        Records that could not be used, with the reason.
    error : str or None
        Why the group has no model.
    flags : tuple of (str or None, Flag)
        Plausibility flags with the numbers that triggered them: of a record (its file; the
        record is left out of the fit and of the held-out test) or of the group's model
        (``None``: e.g. a negative damping ratio, a resonance outside the excited band).
    """

    preload: object
    force_level: object
    fit: object = field(default=None, repr=False)
    estimation: tuple = ()
    held_out: tuple = ()
    failed: tuple = ()
    error: str | None = None
    flags: tuple = ()

    def summary(self) -> dict:
        d = {"preload": self.preload, "force_level": self.force_level, "estimation": list(self.estimation),
             "held_out": [dict(h) for h in self.held_out], "failed": list(self.failed), "error": self.error,
             "flags": [{"file": file, **f.summary()} for file, f in self.flags]}
        if self.fit is not None:
            d["model"] = self.fit.summary()
            derived = self.fit.derived()
            d.update({k: derived[k][0] for k in ("f1_hz", "zeta") if k in derived})
            d.update({f"{k}_stderr": derived[k][1] for k in ("f1_hz", "zeta") if k in derived})
        return d

    def report(self) -> str:
        head = f"preload {self.preload}, F = {self.force_level}: "
        flagged = [f"  flagged{'' if file is None else ' ' + str(file)}: {f.report()}" for file, f in self.flags]
        if self.fit is None:
            return "\n".join([head + f"no broadband model ({self.error})"] + flagged)
        d = self.fit.derived()
        lines = [head + f"broadband model on {len(self.estimation)} record(s): f1 {d['f1_hz'][0]:.5g} Hz, "
                        f"zeta {100 * d['zeta'][0]:.4g} %"]
        for h in self.held_out:
            lines.append(f"  held out {h['file']}: free-run simulation error rms {h['rms_error']:.4g} "
                         f"({100 * h['relative_error']:.2f} % of the response rms)")
        lines += [f"  not used: {m}" for m in self.failed]
        return "\n".join(lines + flagged)

    def _repr_html_(self) -> str:
        return f"<pre>{html.escape(self.report())}</pre>"


def _read(spec, to_modal):
    """``(t, force, response, measured kind)`` of a broadband record."""
    if to_modal is not None:
        data = read_record(spec, required=("time",) + tuple(to_modal.required_columns))
        Q, qdd, _ = to_modal.to_modal(data.channels)
        return data.time, Q, qdd, "acceleration"
    data = read_record(spec, required=("time", "force"))
    for column, kind in _RESPONSES:
        if column in data.channels:
            return data.time, data.channels["force"], data.channels[column], kind
    raise RecordError(f"{where(spec.file, spec.index)}no response column: expected one of "
                      f"{[c for c, _ in _RESPONSES]}, found {sorted(data.channels)}")


def _periods(spec, n, fs):
    """``(samples per period, slice of the whole periods after the first)`` of a multisine record."""
    n_per = int(round(float(spec.period_s) * fs))
    if n_per < 8 or n_per > n:
        raise RecordError(f"{where(spec.file, spec.index)}period_s = {spec.period_s} s is {n_per} samples at "
                          f"{fs:.6g} Hz; the record has {n}")
    use = max(n // n_per - 1, 1)  # the first whole period is a transient when there are several
    return n_per, slice(n - use * n_per, n)


def power_band(u, fs, tail: float = POWER_TAIL) -> tuple:
    """``(f_lo, f_hi)`` [Hz]: the band holding all but ``tail`` of the force power at each end.

    Isolated spurious lines far above a multisine's band (at 1e-3 of its amplitude) carry no
    power and do not widen it, as they would with a threshold on the line amplitude.
    """
    U = np.fft.rfft(np.asarray(u, float) - np.mean(u))
    f = np.fft.rfftfreq(np.size(u), 1.0 / fs)
    p = np.abs(U) ** 2
    p[0] = 0.0
    if not np.any(p > 0):
        raise RecordError("channel 'force': the excitation is constant")
    c = np.cumsum(p) / p.sum()
    lo = f[min(int(np.searchsorted(c, tail)), f.size - 1)]
    hi = f[min(int(np.searchsorted(c, 1.0 - tail)), f.size - 1)]
    return float(max(lo, f[1])), float(hi)


#: A random record's band also ends where the force's spectral density (Welch) falls below this fraction of its
#: peak: a measured force's white noise floor (1 % of the rms of a 15-40 Hz random force sampled at 2 kHz lies
#: about 55 dB below its density in the band) holds more than :data:`POWER_TAIL` of the power over the whole
#: spectrum and would widen the band to the noise, where force and response are not coherent.
PSD_FLOOR = 1e-4


def random_band(u, fs) -> tuple:
    """``(f_lo, f_hi)`` [Hz] of a random record: the force's power band (:func:`power_band`) within the
    frequencies where its spectral density is above :data:`PSD_FLOOR` of its peak, with the low edge
    keeping the filters' settling (2 fs / low at each end) to a tenth of the record, below 0.45 fs."""
    from scipy import signal as ssignal

    u = np.asarray(u, float)
    lo, hi = power_band(u, fs)
    f, p = ssignal.welch(u - u.mean(), fs=fs, nperseg=int(min(max(64, u.size // 16), u.size)))
    p[:2] = 0.0  # the Hann window's main lobe spreads the segments' means over the first bin
    above = np.flatnonzero(p >= PSD_FLOOR * p.max())
    if above.size:
        lo, hi = max(lo, float(f[above[0]])), min(hi, float(f[above[-1]]))
    return max(lo, 20.0 * fs / u.size), min(hi, 0.45 * fs)


def _states(spec, raw):
    t, u, y, kind, fs = raw
    names = ("force", "response")
    if spec.excitation == "multisine":
        n_per, seg = _periods(spec, t.size, fs)
        use = (seg.stop - seg.start) // n_per
        ub = u[seg].reshape(use, n_per).mean(axis=0)
        yb = y[seg].reshape(use, n_per).mean(axis=0)
        return periodic_states(ub, yb, fs, measured=kind, band=power_band(ub, fs), channels=names)
    return random_states(t, u, y, measured=kind, band=random_band(u, fs), channels=names)


def _group(key, members, settings):
    raw, failed = {}, []
    for spec, tm in members:
        try:
            t, u, y, kind = _read(spec, tm)
            raw[spec.index] = (t, u, y, kind, (t.size - 1) / (t[-1] - t[0]))
        except JointidError as exc:
            failed.append(str(exc))
    ok = [s for s, _ in members if s.index in raw]
    flags = []
    for s in list(ok):
        try:
            found = record_flags(s, raw[s.index])
        except JointidError as exc:
            failed.append(str(exc))
            ok.remove(s)
            continue
        if found:  # a flagged record is neither fitted nor used as a held-out test
            flags += [(s.file, f) for f in found]
            ok.remove(s)
    if not ok:
        return BroadbandGroup(key[0], key[1], failed=tuple(failed), error="no usable record", flags=tuple(flags))
    multi = [s for s in ok if s.excitation == "multisine"]
    if multi and len(multi) < len(ok):
        est = multi
    else:
        est = ok[:-1] if len(ok) >= 2 else ok
    held = [s for s in ok if s not in est]
    states = {}
    for s in est:
        try:
            states[s.index] = _states(s, raw[s.index])
        except JointidError as exc:
            failed.append(str(exc))
    est = [s for s in est if s.index in states]
    if not est:
        return BroadbandGroup(key[0], key[1], failed=tuple(failed), error="no record to fit", flags=tuple(flags))
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", JointidWarning)
            fit = BroadbandForceStateMapping(settings.terms, fit_inertia=settings.force_gain == "unknown",
                                             offset=True).fit([states[s.index] for s in est]).result_
    except (JointidError, ValueError, np.linalg.LinAlgError) as exc:
        return BroadbandGroup(key[0], key[1], failed=tuple(failed), error=str(exc), flags=tuple(flags))
    flags += [(None, f) for f in model_flags(fit, [states[s.index] for s in est])]
    out = []
    for s in held:
        t, u, y, kind, fs = raw[s.index]
        try:
            y_sim = fit.simulate(u, fs)
            if kind != "displacement":  # compare in the measured quantity
                y_sim = _differentiate(y_sim, fs, {"velocity": 1, "acceleration": 2}[kind])
            part = _periods(s, t.size, fs)[1] if s.excitation == "multisine" else slice(0, t.size)
            e, yr = y[part] - y_sim[part], y[part]
            err = float(np.sqrt(np.mean(e**2)))
            rms = float(np.sqrt(np.mean((yr - np.mean(yr)) ** 2)))
            out.append({"file": s.file, "index": s.index, "excitation": s.excitation, "rms_error": err,
                        "rms_response": rms, "relative_error": err / rms if rms > 0 else float("nan"),
                        "samples": int(part.stop - part.start) if part.stop else int(t.size), "measured": kind})
        except (JointidError, ValueError, FloatingPointError) as exc:
            failed.append(f"{where(s.file, s.index)}simulation failed: {exc}")
    return BroadbandGroup(key[0], key[1], fit, tuple(s.file for s in est), tuple(out), tuple(failed),
                          flags=tuple(flags))


def record_flags(spec, raw) -> list:
    """Plausibility flags of a broadband record (:func:`~jointid.signal.broadband.multisine_flags`,
    :func:`~jointid.signal.broadband.random_flags`); a ``period_s`` that does not fit the record raises."""
    t, u, y, kind, fs = raw
    if spec.excitation == "multisine":
        n_per, _ = _periods(spec, t.size, fs)
        return multisine_flags(u, n_per) + multisine_transient_flags(y, n_per, channel=kind)
    band = random_band(u, fs)
    return random_flags(u, y, fs, band, channels=("force", kind)) if band[0] < band[1] else []


#: Standard errors by which a damping ratio must be negative to be flagged.
ZETA_Z = 2.0


def model_flags(fit, states) -> list:
    """Flags of a group's broadband model: ``negative_damping`` (a damping ratio negative beyond
    ``ZETA_Z`` standard errors: a passive joint dissipates) and ``resonance_outside_band`` (the
    identified natural frequency outside the band the fitted records excite: it is extrapolated)."""
    out = []
    d = fit.derived()
    if "zeta" in d:
        z, se = (float(x) for x in d["zeta"][:2])
        if np.isfinite(z) and z < 0 and (not np.isfinite(se) or -z > ZETA_Z * se):
            out.append(Flag("negative_damping", f"damping ratio zeta = {z:.4g} ± {se:.2g} is negative: a passive "
                                                "joint dissipates (a wrong period, unrelated channels, or a "
                                                "record without a resonance)", {"zeta": z, "zeta_stderr": se}))
    if "f1_hz" in d:
        f1 = float(d["f1_hz"][0])
        bands = [getattr(s, "band", None) for s in states]
        bands = [b for b in bands if b is not None]
        if bands:
            lo, hi = min(float(b[0]) for b in bands), max(float(b[1]) for b in bands)
            if not (np.isfinite(f1) and lo <= f1 <= hi):
                out.append(Flag("resonance_outside_band", f"identified f1 = {f1:.5g} Hz lies outside the excited band "
                                                          f"{lo:.4g}-{hi:.4g} Hz of the fitted records",
                                {"f1_hz": f1, "band_low_hz": lo, "band_high_hz": hi}))
    return out


def _differentiate(x, fs, order):
    X = np.fft.rfft(x)
    w = 2j * np.pi * np.fft.rfftfreq(x.size, 1.0 / fs)
    return np.fft.irfft(X * w**order, x.size)


def identify_broadband(pairs, settings) -> tuple:
    """:class:`BroadbandGroup` of every (preload, force level) group of broadband records.

    Parameters
    ----------
    pairs : sequence of (RecordSpec, Structure or None)
    settings : IdentifySettings
        ``terms`` and ``force_gain`` are used.
    """
    groups = {}
    for spec, tm in pairs:
        groups.setdefault(spec.group, []).append((spec, tm))
    out = []
    for key in sorted(groups, key=lambda k: (str(k[0]), str(k[1]))):
        try:
            out.append(_group(key, groups[key], settings))
        except IdentificationError as exc:  # one group never loses the others
            out.append(BroadbandGroup(key[0], key[1], error=str(exc)))
    return tuple(out)


def broadband_problem_lines(groups) -> list:
    """One line per flag, unusable record or group without a model among the broadband groups (empty
    when none): a run with any of them is not a clean run."""
    lines = []
    for b in groups:
        head = f"broadband preload {b.preload}, F = {b.force_level}: "
        lines += [head + ("" if file is None else f"{file}: ") + f.report() for file, f in b.flags]
        lines += [head + f"not used: {m}" for m in b.failed]
        if b.error and not b.flags and not b.failed:
            lines.append(head + f"no model ({b.error})")
    return lines
