"""Clean data are never flagged; a unit error still is.

The damping scale check compares a record's equivalent viscous damping ``<Q q'> / <q'^2>``
(with its standard error) with its group's trend.  It used the coefficient of ``q'`` alone,
which a fit with ``|q'|q'`` and ``q'^3`` beside it does not resolve: README command 4 on a
clean simulated campaign flagged records 42, 52 and 55 (``c`` 0.05-0.11 times the trend).
"""

import tempfile
import warnings
from pathlib import Path

import numpy as np
import pytest

from jointid.app.records import IdentifySettings, flag_group_outliers, process_all
from jointid.app.synthesis import load_simulation_config, simulate_campaign
from jointid.io.campaign import load_campaign, read_record, write_csv_record
from jointid.signal.checks import equivalent_damping, trend_outliers

ROOT = Path(__file__).resolve().parents[1]
README_4 = dict(terms="q - q^3 + q' + |q'|q' + q'^3", n_harmonics=4, damping_order=1)
FIT_TERMS = ("q + -q^3 + q'", README_4["terms"], "q + -q^3 + q' + |q'|q'", "q + -q^3 + q' + q'^3")


def _flags(folder, settings):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = flag_group_outliers(process_all(load_campaign(folder).records, settings, None))
    return [(o.spec.index, o.error if not o.ok else [f.report() for f in o.flags]) for o in out
            if o.flags or not o.ok], out


def test_equivalent_damping_closed_form():
    """A viscous record gives its c, whatever the harmonics; a unit factor scales it."""
    w, c, n = 30.0, 0.7, 4000
    F = [0.0, 2.0, c * 0.05 * w]  # Q = 2 cos + c v with v = 0.05 w sin
    V = [0.0, 0.0, 0.05 * w]
    val, se = equivalent_damping(F, V, w, 0.01, 0.01, n)
    assert val == pytest.approx(c, rel=1e-12) and 0 < se < 1e-2 * c
    g, _ = equivalent_damping(F, np.array(V) / 9.81, w, 0.01, 0.01, n)  # acceleration (and velocity) in g
    assert g == pytest.approx(9.81 * c)


def test_trend_check_needs_resolved_values():
    """A value off the trend by a large factor is flagged only when its standard error resolves it."""
    q = {i: 1e-3 * (i + 1) for i in range(8)}
    c = {i: 0.1 + 50 * q[i] for i in range(8)}
    c[3] *= 0.05
    se = {i: 1e-3 * c[i] for i in range(8)}
    assert list(trend_outliers(q, c, factor=(3.0, 8.0), stderr=se)) == [3]
    se[3] = 0.2 * c[3] / 0.05  # resolved to +-0.2 of the trend: no evidence of a unit error
    assert trend_outliers(q, c, factor=(3.0, 8.0), stderr=se) == {}
    c[3] = 9.81 * (0.1 + 50 * q[3])
    se[3] = 0.05 * c[3]
    assert list(trend_outliers(q, c, factor=(3.0, 8.0), stderr=se)) == [3]


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    cfg = {"model": [{"preload": "p", "terms": "q + -q^3 + q'", "omega1": 170.0, "coefficients": {"k3": 5e6},
                      "amplitude_laws": {"c": [0.08, 70.0, 1e4]}}],
           "excitation": {"omega_start": 160.0, "omega_stop": 180.0, "n_frequencies": 9, "force_levels": [1.0]},
           "acquisition": {"fs": 2000.0, "periods": 20.0, "noise": 0.01, "seed": 4, "write_frequency": False}}
    return load_simulation_config(cfg)


@pytest.mark.parametrize("kind, record", [("accel_in_g", 4), ("accel_in_mm", 4), ("force_in_g", 2),
                                          ("accel_in_g", 8), ("time_in_ms", 6)])
def test_unit_errors_are_flagged_with_richer_damping_terms(tmp_path, small, kind, record):
    """README command 4's terms: a record in other units is flagged; the clean ones are not."""
    folder = simulate_campaign(small, tmp_path / "c")
    spec = load_campaign(folder).records[record]
    d = read_record(spec)
    t, Q, a = d.time, d.channels["force"], d.channels["accel"]
    if kind == "accel_in_g":
        a = a / 9.81
    elif kind == "accel_in_mm":
        a = a * 1000.0
    elif kind == "force_in_g":
        Q = Q / 9.81
    else:
        t = t * 1000.0
    write_csv_record(spec.path, t, {"force": Q, "accel": a})
    flagged, _ = _flags(folder, IdentifySettings(**README_4, repredict=False))
    assert [i for i, _ in flagged] == [record], flagged
    names = {f.split(":")[0] for f in flagged[0][1]}
    assert names & {"scale_outlier", "time_unit"}, flagged


@pytest.mark.slow
def test_readme_command_4_campaign_is_not_flagged(tmp_path):
    """``jointid simulate examples/noisy_softening.toml`` then README command 4: no record flagged
    (the check flagged records 42, 52 and 55 of this campaign)."""
    folder = simulate_campaign(load_simulation_config(ROOT / "examples" / "noisy_softening.toml"), tmp_path / "c")
    flagged, out = _flags(folder, IdentifySettings(**README_4, repredict=False))
    assert flagged == [] and len(out) == 123


def _random_campaign(seed):
    """A small clean campaign: random model (hardening or softening, damping law, sometimes a
    quadratic damping term), band, force levels, noise 0.1-3 %, record length, sampling rate,
    frequency written or estimated; and random identification settings (README command 4's
    among them)."""
    rng = np.random.default_rng(seed)
    w1 = float(rng.uniform(100.0, 300.0))
    k3 = float(rng.uniform(1e6, 8e6) * (w1 / 170.0) ** 2 * rng.choice([-1.0, 1.0]))
    law = [float(rng.uniform(0.03, 0.3)), float(rng.uniform(0.0, 150.0)), float(rng.uniform(0.0, 3e4))]
    terms, coefs = "q + -q^3 + q'", {"k3": k3}
    if rng.random() < 0.3:
        terms += " + |q'|q'"
        coefs["c_quad"] = float(rng.uniform(0.0, 20.0))
    half = float(rng.uniform(0.04, 0.08))
    cfg = {"model": [{"preload": "p", "terms": terms, "omega1": w1, "coefficients": coefs, "amplitude_laws": {"c": law}}],
           "excitation": {"omega_start": w1 * (1 - half), "omega_stop": w1 * (1 + half),
                          "n_frequencies": int(rng.integers(5, 9)),
                          "force_levels": sorted(rng.uniform(0.3, 2.5, int(rng.integers(1, 3))).round(3).tolist())},
           "acquisition": {"fs": float(rng.uniform(1000.0, 2500.0)), "periods": float(rng.integers(6, 17)),
                           "noise": float(np.exp(rng.uniform(np.log(0.001), np.log(0.03)))),
                           "seed": int(rng.integers(1 << 30)), "write_frequency": bool(rng.random() < 0.5),
                           "n_harmonics": 9, "t0": float(rng.uniform(0.0, 0.2))}}
    if rng.random() < 0.25:
        settings = IdentifySettings(**README_4, repredict=False)
    else:
        settings = IdentifySettings(terms=str(rng.choice(FIT_TERMS)), n_harmonics=int(rng.integers(3, 6)),
                                    damping_order=int(rng.integers(0, 3)), repredict=False)
    return load_simulation_config(cfg), settings


@pytest.mark.slow
def test_no_flag_on_300_random_clean_campaigns():
    """300 random clean campaigns (about 3500 records): no record flagged or failed."""
    bad = []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(300):
            cfg, settings = _random_campaign(seed)
            folder = simulate_campaign(cfg, Path(tmp) / f"c{seed}")
            flagged, _ = _flags(folder, settings)
            if flagged:
                bad.append((seed, settings.terms, flagged))
    assert bad == []
