"""The virtual rig: Table 4 structure, harmonic balance of the reduced model, records, campaigns."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from jointid.errors import StructureError
from jointid.io.campaign import RecordSpec, load_campaign, read_record
from jointid.io.uff import read_uff
from jointid.modal.beam import SEED_TABLE4_HZ
from jointid.modal.structure import Structure
from jointid.rig.iwan import IwanParameters, JointLaw
from jointid.rig.plan import MeasurementPlan, read_random_record, run_test_plan, structure_section, write_manifest
from jointid.rig.reduced import integrate, sample_series, series, settle_check
from jointid.rig.rig import Acquisition, RandomTest, VirtualRig, parabolic_peak, seed_rig
from jointid.signal.frf import fit_modes, h1_estimate


@pytest.fixture(scope="module")
def rig120():
    return seed_rig(120)


@pytest.fixture(scope="module")
def rig540():
    return seed_rig(540)


@pytest.mark.parametrize("preload", [120, 540])
def test_linear_frequencies_match_table4(preload):
    rig = seed_rig(preload)
    np.testing.assert_allclose(rig.linear_frequencies_hz[:3], SEED_TABLE4_HZ[preload], rtol=1e-5)
    law = rig.joint_laws["rotation"]
    assert law.linear_stiffness < rig.beam.joint.k_t  # K_T is part of the updated joint spring


def test_lower_preload_has_the_weaker_joint(rig120, rig540):
    a, b = rig120.joint_laws["rotation"].iwan, rig540.joint_laws["rotation"].iwan
    assert a.F_S < b.F_S and a.phi_max < b.phi_max
    assert rig120.modal_cubic_coefficient > rig540.modal_cubic_coefficient > 0


def test_harmonic_balance_linear_limit(rig120):
    """At a tiny force the joint stays stuck: the steady state is the linear (stuck) FRF."""
    f = 26.3
    s = rig120.steady_state(f, 1e-7)
    H = rig120.model.linear_frf([f])[:, 0] * 1e-7
    a1 = -(s.omega**2) * (rig120.model.sensor_shapes @ (s.modal[:, 1] - 1j * s.modal[:, 2]))
    # F sin(wt) has complex amplitude -i F in the a - i b convention
    np.testing.assert_allclose(a1, -1j * H, rtol=1e-6)


def test_harmonic_balance_energy_balance(rig120):
    """Work of the shaker per cycle = material damping + the joint's hysteresis loop."""
    s = rig120.steady_state(26.30, 6.0)
    m = rig120.model
    n = 8192
    t = np.arange(n) / n / s.frequency_hz
    F = s.force_at(t)
    eta_d = s.modal_at(t, 1)
    T = 1 / s.frequency_hz
    w_in = np.mean(F * (m.force_shape @ eta_d)) * T
    w_mat = np.mean(np.sum(2 * (m.zeta * m.omega)[:, None] * eta_d**2, axis=0)) * T
    law = m.laws[0]
    u = s.joint_at(t)[0]
    f, _ = law.periodic_force(u)
    du = series(s.joint, s.omega, t, 1)[0]
    w_joint = np.mean(f * du) * T
    assert w_joint > 0.1 * w_mat  # the joint dissipates a good share at 6 N
    assert w_in == pytest.approx(w_mat + w_joint, rel=2e-3)


def test_reduced_model_is_the_engines_linear_model(rig120):
    """The rig's reduced model uses the harmonic-balance engine's linear model (receptance, sizes,
    shape checks) and its AFT force, not copies of them."""
    import dataclasses

    m = rig120.model
    eng = m.engine()
    w = 2 * np.pi * np.linspace(10.0, 900.0, 37)
    assert np.array_equal(m.receptance(w), eng.receptance(w))
    assert (m.n_modes, m.n_joints) == (eng.n_modes, eng.n_joints) == (4, 1)
    U = 1e-5 * np.random.default_rng(0).standard_normal((1, 11))
    F, J = m.joint_aft(U, 64, jacobian=True)
    F2, J2, _ = eng.aft(U, 1.0, 5, 64)
    assert np.array_equal(F, F2) and np.array_equal(J, J2)
    with pytest.raises(StructureError, match="force_shape"):
        dataclasses.replace(m, force_shape=m.force_shape[:3])
    with pytest.raises(StructureError, match="finite"):
        dataclasses.replace(m, joint_shapes=np.full_like(m.joint_shapes, np.nan))


def test_settle_check_passes_on_the_orbit(rig120):
    states = rig120.sweep([26.2, 26.3, 26.4], 6.0)
    dev = settle_check(rig120.model, states, n_periods=4, steps_per_period=1024)
    assert np.all(dev < 3e-3)


def test_sample_series_equals_series():
    c = np.random.default_rng(1).standard_normal((2, 2 * 21 + 1))
    t = np.arange(500) / 2048.0
    for d in (0, 1, 2):
        np.testing.assert_allclose(sample_series(c, 160.0, 500, 1 / 2048.0, d), series(c, 160.0, t, d),
                                   rtol=1e-10, atol=1e-10 * np.abs(series(c, 160.0, t, d)).max())


def test_record_channels_and_noise(rig120):
    acq = Acquisition(fs=2048.0, duration=1.0, force_noise=0.01, accel_noise=0.05)
    s = rig120.steady_state(26.3, 3.0)
    clean = rig120.record(s, Acquisition(fs=2048.0, duration=1.0, force_noise=0.0, accel_noise=0.0), 0)
    rec = rig120.record(s, acq, np.random.default_rng(3))
    assert rec.names == ("force", "accel_30", "accel_42")
    assert rec.n_samples == 2048 and rec.fs == 2048.0 and rec.time[0] == 0.0
    assert rec.units["force"] == "N" and rec.units["accel_42"] == "m/s^2"
    assert np.std(rec["force"] - clean["force"]) == pytest.approx(0.01, rel=0.1)
    assert np.std(rec["accel_42"] - clean["accel_42"]) == pytest.approx(0.05, rel=0.1)
    # the noise-free record is the steady state (harmonics above the anti-aliasing cut-off left out)
    t = clean.time
    ref = rig120.model.sensor_shapes[1] @ series(s.modal, s.omega, t, 2)
    assert np.max(np.abs(clean["accel_42"] - ref)) < 1e-3 * np.max(np.abs(ref))


def test_force_distortion_is_measured(rig540):
    acq = Acquisition(duration=1.0, force_noise=0.0, accel_noise=0.0, distortion=((2, 0.05, 0.3), (3, 0.02, 0.0)))
    d = rig540.stepped_sine([26.5], 3.0, acq, rng=0, settle=False)[0]
    t, F = d.record.time, d.record["force"]
    w = 2 * np.pi * 26.5
    A = np.column_stack([np.sin(k * w * t + p) for k, p in ((1, 0.0), (2, 0.3), (3, 0.0))])
    coef = np.linalg.lstsq(A, F, rcond=None)[0]
    np.testing.assert_allclose(coef, [3.0, 0.15, 0.06], rtol=1e-6)
    # the second harmonic of the force makes even harmonics in the response (none without it)
    assert np.hypot(*d.state.joint[0, 3:5]) > 1e-5 * np.hypot(*d.state.joint[0, 1:3])
    pure = rig540.steady_state(26.5, 3.0)
    assert np.hypot(*pure.joint[0, 3:5]) < 1e-12 * np.hypot(*pure.joint[0, 1:3])


def test_random_test_gives_the_linear_frequencies(rig540):
    test = RandomTest()  # the demo's: 128 s, segments of 65536 samples (0.03 Hz)
    rec = rig540.random_test(test, rng=0)
    frf = h1_estimate(rec["force"], np.vstack([rec["accel_30"], rec["accel_42"]]), rec.fs, nperseg=test.nperseg)
    fit = fit_modes(frf, n_modes=3, channel=1, f_range=(15.0, 700.0), min_coherence=0.5)
    np.testing.assert_allclose(fit.frequencies_hz, rig540.linear_frequencies_hz[:3], rtol=5e-4)
    assert max(rig540.random_linearity(rec.meta["joint_rms"])) < 0.02  # the joint is linear at this level


@pytest.fixture(scope="module")
def small_campaign(tmp_path_factory, rig540):
    plan = MeasurementPlan(force_levels=(3.0,), n_frequencies=5, band=(0.99, 1.005),
                    acquisition=Acquisition(duration=1.0), random=RandomTest(duration=16.0, nperseg=8192),
                    random_formats=("uff", "csv"))
    return run_test_plan(rig540, plan, tmp_path_factory.mktemp("rigcamp") / "p540", rng=1)


def test_test_plan_writes_a_physical_campaign(small_campaign, rig540):
    camp = load_campaign(small_campaign.folder)
    assert camp.coordinates == "physical"
    assert len(camp.records) == 5
    assert all(r.path.suffix == ".uff" and r.force_level == 3.0 and r.frequency_hz for r in camp.records)
    st = Structure.from_mapping(camp.structure)  # the as-built description parses
    assert st.required_columns == ("force", "accel_30", "accel_42")
    rnd = read_random_record(small_campaign.folder)
    assert rnd.n_samples == 16 * 2048 and rnd.names == ("force", "accel_30", "accel_42")
    assert all(d.settled for d in small_campaign.dwells)


def test_uff58_records_read_back_identical_to_csv(small_campaign):
    """Done-when item: every UFF 58 record equals its CSV twin, bit for bit."""
    for e in small_campaign.entries:
        path_csv = small_campaign.folder / e["files"]["csv"]
        csv = read_record(RecordSpec(0, e["files"]["csv"], path_csv, None, None, None), required=("time", "force"))
        uff = read_uff(small_campaign.folder / e["files"]["uff"])
        assert uff.meta["format"] == "uff58b"
        np.testing.assert_array_equal(uff.time, csv.time)
        assert list(csv.channels) == list(uff.names)
        for k in csv.channels:
            np.testing.assert_array_equal(uff[k], csv.channels[k])


def test_updated_structure_gives_the_rig_mode_shape(small_campaign, rig540):
    section = structure_section(rig540, rig540.beam)
    write_manifest(small_campaign, section)
    camp = load_campaign(small_campaign.folder)
    st = Structure.from_mapping(camp.structure)
    np.testing.assert_allclose(st.phi_sensors[:, 0], rig540.model.sensor_shapes[:, 0], rtol=1e-6)
    assert st.phi_force[0] == pytest.approx(rig540.model.force_shape[0], rel=1e-6)


def test_identify_campaign_reads_the_rig_campaign(small_campaign, rig540):
    from jointid.app.workflow import identify_campaign

    write_manifest(small_campaign, structure_section(rig540, rig540.beam))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = identify_campaign(small_campaign.folder)
    assert not res.failed
    g = res.groups[0]
    assert g.pooled.omega1 / (2 * np.pi) == pytest.approx(rig540.linear_frequencies_hz[0], rel=2e-3)


def test_parabolic_peak():
    x = np.linspace(0, 1, 11)
    y = 2 - (x - 0.537) ** 2
    xp, yp = parabolic_peak(x, y)
    assert xp == pytest.approx(0.537, abs=1e-12) and yp == pytest.approx(2.0, abs=1e-12)


def test_invalid_rig_inputs(rig120):
    law = JointLaw(IwanParameters(1.0, 1000.0, -0.5, 0.5))
    with pytest.raises(StructureError):
        VirtualRig(120.0, rig120.beam, {"shear": law})
    with pytest.raises(StructureError):
        VirtualRig(120.0, rig120.beam, {})
    with pytest.raises(StructureError):
        Acquisition(fs=-1.0)
    with pytest.raises(StructureError):
        Acquisition(distortion=((1, 0.1, 0.0),))
    with pytest.raises(StructureError):
        seed_rig(300)
    with pytest.raises(StructureError):
        integrate(rig120.model, [160.0], [[0, 0, 1.0]], 0.01, dt=1e-3)  # above the stability limit
    with pytest.raises(StructureError):
        MeasurementPlan(manifest_format="csv", formats=("uff",))


@pytest.mark.slow
def test_harmonic_balance_matches_time_integration_from_rest(rig120):
    """The steady state the rig records is the one a long time integration from rest reaches."""
    acq = Acquisition(force_noise=0.0, accel_noise=0.0, duration=0.5)
    freqs = [26.25, 26.32]
    hb = rig120.stepped_sine(freqs, 6.0, acq, rng=0)
    ti = rig120.stepped_sine(freqs, 6.0, Acquisition(force_noise=0.0, accel_noise=0.0, duration=0.5, settle_tol=2e-4),
                             rng=0, method="time", chunk=2.0, max_time=60.0)
    assert all(d.settled for d in hb + ti)
    for a, b in zip(hb, ti):
        w = 2 * np.pi * a.frequency_hz
        t = np.arange(a.record.n_samples) / acq.fs
        A = np.column_stack([np.cos(w * t), np.sin(w * t)])
        ca = np.linalg.lstsq(A, a.record["accel_42"], rcond=None)[0]
        cb = np.linalg.lstsq(A, b.record["accel_42"], rcond=None)[0]
        assert np.hypot(*cb) == pytest.approx(np.hypot(*ca), rel=2e-3)


def _uncondensed_backbone(model, amplitudes, H, n_time, tol=1e-13):
    """Reference EPMC of mode 1 with every modal harmonic an unknown (no condensation), Newton by
    least squares with a finite-difference Jacobian in ``w`` and ``xi``; the joint force by the AFT."""
    nm, n = model.n_modes, 2 * H + 1
    k = np.repeat(np.arange(H + 1), 2)[1:]  # harmonic of each coefficient [0, 1, 1, 2, 2, ...]
    Psi = model.joint_shapes

    def residual(Y, w, xi, jac):
        F, JF = model.joint_aft(Psi @ Y, n_time, jacobian=jac)
        d = (2 * model.zeta * model.omega - xi)[:, None]
        R = Psi.T @ F + (model.omega[:, None] ** 2 - (k * w) ** 2) * Y
        R[:, 1::2] += d * k[1::2] * w * Y[:, 2::2]
        R[:, 2::2] -= d * k[2::2] * w * Y[:, 1::2]
        if not jac:
            return R
        G = np.einsum("jm,jakb,kl->malb", Psi, JF.reshape(Psi.shape[0], n, Psi.shape[0], n), Psi)
        for i in range(nm):
            G[i, :, i, :] += np.diag(model.omega[i] ** 2 - (k * w) ** 2)
            G[i, 1::2, i, 2::2] += np.diag(d[i, 0] * k[1::2] * w)
            G[i, 2::2, i, 1::2] -= np.diag(d[i, 0] * k[2::2] * w)
        h = 1e-7 * w
        dw = (residual(Y, w + h, xi, False) - residual(Y, w - h, xi, False)) / (2 * h)
        dxi = (residual(Y, w, xi + h, False) - residual(Y, w, xi - h, False)) / (2 * h)
        return R, np.column_stack([G.reshape(nm * n, nm * n), dw.ravel(), dxi.ravel()])

    free = np.ones(nm * n + 2, bool)
    free[[1, 2]] = False  # eta_1 = a cos(w t) + higher harmonics
    Y, w, xi = np.zeros((nm, n)), float(model.omega[0]), float(2 * model.zeta[0] * model.omega[0])
    out = []
    for a in amplitudes:
        Y[0, 1], Y[0, 2] = a, 0.0
        for _ in range(40):
            R, J = residual(Y, w, xi, True)
            if np.linalg.norm(R) < tol * model.omega[0] ** 2 * a:
                break
            x = np.concatenate([Y.ravel(), [w, xi]])
            x[free] += np.linalg.lstsq(J[:, free], -R.ravel(), rcond=None)[0]
            Y, w, xi = x[:-2].reshape(nm, n), x[-2], x[-1]
        else:
            raise AssertionError(f"reference backbone did not converge at {a}")
        out.append((w, xi / (2 * w)))
    return np.array(out).T


def test_backbone_against_an_uncondensed_reference(rig120):
    """The rig's backbone (the engine's condensed EPMC) against the same nonlinear modes solved with
    all modal harmonics as unknowns: the condensation is exact, so they agree to the solvers'
    tolerance (measured 1.8e-14 in frequency, 1.1e-11 in damping ratio at tol 1e-13); the joint softens
    mode 1 and damps it more as the amplitude grows."""
    amps = np.geomspace(1e-5, 1e-2, 5)
    bb = rig120.backbone(amps, n_harmonics=5, n_time=64, tol=1e-13)
    w, zeta = _uncondensed_backbone(rig120.model, amps, 5, 64)
    np.testing.assert_allclose(bb.omega, w, rtol=1e-12)
    np.testing.assert_allclose(bb.zeta, zeta, rtol=1e-9)
    assert bb.frequency_hz[0] - bb.frequency_hz[-1] > 0.1 and bb.zeta[-1] > 1.5 * bb.zeta[0]
