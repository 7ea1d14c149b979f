import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from jointid.errors import RecordError
from jointid.signal.harmonics import (
    HarmonicSeries,
    check_time_base,
    estimate_frequency,
    fit_harmonics,
    series_max_abs,
    steady_state_signals,
)


def _signal(t, w, t0=0.0):
    return 2.0 * np.sin(w * (t - t0)) + 0.3 * np.cos(w * (t - t0)) + 0.05 * np.sin(3 * w * (t - t0) + 0.4) + 0.01


@pytest.mark.parametrize("periods", [2.0, 2.37, 11.5, 40.0])
@pytest.mark.parametrize("t0", [0.0, 1234.5678])
def test_fit_recovers_harmonics_any_length_and_start(periods, t0):
    w = 2 * np.pi * 17.3
    fs = 2000.0
    t = t0 + np.arange(int(periods * fs / 17.3)) / fs
    s, resid = fit_harmonics(t, _signal(t, w, t0), w, 4)
    assert resid < 1e-7  # one-pass residual: |x|^2 - theta.r, exact to sqrt(eps) of the RMS
    assert np.allclose(s(t), _signal(t, w, t0), atol=1e-12)
    amp = s.amplitudes()
    assert amp[0] == pytest.approx(np.hypot(2.0, 0.3), rel=1e-12)
    assert amp[2] == pytest.approx(0.05, rel=1e-10)
    assert abs(amp[1]) < 1e-12 and abs(amp[3]) < 1e-12


def test_fit_just_above_nyquist_and_refused_at_it():
    f = 10.0
    w = 2 * np.pi * f
    fs = 2 * 3 * f * 1.05  # third harmonic just below Nyquist
    t = np.arange(400) / fs
    x = np.cos(w * t) + 0.1 * np.sin(3 * w * t)
    s, resid = fit_harmonics(t, x, w, 3)
    assert resid < 1e-7
    assert np.allclose(s(t), x, atol=1e-11)
    with pytest.raises(RecordError, match="Nyquist"):
        fit_harmonics(t, x, w, 4)


def test_analytic_integration_matches_closed_form():
    w = 50.0
    t = np.arange(5000) / 4000.0
    A, B = 0.02, 1e-3
    q = A * np.cos(w * t) + B * np.sin(3 * w * t)
    v = -A * w * np.sin(w * t) + 3 * B * w * np.cos(3 * w * t)
    a = -A * w**2 * np.cos(w * t) - 9 * B * w**2 * np.sin(3 * w * t)
    s, _ = fit_harmonics(t, a + 5.0, w, 5)  # an offset in the accelerometer must not leak
    assert np.allclose(s.integral()(t), v, atol=1e-12 * A * w)
    assert np.allclose(s.integral().integral()(t), q, atol=1e-12 * A)


def test_series_max_abs_exact():
    c = np.array([0.0, 1.0, 0.3, 0.0, 0.0, 0.2, -0.1])
    tt = np.linspace(0, 2 * np.pi, 2_000_001)
    brute = np.max(np.abs(HarmonicSeries(1.0, c)(tt)))
    assert series_max_abs(c) == pytest.approx(brute, rel=1e-11)
    assert series_max_abs(c) >= brute


def test_frequency_estimate_noise_and_start_time():
    rng = np.random.default_rng(3)
    fs = 1000.0
    t = 77.7 + np.arange(20000) / fs
    f = 26.4813
    x = 1.5 * np.sin(2 * np.pi * f * t + 0.7) + 0.01 * 1.5 * rng.standard_normal(t.size)
    assert estimate_frequency(t, x) == pytest.approx(f, rel=1e-7)


def test_frequency_estimate_short_record_non_integer_periods():
    fs = 5000.0
    f = 27.0531
    t = np.arange(int(2.3 * fs / f)) / fs
    assert estimate_frequency(t, np.sin(2 * np.pi * f * t + 1.0)) == pytest.approx(f, rel=1e-9)


def test_no_frequency_in_noise_and_zero_force():
    rng = np.random.default_rng(1)
    t = np.arange(5000) / 1000.0
    with pytest.raises(RecordError, match="no excitation frequency found"):
        estimate_frequency(t, rng.standard_normal(t.size))
    with pytest.raises(RecordError, match="zero"):
        steady_state_signals(t, np.zeros_like(t), np.sin(t))


@pytest.mark.parametrize(
    "t, msg",
    [
        (np.array([0.0, 0.1, 0.1, 0.3]), "increase"),
        (np.array([0.0, 0.1, 0.3, 0.4]), "uneven"),
        (np.array([0.0, 0.1, np.nan, 0.3]), "non-finite"),
    ],
)
def test_time_base_errors(t, msg):
    with pytest.raises(RecordError, match=msg):
        check_time_base(t)


def test_short_record_refused():
    t = np.arange(100) / 1000.0  # 0.1 s of 10 Hz = 1 period
    x = np.sin(2 * np.pi * 10 * t)
    with pytest.raises(RecordError, match="at least 2"):
        steady_state_signals(t, x, x, frequency_hz=10.0)


def test_lengths_and_nan_name_channel():
    t = np.arange(1000) / 1000.0
    x = np.sin(2 * np.pi * 10 * t)
    with pytest.raises(RecordError, match="'accel'.*999"):
        steady_state_signals(t, x, x[:-1], frequency_hz=10.0)
    y = x.copy()
    y[5] = np.inf
    with pytest.raises(RecordError, match="'force'.*sample 5"):
        steady_state_signals(t, y, x, frequency_hz=10.0)


@settings(max_examples=25, deadline=None)
@given(shift=st.floats(-50.0, 50.0), unit=st.floats(1e-3, 1e3))
def test_state_reconstruction_invariant_to_time_shift_and_units(shift, unit):
    w = 2 * np.pi * 12.0
    t = np.arange(3000) / 1500.0
    a = np.cos(w * t) + 0.1 * np.sin(3 * w * t)
    s1 = steady_state_signals(t, np.sin(w * t), a, n_harmonics=4)
    s2 = steady_state_signals(t + shift, unit * np.sin(w * t), unit * a, n_harmonics=4)
    assert s2.frequency_hz == pytest.approx(s1.frequency_hz, rel=1e-9)
    assert s2.q_max() == pytest.approx(unit * s1.q_max(), rel=1e-8)
    q1, v1, _ = s1.states()
    q2, v2, _ = s2.states()
    assert np.allclose(q2, unit * q1, atol=1e-8 * unit * s1.q_max())


def test_harmonics_limited_by_nyquist_are_reduced_with_a_warning():
    from jointid.errors import JointidWarning

    f = 10.0
    fs = 2 * 3.5 * f  # harmonics 1..3 below Nyquist (35 Hz)
    t = np.arange(700) / fs
    x = np.sin(2 * np.pi * f * t)
    with pytest.warns(JointidWarning, match="fitting 3 harmonics instead of 5"):
        s = steady_state_signals(t, x, x, frequency_hz=f, n_harmonics=5)
    assert s.acceleration.n_harmonics == 3
    t2 = np.arange(300) / 45.0  # harmonics 1..2 below Nyquist (22.5 Hz)
    x2 = np.sin(2 * np.pi * f * t2)
    with pytest.raises(RecordError, match="at least 3"):
        steady_state_signals(t2, x2, x2, frequency_hz=f, n_harmonics=5)


def test_rounded_given_frequency_is_refined_on_the_force_with_a_warning():
    from jointid.errors import JointidWarning

    f = 26.4837
    t = np.arange(40000) / 2000.0  # 20 s: a 0.0037 Hz error drifts 0.46 rad
    x = np.sin(2 * np.pi * f * t + 0.3)
    with pytest.warns(JointidWarning, match="differs from the force's"):
        s = steady_state_signals(t, x, x, frequency_hz=26.48, n_harmonics=3)
    assert s.frequency_hz == pytest.approx(f, rel=1e-10)
    kept = steady_state_signals(t, x, x, frequency_hz=26.48, n_harmonics=3, refine_frequency=False)
    assert kept.frequency_hz == 26.48
