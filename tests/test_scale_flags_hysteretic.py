"""The damping scale check on a friction joint: sticking records are physics, a unit error is not.

A Jenkins joint dissipates nothing below its slip amplitude and a lot just above it, so within one force level
the equivalent viscous damping ``c_eq`` of the dwells below slip is several times below the power-law trend of
the slipping ones.  The check compared the records' ``c_eq`` with that trend vertically and flagged them as
``scale_outlier`` (``identify --terms auto`` then exited 1 on a correct Jenkins campaign).  A factor ``s`` on the
acceleration moves a record along ``(q_max, c_eq) -> (s q_max, c_eq / s)``; the check now asks for the factor
along that direction that puts the record on the trend.  Ground truth: the time-integrated Jenkins oscillator of
``test_hysteretic_fsm`` (exact play operator, no harmonic balance of jointid), one force level, 0.5 % noise.
"""

import math
import warnings
from dataclasses import replace

import numpy as np
import pytest
from test_hysteretic_fsm import JENKINS, C, K, integrate, sliders_of

from jointid.app.records import (
    IdentifySettings,
    _equivalent_damping,
    flag_group_outliers,
    process_all,
    process_record,
)
from jointid.identify.hysteretic import first_harmonic_peak
from jointid.io.campaign import (
    load_campaign,
    read_record,
    write_campaign,
    write_csv_record,
)
from jointid.signal.checks import trend_outliers

SETTINGS = IdentifySettings(terms="q - q^3 + q'")  # the seed terms --terms auto processes the records with


@pytest.fixture(scope="module", params=[10.0, 12.0])
def group(request, tmp_path_factory):
    """One Jenkins force level, 13 dwells over +-6 % of its first-harmonic peak, written as a campaign: at 10 N the
    two lowest dwells stay below slip (q_slip = 1 mm) and the slipping ones' c_eq rises with q_max; at 12 N the lowest
    dwell just slips and the others' c_eq is nearly flat in q_max."""
    return _group(request.param, tmp_path_factory)


@pytest.fixture(scope="module")
def group14(tmp_path_factory):
    """The same at 14 N (the top level of the Jenkins campaigns): every dwell slips, c_eq falls with q_max."""
    return _group(14.0, tmp_path_factory)


def _group(level, tmp_path_factory):
    fp, _ = first_harmonic_peak(K, C, JENKINS, level)
    ws = 2 * np.pi * fp * (1 + 0.06 * np.linspace(-1, 1, 13))
    sl = sliders_of(JENKINS)
    t, _, a, err = integrate(K, C, sl.stiffness, sl.slip_displacement, np.full(ws.size, level), ws, steps=128,
                             periods=100, record=8, sub=1)
    assert err.max() < 1e-4
    specs, outcomes = _noisy_group(tmp_path_factory.mktemp("jenkins_group"), t, a, ws, level, 7)
    assert all(o.ok for o in outcomes)
    return specs, outcomes


def _noisy_group(folder, t, a, ws, level, seed):
    """Dwells of one force level with 0.5 % noise on force and acceleration, written as a campaign and
    identified: ``(specs, outcomes)``."""
    rng = np.random.default_rng(seed)
    entries = []
    for i, w in enumerate(ws):
        F = level * np.cos(w * t[i])
        F = F + 0.005 * np.std(F) * rng.standard_normal(F.size)
        A = a[i] + 0.005 * np.std(a[i]) * rng.standard_normal(a[i].size)
        write_csv_record(folder / f"r{i:02d}.csv", t[i], {"force": F, "accel": A})
        entries.append({"file": f"r{i:02d}.csv", "frequency_hz": float(w / (2 * np.pi)), "force_level": level,
                        "preload": "p"})
    write_campaign(folder, "group", entries)
    specs = load_campaign(folder).records
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return specs, process_all(specs, SETTINGS, None)


def _flags(outcomes):
    return {i: [f for f in o.flags if f.name == "scale_outlier"] for i, o in enumerate(flag_group_outliers(outcomes))
            if any(f.name == "scale_outlier" for f in o.flags)}


def test_sticking_and_slipping_records_of_a_jenkins_group_are_not_flagged(group):
    _, outcomes = group
    ceq = np.array([_equivalent_damping(o)[0] for o in outcomes])
    q = np.array([o.fit.q_max for o in outcomes])
    # the physics this test is about: dwells at or below slip dissipate by the viscous c (almost) alone, the others
    # 3-4 times more
    near = q < 1.01 * JENKINS.slip_displacement
    assert 1 <= near.sum() <= 4 and np.allclose(ceq[near], C, rtol=0.06)
    assert ceq[~near].max() > 3.5 * C
    # the vertical comparison with the slipping records' power law (the check before) calls the sticking ones off
    x, y = dict(enumerate(q)), dict(enumerate(ceq))
    se = {i: _equivalent_damping(o)[1] for i, o in enumerate(outcomes)}
    assert set(trend_outliers(x, y, factor=(3.0, 8.0), stderr=se)) == set(np.flatnonzero(near))
    assert _flags(outcomes) == {}


def _rescaled(specs, outcomes, i, factor, tmp_path, channel="accel"):
    """The outcomes with record ``i``'s ``channel`` multiplied by ``factor`` (written to a copy)."""
    d = read_record(specs[i])
    cols = {"force": d.channels["force"], "accel": d.channels["accel"]}
    cols[channel] = factor * cols[channel]
    path = tmp_path / specs[i].path.name
    write_csv_record(path, d.time, cols)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        bad = process_record(replace(specs[i], path=path), SETTINGS)
    assert bad.ok
    return outcomes[:i] + [bad] + outcomes[i + 1:]


def _index(outcomes, which):
    q = [o.fit.q_max for o in outcomes]
    return {"stuck": int(np.argmin(q)), "resonant": int(np.argmax(q)), "above": len(q) - 2}[which]


@pytest.mark.parametrize("factor", [9.81, 1 / 9.81])
@pytest.mark.parametrize("which", ["stuck", "resonant", "above"])
def test_a_unit_error_in_the_jenkins_group_is_still_flagged(group, tmp_path, factor, which):
    """Acceleration in g (1 / 9.81) or g counted twice (9.81) on a sticking record, the resonant one, or one above
    resonance: that record alone is flagged, and the flag names a factor of at least 3 the same way (not the 9.81
    itself: a sticking record is off the slipping ones' power law by the knee as well) or the record's dissipation
    breaks the rule that it does not fall with amplitude."""
    specs, outcomes = group
    i = _index(outcomes, which)
    flags = _flags(_rescaled(specs, outcomes, i, factor, tmp_path))
    assert list(flags) == [i], flags
    for f in flags[i]:
        s = f.values.get("acceleration_scale")
        if s is not None:  # the damping check (omega1's check may catch it first)
            assert (s > 1) == (factor > 1) and max(s, 1 / s) >= 3.0, f.values


@pytest.mark.parametrize("factor", [9.81, 1 / 9.81])
@pytest.mark.parametrize("which", ["stuck", "resonant", "above"])
def test_a_force_unit_error_in_the_jenkins_group_is_still_flagged(group, tmp_path, factor, which):
    """A force in kgf (1 / 9.81) or scaled twice (9.81): c_eq moves by the factor at the same q_max.  A sticking
    dwell's force in kgf puts it further below the trend where a sticking joint already is: flagged only when the
    dwell's stiffness or dissipation tells it apart (at 10 N, not at 12 N); no other record is flagged."""
    specs, outcomes = group
    i = _index(outcomes, which)
    flags = _flags(_rescaled(specs, outcomes, i, factor, tmp_path, channel="force"))
    if which == "stuck" and factor < 1:
        assert list(flags) in ([], [i]), flags
    else:
        assert list(flags) == [i], flags


def test_scale_factor_along_the_invariant_is_exact_on_a_power_law():
    """On a power-law trend ``c = A q^p`` a member moved to ``(s q, c / s)`` is put back by the factor ``s``
    whatever ``p``; it is flagged when it is also off the trend vertically by the factor (3 below, 8 above), as
    before (the check never flags what it did not), and not for ``p = -1``, where ``c q`` is constant."""
    q = {i: 1e-3 * 1.25**i for i in range(9)}
    n_flagged = 0
    for p in (-0.5, 0.0, 0.7, 2.0):
        for s in (9.81, 1 / 9.81, 1000.0):
            c = {i: 3.0 * (v / 1e-3) ** p for i, v in q.items()}
            x = dict(q)
            x[4], c[4] = s * q[4], c[4] / s
            out = trend_outliers(x, c, factor=(3.0, 8.0), invariant=-1.0)
            vertical = -(1 + p) * math.log(s)  # the log of c[4] over the trend at x[4]
            if abs(vertical) <= math.log(3.0 if vertical < 0 else 8.0):
                assert out == {}, (p, s, out)
                continue
            n_flagged += 1
            assert list(out) == [4], (p, s, out)
            assert out[4][2] == pytest.approx(s, rel=1e-9)
            assert out[4][0] == pytest.approx(math.exp(vertical), rel=1e-9)
    assert n_flagged == 11  # all but p = -0.5 with 1 / 9.81: 9.81^0.5 above the trend
    # a Coulomb-like trend (c q constant): the moved member lies on it
    c = {i: 3e-3 / v for i, v in q.items()}
    x = dict(q)
    x[4], c[4] = 9.81 * q[4], c[4] / 9.81
    assert trend_outliers(x, c, factor=(3.0, 8.0), invariant=-1.0) == {}


def test_a_knee_below_the_others_amplitudes_is_no_scale_error():
    """Closed-form first-harmonic c_eq of a Jenkins joint plus viscous damping, ``c + 4 Fs (q - phi) / (pi w q^2)``
    above slip: the records below slip lie far below the slipping ones' power law, but the factor along the
    unit-error direction that would put them on it takes them further below all the others' amplitudes."""
    w, phi, Fs, c0 = 200.0, 1e-3, 10.0, 5.0
    qs = [0.8e-3, 0.9e-3] + list(np.geomspace(1.15e-3, 4e-3, 9))
    q = dict(enumerate(qs))
    c = {i: c0 + (4 * Fs * (v - phi) / (math.pi * w * v**2) if v > phi else 0.0) for i, v in q.items()}
    vertical = set(trend_outliers(q, c, factor=(3.0, 8.0)))  # the comparison before
    assert vertical and vertical <= {0, 1}
    assert trend_outliers(q, c, factor=(3.0, 8.0), invariant=-1.0) == {}


@pytest.mark.parametrize("factor", [9.81, 1 / 9.81])
def test_an_acceleration_unit_error_on_any_dwell_of_the_top_level_is_flagged(group14, tmp_path, factor):
    """Acceleration in g (1 / 9.81) or g counted twice (9.81) on each dwell of the 14 N group in turn: that record
    alone is flagged.  The resonant dwells in g land at a tenth of the group's amplitudes, where the extrapolated
    c_eq trend cannot call them off (the check before missed 7 of the 13); their dissipation per cycle over q_max,
    which the unit leaves as it was, is that of records with about 8 times their q_max."""
    specs, outcomes = group14
    assert _flags(outcomes) == {}
    missed, others = [], []
    for i in range(len(outcomes)):
        flags = _flags(_rescaled(specs, outcomes, i, factor, tmp_path))
        if i not in flags:
            missed.append(i)
        if set(flags) - {i}:
            others.append((i, sorted(set(flags) - {i})))
    assert missed == [] and others == [], (missed, others)
    if factor < 1:  # the flag of the resonant dwell names the amplitude factor, as large as the unit's
        i = _index(outcomes, "resonant")
        (f,) = _flags(_rescaled(specs, outcomes, i, factor, tmp_path))[i]
        r = f.values["amplitude_ratio"]
        assert r is not None and 3.0 < 1 / r <= 9.81 * 1.05, f.values


@pytest.mark.slow
def test_an_acceleration_in_g_on_a_coulomb_viscous_group_is_flagged(tmp_path):
    """Coulomb + viscous damping (time-integrated, test_selection_hysteretic's generator), one level of 13 dwells
    over +-5 %: c_eq ~ 1 / q_max, the direction a factor on the acceleration moves a record along, so the c_eq trend
    does not see acceleration in g (the check before missed 10 of the 13 dwells).  The dissipation per cycle over
    q_max does: only the dwell whose W / q_max is already the group's smallest (the lowest frequency) is not told from a
    record of the same joint at a tenth of its amplitude."""
    from test_selection_hysteretic import FAMILIES, _peak_guess
    from test_selection_hysteretic import integrate as integrate_smooth

    name, level = "Coulomb + viscous", 6.0
    force, sl, _, _ = FAMILIES[name]
    ws = 2 * np.pi * _peak_guess(name, level) * (1 + 0.05 * np.linspace(-1, 1, 13))
    t, a, err = integrate_smooth(force, sl, [level] * ws.size, list(ws))
    assert err.max() < 2e-4
    specs, outcomes = _noisy_group(tmp_path, t, a, ws, level, 11)
    assert all(o.ok for o in outcomes) and _flags(outcomes) == {}
    smallest = int(np.argmin([_equivalent_damping(o)[0] * o.signals.omega * o.fit.q_max for o in outcomes]))
    bad = tmp_path / "bad"
    bad.mkdir()
    missed, others = [], []
    for i in range(len(outcomes)):
        flags = _flags(_rescaled(specs, outcomes, i, 1 / 9.81, bad))
        if i not in flags:
            missed.append(i)
        others += sorted(set(flags) - {i})
    assert missed in ([], [smallest]) and others == [], (missed, others)
