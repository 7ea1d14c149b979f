"""A measured peak error is quoted only where the dwells resolve the peak (bracket it, closely enough)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from jointid.app.paper_example import paper_config
from jointid.app.reprediction import identified_model, repredict_group
from jointid.app.synthesis import load_simulation_config, simulate_campaign
from jointid.app.workflow import identify_campaign
from jointid.simulate.hbm import frequency_response


@pytest.fixture(scope="module")
def identified(tmp_path_factory):
    """The seed's numerical example, 1 % noise, 15 dwells over 160-180 rad/s (a 0.16 Hz wide peak)."""
    cfg = paper_config(n_frequencies=15, noise=0.01, seed=5, write_frequency=False, periods=10)
    camp = simulate_campaign(load_simulation_config(cfg), tmp_path_factory.mktemp("peak") / "c")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = identify_campaign(camp, repredict=False)
    return res, res.groups[0]


def _no_peak_error(r):
    s = r.summary()
    assert r.peak_resolved is False and s["peak_resolved"] is False
    assert s["peak_frequency_error_percent"] is None and s["peak_amplitude_error_percent"] is None
    assert np.isnan(r.peak_frequency_error_percent) and np.isnan(r.peak_amplitude_error_percent)
    text = r.report()
    assert "no peak error" in text and " %)" not in text, text
    assert s["peak_status"] in text
    assert np.isfinite(s["peak_predicted"]["frequency_hz"])  # the predicted peak is still given
    return s, text


def test_coarse_dwells_do_not_resolve_the_peak(identified):
    res, g = identified
    r = repredict_group(res, g)
    s, text = _no_peak_error(r)
    assert r.peak_bracketed and s["peak_bracketed"] is True
    assert "do not resolve the peak" in text and s["dwell_spacing_hz"] > 0.5 * s["bandwidth_hz"]
    assert "measured points rms" in text


def test_dwells_below_the_peak_do_not_bracket_it(identified):
    res, g = identified
    full = repredict_group(res, g)
    below = full.measured_frequency_hz < full.peak_predicted[0] - 0.2
    assert below.sum() >= 3 and np.all(np.diff(full.measured[below]) > 0)  # still rising at the last dwell
    span = (float(full.measured_frequency_hz.min()), float(full.measured_frequency_hz.max()))
    r = repredict_group(res, g, measured=(full.measured_frequency_hz[below], full.measured[below]), span=span)
    s, text = _no_peak_error(r)
    assert r.peak_bracketed is False and s["peak_bracketed"] is False
    assert "do not bracket the peak" in text


def test_dense_dwells_about_the_peak_give_a_peak_error(identified):
    """Dwells 0.01 Hz apart across the model's own peak: resolved, and the errors are small."""
    res, g = identified
    full = repredict_group(res, g)
    model = identified_model(res, g)
    f = full.peak_predicted[0] + np.arange(-0.3, 0.3001, 0.01)
    sweep = frequency_response(model, full.forcing, 2 * np.pi * f, n_harmonics=5, stability=False)
    H = sweep.omega**2 * sweep.amplitude / full.forcing
    r = repredict_group(res, g, measured=(f, H), span=(float(f[0]), float(f[-1])))
    assert r.peak_resolved and r.peak_bracketed
    assert abs(r.peak_frequency_error_percent) < 0.02 and abs(r.peak_amplitude_error_percent) < 1.0
    s = r.summary()
    assert s["peak_frequency_error_percent"] == pytest.approx(r.peak_frequency_error_percent)
    assert s["peak_status"] == "resolved by the dwells" and "no peak error" not in r.report()
