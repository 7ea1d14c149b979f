"""Stepped-sine backbone points when the force column has an unknown gain and the response a channel delay.

The equivalent linearisation of a dwell needs the force in the model's units: with
``--force-gain unknown`` that is the recorded column times the identified gain, and with
``--channel-delay`` the response corrected by the estimated delay.  A simulated campaign
with a known gain != 1 and a known delay gives the truth (the UNESP dwells against
docs/public-data.md section 5: tests/test_unesp_outputs.py).
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from jointid.app.backbones import backbones_from_results
from jointid.app.workflow import identify_campaign
from jointid.identify.backbone import equivalent_linearisation, model_backbone
from jointid.io.campaign import write_campaign, write_csv_record
from jointid.simulate.hbm import steady_state
from jointid.simulate.model import seed_model
from jointid.simulate.synth import synthesize_record

GAIN = 0.37  # force per unit of the recorded column (a "voltage" Q / GAIN is written)
TAU = -8e-4  # the response channel leads the excitation by 0.8 ms


class _Delayed:
    """A steady state whose acceleration is read ``TAU`` late (``q_measured(t) = q(t - TAU)``)."""

    def __init__(self, state):
        self.state = state

    def force(self, t):
        return self.state.force(t)

    def acceleration(self, t):
        return self.state.acceleration(np.asarray(t) - TAU)


def _campaign(folder, seed=0):
    """Seed model with a damping law of order 1, two force levels of 9 dwells, voltage and delayed accel."""
    model = seed_model(c_law=(0.5, 100.0))
    rng = np.random.default_rng(seed)
    entries = []
    for F in (0.5, 1.5):
        for i, w in enumerate(np.linspace(164.0, 174.0, 9)):
            s = steady_state(model, w, F, n_harmonics=7, stability=False)
            t, Q, qdd = synthesize_record(_Delayed(s), fs=2000.0, duration=1.0, noise=0.003, rng=rng)
            rel = f"records/F{F:g}_{i}.csv"
            write_csv_record(folder / rel, t, {"force": Q / GAIN, "accel": qdd})
            entries.append({"file": rel, "frequency_hz": w / (2 * np.pi), "force_level": F, "preload": 1})
    write_campaign(folder, "voltage and delayed response", entries)
    return model


@pytest.fixture(scope="module")
def identified(tmp_path_factory):
    folder = tmp_path_factory.mktemp("gain_delay")
    model = _campaign(folder)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = identify_campaign(folder, force_gain="unknown", channel_delay="estimate", damping_order=1,
                                repredict=False)
    return model, res


def test_unknown_gain_and_delay_reach_the_stepped_sine_points(identified):
    model, res = identified
    assert abs(res.channel_delay.delay_s - TAU) < 0.02 * abs(TAU)
    assert all(abs(g.gain.gain / GAIN - 1) < 2e-3 for g in res.groups)
    st = res.backbones[1].stepped
    assert len(st) == 18 and np.all(np.isfinite(st.omega))
    truth = model_backbone(model.terms, model.coefficients, st.amplitude, amplitude_laws=model.amplitude_laws,
                           n_harmonics=5)
    # not the dwell frequencies (164-174 rad/s) but the model's natural frequency at each amplitude
    assert np.max(np.abs(st.omega / truth.omega - 1)) < 2e-5
    assert np.max(np.abs((st.omega - truth.omega) / st.omega_stderr)) < 4
    assert np.max(np.abs(st.zeta / truth.zeta - 1)) < 0.01
    assert np.all(st.zeta_stderr > 0) and np.max(np.abs((st.zeta - truth.zeta) / st.zeta_stderr)) < 4
    assert st.meta["force_gain"][0] == pytest.approx(GAIN, rel=2e-3)
    # the phase-resonance point of each force level lies on the backbone too
    pr = res.backbones[1].phase_resonance
    assert len(pr) == 2
    ref = model_backbone(model.terms, model.coefficients, pr.amplitude, amplitude_laws=model.amplitude_laws,
                         n_harmonics=5)
    assert np.max(np.abs(pr.omega / ref.omega - 1)) < 1e-4
    # results.json keeps the corrected points (what `jointid backbone results.json` draws)
    again = backbones_from_results(json.loads(json.dumps(res.summary())))
    np.testing.assert_allclose(again[1].stepped.omega, st.omega, rtol=1e-12)


def test_gain_and_delay_errors_widen_the_points(identified):
    _, res = identified
    ok = [r for r in res.records if r.ok]
    sig = [r.signals for r in ok]
    g = res.groups[0].gain.gain
    base = equivalent_linearisation(sig, force_gain=g)
    wide = equivalent_linearisation(sig, force_gain=g, force_gain_stderr=0.01 * g, delay_stderr=1e-4)
    np.testing.assert_allclose(wide.omega, base.omega, rtol=0)
    assert np.all(wide.omega_stderr > base.omega_stderr) and np.all(wide.zeta_stderr > base.zeta_stderr)
    # an unknown gain for a record gives no point, never a number made with the voltage
    none = equivalent_linearisation(sig[:2], force_gain=[None, g])
    assert np.isnan(none.omega[0]) and np.isfinite(none.omega[1])
