"""Stepped sine with an unknown force gain (shaker voltage as force): ground truth."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from conftest import consistent_record
from jointid.errors import IdentificationError, IllConditionedWarning, RecordError
from jointid.identify.gain import PooledGainForceStateMapping, sine_dwell_signals
from jointid.signal.harmonics import steady_state_signals

GAIN = 0.37  # newton (of unit-mass modal force) per volt
W1 = 2 * np.pi * 5.0
ZETA = 0.02
C = 2 * ZETA * W1
K3 = 2.0e4  # seed convention h = w1^2 q - k3 q^3 + c q': softening


def test_exact_consistent_records_recover_gain_free_parameters():
    omega1, k3 = 170.0, 5e6
    recs = []
    cs = [0.8, 1.0, 1.3, 1.1]
    for w, c, amp in zip((160.0, 166.0, 172.0, 178.0), cs, (0.004, 0.006, 0.007, 0.005)):
        t, Q, a, q, v = consistent_record([omega1**2, k3, c], omega=w, amps=((1, amp, 0.0), (3, 0.0, 2e-5)),
                                          fs=5000.0, duration=0.5)
        recs.append(steady_state_signals(t, Q / GAIN, a, frequency_hz=w / (2 * np.pi), n_harmonics=5))
    fit = PooledGainForceStateMapping().fit(recs).result_
    assert fit.gain == pytest.approx(GAIN, rel=1e-9)
    assert fit.omega1 == pytest.approx(omega1, rel=1e-10)
    assert fit.k3_over_m == pytest.approx(k3, rel=1e-8)
    assert fit.k3_over_k == pytest.approx(k3 / omega1**2, rel=1e-8)
    cm, _ = fit.per_record("c")
    np.testing.assert_allclose(cm, cs, rtol=1e-8)
    np.testing.assert_allclose(fit.omega1_per_record, omega1, rtol=1e-9)
    assert fit.omega1_spread() < 1e-9
    s = fit.summary()
    assert s["derived"]["gain"] == pytest.approx(GAIN, rel=1e-9)
    assert len(s["c_over_m"]) == 4
    assert "shared" in fit.report() and "<pre>" in fit._repr_html_()


def simulate_dwell(omega, force_amp, t_settle=24.0, t_record=4.0, fs=500.0):
    """Steady state of the softening Duffing oscillator under F sin(omega t), with dense output."""

    def rhs(t, x):
        q, v = x
        return [v, force_amp * np.sin(omega * t) - C * v - W1**2 * q + K3 * q**3]

    t_end = t_settle + t_record
    sol = solve_ivp(rhs, (0.0, t_end), [0.0, 0.0], method="DOP853", rtol=1e-11, atol=1e-13, dense_output=True)
    assert sol.success
    t = t_settle + np.arange(int(round(t_record * fs))) / fs
    return t, sol


@pytest.fixture(scope="module")
def dwells():
    out = []
    for f in (4.7, 4.85, 5.0, 5.15, 5.3):
        w = 2 * np.pi * f
        t, sol = simulate_dwell(w, 1.5)
        out.append((w, t, sol))
    return out


def _records(dwells, measured="acceleration", delay=0.0, correct=0.0, n_harmonics=5):
    recs = []
    for w, t, sol in dwells:
        F = 1.5 * np.sin(w * t)
        q, v = sol.sol(t - delay)
        a = 1.5 * np.sin(w * (t - delay)) - C * v - W1**2 * q + K3 * q**3
        resp = {"acceleration": a, "velocity": v, "displacement": q}[measured]
        recs.append(sine_dwell_signals(t, F / GAIN, resp, measured=measured, n_harmonics=n_harmonics,
                                       delay=correct))
    return recs


def test_simulated_stepped_sine_with_voltage(dwells):
    fit = PooledGainForceStateMapping().fit(_records(dwells)).result_
    assert fit.gain == pytest.approx(GAIN, rel=2e-4)
    assert fit.omega1 == pytest.approx(W1, rel=1e-5)
    assert fit.k3_over_m == pytest.approx(K3, rel=5e-3)
    cm, _ = fit.per_record("c")
    np.testing.assert_allclose(cm, C, rtol=2e-3)
    np.testing.assert_allclose(fit.damping_ratio(), ZETA, rtol=2e-3)
    assert fit.omega1_spread() < 1e-4
    d = fit.derived()
    assert d["k3/m"][0] > 3 * d["k3/m"][1]  # softening detected


@pytest.mark.parametrize("measured", ["velocity", "displacement"])
def test_any_measured_response_gives_the_same_fit(dwells, measured):
    ref = PooledGainForceStateMapping().fit(_records(dwells)).result_
    fit = PooledGainForceStateMapping().fit(_records(dwells, measured)).result_
    assert fit.gain == pytest.approx(ref.gain, rel=1e-6)
    assert fit.omega1 == pytest.approx(ref.omega1, rel=1e-7)
    assert fit.k3_over_m == pytest.approx(ref.k3_over_m, rel=1e-4)


def test_channel_delay_biases_damping_and_is_corrected(dwells):
    tau = 2e-3
    biased = PooledGainForceStateMapping().fit(_records(dwells, delay=tau)).result_
    cm_b, _ = biased.per_record("c")
    # a response lagging by tau: c_r/m ~ c/m + tau (w1^2 - w^2), larger below resonance, smaller above
    assert cm_b[0] > C > cm_b[-1]
    w = np.array([d[0] for d in dwells])
    np.testing.assert_allclose(cm_b, C + tau * (W1**2 - w**2), rtol=0.1, atol=0.05 * C)
    assert biased.omega1 == pytest.approx(W1, rel=3e-3)  # the in-phase part hardly moves
    fixed = PooledGainForceStateMapping().fit(_records(dwells, delay=tau, correct=tau)).result_
    cm, _ = fixed.per_record("c")
    np.testing.assert_allclose(cm, C, rtol=2e-3)


def test_single_record_warns_and_same_frequency_warns(dwells):
    recs = _records(dwells)
    with pytest.warns(IllConditionedWarning, match="one record only"):
        PooledGainForceStateMapping().fit(recs[:1])
    with pytest.warns(IllConditionedWarning, match="same excitation frequency"):
        PooledGainForceStateMapping().fit([recs[0], recs[0]])


def test_errors(dwells):
    w, t, sol = dwells[0]
    q, v = sol.sol(t)
    bad = v.copy()
    bad[10] = np.nan
    with pytest.raises(RecordError, match="'laser'.*non-finite"):
        sine_dwell_signals(t, np.sin(w * t), bad, measured="velocity", channels=("time", "voltage", "laser"))
    with pytest.raises(RecordError, match="'voltage'.*constant"):
        sine_dwell_signals(t, np.ones_like(t), v, measured="velocity", channels=("time", "voltage", "laser"))
    with pytest.raises(RecordError, match="measured"):
        sine_dwell_signals(t, np.sin(w * t), v, measured="jerk")
    recs = _records(dwells)
    with pytest.raises(IdentificationError, match="'q'"):
        PooledGainForceStateMapping("-q^3 + q'").fit(recs)
    with pytest.raises(IdentificationError, match="at least one record"):
        PooledGainForceStateMapping().fit([])
    with pytest.raises(IdentificationError, match="weighting"):
        PooledGainForceStateMapping(weighting="x").fit(recs)


def test_unweighted_equals_weighted_for_exact_data(dwells):
    recs = _records(dwells)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        a = PooledGainForceStateMapping(weighting="none").fit(recs).result_
        b = PooledGainForceStateMapping(weighting="noise").fit(recs).result_
    assert a.omega1 == pytest.approx(b.omega1, rel=1e-6)
