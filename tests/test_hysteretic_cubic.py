"""A joint law with a cubic spring beside it (``"jenkins+cubic"``): a campaign made by time integration of
``q'' + c q' + k q + kt (q - x) - k3 q^3 = Q cos(omega t)`` (the slider ``x`` by the play operator, as in
tests/test_hysteretic_fsm.py) recovers its five parameters within their standard errors; the law without the
cubic leaves a residual far above the noise."""

import math

import numpy as np
import pytest

from jointid.identify.hysteretic import HystereticForceStateMapping, first_harmonic_peak
from test_hysteretic_fsm import C, JENKINS, JENKINS_LEVELS, K, noisy


def integrate_cubic(k3, Qs, omegas, steps=256, periods=150, record=24, sub=2):
    """RK4 of the Jenkins oscillator with a cubic spring ``-k3 q^3``; ``(t, accel)`` of the last periods."""
    Q, w = np.asarray(Qs, float), np.asarray(omegas, float)
    kt, phi = JENKINS.kt, JENKINS.slip_displacement
    dt = 2 * np.pi / w / steps
    q, v, x = np.zeros(Q.size), np.zeros(Q.size), np.zeros(Q.size)

    def acc(t, qq, vv, x0):
        xs = np.clip(x0, qq - phi, qq + phi)
        return Q * np.cos(w * t) - C * vv - K * qq - kt * (qq - xs) + k3 * qq**3

    start = (periods - 1) * steps
    keep_t, keep_a, keep_q = [], [], []
    for n in range(start + (record + 1) * steps):
        t = n * dt
        a1 = acc(t, q, v, x)
        a2 = acc(t + 0.5 * dt, q + 0.5 * dt * v, v + 0.5 * dt * a1, x)
        v2 = v + 0.5 * dt * a1
        a3 = acc(t + 0.5 * dt, q + 0.5 * dt * v2, v + 0.5 * dt * a2, x)
        v3 = v + 0.5 * dt * a2
        a4 = acc(t + dt, q + dt * v3, v + dt * a3, x)
        v4 = v + dt * a3
        q, v = q + dt / 6 * (v + 2 * v2 + 2 * v3 + v4), v + dt / 6 * (a1 + 2 * a2 + 2 * a3 + a4)
        x = np.clip(x, q - phi, q + phi)
        m = n + 1
        if m > start and (m - start) % sub == 0:
            keep_t.append(m * dt)
            keep_a.append(acc(m * dt, q, v, x))
            keep_q.append(q.copy())
    t, a, qq = (np.array(z).T for z in (keep_t, keep_a, keep_q))
    per = steps // sub
    err = np.abs(qq[:, -per:] - qq[:, :per]).max(axis=1) / np.abs(qq[:, -per:]).max(axis=1)
    assert err.max() < 1e-5, f"not in steady state: {err.max():.3g}"
    return t[:, per:], a[:, per:]


@pytest.fixture(scope="module")
def cubic_campaign():
    _, a_top = first_harmonic_peak(K, C, JENKINS, JENKINS_LEVELS[-1])
    k3 = 0.01 * K / (0.75 * a_top**2)  # softens the top level's peak by about 1 % of K
    Qs, ws = [], []
    for Q in JENKINS_LEVELS:
        fp, _ = first_harmonic_peak(K, C, JENKINS, Q, k3=k3)
        for f in fp * (1 + 0.06 * np.linspace(-1, 1, 13)):
            Qs.append(Q)
            ws.append(2 * np.pi * f)
    t, a = integrate_cubic(k3, Qs, ws)
    return k3, (t, a, np.array(Qs), np.array(ws))


@pytest.mark.slow
def test_jenkins_with_a_cubic_spring_recovers_its_parameters(cubic_campaign):
    k3, data = cubic_campaign
    sigs = noisy(data, np.random.default_rng(31))
    res = HystereticForceStateMapping("jenkins+cubic").fit(sigs).result_
    truth = {"k": K, "c": C, "kt": JENKINS.kt, "Fs": JENKINS.Fs, "k3": k3}
    z = {n: (res.get(n) - v) / res.get_stderr(n) for n, v in truth.items()}
    print({n: round(v, 2) for n, v in z.items()}, "residual rms", round(res.residual_rms, 3))
    assert all(abs(v) < 2.5 for v in z.values()), z
    assert res.get_stderr("k3") < 0.05 * k3  # resolved: its column is not lost to the scaling of the others
    assert 0.5 < res.residual_rms < 1.5
    assert res.k3 == res.get("k3") and "k3" in res.summary()["parameters"]
    # the model's first harmonic carries the cubic: K(a) = k + k_eq(a) - 3/4 k3 a^2
    k_eq, _ = res.law.first_harmonic(1e-3)
    assert res.first_harmonic(1e-3)[0] == pytest.approx(res.k + k_eq - 0.75 * res.k3 * 1e-6, rel=1e-12)
    without = HystereticForceStateMapping("jenkins").fit(sigs).result_
    assert without.residual_rms > 3 * res.residual_rms
    # the top level's peak: the fitted model against the true one, both by first-harmonic balance
    fq, aq = res.peak(JENKINS_LEVELS[-1])
    ft, at = first_harmonic_peak(K, C, JENKINS, JENKINS_LEVELS[-1], k3=k3)
    assert abs(fq / ft - 1) < 2e-4 and abs(aq / at - 1) < 5e-3
    assert math.isfinite(res.loop(sigs[6]).rms_difference) and res.loop(sigs[6]).rms_difference < 0.05


@pytest.mark.slow
def test_fit_on_the_fundamental_only(cubic_campaign):
    """``fit_harmonics=1``: the same campaign compared on the first harmonic only (what a single-mode model of a
    structure represents) still recovers the parameters within their standard errors."""
    k3, data = cubic_campaign
    sigs = noisy(data, np.random.default_rng(32))
    full = HystereticForceStateMapping("jenkins+cubic").fit(sigs).result_
    res = HystereticForceStateMapping("jenkins+cubic", fit_harmonics=1).fit(sigs).result_
    truth = {"k": K, "c": C, "kt": JENKINS.kt, "Fs": JENKINS.Fs, "k3": k3}
    z = {n: (res.get(n) - v) / res.get_stderr(n) for n, v in truth.items()}
    print({n: round(v, 2) for n, v in z.items()}, "residual rms", round(res.residual_rms, 3))
    assert all(abs(v) < 2.5 for v in z.values()), z
    # the residual's scale: each record's weight is its force and acceleration noise together, but near
    # resonance the acceleration noise of the fundamental largely cancels in q'' + k q, so this rms reads
    # below one (0.26 here); the standard errors come from the sandwich, which propagates it exactly
    assert res.residual_rms < 1.5
    print("standard errors, fundamental only / all harmonics:",
          {n: round(res.get_stderr(n) / full.get_stderr(n), 2) for n in truth})
    assert full.residual_rms > 0.5  # the same records with all harmonics: the residual at the noise


def test_bad_fit_harmonics():
    from jointid.errors import IdentificationError

    with pytest.raises(IdentificationError, match="fit_harmonics"):
        HystereticForceStateMapping("jenkins", fit_harmonics=0)
    with pytest.raises(IdentificationError, match="law must be one of"):
        HystereticForceStateMapping("iwan4+quintic").fit([])
