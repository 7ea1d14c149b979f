"""Virtual rig (Iwan joint) at both preloads: the cubic model is flagged, the selected model (amplitude laws)
re-predicts the held-out force levels' nonlinear FRF peaks against the rig's exact FRF (slow: runs the demo's
campaigns); the top level's extrapolated amplitude is an open point (see the xfail below)."""

import warnings

import pytest

from jointid.app.reprediction import repredict_group
from jointid.identify.model import PreloadForceStateMapping
from jointid.app.heldout_scoring import single_mode_model
from jointid.identify.selection import select_model
from jointid.identify.terms import library


def usable_records(pr):
    """``(signals, force levels)`` of a preload's usable records."""
    recs = [o for o in pr.result.records if o.usable and o.spec.preload == pr.preload]
    return [o.signals for o in recs], [o.spec.force_level for o in recs]


def sensor_scale(pr, sensor="accel_42"):
    """``(|phi_force|, |phi_sensor|)`` of mode 1 in the preload's updated structure."""
    s = pr.structure
    return abs(float(s.phi_force[0])), abs(float(s.phi_sensors[list(s.sensors).index(sensor), 0]))


def _held_out(pr, key, sigs, lev, cand, level):
    """The candidate fitted without one force level, solved at that level against the rig's exact FRF."""
    train = [i for i, x in enumerate(lev) if x != level]
    m = PreloadForceStateMapping(cand.terms, amplitude_laws=cand.laws).fit([sigs[i] for i in train]).result_
    model = single_mode_model(library(cand.terms), m.law_orders, m.parameters)
    phi_f, phi_s = sensor_scale(pr)
    exact = next(r.exact for r in pr.repredictions if r.force_level == level)
    r = repredict_group(pr.result, pr.result.group(key, level), forcing=phi_f * float(level), scale=phi_s * phi_f,
                        exact=exact, model=model)
    return r.peak_frequency_error_percent, r.peak_amplitude_error_percent


@pytest.mark.slow
def test_rig_cubic_flagged_and_selected_model_repredicts_held_out_level(demo_run):
    demo = demo_run
    misses = []
    for pr in demo.preloads:
        key = next(iter(pr.result.adequacy))
        adq = pr.result.adequacy[key]
        k3 = next(e for e in adq.equality if e.name == "k3")
        print(f"preload {key:g} N: {adq.verdict}")
        assert not adq.adequate and k3.p_value < 1e-6 and k3.ratio > 2.0  # k3 falls ~3x (120 N), ~4x (540 N)
        assert "the cubic model does not hold at this preload" in adq.verdict
        sigs, lev = usable_records(pr)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            sel = select_model(sigs, lev, preload=key, fit_selected=False)
        print(sel.report())
        # the rig's joint (Iwan plus a cubic spring) is an amplitude-dependent stiffness and damping: the pick is
        # a family with amplitude laws, never the cubic the adequacy check rejects; it is judged below by its
        # held-out predictions against the rig's exact FRF
        print(f"  selected: {sel.selected}")
        assert sel.selected != "cubic" and sel.candidate.laws
        assert sel.score("cubic").cv_force > 3 * sel.selected_score.cv_force
        cubic = sel.score("cubic").candidate
        for level in sorted(set(lev)):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                f_sel, a_sel = _held_out(pr, key, sigs, lev, sel.candidate, level)
                f_cub, a_cub = _held_out(pr, key, sigs, lev, cubic, level)
            print(f"  held-out F = {level} N: selected peak frequency {f_sel:+.4f} %, amplitude {a_sel:+.3f} %; "
                  f"cubic {f_cub:+.4f} %, {a_cub:+.3f} %")
            assert abs(f_sel) < 0.05
            if level < max(lev):
                assert abs(a_sel) < 1.0
            elif abs(a_sel) >= 1.0:  # the top level: amplitudes beyond the others' (the laws extrapolate)
                misses.append(f"{key:g} N: {sel.selected} {a_sel:+.2f} % at {level:g} N")
    if misses:
        # Known and open (issue 22): the held-out rule picks the order-2 amplitude-dependent stiffness at 120 N,
        # whose extrapolation to the top level misses the rig's exact peak amplitude by about 2.4 % (micro-slip
        # power laws: +0.6 %).  Since the top level's peak is scored as a peak also for a model with a fold among
        # its dwells, micro-slip has the best held-out score (0.027 against 0.038), but the order-2 laws are within
        # noise of it (ratio 1.5) with as many parameters and none fitted as an exponent, and win the tie.
        pytest.xfail("top-level peak amplitude extrapolated beyond 1 %: " + "; ".join(misses))
