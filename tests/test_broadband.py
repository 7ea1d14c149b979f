"""Broadband (multisine / random) processing and force-state mapping: ground truth from simulation."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from jointid.errors import IdentificationError, RecordError
from jointid.identify.broadband import (
    BroadbandForceStateMapping,
    delta_method,
    equivalent_linear_track,
    simulate_response,
)
from jointid.identify.terms import library
from jointid.signal.broadband import (
    average_periods,
    band_filter,
    detect_period,
    excited_lines,
    find_periodic_segments,
    periodic_states,
    random_states,
)

# Duffing SDOF in the seed's convention: q'' + c q' + w1^2 q - k3 q^3 = F(t)   (k3 < 0: hardening)
W1 = 2 * np.pi * 5.0
ZETA = 0.05
C = 2 * ZETA * W1
K3 = -1.0e5
GAIN = 0.37  # force per volt: the recorded "force" is F / GAIN


def multisine(fs, n, lines, rms, seed=0):
    """Random-phase multisine with flat amplitude on ``lines``; returns a function of t and its period."""
    rng = np.random.default_rng(seed)
    f = np.asarray(lines) * fs / n
    ph = rng.uniform(0, 2 * np.pi, f.size)
    amp = rms * np.sqrt(2.0 / f.size)

    def u(t):
        t = np.atleast_1d(t)
        return (amp * np.cos(2 * np.pi * np.outer(t, f) + ph)).sum(axis=1)

    return u


def simulate_duffing(force, t_end, fs, *, w1=W1, c=C, k3=K3):
    """Response of the Duffing oscillator to ``force(t)`` sampled at ``fs`` (DOP853, tight tolerances)."""

    def rhs(t, x):
        q, v = x
        return [v, force(t)[0] - c * v - w1**2 * q + k3 * q**3]

    t_eval = np.arange(int(round(t_end * fs))) / fs
    sol = solve_ivp(rhs, (0.0, t_eval[-1]), [0.0, 0.0], method="DOP853", t_eval=t_eval, rtol=1e-11, atol=1e-14)
    assert sol.success
    return t_eval, sol.y[0], sol.y[1]


@pytest.fixture(scope="module")
def duffing_multisine():
    """Steady-state periods of the Duffing oscillator under a multisine (4 transient + 3 recorded periods)."""
    fs, n = 256.0, 1024  # 4 s period, 0.25 Hz resolution
    lines = np.arange(4, 61)  # 1-15 Hz around the 5 Hz mode
    F = multisine(fs, n, lines, rms=4.0, seed=1)  # k3 q^3 reaches 10 % of w1^2 q
    P_skip, P = 4, 3
    t, q, v = simulate_duffing(F, (P_skip + P) * n / fs, fs)
    force = F(t)
    return {"fs": fs, "n": n, "t": t, "q": q, "v": v, "force": force, "skip": P_skip, "lines": lines}


def test_periodic_states_exact_for_each_measured_kind():
    fs, n = 200.0, 400
    t = np.arange(n) / fs
    k = np.arange(2, 30)
    w = 2 * np.pi * k * fs / n
    ph = np.linspace(0, 3, k.size)
    q = (np.cos(np.outer(t, w) + ph) / k).sum(1)
    v = (-w * np.sin(np.outer(t, w) + ph) / k).sum(1)
    a = (-(w**2) * np.cos(np.outer(t, w) + ph) / k).sum(1)
    u = np.cos(2 * np.pi * 1.0 * t)
    for measured, x in (("displacement", q), ("velocity", v), ("acceleration", a)):
        s = periodic_states(u, x + 0.3, fs, measured=measured, band=(0.5, 20.0))
        assert s.response_mean == pytest.approx(0.3)
        np.testing.assert_allclose(s.displacement, q, atol=1e-12 * np.abs(q).max() * 100)
        np.testing.assert_allclose(s.velocity, v, atol=1e-10 * np.abs(v).max())
        np.testing.assert_allclose(s.acceleration, a, atol=1e-10 * np.abs(a).max())


def test_band_limits_states_and_removes_dc():
    fs, n = 100.0, 200
    t = np.arange(n) / fs
    q = 2.0 + np.cos(2 * np.pi * 5 * t) + 0.1 * np.cos(2 * np.pi * 30 * t)
    s = periodic_states(np.sin(2 * np.pi * 5 * t), q, fs, band=(1.0, 10.0))
    np.testing.assert_allclose(s.displacement, np.cos(2 * np.pi * 5 * t), atol=1e-12)


def test_detect_period_and_noise_per_line():
    rng = np.random.default_rng(3)
    n, P, sigma = 512, 16, 0.05
    x = np.tile(multisine(512.0, n, np.arange(1, 100), 1.0, seed=2)(np.arange(n) / 512.0), P)
    noisy = x + sigma * rng.standard_normal(x.size)
    assert detect_period(noisy) == n
    avg = average_periods({"u": noisy, "y": 2 * noisy}, 512.0, skip_periods=1)
    assert avg.n_periods == P - 1 and avg.samples_per_period == n
    # white noise of variance sigma^2 per sample: each DFT line has variance n sigma^2, the mean of P-1 periods 1/(P-1)
    expected = n * sigma**2 / (P - 1)
    assert np.median(avg.noise_var["u"][1:-1]) == pytest.approx(expected, rel=0.15)
    assert avg.noise_rms("u") == pytest.approx(sigma / np.sqrt(P - 1), rel=0.1)
    assert list(avg.excited) == list(range(1, 100))
    assert "15 periods" in avg.report()
    assert avg.summary()["n_excited_lines"] == 99


def test_detect_period_fails_on_noise():
    rng = np.random.default_rng(0)
    with pytest.raises(RecordError, match="no period found"):
        detect_period(rng.standard_normal(4096), channel="u")


def test_find_periodic_segments_with_gaps_and_transients():
    n = 256
    parts, expected = [], []
    pos = 0
    for r in range(3):
        period = multisine(256.0, n, np.arange(1, 60), 1.0, seed=10 + r)(np.arange(n) / 256.0)
        block = np.concatenate([np.zeros(50), period[-40:], period])  # gap, 40 transient samples, one period
        parts.append(block)
        expected.append(pos + 50 + 40 + n)  # end of the steady period
        pos += block.size
    x = np.concatenate(parts)
    segs = find_periodic_segments(x, n)
    assert [s.stop for s in segs] == expected


def test_errors_name_the_channel():
    fs = 100.0
    with pytest.raises(RecordError, match="'y'.*non-finite"):
        periodic_states(np.ones(8) * np.arange(8), np.r_[np.zeros(7), np.nan], fs, channels=("u", "y"))
    with pytest.raises(RecordError, match="'u'.*no excited line"):
        periodic_states(np.ones(16), np.zeros(16), fs, channels=("u", "y"))
    with pytest.raises(RecordError, match="no frequency line"):
        periodic_states(np.sin(np.arange(16)), np.zeros(16), fs, band=(1.0, 2.0))
    with pytest.raises(RecordError, match="measured"):
        periodic_states(np.sin(np.arange(16)), np.zeros(16), fs, measured="jerk")
    t = np.arange(1000) / 100.0
    with pytest.raises(RecordError, match="too short"):
        random_states(t, np.sin(t), np.sin(t), band=(0.2, 10.0), channels=("f", "acc"))
    with pytest.raises(RecordError, match="band"):
        random_states(t, np.sin(t), np.sin(t), band=(1.0, 80.0))


def test_duffing_multisine_recovers_parameters_with_unknown_gain(duffing_multisine):
    d = duffing_multisine
    rng = np.random.default_rng(5)
    volt = d["force"] / GAIN  # recorded excitation: a voltage, gain 0.37 N/V for the unit modal mass
    y = d["q"] + 1e-6 * np.abs(d["q"]).max() * rng.standard_normal(d["q"].size)
    avg = average_periods({"u": volt, "y": y}, d["fs"], period=d["n"], skip_periods=d["skip"])
    # a full multisine on a cubic system has a small static displacement (intermodulation
    # f_a + f_b - f_c = 0): keep the measured mean, it is part of the state
    states = avg.states("u", "y", measured="displacement", band=(0.2, 100.0), keep_mean=True)
    est = BroadbandForceStateMapping("q + -q^3 + q'", fit_inertia=True).fit(states)
    r = est.result_
    assert r.gain == pytest.approx(GAIN, rel=1e-5)  # 1e-6 output noise
    assert r.omega1 == pytest.approx(W1, rel=1e-6)
    assert r.zeta == pytest.approx(ZETA, rel=1e-5)
    assert r.k3_over_k == pytest.approx(K3 / W1**2, rel=1e-4)
    assert r.k3_over_m == pytest.approx(K3, rel=1e-4)
    d_ = r.derived()
    assert set(d_) >= {"omega1", "f1_hz", "zeta", "k3/k", "k3/m", "c/m", "gain"}
    # standard errors are small and positive
    assert 0 < d_["omega1"][1] < 1e-3 * W1
    s = r.summary()
    assert s["derived"]["gain"] == pytest.approx(GAIN, rel=1e-4)
    assert "m·[q'']" in r.report() and "<pre>" in r._repr_html_()


def test_duffing_multisine_noise_weighting_and_noisy_data(duffing_multisine):
    d = duffing_multisine
    rng = np.random.default_rng(9)
    q, f = d["q"], d["force"]
    y = q + 2e-3 * np.std(q) * rng.standard_normal(q.size)
    u = f + 2e-3 * np.std(f) * rng.standard_normal(f.size)
    avg = average_periods({"u": u, "y": y}, d["fs"], period=d["n"], skip_periods=d["skip"])
    states = avg.states("u", "y", band=(0.2, 60.0))
    r = BroadbandForceStateMapping(weighting="noise").fit(states).result_  # mean removed: small bias in k3
    assert r.omega1 == pytest.approx(W1, rel=2e-3)
    assert r.zeta == pytest.approx(ZETA, rel=3e-2)
    assert r.k3_over_k == pytest.approx(K3 / W1**2, rel=3e-2)
    assert r.mass == pytest.approx(1.0, rel=3e-3)


def test_known_mass_matches_seed_form(duffing_multisine):
    d = duffing_multisine
    avg = average_periods({"u": d["force"], "y": d["q"]}, d["fs"], period=d["n"], skip_periods=d["skip"])
    states = avg.states("u", "y", band=(0.2, 100.0), keep_mean=True)
    r = BroadbandForceStateMapping(fit_inertia=False, mass=1.0).fit(states).result_
    assert "m" not in r.coefficient_names
    assert r.get("omega1^2") == pytest.approx(W1**2, rel=1e-8)
    assert r.get("k3") == pytest.approx(K3, rel=1e-6)
    assert r.get("c") == pytest.approx(C, rel=1e-6)


def test_invariant_to_time_shift_and_units(duffing_multisine):
    d = duffing_multisine
    n, skip = d["n"], d["skip"]
    sl = slice(skip * n, (skip + 1) * n)
    base = periodic_states(d["force"][sl], d["q"][sl], d["fs"], band=(0.2, 100.0))
    r0 = BroadbandForceStateMapping().fit(base).result_
    shifted = periodic_states(np.roll(d["force"][sl], 100), np.roll(d["q"][sl], 100), d["fs"], band=(0.2, 100.0))
    r1 = BroadbandForceStateMapping().fit(shifted).result_
    scaled = periodic_states(1000 * d["force"][sl], 1000 * d["q"][sl], d["fs"], band=(0.2, 100.0))  # mm, mN
    r2 = BroadbandForceStateMapping().fit(scaled).result_
    assert r1.omega1 == pytest.approx(r0.omega1, rel=1e-9)
    assert r2.omega1 == pytest.approx(r0.omega1, rel=1e-9)
    assert r2.zeta == pytest.approx(r0.zeta, rel=1e-9)
    assert r2.k3_over_k * 1e6 == pytest.approx(r0.k3_over_k, rel=1e-7)


def test_several_realisations_and_offset():
    fs, n = 256.0, 512
    t = np.arange(n) / fs
    recs = []
    for seed in range(3):
        w = 2 * np.pi * np.arange(2, 40) * fs / n
        rng = np.random.default_rng(seed)
        ph = rng.uniform(0, 6, w.size)
        q = (0.01 * np.cos(np.outer(t, w) + ph)).sum(1)
        v = (-0.01 * w * np.sin(np.outer(t, w) + ph)).sum(1)
        a = (-0.01 * w**2 * np.cos(np.outer(t, w) + ph)).sum(1)
        u = 2.0 * a + 700.0 * q + 40.0 * q**2 + 1.5 * v + 0.25  # static offset 0.25
        recs.append(periodic_states(u, q + 1.0, fs, band=(0.5, 120.0)))
    r = BroadbandForceStateMapping("q + q^2 + q'", offset=True).fit(recs).result_
    assert r.n_records == 3
    assert r.mass == pytest.approx(2.0, rel=1e-8)
    assert r.get("k2") == pytest.approx(40.0, rel=1e-6)
    # the DC line of each record: mean(u) = k2 mean(q^2) + u0
    assert r.offset == pytest.approx(0.25, rel=1e-8)
    assert r.response_mean == pytest.approx(1.0)


def test_random_path_integrates_within_band():
    fs = 200.0
    t = np.arange(int(60 * fs)) / fs
    f = np.array([2.3, 3.7, 5.1, 7.9, 11.3, 13.7])
    ph = np.arange(f.size)
    w = 2 * np.pi * f
    q = (np.cos(np.outer(t, w) + ph) / f).sum(1)
    a = (-(w**2) * np.cos(np.outer(t, w) + ph) / f).sum(1)
    for method, tol in (("window", 2e-3), ("highpass", 3e-2)):
        s = random_states(t, a, a, measured="acceleration", band=(1.0, 30.0), method=method)
        assert not s.periodic and s.valid.stop - s.valid.start > 0.6 * t.size
        err = s.displacement[s.valid] - q[s.valid]
        assert np.sqrt(np.mean(err**2)) < tol * np.std(q), method
        assert np.abs(s.acceleration[s.valid] - a[s.valid]).max() < 0.05 * np.abs(a).max()


def test_random_path_linear_sdof_regression():
    """A non-periodic record of a linear oscillator: the band-filtered regression recovers it."""
    fs = 200.0
    rng = np.random.default_rng(4)
    t = np.arange(int(80 * fs)) / fs
    f = np.sort(rng.uniform(1.5, 15.0, 40))
    ph = rng.uniform(0, 6, f.size)
    w = 2 * np.pi * f
    w1, c = 2 * np.pi * 6.0, 1.2
    H = 1.0 / (w1**2 - w**2 + 1j * w * c)
    Fk = np.ones(f.size)
    force = (Fk * np.cos(np.outer(t, w) + ph)).sum(1)
    acc = (-(w**2) * np.abs(H) * np.cos(np.outer(t, w) + ph + np.angle(H))).sum(1)
    s = random_states(t, force / GAIN, acc, measured="acceleration", band=(1.0, 20.0))
    r = BroadbandForceStateMapping("q + q'").fit(s).result_
    assert r.omega1 == pytest.approx(w1, rel=1e-3)
    assert r.value("c/m") == pytest.approx(c, rel=1e-2)
    assert r.gain == pytest.approx(GAIN, rel=1e-3)


def test_band_filter_passes_band_and_differentiates():
    fs = 100.0
    t = np.arange(4000) / fs
    x = np.sin(2 * np.pi * 3 * t) + np.sin(2 * np.pi * 30 * t)
    y = band_filter(x, fs, (1.0, 10.0), edge_hz=1.0)
    mid = slice(500, 3500)
    np.testing.assert_allclose(y[mid], np.sin(2 * np.pi * 3 * t[mid]), atol=2e-3)
    dy = band_filter(x, fs, (1.0, 10.0), edge_hz=1.0, order=1)
    np.testing.assert_allclose(dy[mid], 2 * np.pi * 3 * np.cos(2 * np.pi * 3 * t[mid]), atol=5e-2)


def test_excited_lines():
    U = np.zeros(10, complex)
    U[[0, 2, 5]] = [100, 1, 0.5]
    assert list(excited_lines(U)) == [2, 5]


def test_delta_method_matches_analytic():
    theta = np.array([4.0, 900.0])
    cov = np.array([[0.01, 0.02], [0.02, 25.0]])
    val, se = delta_method(lambda p: np.sqrt(p[1] / p[0]), theta, cov)
    g = np.array([-0.5 * np.sqrt(theta[1]) * theta[0] ** -1.5, 0.5 / np.sqrt(theta[0] * theta[1])])
    assert val == pytest.approx(15.0)
    assert se == pytest.approx(np.sqrt(g @ cov @ g), rel=1e-6)


def test_simulation_matches_ode_solver():
    fs = 100.0
    n = 1500
    ms = multisine(fs, 1000, np.arange(5, 80), 4.0, seed=7)

    def F(t):  # starts smoothly from zero, as a sampled band-limited record should
        t = np.atleast_1d(t)
        return ms(t) * np.clip(t / 2.0, 0, 1) ** 2 * (3 - 2 * np.clip(t / 2.0, 0, 1))

    t, q, _ = simulate_duffing(F, n / fs, fs)
    lib = library("q + -q^3 + q'")
    qs, _ = simulate_response(lib, [W1**2, K3, C], 1.0, F(t), fs, oversample=16)
    inner = slice(0, n - 20)  # the interpolation assumes zeros after the record end
    assert np.sqrt(np.mean((qs[inner] - q[inner]) ** 2)) < 2e-3 * np.std(q)


def test_fit_validation_errors(duffing_multisine):
    with pytest.raises(IdentificationError, match="at least one record"):
        BroadbandForceStateMapping().fit([])
    with pytest.raises(IdentificationError, match="weighting"):
        d = duffing_multisine
        s = periodic_states(d["force"][: d["n"]], d["q"][: d["n"]], d["fs"])
        BroadbandForceStateMapping(weighting="bogus").fit(s)
    with pytest.raises(IdentificationError, match="BroadbandStates"):
        BroadbandForceStateMapping().fit([object()])


def test_ill_conditioned_single_line_warns():
    fs, n = 100.0, 200
    t = np.arange(n) / fs
    q = np.cos(2 * np.pi * 5 * t)
    u = 900 * q
    s = periodic_states(u, q, fs, band=(4.0, 6.0))
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        BroadbandForceStateMapping("q + q'").fit(s)
    assert any("ill-conditioned" in str(x.message) for x in w)


def test_equivalent_linear_track_softening():
    fs = 200.0
    t = np.arange(int(40 * fs)) / fs
    amp = 0.5 + 0.5 * np.sin(np.pi * t / 40)  # rises and falls
    q = amp * np.sin(2 * np.pi * 4 * t)
    v = np.gradient(q, 1 / fs)
    f = 100 * q - 40 * q**3 + 2 * v  # softening cubic
    tr = equivalent_linear_track(q, v, f, fs, window_s=1.0)
    assert tr.spearman_k_amplitude() < -0.9
    assert tr.k.max() <= 100.0 + 1e-6 and tr.k.min() < 80.0
    assert "windows" in tr.report()


def test_a_random_force_with_measurement_noise_keeps_its_band_and_is_not_flagged():
    """A 15-40 Hz random force measured with 1 % white noise (an ordinary force cell): the noise floor holds
    more than the power band's tail over the whole spectrum, which widened the band to 2.9-900 Hz, where force
    and response are not coherent (a false random_coherence flag on good data). The band stops where the
    force's spectral density reaches its floor."""
    from scipy import signal as ssignal

    from jointid.app.broadband_records import random_band
    from jointid.signal.broadband import random_flags

    fs, n = 2000.0, 14000
    rng = np.random.default_rng(3)
    b, a = ssignal.butter(4, [15 / (fs / 2), 40 / (fs / 2)], "band")
    u = ssignal.filtfilt(b, a, rng.standard_normal(n))
    w0, zeta = 2 * np.pi * 27.0, 0.01  # a linear mode: receptance to acceleration
    sys = ssignal.lti([1.0, 0.0, 0.0], [1.0, 2 * zeta * w0, w0**2])
    t = np.arange(n) / fs
    _, y, _ = ssignal.lsim(sys, u, t)
    noisy = [x + 0.01 * np.std(x) * rng.standard_normal(n) for x in (u, y)]
    lo, hi = random_band(noisy[0], fs)
    assert 5.0 < lo < 15.0 and 40.0 < hi < 80.0, (lo, hi)
    assert random_flags(*noisy, fs, (lo, hi)) == []
    # the response of another excitation is still flagged over that band
    _, other, _ = ssignal.lsim(sys, ssignal.filtfilt(b, a, rng.standard_normal(n)), t)
    assert [f.name for f in random_flags(noisy[0], other, fs, (lo, hi))] == ["random_coherence"]


def test_a_multisine_response_still_settling_is_flagged_a_steady_one_is_not():
    """A lightly damped mode (zeta 0.2 %, 27 Hz: time constant 2.9 s) driven by a 1 s multisine from rest:
    the periods after the first still carry the start-up transient (flagged multisine_transient); the same
    record after 30 s of settling is steady, and 1 % noise alone gives a ratio near 1."""
    from scipy import signal as ssignal

    from jointid.signal.broadband import multisine_transient_flags

    fs, n_per = 1000.0, 1000
    rng = np.random.default_rng(4)
    k = np.arange(20, 36)
    one = sum(np.cos(2 * np.pi * kk * np.arange(n_per) / n_per + rng.uniform(0, 2 * np.pi)) for kk in k)
    w0 = 2 * np.pi * 27.0
    sys = ssignal.lti([1.0, 0.0, 0.0], [1.0, 2 * 0.002 * w0, w0**2])
    u = np.tile(one, 35)
    _, y, _ = ssignal.lsim(sys, u, np.arange(u.size) / fs)
    y = y + 0.01 * np.std(y) * rng.standard_normal(y.size)
    settling = y[:5 * n_per]  # periods 2-5 used: still settling
    steady = y[-5 * n_per:]
    (flag,) = multisine_transient_flags(settling, n_per, channel="acceleration")
    assert flag.name == "multisine_transient" and flag.values["ratio"] > 2.0
    assert multisine_transient_flags(steady, n_per) == []
