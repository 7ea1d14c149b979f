"""Channel delay between the excitation and response channels, estimated from stepped-sine dwells.

A time shift ``tau`` of the response channel behind the excitation channel (anti-alias
filters, vibrometer decoder latency, or -- with a shaker voltage recorded as the
excitation -- the lag of the shaker force behind its voltage) rotates the phase of every
harmonic ``k`` of the response by ``k omega tau``.  In a single-mode fit of a dwell at
``omega`` it moves part of the in-phase (stiffness / inertia) force into the quadrature
(damping) part, and the apparent damping coefficient becomes, to first order in
``tau``::

    c_r = c(q_r) + tau (omega1^2 - omega_r^2)

(``q_measured(t) = q(t - tau)``, so ``q = q_m + tau q_m'`` and ``q_m''' = -omega^2 q_m'``;
``c`` per unit modal mass).  With ``tau < 0`` (the response leads) the damping is
under-estimated below resonance and over-estimated above it, and far enough below it
turns negative -- the signature of a channel delay, not of the joint.

:class:`ChannelDelayEstimator` estimates ``tau`` with its standard error from the
per-dwell damping of a pooled fit by weighted least squares on the model above, with the
damping law ``c(q) = c0 + c1 q + ...`` (``law_order``; one law per group of dwells that
share it, e.g. per preload) and ``tau`` shared by all dwells.  The dwells are then
shifted by the estimate (:func:`shift_response`), the pooled fit repeated and the
estimate refined until the correction is negligible, so the final ``tau`` is the one at
which the corrected data show no delay signature.  The standard error is that of the
last regression, scaled by the square root of its reduced chi-square when above one
(the scatter of the dwells about the model, not only their own standard errors).
"""

from __future__ import annotations

import html
from dataclasses import dataclass, replace

import numpy as np

from ..errors import IdentificationError
from ..signal.harmonics import HarmonicSeries, StateSignals

__all__ = ["ChannelDelay", "ChannelDelayEstimator", "shift_response", "delay_regression"]


def shift_response(signals: StateSignals, delay: float) -> StateSignals:
    """The dwell with its response advanced by ``delay`` [s] (a delayed response channel corrected).

    The harmonic series of the response is re-timed (exact for every harmonic); the
    excitation samples are untouched.  The measured acceleration samples are kept as they
    are (they are only used for residuals and unfiltered loops).
    """
    s = signals.acceleration
    return replace(signals, acceleration=HarmonicSeries(s.omega, s.coefficients, s.t0 - float(delay)))


def delay_regression(c, c_stderr, omega, omega1, q_max, groups=None, law_order: int = 1):
    """Weighted least squares of ``c_r = c_g(q_r) + tau (omega1_g^2 - omega_r^2)``.

    Parameters
    ----------
    c, c_stderr : array_like, shape (n,)
        Per-dwell damping coefficients (per unit modal mass) and standard errors.
    omega : array_like, shape (n,)
        Dwell angular frequencies [rad/s].
    omega1 : array_like, shape (n,) or float
        Natural angular frequency of each dwell's group.
    q_max : array_like, shape (n,)
        Response amplitude of each dwell.
    groups : array_like, shape (n,), optional
        Label of the damping law each dwell follows (default: one law).
    law_order : int
        Polynomial order of each damping law in ``q_max``.

    Returns
    -------
    (tau, tau_stderr, reduced_chi2, dof)
    """
    c = np.asarray(c, float)
    s = np.asarray(c_stderr, float)
    w = np.asarray(omega, float)
    w1 = np.broadcast_to(np.asarray(omega1, float), c.shape)
    q = np.asarray(q_max, float)
    labels = np.zeros(c.size, int) if groups is None else np.unique(np.asarray(groups, str), return_inverse=True)[1]
    cols = []
    for g in np.unique(labels):
        sel = (labels == g).astype(float)
        scale = max(float(np.max(q[labels == g])), np.finfo(float).tiny)
        cols += [sel * (q / scale) ** k for k in range(int(law_order) + 1)]
    cols.append(w1**2 - w**2)
    X = np.column_stack(cols)
    n, p = X.shape
    if n <= p:
        raise IdentificationError(
            f"channel delay: {n} dwells for {p} parameters (damping law of order {law_order} per group and the "
            "delay); add dwells or lower the law order")
    if not (np.all(np.isfinite(c)) and np.all(np.isfinite(s)) and np.all(s > 0)):
        raise IdentificationError("channel delay: per-dwell damping and its standard errors must be finite and > 0")
    Xw, yw = X / s[:, None], c / s
    coef, *_ = np.linalg.lstsq(Xw, yw, rcond=None)
    r = yw - Xw @ coef
    dof = n - p
    chi2 = float(r @ r / dof)
    cov = np.linalg.pinv(Xw.T @ Xw) * max(chi2, 1.0)
    return float(coef[-1]), float(np.sqrt(cov[-1, -1])), chi2, dof


@dataclass(frozen=True)
class ChannelDelay:
    """An estimated channel delay.

    Attributes
    ----------
    delay_s : float
        Delay of the response channel behind the excitation channel [s]: positive when the
        response lags (anti-alias filters, a shaker force lagging its recorded voltage),
        negative when it leads the excitation channel.
    stderr_s : float
        Standard error [s].
    reduced_chi2 : float
        Of the last regression (scatter of the dwells about the damping-law-plus-delay model).
    dof : int
        Degrees of freedom of the last regression.
    n_dwells : int
    law_order : int
    iterations : int
    steps_s : tuple of float
        The delay after each iteration.
    source : str
        ``"estimated"`` or ``"given"``.
    """

    delay_s: float
    stderr_s: float
    reduced_chi2: float = float("nan")
    dof: int = 0
    n_dwells: int = 0
    law_order: int = 1
    iterations: int = 0
    steps_s: tuple = ()
    source: str = "estimated"

    @property
    def ci95_s(self) -> tuple:
        return (self.delay_s - 1.96 * self.stderr_s, self.delay_s + 1.96 * self.stderr_s)

    def summary(self) -> dict:
        return {"delay_s": self.delay_s, "stderr_s": self.stderr_s, "ci95_s": list(self.ci95_s),
                "reduced_chi2": self.reduced_chi2, "dof": self.dof, "n_dwells": self.n_dwells,
                "law_order": self.law_order, "iterations": self.iterations, "steps_s": list(self.steps_s),
                "source": self.source}

    @property
    def direction(self) -> str:
        """What the sign means, as a phrase: ``"the response channel leads the excitation channel by 0.773 ms"``."""
        ms = abs(1e3 * self.delay_s)
        if self.delay_s < 0:
            return f"the response channel leads the excitation channel by {ms:.4g} ms"
        if self.delay_s > 0:
            return f"the response channel lags the excitation channel by {ms:.4g} ms"
        return "no delay between the channels"

    def report(self) -> str:
        if self.source == "given":
            return f"channel delay {1e3 * self.delay_s:.4f} ms (given: {self.direction})"
        return (f"channel delay {1e3 * self.delay_s:.4f} ± {1e3 * self.stderr_s:.2g} ms ({self.direction}; "
                f"{self.n_dwells} dwells, damping law of order {self.law_order}, reduced chi2 "
                f"{self.reduced_chi2:.3g} on {self.dof} dof, {self.iterations} iterations)")

    def _repr_html_(self) -> str:
        return f"<pre>{html.escape(self.report())}</pre>"


class ChannelDelayEstimator:
    """Estimate the response-channel delay of a set of stepped-sine dwells.

    Parameters
    ----------
    fit_groups : callable
        ``fit_groups(signals_by_group) -> {label: (c, c_stderr, omega, omega1, q_max)}``:
        the pooled fit of each group of dwells, returning per-dwell damping (per unit
        modal mass), its standard error, the dwell frequencies, the group's natural
        frequency and the amplitudes.  The workflow passes its own pooled fit, so the
        estimate uses exactly the model that is identified.
    law_order : int
        Order of the damping law ``c(q_max)`` (0: constant damping).
    law_of : callable, optional
        ``law_of(group label) -> law label``: groups that share a damping law (e.g. the
        force levels of one preload); default one law per group.
    tol : float
        Stop when an iteration changes the delay by less than ``tol`` times its standard error.
    max_iter : int

    Attributes
    ----------
    result_ : ChannelDelay
    signals_ : dict
        The dwells of each group, corrected by the estimate.
    """

    def __init__(self, fit_groups, law_order: int = 1, law_of=None, tol: float = 0.01, max_iter: int = 8):
        self.fit_groups = fit_groups
        self.law_order = law_order
        self.law_of = law_of
        self.tol = tol
        self.max_iter = max_iter

    def fit(self, signals_by_group: dict):
        """Estimate the delay of the dwells ``{group label: [StateSignals, ...]}``; returns ``self``."""
        if not signals_by_group or not any(len(v) for v in signals_by_group.values()):
            raise IdentificationError("channel delay: no dwells to estimate it from")
        tau, steps = 0.0, []
        current = {k: list(v) for k, v in signals_by_group.items()}
        se = chi2 = float("nan")
        dof = n = 0
        for it in range(1, int(self.max_iter) + 1):
            per = self.fit_groups(current)
            cols = [[], [], [], [], [], []]
            for label, (c, s, w, w1, q) in per.items():
                c = np.atleast_1d(np.asarray(c, float))
                law = str(label if self.law_of is None else self.law_of(label))
                for lst, v in zip(cols, (c, s, w, np.broadcast_to(w1, c.shape), q, np.full(c.shape, law))):
                    lst.extend(np.atleast_1d(v).tolist())
            c, s, w, w1, q, g = (np.asarray(x) for x in cols)
            n = c.size
            step, se, chi2, dof = delay_regression(c, s, w, w1, q, g, self.law_order)
            tau += step
            steps.append(tau)
            current = {k: [shift_response(x, tau) for x in v] for k, v in signals_by_group.items()}
            if abs(step) <= self.tol * se:
                break
        self.result_ = ChannelDelay(float(tau), float(se), float(chi2), int(dof), int(n), int(self.law_order), it,
                                    tuple(float(x) for x in steps))
        self.signals_ = current
        return self


# ----------------------------------------------------------------------- plausibility of a delay
#: Largest delay, as a fraction of the shortest excitation period, that is taken as a channel
#: delay: beyond a quarter period the phase correction of the fundamental exceeds 90 degrees
#: (the harmonics' many times that) and no longer describes filter or decoder latency.
MAX_DELAY_PERIODS = 0.25
#: Largest delay as a fraction of the shortest record.
MAX_DELAY_RECORD = 0.1


def check_delay_plausible(delay_s, frequencies_hz, durations_s=(), source: str = "given") -> None:
    """Raise an :class:`IdentificationError` for a delay that cannot be a channel delay.

    A delay must be finite, shorter than ``MAX_DELAY_PERIODS`` of the shortest excitation
    period of the dwells it corrects and than ``MAX_DELAY_RECORD`` of the shortest record;
    the message gives the numbers.
    """
    tau = float(delay_s)
    if not np.isfinite(tau):
        raise IdentificationError(f"channel delay ({source}) must be a finite number of seconds, got {tau!r}")
    f = np.asarray([x for x in frequencies_hz if np.isfinite(x) and x > 0], float)
    if f.size:
        f_max = float(np.max(f))
        if abs(tau) * f_max > MAX_DELAY_PERIODS:
            raise IdentificationError(
                f"channel delay ({source}) {tau:.6g} s is {abs(tau) * f_max:.3g} periods of the highest dwell "
                f"frequency {f_max:.6g} Hz; a channel delay is below {MAX_DELAY_PERIODS:g} of a period (a delay in "
                "ms given in s?)")
    d = np.asarray([x for x in durations_s if np.isfinite(x) and x > 0], float)
    if d.size and abs(tau) > MAX_DELAY_RECORD * float(np.min(d)):
        raise IdentificationError(
            f"channel delay ({source}) {tau:.6g} s is {abs(tau) / float(np.min(d)):.3g} of the shortest record "
            f"({float(np.min(d)):.6g} s); a channel delay is below {MAX_DELAY_RECORD:g} of a record")


def delay_chi2_limit(dof: int) -> float:
    """Reduced chi-square above which the dwells do not follow the damping-law-plus-delay model:
    six standard deviations of the reduced chi-square of a correct model (``sqrt(2 / dof)``)."""
    return 1.0 + 6.0 * np.sqrt(2.0 / max(int(dof), 1))


def delay_refusal(delay: ChannelDelay) -> str | None:
    """Why an estimated delay is not to be applied, or ``None``.

    An estimate whose regression does not describe the dwells (reduced chi-square beyond
    :func:`delay_chi2_limit`) and that is not resolved (within 3 standard errors of zero)
    is refused: applying it would move every dwell's damping by an amount its standard
    error does not carry.  A resolved delay is applied with its standard error (scaled by
    the root of the reduced chi-square) carried into the damping (:func:`delay_c_stderr`).
    """
    if delay.source != "estimated":
        return None
    if not (np.isfinite(delay.delay_s) and np.isfinite(delay.stderr_s)):
        return f"the estimate is not finite ({delay.delay_s!r} ± {delay.stderr_s!r} s)"
    limit = delay_chi2_limit(delay.dof)
    if delay.reduced_chi2 > limit and abs(delay.delay_s) < 3.0 * delay.stderr_s:
        return (f"the dwells' damping does not follow a damping law of order {delay.law_order} plus a delay "
                f"(reduced chi2 {delay.reduced_chi2:.3g} on {delay.dof} dof, above {limit:.3g}) and the delay "
                f"{1e3 * delay.delay_s:.3g} ± {1e3 * delay.stderr_s:.2g} ms is not resolved; no correction applied "
                "(a higher --damping-order, or a known delay)")
    return None


def delay_c_stderr(delay: ChannelDelay, omega1, omega):
    """Standard error a delay's uncertainty gives a dwell's damping: ``se(tau) |omega1^2 - omega^2|``
    (the first-order model of the module docstring)."""
    return float(delay.stderr_s) * np.abs(np.asarray(omega1, float) ** 2 - np.asarray(omega, float) ** 2)
