"""Single nonlinear mode from first harmonics: known parameters recovered, mixed controls, re-prediction with
the measured force, selection by leave-one-level-out, calibrated standard errors (Monte Carlo)."""

from __future__ import annotations

import numpy as np
import pytest

from jointid.identify.firstharmonic import (
    AmplitudeLaw,
    FirstHarmonicLevel,
    FirstHarmonicModel,
    adequacy,
    fit_first_harmonic,
    leave_one_level_out,
    repredict_level,
    select_laws,
    simulate_levels,
)

# a softening joint: f0 = 80 Hz, -0.4 % at a_ref then back up (non-monotone), damping 0.1 % -> 0.4 %
TRUTH = FirstHarmonicModel(AmplitudeLaw("poly2"), AmplitudeLaw("poly1"), 60.0,
                           np.array([-0.5, -0.4, -0.2, 80.0, -0.008, 0.004, 0.001, 0.003]))


def _campaign(rng, noise=0.01, forces=(0.15, 0.4, 0.8, 1.2), model=TRUTH, n=41):
    """Force-controlled levels whose force dips near resonance, as a controller holds it."""
    levels = []
    for k, F0 in enumerate(forces):
        f = np.linspace(79.0, 81.0, n)
        F = F0 * (1 - 0.25 * np.exp(-((f - 79.9) / 0.25) ** 2))
        dummy = FirstHarmonicLevel(f, F, 0.0, np.ones(n), 0.0, f"L{k + 1}")
        a = repredict_level(model, dummy).accel_predicted
        H = model.frf(2 * np.pi * f, a)
        Hn = H + noise * np.abs(H) * (rng.standard_normal(n) + 1j * rng.standard_normal(n))
        levels.append(FirstHarmonicLevel(f, F, 0.0, np.abs(Hn) * F, np.angle(Hn), f"L{k + 1}"))
    return levels


@pytest.mark.parametrize("sign", [1, -1], ids=["phase 0 to -180 (export)", "phase 180 to 0 (accelerance)"])
def test_known_parameters_are_recovered_and_every_level_repredicted_from_its_forces(sign):
    truth = FirstHarmonicModel(TRUTH.frequency_law, TRUTH.damping_law, TRUTH.a_ref,
                               TRUTH.params * np.r_[sign, sign, sign, np.ones(5)])
    levels = _campaign(np.random.default_rng(1), model=truth)
    fit = fit_first_harmonic(levels, "poly2", "poly1", a_ref=60.0)
    z = (fit.params - truth.params) / fit.stderr
    assert np.all(np.abs(z) < 4), dict(zip(fit.names, z))
    assert abs(fit.residual_scale / 0.01 - 1) < 0.15  # noise of each part: 0.01 |H|
    mm, se = fit.modal_mass
    assert abs(mm - 2.0) < 4 * se
    for pr in fit.predictions:
        assert pr.amplitude_rms_rel < 0.03 and pr.phase_rms_deg < 2.0, pr.summary()
    assert fit.low_level["level"] == "L1"
    assert abs(fit.low_level["modal_constant"] + 0.5 * sign) < 5 * fit.low_level["stderr"]
    # backbone with bands covers the truth
    bb = fit.backbone()
    wn_true = truth.omega_n(bb.amplitude)
    assert np.all(np.abs(bb.omega - wn_true) < 4 * bb.omega_stderr + 1e-9)
    assert "driving point" in bb.meta["amplitude_unit"]


def test_reprediction_uses_the_measured_force_not_a_nominal_level():
    levels = _campaign(np.random.default_rng(2), noise=0.0)
    lv = levels[3]
    good = repredict_level(TRUTH, lv)
    assert good.amplitude_rms_rel < 1e-8
    nominal = FirstHarmonicLevel(lv.frequency_hz, np.full(len(lv), lv.force.max()), 0.0, lv.accel, lv.accel_phase)
    assert repredict_level(TRUTH, nominal).amplitude_rms_rel > 0.05  # the force dip matters


def test_force_response_and_phase_resonance_controls_mixed_in_one_fit():
    rng = np.random.default_rng(3)
    levels = _campaign(rng, forces=(0.2, 1.0))
    # response-controlled: the acceleration held at 30 m/s^2, the force follows
    f = np.linspace(79.0, 81.0, 31)
    a = np.full(f.size, 30.0)
    H = TRUTH.frf(2 * np.pi * f, a)
    H = H * (1 + 0.01 * (rng.standard_normal(f.size) + 1j * rng.standard_normal(f.size)))
    levels.append(FirstHarmonicLevel(f, a / np.abs(H), 0.0, a, np.angle(H), "a=30", "response"))
    # phase resonance: the mode term in quadrature at each amplitude
    amps = np.linspace(5.0, 55.0, 11)
    fr = TRUTH.omega_n(amps) / (2 * np.pi)
    H = TRUTH.frf(2 * np.pi * fr, amps)
    H = H * (1 + 0.01 * (rng.standard_normal(amps.size) + 1j * rng.standard_normal(amps.size)))
    levels.append(FirstHarmonicLevel(fr, amps / np.abs(H), 0.0, amps, np.angle(H), "PR", "phase-resonance"))
    fit = fit_first_harmonic(levels, "poly2", "poly1", a_ref=60.0)
    z = (fit.params - TRUTH.params) / fit.stderr
    assert np.all(np.abs(z) < 4), dict(zip(fit.names, z))
    assert [lv.control for lv in fit.levels] == ["force", "force", "response", "phase-resonance"]


def test_selection_by_leave_one_level_out_and_adequacy():
    levels = _campaign(np.random.default_rng(4))
    cands = (("poly1", "poly1"), ("poly2", "poly1"), ("poly3", "poly2"))
    sel = select_laws(levels, candidates=cands, a_ref=60.0)
    assert sel["selected"] == ("poly2", "poly1")  # the true law; poly1 cannot bend back, poly3/poly2 adds nothing
    scores = {(t["frequency_law"], t["damping_law"]): t["lolo_complex_rms_rel"] for t in sel["table"]}
    assert scores[("poly1", "poly1")] > 2 * scores[("poly2", "poly1")]
    lolo = leave_one_level_out(levels, "poly2", "poly1", a_ref=60.0)
    top = lolo[-1]["peaks"]
    assert abs(top["amplitude_error_rel"]) < 0.03 and abs(top["frequency_error_rel"]) < 1e-3  # extrapolated
    good = adequacy(fit_first_harmonic(levels, "poly2", "poly1", a_ref=60.0))
    bad = adequacy(fit_first_harmonic(levels, "poly1", "poly1", a_ref=60.0))
    assert good["adequate"] and not bad["adequate"]


@pytest.mark.slow
def test_standard_errors_are_calibrated_by_monte_carlo():
    """std(z) of every parameter in 0.8 .. 1.25 over synthetic campaigns with the same lines and noise."""
    base = fit_first_harmonic(_campaign(np.random.default_rng(5), noise=0.02), "poly2", "poly1", a_ref=60.0)
    rng = np.random.default_rng(6)
    zs = []
    for _ in range(150):
        levels = simulate_levels(base, rng)
        fit = fit_first_harmonic(levels, "poly2", "poly1", a_ref=60.0, repredict=False, low_level=False)
        zs.append((fit.params - base.params) / fit.stderr)
    sd = np.std(zs, axis=0)
    assert np.all((sd > 0.8) & (sd < 1.25)), dict(zip(base.names, sd))
