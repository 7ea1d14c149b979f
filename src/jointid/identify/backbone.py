"""Backbone curves: amplitude-dependent natural frequency ``omega(a)`` and damping ratio ``zeta(a)``.

Three sources, one result type (:class:`Backbone`):

Identified single-mode model (:func:`model_backbone`)
    ``q'' + h(q, q') = 0`` with ``h = sum_j theta_j phi_j(q, q')`` (any term library, any
    coefficient following a polynomial amplitude law).  With first-harmonic balance (a
    single nonlinear mode) the motion is ``q = a cos(th)``, ``q' = -a w sin(th)`` and the
    Fourier coefficients of ``h`` over one period give the equivalent stiffness and
    damping::

        k_eq(a, w) =  1 / (pi a)   int_0^2pi h(a cos th, -a w sin th) cos th dth
        c_eq(a, w) = -1 / (pi a w) int_0^2pi h(a cos th, -a w sin th) sin th dth

    and the backbone ``w(a)^2 = k_eq(a, w)``, ``zeta(a) = c_eq / (2 w)``.  With
    ``n_harmonics > 1`` the higher harmonics are kept: the periodic motion of
    ``q'' + h(q, q') - xi q' = 0`` whose fundamental is ``a cos(w t)`` is solved for
    ``w``, ``xi`` and the other harmonics (the extended periodic motion concept of
    Krack 2015 for one coordinate), and ``zeta = xi / (2 w)``.  95 % bands come from
    linear propagation of the parameter covariance through the Jacobian of
    ``(w, zeta)`` with respect to the parameters (central differences).

Stepped-sine records (:func:`equivalent_linearisation`, :func:`phase_resonance_points`)
    The first harmonics ``X`` of the displacement and ``Q1`` of the force of one dwell
    (``Q1`` times the identified gain ``g`` when the force column is, e.g., a shaker
    voltage; ``X`` from the record's harmonic fit, which carries a channel-delay
    correction) give the restoring force's first harmonic ``h1 = g Q1 + w^2 X`` and the equivalent
    complex stiffness ``h1 / X = k_eq + i D``.  The record's point is
    ``omega_eq = sqrt(k_eq)``, ``zeta = D / (2 w omega_eq)``, at ``a = |X|``.  ``D`` is
    ``c w`` for viscous damping and the same at any frequency for hysteretic damping, so
    away from resonance the ratio carries an error of about ``|w / omega_eq - 1| / 2``;
    the phase-resonance point of a force level (``k_eq = w^2``, the response in
    quadrature with the force) has no such error and is interpolated between the dwells
    on either side.

Amplitudes ``a`` are first-harmonic amplitudes of the modal displacement.
"""

from __future__ import annotations

import numpy as np

from ..errors import ConvergenceError, IdentificationError
from ..signal.backbone import Z95, Backbone  # noqa: F401  (the result type, plain data, lives on the signal floor)
from .powerlaw import PowerLaw
from .terms import library

__all__ = [
    "Backbone",
    "model_backbone",
    "equivalent_linearisation",
    "phase_resonance_points",
    "parameter_vector",
]

# ----------------------------------------------------------------------------------------
# Backbone of an identified model
# ----------------------------------------------------------------------------------------


def parameter_vector(terms, coefficients, amplitude_laws=None):
    """Flatten a model's parameters in the order the covariance of :func:`model_backbone` uses.

    The coefficients of the terms without an amplitude law (library order), then the
    polynomial coefficients ``p0, p1, ...`` of each amplitude law (library order).

    Returns
    -------
    p : ndarray
    names : list of str
        ``"omega1^2"``, ``"k3"``, ``"c[0]"``, ``"c[1]"`` ...
    """
    lib = library(terms)
    coefficients = np.asarray(coefficients, float)
    laws = {lib[k].coefficient: np.atleast_1d(np.asarray(v, float)) for k, v in dict(amplitude_laws or {}).items()}
    if coefficients.size != len(lib):
        raise IdentificationError(f"{len(lib)} coefficients expected for {lib.names}, got {coefficients.size}")
    p, names = [], []
    for t, c in zip(lib, coefficients):
        if t.coefficient not in laws:
            p.append(float(c))
            names.append(t.coefficient)
    for t in lib:
        if t.coefficient in laws:
            for k, v in enumerate(laws[t.coefficient]):
                p.append(float(v))
                names.append(f"{t.coefficient}[{k}]")
    return np.array(p), names


def _unflatten(lib, p, law_sizes):
    """Inverse of :func:`parameter_vector`: ``(base coefficients, {coefficient: poly})``."""
    base = np.zeros(len(lib))
    i = 0
    for j, t in enumerate(lib):
        if t.coefficient not in law_sizes:
            base[j] = p[i]
            i += 1
    laws = {}
    for t in lib:
        if t.coefficient in law_sizes:
            n = law_sizes[t.coefficient]
            laws[t.coefficient] = p[i:i + n]
            i += n
    return base, laws


def _theta_at(lib, base, laws, q_max, power=frozenset()):
    theta = base.copy()
    for name, poly in laws.items():
        theta[lib.index(name)] = (PowerLaw(*poly).value(q_max) if name in power
                                  else np.polynomial.polynomial.polyval(q_max, poly))
    return theta


def _first_harmonic(lib, theta, a, n_phase, w_guess):
    """``(w, zeta)`` of the first-harmonic backbone at amplitude ``a`` (fixed point on ``w``)."""
    th = 2 * np.pi * (np.arange(n_phase) + 0.5) / n_phase  # mid-points: no sample where q' = 0
    c, s = np.cos(th), np.sin(th)
    q = a * c
    w = w_guess
    for _ in range(100):
        h = lib.restoring_force(q, -a * w * s, theta)
        k_eq = 2.0 * np.mean(h * c) / a
        if not k_eq > 0:
            raise IdentificationError(
                f"the model has no oscillation at amplitude {a:.4g}: equivalent stiffness {k_eq:.4g} <= 0")
        w_new = np.sqrt(k_eq)
        done = abs(w_new - w) <= 1e-15 * w_new
        w = w_new
        if done:
            break
    h = lib.restoring_force(q, -a * w * s, theta)
    c_eq = -2.0 * np.mean(h * s) / (a * w)
    return w, c_eq / (2 * w)


def _epmc_sdof(lib, theta_of, a, n_harmonics, w0, xi0, n_time):
    """Multi-harmonic periodic motion of ``q'' + h - xi q' = 0`` with fundamental ``a cos(w t)``.

    ``theta_of(q_max)`` gives the coefficients (amplitude laws closed on the solution's own
    ``max |q|``).  Returns ``(w, zeta, q_max)``.
    """
    H = int(n_harmonics)
    tau = 2 * np.pi * np.arange(n_time) / n_time
    k = np.arange(1, H + 1)
    C = np.cos(np.outer(tau, k))
    S = np.sin(np.outer(tau, k))

    def unpack(x):  # unknowns scaled: harmonics by a, w and xi by w0
        a0 = a * x[0]
        ak = a * np.concatenate([[1.0], x[1:H]])
        bk = a * np.concatenate([[0.0], x[H:2 * H - 1]])
        return a0, ak, bk, w0 * x[-2], w0 * x[-1]

    def motion(x):
        a0, ak, bk, w, xi = unpack(x)
        q = a0 + C @ ak + S @ bk
        v = w * (S @ (-k * ak) + C @ (k * bk))
        acc = -(w**2) * (C @ (k**2 * ak) + S @ (k**2 * bk))
        return q, v, acc

    qmax = [a]

    def residual(x):
        q, v, acc = motion(x)
        theta = theta_of(qmax[0])
        r = acc + lib.restoring_force(q, v, theta) - w0 * x[-1] * v
        out = np.empty(2 * H + 1)
        out[0] = np.mean(r)
        out[1::2] = 2 * (C.T @ r) / n_time
        out[2::2] = 2 * (S.T @ r) / n_time
        return out / (w0**2 * a)

    x = np.zeros(2 * H + 1)
    x[-2], x[-1] = 1.0, xi0 / w0
    eye = 1e-7 * np.eye(x.size)
    for _ in range(50):  # Newton (difference Jacobian), the amplitude-law closure updated each step
        q, _, _ = motion(x)
        qmax[0] = float(np.max(np.abs(q)))
        r = residual(x)
        J = np.column_stack([(residual(x + e) - residual(x - e)) / 2e-7 for e in eye])
        step = np.linalg.solve(J, -r)
        x = x + step
        if np.max(np.abs(step)) < 1e-13:
            break
    else:
        raise ConvergenceError(f"backbone harmonic balance at amplitude {a:.4g} did not converge "
                               f"(residual {np.max(np.abs(residual(x))):.3g})")
    w, xi = w0 * x[-2], w0 * x[-1]
    return w, xi / (2 * w), qmax[0]


def model_backbone(terms, coefficients, amplitudes, *, amplitude_laws=None, covariance=None, n_harmonics=1,
                   n_phase=256, label="") -> Backbone:
    """Backbone of an identified single-mode model ``q'' + h(q, q') = Q``.

    Parameters
    ----------
    terms : TermLibrary or str
        The restoring-force terms (``"q + -q^3 + q'"`` ...); the term ``q`` is needed.
    coefficients : array_like
        One value per term (ignored for a term with an amplitude law).
    amplitudes : array_like
        First-harmonic amplitudes ``a`` of ``q`` at which to evaluate.
    amplitude_laws : mapping, optional
        ``{coefficient or term name: (p0, p1, ...)}``: that coefficient is
        ``p0 + p1 q_max + ...`` (``q_max = a`` at first order); or
        ``{name: PowerLaw(c0, c1, p)}``: ``c0 + c1 q_max^p``.
    covariance : array_like, optional
        Covariance of the parameter vector of :func:`parameter_vector` (coefficients
        without a law, then the law polynomials; a power law's ``c0, c1, p``).  Without it
        the bands are ``nan``.
    n_harmonics : int
        1: first-harmonic balance (closed form above).  More: the multi-harmonic
        periodic motion with the damping replaced by ``xi q'`` (module docstring).
    n_phase : int
        Phase samples of one period.
    label : str

    Returns
    -------
    Backbone

    Examples
    --------
    >>> b = model_backbone("q + -q^3 + q'", [100.0**2, 1e6, 2.0], [0.0, 0.01])
    >>> [round(float(w), 4) for w in b.omega]          # sqrt(w1^2 - 3/4 k3 a^2)
    [100.0, 99.6243]
    >>> [round(float(z), 6) for z in b.zeta]           # c / (2 w)
    [0.01, 0.010038]
    """
    lib = library(terms)
    if "q" not in lib.names:
        raise IdentificationError(f"a backbone needs the linear term 'q' in the model; got {lib.names}")
    a = np.atleast_1d(np.asarray(amplitudes, float))
    if a.ndim != 1 or not np.all(np.isfinite(a)) or np.any(a < 0):
        raise IdentificationError(f"amplitudes must be finite and >= 0, got {amplitudes!r}")
    given = dict(amplitude_laws or {})
    power = frozenset(lib[k].coefficient for k, v in given.items() if isinstance(v, PowerLaw))
    laws = {lib[k].coefficient: np.atleast_1d(np.asarray(v.parameters if isinstance(v, PowerLaw) else v, float))
            for k, v in given.items()}
    p, names = parameter_vector(lib, coefficients, laws)
    sizes = {k: v.size for k, v in laws.items()}
    H = int(n_harmonics)
    n_time = max(int(n_phase), 8 * (H + 1))

    def evaluate(pv):
        base, lw = _unflatten(lib, pv, sizes)
        w = np.empty(a.size)
        z = np.empty(a.size)
        w_prev = np.sqrt(max(base[lib.index("q")] if "omega1^2" not in lw else lw["omega1^2"][0], 1e-300))
        for i, ai in enumerate(a):
            if ai == 0:  # the linear limit
                th = _theta_at(lib, base, lw, 0.0, power)
                w[i] = np.sqrt(th[lib.index("q")])
                z[i] = (th[lib.index("q'")] if "q'" in lib.names else 0.0) / (2 * w[i])
                continue
            if H <= 1:
                w[i], z[i] = _first_harmonic(lib, _theta_at(lib, base, lw, ai, power), ai, n_time, w_prev)
            else:
                w1, z1 = _first_harmonic(lib, _theta_at(lib, base, lw, ai, power), ai, n_time, w_prev)
                w[i], z[i], _ = _epmc_sdof(lib, lambda qm: _theta_at(lib, base, lw, qm, power), ai, H, w1,
                                           2 * z1 * w1, n_time)
            w_prev = w[i]
        return w, z

    w, z = evaluate(p)
    w_se = np.full(a.size, np.nan)
    z_se = np.full(a.size, np.nan)
    if covariance is not None:
        cov = np.atleast_2d(np.asarray(covariance, float))
        if cov.shape != (p.size, p.size):
            raise IdentificationError(
                f"covariance must be {p.size} x {p.size} for the parameters {names}, got {cov.shape}")
        Jw = np.empty((a.size, p.size))
        Jz = np.empty((a.size, p.size))
        sd = np.sqrt(np.clip(np.diag(cov), 0, None))
        for j in range(p.size):
            h = 1e-4 * sd[j] if sd[j] > 0 else 1e-7 * max(abs(p[j]), 1e-12)
            dp = np.zeros(p.size)
            dp[j] = h
            wp, zp = evaluate(p + dp)
            wm, zm = evaluate(p - dp)
            Jw[:, j] = (wp - wm) / (2 * h)
            Jz[:, j] = (zp - zm) / (2 * h)
        w_se = np.sqrt(np.clip(np.einsum("ij,jk,ik->i", Jw, cov, Jw), 0, None))
        z_se = np.sqrt(np.clip(np.einsum("ij,jk,ik->i", Jz, cov, Jz), 0, None))
    return Backbone(a, w, z, w_se, z_se, "model", np.zeros_like(a), label,
                    {"terms": list(lib.names), "parameters": names, "n_harmonics": H})


# ----------------------------------------------------------------------------------------
# Backbone points straight from stepped-sine records
# ----------------------------------------------------------------------------------------


def _fundamental(t, x, omega):
    """First-harmonic complex amplitude ``X`` (``x ~ Re(X e^{i w t})``) with its standard error.

    Least squares on ``[1, cos, sin]``; the standard error is that of the amplitude (the
    residual RMS times ``sqrt(2 / n)`` for a record of many periods).
    """
    from ..signal.harmonics import _blocks, _streaming_fit

    t = np.asarray(t, float)
    x = np.asarray(x, float)
    # block by block (normal equations on the sinusoids at every omega (t - t0), then the
    # residual): a long record is never copied
    series, _ = _streaming_fit(t, x, float(omega), 1, float(t[0]), "fundamental", origin=float(t[0]))
    coef = series.coefficients
    rr = sum(float(np.sum((x[sl] - series(t[sl])) ** 2)) for sl in _blocks(x.size))
    sigma = np.sqrt(rr / max(x.size - 3, 1))
    X = (coef[1] - 1j * coef[2]) * np.exp(-1j * omega * t[0])
    return X, sigma * np.sqrt(2.0 / x.size)


def _series_fundamental(series):
    """First-harmonic complex amplitude of a :class:`~jointid.signal.harmonics.HarmonicSeries`
    in absolute time (``x ~ Re(X e^{i w t})``), the convention of :func:`_fundamental`."""
    c = np.asarray(series.coefficients, float)
    return (c[1] - 1j * c[2]) * np.exp(-1j * series.omega * series.t0)


def _per_record(value, n, name):
    """A scalar or one value per record (``None`` kept: unknown for that record)."""
    if value is None or np.ndim(value) == 0:
        return [value] * n
    v = list(value)
    if len(v) != n:
        raise IdentificationError(f"{name}: one value per record expected ({n}), got {len(v)}")
    return v


def equivalent_linearisation(signals_list, *, force_level=None, force_gain=1.0, force_gain_stderr=0.0,
                             delay_stderr=0.0, label="") -> Backbone:
    """One backbone point per steady-state record: equivalent stiffness and damping at its amplitude.

    Parameters
    ----------
    signals_list : sequence of StateSignals
        Reduced records (:func:`jointid.signal.harmonics.steady_state_signals`): modal
        force and acceleration, excitation frequency.  The response's fundamental is taken
        from the record's harmonic fit (``signals.acceleration``), so a channel-delay
        correction applied to it (:func:`jointid.identify.delay.shift_response`) is part
        of the point.
    force_level : sequence, optional
        Force level of each record (kept in ``meta``).
    force_gain : float or sequence, default 1
        Force per unit of the recorded force column (a scalar, or one value per record).
        With an unknown gain (a shaker voltage recorded as the force) this is the gain
        identified with the records (:class:`jointid.identify.gain.GainFit`, ``1 / m``):
        the restoring force is ``g Q1 + w^2 X``.  A ``None`` entry marks a record whose
        gain is not known: its point is ``nan``.
    force_gain_stderr : float or sequence, default 0
        Standard error of the gain; propagated into the point's errors.
    delay_stderr : float, default 0
        Standard error [s] of the channel delay by which the records were corrected;
        propagated into the point's errors.
    label : str

    Returns
    -------
    Backbone
        ``source = "stepped-sine"``; ``meta`` holds the excitation frequency, the phase of
        the response, the gain and ``k_eq``, ``D`` of every record.  A record whose ``k_eq``
        is not positive, or whose gain is unknown, gets ``nan``.

    Notes
    -----
    The standard errors come from the noise left outside the fundamental (the residuals
    of the force and of the acceleration around their first harmonic, which also holds
    the higher harmonics: a conservative scale), the gain's and the delay's standard
    errors, propagated linearly.  The damping ratio's error also holds
    ``|w / omega_eq - 1| / 2`` of itself: the spread between a viscous and a hysteretic
    reading of ``D`` away from resonance.
    """
    n = len(signals_list)
    gains = _per_record(force_gain, n, "force_gain")
    gain_se = _per_record(force_gain_stderr, n, "force_gain_stderr")
    s_tau = float(delay_stderr or 0.0)
    a, w_eq, z, a_se, w_se, z_se = ([] for _ in range(6))
    freqs, phases, keqs, Ds, used_gain = [], [], [], [], []
    for s, g, sg in zip(signals_list, gains, gain_se):
        w = s.omega
        _, sa = _fundamental(s.t, s.accel_measured, w)  # noise scale of the measured response
        Xa = _series_fundamental(s.acceleration)  # the fitted (delay-corrected) response
        Q1, sq = _fundamental(s.t, s.force, w)
        X = -Xa / w**2
        sx = sa / w**2
        amp = abs(X)
        a.append(amp)
        a_se.append(sx)
        freqs.append(s.frequency_hz)
        phases.append(float(np.angle(X / Q1)))
        used_gain.append(None if g is None else float(g))
        if g is None or not np.isfinite(g):
            keqs.append(np.nan), Ds.append(np.nan)
            w_eq.append(np.nan), z.append(np.nan), w_se.append(np.nan), z_se.append(np.nan)
            continue
        g = float(g)
        sg = float(sg or 0.0)
        gQ = g * Q1 / X
        G = gQ + w**2  # k_eq + i D
        k, D = G.real, G.imag
        keqs.append(float(k))
        Ds.append(float(D))
        if not k > 0:
            w_eq.append(np.nan), z.append(np.nan), w_se.append(np.nan), z_se.append(np.nan)
            continue
        we = np.sqrt(k)
        w_eq.append(we)
        z.append(D / (2 * w * we))
        # linear propagation: dG = g dQ1 / X - g Q1 dX / X^2 (the w^2 X part cancels), isotropic noise
        gs = abs(g) * np.hypot(sq / amp, abs(Q1) * sx / amp**2)
        noise_w = gs / (2 * we) / np.sqrt(2)
        noise_z = np.hypot(gs / np.sqrt(2) / (2 * w * we), D * gs / np.sqrt(2) / (4 * w * we**3))
        # the gain (dG/dg = Q1 / X) and the delay (X = X_m e^{i w tau}: dG/dtau = -i w g Q1 / X)
        extra_w, extra_z = [], []
        for dG in (gQ / g * sg, -1j * w * gQ * s_tau):
            dk, dD = dG.real, dG.imag
            extra_w.append(dk / (2 * we))
            extra_z.append(dD / (2 * w * we) - D * dk / (4 * w * we**3))
        w_se.append(float(np.sqrt(noise_w**2 + sum(e**2 for e in extra_w))))
        # the damping convention (viscous or hysteretic) is unknown: its spread is part of the error
        z_se.append(float(np.sqrt(noise_z**2 + sum(e**2 for e in extra_z)
                                  + (0.5 * abs(w / we - 1) * D / (2 * w * we))**2)))
    meta = {"frequency_hz": [float(f) for f in freqs], "phase": phases, "k_eq": keqs, "D": Ds,
            "force_gain": used_gain}
    if force_level is not None:
        meta["force_level"] = [_level_key(f) for f in force_level]
    return Backbone(np.array(a), np.array(w_eq), np.array(z), np.array(w_se), np.array(z_se), "stepped-sine",
                    np.array(a_se), label, meta)


def _level_key(level):
    """A force level as a JSON-safe grouping key: a number, or the manifest's text label as it is."""
    if level is None or isinstance(level, str):
        return level
    return float(level)


def phase_resonance_points(points: Backbone, force_level=None, label="") -> Backbone:
    """Phase-resonance points (response in quadrature with the force) of each force level.

    Within the records of one force level (``points.meta["force_level"]``, or all of
    them), sorted by excitation frequency, the crossing of ``k_eq - w^2 = 0`` is located
    by linear interpolation between the two dwells on either side; the amplitude,
    ``omega`` (= the excitation frequency there) and ``zeta = D / (2 w^2)`` are
    interpolated alike.

    Parameters
    ----------
    points : Backbone
        From :func:`equivalent_linearisation`.
    force_level : sequence, optional
        Overrides ``points.meta["force_level"]``.

    Returns
    -------
    Backbone
        ``source = "phase-resonance"``, one point per crossing (``meta["force_level"]``).
    """
    f = np.asarray(points.meta["frequency_hz"], float)
    k = np.asarray(points.meta["k_eq"], float)
    D = np.asarray(points.meta["D"], float)
    levels = force_level if force_level is not None else points.meta.get("force_level", [None] * f.size)
    levels = [_level_key(v) for v in levels]
    out = {"a": [], "w": [], "z": [], "ase": [], "wse": [], "zse": [], "level": []}
    numbers_first = lambda v: (v is None, isinstance(v, str), 0.0 if isinstance(v, str) or v is None else v, str(v))  # noqa: E731
    for lev in sorted(set(levels), key=numbers_first):
        idx = np.array([i for i, v in enumerate(levels) if v == lev], int)
        idx = idx[np.argsort(f[idx])]
        w = 2 * np.pi * f[idx]
        g = k[idx] - w**2  # > 0 below resonance
        for j in range(idx.size - 1):
            if not (np.isfinite(g[j]) and np.isfinite(g[j + 1])) or g[j] * g[j + 1] > 0 or g[j] == g[j + 1]:
                continue
            s = g[j] / (g[j] - g[j + 1])
            i0, i1 = idx[j], idx[j + 1]

            def lerp(x):
                return (1 - s) * x[i0] + s * x[i1]

            wr = lerp(2 * np.pi * f)
            out["a"].append(lerp(points.amplitude))
            out["w"].append(wr)
            out["z"].append(lerp(D) / (2 * wr**2))
            out["ase"].append(lerp(points.amplitude_stderr))
            out["wse"].append(lerp(points.omega_stderr))
            out["zse"].append(lerp(points.zeta_stderr))
            out["level"].append(lev)
    return Backbone(np.array(out["a"]), np.array(out["w"]), np.array(out["z"]), np.array(out["wse"]),
                    np.array(out["zse"]), "phase-resonance", np.array(out["ase"]), label,
                    {"force_level": out["level"]})
