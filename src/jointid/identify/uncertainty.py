"""Noise model of force-state mapping: score covariances and sandwich standard errors.

The regression of a steady-state record runs on ``y = Q - q''_fit`` with regressors
``X = phi(q, q')`` built from the harmonic fit ``alpha`` (basis ``B(t)``, ``m = 2H + 1``
coefficients) of the measured acceleration.  Two white noises enter:

* the force noise ``eps_F`` (variance ``sigma_F^2``) enters ``y`` directly;
* the acceleration noise (variance ``sigma_a^2``) enters only through ``alpha``, whose
  error has covariance ``sigma_a^2 G^-1`` (``G = B^T B``) and moves ``q''``, ``q`` and
  ``q'`` together.

Linearising ``theta = (X^T X)^-1 X^T y`` around the noise-free record gives the error
``d theta = (X^T X)^-1 u`` with the score

    ``u = X^T eps_F + X^T D d_alpha``,
    ``D = d r / d alpha = -(B + h_q B_q + h_v B_v + (d h / d q_max) d q_max / d alpha)``

where ``r = y - X theta``, ``h = sum_k theta_k phi_k``, and ``B_q = B T_q``,
``B_v = B T_v`` the displacement and velocity a unit change of each acceleration
coefficient produces (``T_v``, ``T_q`` the analytic integration maps, the constant
integrates to nothing).  When a coefficient follows a law in the amplitude, the envelope
theorem gives ``d q_max = sign(q(t*)) B_q(t*) d alpha``.  The score covariance is

    ``V = sigma_F^2 X^T X + sigma_a^2 (X^T D) G^-1 (X^T D)^T``

and the covariance of the estimate the sandwich ``M^-1 V M^-1`` with ``M = X^T X``.

:func:`record_pass` makes one streamed pass over a record and keeps what any model on
that record's terms needs (``X^T B`` and the term-wise tensors of ``h_q``, ``h_v``), so
the per-record fit, the pooled group fit and the preload model all evaluate their
covariances without reading the samples again (:meth:`RecordScores.covariance`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import linalg

from ..conventions import n_coefficients
from ..numerics.intervals import Z95
from ..signal.harmonics import HarmonicSeries, StateSignals, _basis
from .regression import reduce_blocks

__all__ = [
    "RecordScores",
    "FrequencySums",
    "record_pass",
    "PooledCovariance",
    "pooled_covariance",
    "LowRankCovariance",
    "Whitening",
    "whitening",
    "ci95",
    "Z95",
    "sandwich",
    "scaled_inverse",
]


def ci95(value, stderr):
    """``[value - 1.96 stderr, value + 1.96 stderr]`` as floats (``None`` when unknown)."""
    if value is None or stderr is None:
        return None
    v, s = float(value), float(stderr)
    if not (np.isfinite(v) and np.isfinite(s)):
        return None
    return [v - Z95 * s, v + Z95 * s]


def scaled_inverse(M) -> np.ndarray:
    """Inverse of a symmetric positive (semi-)definite matrix, computed on its scaled form."""
    M = np.asarray(M, float)
    d = np.sqrt(np.abs(np.diag(M)))
    d[d == 0] = 1.0
    Ms = M / np.outer(d, d)
    w, V = np.linalg.eigh(0.5 * (Ms + Ms.T))
    keep = w > 1e-15 * max(float(np.max(np.abs(w), initial=0.0)), np.finfo(float).tiny)
    inv = (V[:, keep] / w[keep]) @ V[:, keep].T  # pseudo-inverse on an exactly singular matrix
    return inv / np.outer(d, d)


def sandwich(M, V) -> np.ndarray:
    """``M^-1 V M^-1`` (symmetrised)."""
    Mi = scaled_inverse(M)
    C = Mi @ V @ Mi
    return 0.5 * (C + C.T)


def _integration_map(omega, n_harmonics) -> np.ndarray:
    """Matrix ``T`` with ``integral(series).coefficients = T @ series.coefficients``."""
    m = n_coefficients(n_harmonics)
    eye = np.eye(m)
    return np.column_stack([HarmonicSeries(omega, eye[:, i]).integral().coefficients for i in range(m)])


def _peak_direction(q_coefficients, Tq) -> np.ndarray:
    """``d q_max / d alpha`` (envelope theorem) for the displacement series ``q``."""
    c = np.asarray(q_coefficients, float)
    H = (c.size - 1) // 2
    n = 256 * (H + 1)
    tau = np.arange(n) * (2 * np.pi / n)
    B = _basis(tau, 1.0, H)
    q = B @ c
    i = int(np.argmax(np.abs(q)))
    return np.sign(q[i]) * (B[i] @ Tq)


@dataclass(frozen=True)
class RecordScores:
    """What the noise model needs of one record for any model on its terms.

    Attributes
    ----------
    gram : array ``(p, p)``
        ``Phi^T Phi`` of the term columns.
    phi_b : array ``(p, m)``
        ``Phi^T B``.
    phi_dq_b, phi_dv_b : array ``(p, p, m)``
        ``Phi^T diag(d phi_k / d q) B`` and ``Phi^T diag(d phi_k / d v) B`` for every term ``k``
        (first index).
    basis_gram : array ``(m, m)``
        ``G = B^T B``.
    Tq, Tv : array ``(m, m)``
        Displacement and velocity coefficients per unit acceleration coefficient.
    peak : array ``(m,)``
        ``d q_max / d alpha``.
    sigma_force, sigma_accel : float
        White-noise standard deviations of the force and the acceleration outside the fitted
        harmonics (``RSS / (n - m)``).
    n_samples : int
    filtered : bool
        Whether the regression uses the filtered acceleration in ``Q - q''``.
    """

    gram: np.ndarray = field(repr=False)
    phi_b: np.ndarray = field(repr=False)
    phi_dq_b: np.ndarray = field(repr=False)
    phi_dv_b: np.ndarray = field(repr=False)
    basis_gram: np.ndarray = field(repr=False)
    Tq: np.ndarray = field(repr=False)
    Tv: np.ndarray = field(repr=False)
    peak: np.ndarray = field(repr=False)
    sigma_force: float
    sigma_accel: float
    n_samples: int
    filtered: bool = True
    force_coefficients: np.ndarray | None = field(default=None, repr=False)  # harmonic fit of the force
    inertia: bool = False  # column 0 is the filtered acceleration with coefficient m (unknown force gain)
    omega_variance: float = 0.0  # of the excitation frequency when it was estimated from the force
    omega_score: np.ndarray | None = field(default=None, repr=False)  # d(score)/d(omega) in term columns
    omega_sums: FrequencySums | None = field(default=None, repr=False)  # for frequency_score

    def frequency_score(self, theta) -> np.ndarray:
        """``M d theta / d omega`` (``M = X^T X``): how the regression moves when the record is
        analysed at another frequency (harmonic fit of the acceleration, integration and
        regression redone), at coefficients ``theta``; see :class:`FrequencySums`."""
        f = self.omega_sums
        theta = np.asarray(theta, float)
        w = f.omega
        cq = self.Tq @ (f.alpha_prime - (2.0 / w) * f.alpha)  # d(displacement coefficients)/d omega
        cv = self.Tv @ (f.alpha_prime - (1.0 / w) * f.alpha)
        p = theta.size
        out = np.zeros(p)
        if self.filtered:  # X^T dy: y = Q - q''_fit moves with the fit
            out -= f.x_tau_jerk / w + self.phi_b @ f.alpha_prime
        for k in range(p):
            for W, D, Y, c in ((f.tau_q, self.phi_dq_b, f.y_dq_b, cq), (f.tau_v, self.phi_dv_b, f.y_dv_b, cv)):
                out -= theta[k] * (W[k, :p] / w + D[k] @ c)  # X^T (dX theta)
                out[k] += (W[k, p] - W[k, :p] @ theta) / w + (Y[k] - theta @ D[k]) @ c  # dX^T r
        return out

    def score_terms(self, theta, dtheta_dqmax=None) -> np.ndarray:
        """``X^T D`` (``(p, m)``) in the record's term columns for coefficients ``theta``.

        ``dtheta_dqmax`` is ``d theta / d q_max`` when coefficients follow amplitude laws.
        """
        theta = np.asarray(theta, float)
        S = np.tensordot(theta, self.phi_dq_b, axes=1) @ self.Tq + np.tensordot(theta, self.phi_dv_b, axes=1) @ self.Tv
        if self.inertia:  # residual V - m q''_fit - h: the acceleration coefficients enter with m
            S = S + theta[0] * self.phi_b
        elif self.filtered:
            S = S + self.phi_b
        if dtheta_dqmax is not None:
            S = S + np.outer(self.gram @ np.asarray(dtheta_dqmax, float), self.peak)
        return -S

    def covariance(self, theta, dtheta_dqmax=None) -> np.ndarray:
        """Covariance ``V`` of the score ``X^T (noise)`` in the record's term columns."""
        S = self.score_terms(theta, dtheta_dqmax)
        Gi = scaled_inverse(self.basis_gram)
        sa2, sf2 = self.sigma_accel**2, self.sigma_force**2
        V = sf2 * self.gram + sa2 * (S @ Gi @ S.T)
        if not self.filtered:  # the raw acceleration noise also enters y directly
            P = self.phi_b @ Gi @ S.T
            V = V + sa2 * (self.gram - P - P.T)
        if self.omega_score is not None and self.omega_variance > 0:  # the frequency estimate's own error
            V = V + self.omega_variance * np.outer(self.omega_score, self.omega_score)
        return 0.5 * (V + V.T)

    def q_max_variance(self) -> float:
        """Variance of ``q_max`` from the acceleration noise in the fitted harmonics."""
        return float(self.sigma_accel**2 * self.peak @ scaled_inverse(self.basis_gram) @ self.peak)

    def score_q_max_covariance(self, theta) -> np.ndarray:
        """``cov(score, q_max)`` in the record's term columns (both move with the harmonic fit)."""
        S = self.score_terms(theta)
        return self.sigma_accel**2 * (S @ scaled_inverse(self.basis_gram) @ self.peak)



@dataclass(frozen=True)
class FrequencySums:
    """Sums of one record that give the derivative of its regression with respect to the
    frequency analytically (:meth:`RecordScores.frequency_score`).

    With ``tau`` the time from the fit's origin, ``X`` the term columns, ``y`` the
    regression's left-hand side, ``g_k`` the derivative of term ``k`` with respect to
    ``q`` (``tau_q``, ``y_dq_b``) or to ``q'`` (``tau_v``, ``y_dv_b``) and ``B`` the fit's
    sinusoids: a change of frequency moves a series ``B c`` by ``(tau / omega) B D c``
    (``D`` the time derivative) and the acceleration's coefficients by ``alpha_prime``.

    Attributes
    ----------
    omega : float
    alpha, alpha_prime : array ``(m,)``
        The acceleration's coefficients and their derivative with respect to ``omega``.
    x_tau_jerk : array ``(p,)``
        ``X^T (tau j)``, ``j`` the time derivative of the filtered acceleration.
    tau_q, tau_v : array ``(p, p + 1)``
        Row ``k``: ``[X, y]^T (tau g_k q')`` and ``[X, y]^T (tau g_k (q''_fit - a_0))``.
    y_dq_b, y_dv_b : array ``(p, m)``
        Row ``k``: ``(g_k y)^T B``.
    """

    omega: float
    alpha: np.ndarray = field(repr=False)
    alpha_prime: np.ndarray = field(repr=False)
    x_tau_jerk: np.ndarray = field(repr=False)
    tau_q: np.ndarray = field(repr=False)
    tau_v: np.ndarray = field(repr=False)
    y_dq_b: np.ndarray = field(repr=False)
    y_dv_b: np.ndarray = field(repr=False)


def _derivative_map(omega, n_harmonics) -> np.ndarray:
    """Matrix ``D`` with ``series.derivative().coefficients = D @ series.coefficients``."""
    eye = np.eye(n_coefficients(n_harmonics))
    return np.column_stack([HarmonicSeries(omega, e).derivative().coefficients for e in eye])


def _regression_blocks(lib, signals, filtered, inertia):
    """Blocks of the record's regression matrix: ``[X, y_fit, y_raw]`` (force-state mapping,
    ``y = Q - q''``) or, with ``inertia``, ``[q''_fit, X, Q]`` (unknown force gain)."""
    for sl, q, v, a_fit in signals.blocks():
        Q = signals.force[sl]
        if inertia:
            yield np.column_stack([a_fit, lib.evaluate(q, v), Q])
            continue
        y_raw = Q - signals.accel_measured[sl]
        yield np.column_stack([lib.evaluate(q, v), Q - a_fit if filtered else y_raw, y_raw])


def _constant(g):
    """The value of ``g`` when it is the same at every sample, else ``None``."""
    if isinstance(g, float):  # declared constant (Term.dq_const, dv_const)
        return g
    if g.ndim == 0 or g.strides[0] == 0 or g.min() == g.max():
        return float(g.flat[0])
    return None


#: Rows per product of :func:`record_pass` against the sinusoid table (they stay in cache).
PASS_CHUNK = 8192


def record_pass(lib, signals: StateSignals, filtered=True, inertia=False):
    """One streamed pass over a record: its reduced regression factor and :class:`RecordScores`.

    Parameters
    ----------
    lib : TermLibrary
    signals : StateSignals
    filtered : bool
        As in :class:`~jointid.identify.fsm.ForceStateMapping`.
    inertia : bool
        The regression has the filtered acceleration as its first column (unknown force
        gain, :mod:`jointid.identify.gain`: ``m q'' + h(q, q') = V``).

    Returns
    -------
    R : array
        Upper-triangular factor of ``[X, y_fit, y_raw]`` (``y = Q - q''``, filtered and
        raw) or, with ``inertia``, of ``[q''_fit, X, Q]``.
    scores : RecordScores

    Every block's sums against the fit's sinusoids are taken on the block's table rows and
    rotated (:meth:`~jointid.signal.harmonics.StateSignals.basis_factors`); a term whose
    derivative is constant over a block reuses the term columns' sums instead of its own.
    """
    acc = signals.acceleration
    H, omega = acc.n_harmonics, signals.omega
    off = 1 if inertia else 0
    m, p = n_coefficients(H), len(lib) + off
    pre = 0 if inertia else 2  # the columns y_raw, y_fit come first
    ix, iq = pre, pre + p  # columns of X and of Q
    n_w = iq + 1  # [y_raw, y_fit,] X, Q: their Gram gives R and the score Gram
    phi_b = np.zeros((p, m))
    dq_b = np.zeros((p, p, m))
    dv_b = np.zeros((p, p, m))
    bF = np.zeros(m)
    gram_w = np.zeros((n_w, n_w))
    nl = len(lib)
    estimated = not signals.frequency_given
    fsums = estimated and not inertia  # the frequency's derivative sums (see FrequencySums)
    x_tau_jerk, tau_q, tau_v = np.zeros(p), np.zeros((p, p + 1)), np.zeros((p, p + 1))
    y_dq_b, y_dv_b, b_tau_a = np.zeros((p, m)), np.zeros((p, m)), np.zeros(m)
    buf = wbuf = None
    C = signals.series_coefficients()
    if fsums:
        C = np.column_stack([C, acc.derivative().coefficients])
    for sl, T, M in signals.basis_factors():
        rows = sl.stop - sl.start
        if buf is None:
            buf = np.empty((rows, n_w + 2 * nl * p + (1 + 2 * nl) * fsums), order="F")
            wbuf = np.empty((rows, 3 + 2 * nl), order="F")
        S = (C if M is None else M @ C).T @ T.T  # one contiguous row per state
        q, v, a_fit = S[0], S[1], S[2]
        b = buf[:rows]
        Q = b[:, iq]
        Q[:] = signals.force[sl]  # a fresh (aligned) copy: sums independent of the input's memory layout
        if inertia:
            b[:, 0] = a_fit
        else:
            np.subtract(Q, signals.accel_measured[sl], out=b[:, 0])
            if filtered:
                np.subtract(Q, a_fit, out=b[:, 1])
            else:
                b[:, 1] = b[:, 0]
        X = b[:, ix:iq]
        lib.evaluate(q, v, out=X[:, off:])
        gram_w += b[:, :n_w].T @ b[:, :n_w]
        col, slots, derivs = n_w, [], []  # slots: (tensor, term row, column of its product with X, or constant)
        for k, t in enumerate(lib):
            for tensor, g in zip((dq_b, dv_b), t.derivative_values(q, v)):
                c = _constant(g)
                derivs.append((g, c))
                if c is None:
                    np.multiply(X, g[:, None], out=b[:, col : col + p])
                    slots.append((tensor, off + k, col, None))
                    col += p
                elif c != 0.0:
                    slots.append((tensor, off + k, None, c))
        u0 = ix  # U: the sums of columns u0:col against the sinusoids
        if fsums:  # y, tau q'' and g_k y against the sinusoids; tau-weighted states against [X, y]
            u0, ita = 1, col  # column 1 is y
            tau = signals.t[sl] - acc.t0
            np.multiply(tau, signals.accel_measured[sl], out=b[:, ita])
            col += 1
            wb = wbuf[:rows]
            np.multiply(tau, S[3], out=wb[:, 0])
            np.multiply(tau, v, out=wb[:, 1])
            np.subtract(a_fit, acc.coefficients[0], out=wb[:, 2])
            wb[:, 2] *= tau
            wcol, yslots = 3, []  # (derivative index, column of g y in U or of y, column in P, factor)
            for i, (g, c) in enumerate(derivs):
                base = 1 + i % 2  # tau q' (derivative in q) or tau (q'' - a_0) (derivative in q')
                if c is None:
                    np.multiply(b[:, 1], g, out=b[:, col])
                    np.multiply(wb[:, base], g, out=wb[:, wcol])
                    yslots.append((i, col, wcol, 1.0))
                    col += 1
                    wcol += 1
                elif c != 0.0:
                    yslots.append((i, 1, base, c))
            P = b[:, 1:iq].T @ wb[:, :wcol]  # rows y, X
            P = np.vstack([P[1:], P[:1]])  # rows X, y
            x_tau_jerk += P[:p, 0]
        U = sum(b[s : s + PASS_CHUNK, u0:col].T @ T[s : s + PASS_CHUNK] for s in range(0, rows, PASS_CHUNK))
        if M is not None:
            U = U @ M
        phi_b += U[ix - u0 : iq - u0]
        bF += U[iq - u0]
        for tensor, k, j, c in slots:
            tensor[k] += U[ix - u0 : iq - u0] * c if j is None else U[j - u0 : j - u0 + p]
        if fsums:
            b_tau_a += U[ita - u0]
            for i, j, w_col, c in yslots:
                Wt, Yb = (tau_q, y_dq_b) if i % 2 == 0 else (tau_v, y_dv_b)
                Wt[off + i // 2] += c * P[:, w_col]
                Yb[off + i // 2] += c * U[j - u0]
    n = signals.t.size
    if inertia:
        perm = np.arange(n_w)
    else:
        perm = np.r_[ix:iq, 1, 0]
    R = reduce_blocks(lambda: _regression_blocks(lib, signals, filtered, inertia), p, gram=gram_w[np.ix_(perm, perm)])
    gram = gram_w[ix:iq, ix:iq].copy()
    FF = float(gram_w[iq, iq])
    if estimated:  # the information of the frequency in the force
        G, G1, G2 = signals.basis_gram(weighted=True)
    else:
        G = signals.basis_gram()
    dof = max(n - m, 1)
    try:
        coef_F = linalg.solve(G, bF, assume_a="pos")
        rss_F = max(FF - float(bF @ coef_F), 0.0)
    except (linalg.LinAlgError, ValueError):
        coef_F, rss_F = np.full(m, np.nan), float("nan")
    Tv = _integration_map(omega, H)
    Tq = Tv @ Tv
    var_w = 0.0
    if estimated and np.all(np.isfinite(coef_F)):
        # d F / d omega = tau F'(tau) / omega; the force's coefficients are estimated with it
        d = HarmonicSeries(omega, coef_F).derivative().coefficients / omega
        u = G1 @ d
        info = float(d @ G2 @ d - u @ linalg.solve(G, u, assume_a="pos"))
        var_w = (rss_F / dof) / info if info > 0 else 0.0
    freq = None
    if fsums:  # d alpha / d omega of the acceleration's least-squares fit (G alpha = B^T a)
        alpha = acc.coefficients
        D = _derivative_map(omega, H)
        rhs = D.T @ b_tau_a - (D.T @ G1 + G1 @ D) @ alpha
        alpha_prime = linalg.solve(G, rhs, assume_a="pos") / omega
        freq = FrequencySums(float(omega), alpha, alpha_prime, x_tau_jerk, tau_q, tau_v, y_dq_b, y_dv_b)
    scores = RecordScores(
        gram, phi_b, dq_b, dv_b, G, Tq, Tv, _peak_direction(signals.displacement.coefficients, Tq),
        float(np.sqrt(rss_F / dof)), float(signals.accel_residual_rms * np.sqrt(n / dof)), int(n),
        bool(filtered or inertia), coef_F, bool(inertia), float(var_w), omega_sums=freq,
    )
    return R, scores


@dataclass(frozen=True)
class PooledCovariance:
    """Sandwich covariance of a pooled fit with shared and per-record coefficients.

    ``own`` coefficients of different records are correlated only through the shared
    ones, so the whole covariance is kept in a form linear in the number of records:

    * ``shared`` ``(ns, ns)``;
    * ``own`` ``(n_records, no, no)`` and ``own_shared`` ``(n_records, no, ns)``;
    * ``cov(own_r, own_s) = -F_r K_s^T - K_r F_s^T + K_r shared K_s^T`` for ``r != s``,
      with ``K`` and ``F`` ``(n_records, no, ns)``.
    """

    shared: np.ndarray
    own: np.ndarray
    own_shared: np.ndarray
    K: np.ndarray = field(repr=False)
    F: np.ndarray = field(repr=False)
    own_only: np.ndarray = field(repr=False)  # M_oo^-1 V_oo M_oo^-1 of each record
    own_q_max: np.ndarray | None = field(default=None, repr=False)  # cov(own_r, q_max_r) (n_records, no)
    q_max_variance: np.ndarray | None = field(default=None, repr=False)  # (n_records,)

    def own_factor(self, j, records=None):
        """Covariance of own coefficient ``j`` over ``records`` as ``diag(d) + U W U^T``."""
        idx = np.arange(self.own.shape[0]) if records is None else np.asarray(records, int)
        d = self.own_only[idx, j, j]
        U = np.hstack([self.K[idx, j, :], self.F[idx, j, :]])
        ns = self.shared.shape[0]
        eye, zero = np.eye(ns), np.zeros((ns, ns))
        W = np.block([[self.shared, -eye], [-eye, zero]])
        return LowRankCovariance(d, U, W, np.block([[zero, -eye], [-eye, -self.shared]]))


def pooled_covariance(solution, V_list, n_shared, g_list=None, q_var=None) -> PooledCovariance:
    """Sandwich covariance of a :class:`~jointid.identify.regression.PooledSolution`.

    ``V_list[r]`` is record ``r``'s score covariance ordered as its shared columns, then its
    own columns (records are independent).  ``g_list[r]`` (same order) is the covariance of
    that score with the record's ``q_max`` and ``q_var[r]`` the variance of ``q_max``; with
    them the covariance of each own coefficient with its record's amplitude is kept (errors
    in the abscissa of an amplitude law).
    """
    ns = n_shared
    Sch_i = scaled_inverse(solution.schur) if ns else np.zeros((0, 0))
    nr, no = solution.own.shape
    meat = np.zeros((ns, ns))
    Ts, ws = [], solution.weights
    for r, V in enumerate(V_list):
        T = np.hstack([np.eye(ns), -solution.K[r].T])
        Ts.append(T)
        meat += ws[r] ** 4 * (T @ V @ T.T)
    C_ss = Sch_i @ meat @ Sch_i
    C_ss = 0.5 * (C_ss + C_ss.T)
    F = np.zeros((nr, no, ns))
    own_only = np.zeros((nr, no, no))
    own = np.zeros((nr, no, no))
    own_shared = np.zeros((nr, no, ns))
    for r, V in enumerate(V_list):
        Mi, K = solution.own_gram_inv[r], solution.K[r]
        Voo = V[ns:, ns:]
        F[r] = Mi @ (ws[r] ** 2 * (V[ns:] @ Ts[r].T)) @ Sch_i
        own_only[r] = Mi @ Voo @ Mi
        own[r] = own_only[r] - F[r] @ K.T - K @ F[r].T + K @ C_ss @ K.T
        own_shared[r] = F[r] - K @ C_ss
    own_q = None
    if g_list is not None:
        own_q = np.zeros((nr, no))
        for r, g in enumerate(g_list):
            dth_s = Sch_i @ (ws[r] ** 2 * (Ts[r] @ g))
            own_q[r] = solution.own_gram_inv[r] @ g[ns:] - solution.K[r] @ dth_s
    return PooledCovariance(C_ss, own, own_shared, solution.K, F, own_only, own_q,
                            None if q_var is None else np.asarray(q_var, float))


@dataclass(frozen=True)
class LowRankCovariance:
    """A covariance ``diag(d) + U W U^T`` of many quantities (linear memory)."""

    d: np.ndarray
    U: np.ndarray
    W: np.ndarray
    W_inv: np.ndarray | None = None  # the exact inverse of W when known (W may be badly scaled)

    @staticmethod
    def stack(parts):
        """Block-diagonal combination of independent covariances."""
        parts = list(parts)
        d = np.concatenate([p.d for p in parts])
        U = linalg.block_diag(*[p.U for p in parts])
        W = linalg.block_diag(*[p.W for p in parts])
        inv = None
        if all(p.W_inv is not None for p in parts):
            inv = linalg.block_diag(*[p.W_inv for p in parts])
        return LowRankCovariance(d, U, W, inv)

    def congruence(self, L) -> np.ndarray:
        """``L C L^T`` for a matrix ``L`` ``(k, n)``."""
        L = np.atleast_2d(np.asarray(L, float))
        LU = L @ self.U
        out = (L * self.d) @ L.T + LU @ self.W @ LU.T
        return 0.5 * (out + out.T)

    def solve(self, b) -> np.ndarray:
        """``C^-1 b`` by the Woodbury identity (``d`` floored at a tiny positive value)."""
        b = np.asarray(b, float)
        d = np.maximum(self.d, 1e-300 + 1e-14 * np.max(np.abs(self.d), initial=0.0))
        Db = b / (d if b.ndim == 1 else d[:, None])
        DU = self.U / d[:, None]
        k = self.W.shape[0]
        if k == 0:
            return Db
        Winv = self.W_inv if self.W_inv is not None else np.linalg.pinv(self.W)
        core = Winv + self.U.T @ DU
        s = np.sqrt(np.abs(np.diag(core)))
        s[s == 0] = 1.0
        rhs = self.U.T @ Db
        y = np.linalg.solve(core / np.outer(s, s), rhs / (s if rhs.ndim == 1 else s[:, None]))
        y = y / (s if y.ndim == 1 else s[:, None])
        return Db - DU @ y

    def dense(self) -> np.ndarray:
        return np.diag(self.d) + self.U @ self.W @ self.U.T

    def add_diagonal(self, extra) -> "LowRankCovariance":
        return LowRankCovariance(self.d + np.asarray(extra, float), self.U, self.W, self.W_inv)


@dataclass(frozen=True)
class Whitening:
    """Weight of one record in a pooled or preload regression.

    A record enters through its reduced factor: the rows ``R theta = z`` (``R`` the ``p x p``
    triangle of :func:`~jointid.identify.regression.reduce_blocks`), multiplied by ``W``.
    Under the noise model the error of ``z`` has covariance ``S = R^-T V R^-1`` (for white
    noise ``sigma^2 I``).  :func:`whitening` uses the scalar ``W = I / sqrt(tr(S) / p)``; the
    covariance formulas here hold for any ``W``.
    """

    W: np.ndarray  # (p, p)
    R: np.ndarray  # (p, p) upper triangle of the record's reduced factor
    z: np.ndarray  # (p,)

    @property
    def rows(self) -> np.ndarray:
        """Weighted rows ``W [R z]``, ``(p, p + 1)``."""
        return self.W @ np.column_stack([self.R, self.z])

    @property
    def scalar(self) -> float:
        """Equivalent scalar weight ``sqrt(tr(W^T W) / p)``."""
        return float(np.sqrt(np.trace(self.W.T @ self.W) / len(self.W)))

    def _to_reduced(self, A):
        """``R^-T A`` (``A`` with ``p`` rows)."""
        return linalg.solve_triangular(self.R, A, trans="T", check_finite=False)

    def score_covariance(self, V) -> np.ndarray:
        """Covariance of the weighted score ``(W R)^T W eps`` given the record's score covariance ``V``."""
        Rinv_T_V = self._to_reduced(V)
        S = self._to_reduced(Rinv_T_V.T).T  # R^-T V R^-1
        WR = self.W @ self.R
        out = WR.T @ (self.W @ S @ self.W.T) @ WR
        return 0.5 * (out + out.T)

    def score_cross(self, g) -> np.ndarray:
        """Covariance of the weighted score with a scalar whose covariance with the score is ``g``."""
        return (self.W @ self.R).T @ (self.W @ self._to_reduced(np.asarray(g, float)))


def whitening(R_full, scores, theta, dtheta_dqmax=None, weighting="noise", floor=None) -> Whitening:
    """The :class:`Whitening` of a record with coefficients ``theta`` (``weighting="none"``: ``W = I``).

    ``"noise"``: ``W = I / sigma`` with ``sigma^2 = tr(S) / p = tr(M^-1 V) / p``, the white-noise
    level that carries the same information as the record's own fit, floored at ``floor``
    so that noise-free records keep finite, equal weights.

    Notes
    -----
    Full generalised least squares (``W^T W = S^-1``) was tried: it exploits directions in
    which the acceleration noise cancels, and there the neglected second-order errors
    (frequency estimate, harmonics beyond the fitted ones) dominate, so its standard errors
    of ``omega1`` and ``k3`` came out 2-3 times too small in Monte Carlo campaigns.  The
    scalar weight keeps the intervals calibrated.
    """
    p = scores.gram.shape[0]
    R, z = np.asarray(R_full, float)[:p, :p], np.asarray(R_full, float)[:p, p]
    if weighting == "none":
        return Whitening(np.eye(p), R, z)
    wh = Whitening(np.eye(p), R, z)
    V = scores.covariance(theta, dtheta_dqmax)
    Rinv_T_V = wh._to_reduced(V)
    S = wh._to_reduced(Rinv_T_V.T).T
    sigma = float(np.sqrt(max(np.trace(S) / p, 0.0)))
    sigma = max(sigma if np.isfinite(sigma) else 0.0, floor or 0.0, np.finfo(float).tiny)
    return Whitening(np.eye(p) / sigma, R, z)
