"""Virtual rig, both preloads, 1 % noise: backbones from stepped sine and ring-downs vs the rig's exact one.

The exact backbone is the damped nonlinear mode of the rig's reduced model with its Iwan
joint (:meth:`VirtualRig.backbone`).  Slow: the ring-downs are integrated in time.
"""

import numpy as np
import pytest

from jointid.identify.backbone import equivalent_linearisation, phase_resonance_points
from jointid.rig import Acquisition, seed_rig
from jointid.signal.harmonics import steady_state_signals
from jointid.signal.ringdown import fit_decay

pytestmark = pytest.mark.slow

STEP_LEVELS = (0.12, 0.5, 2.0, 6.0)  # N: 1.5 decades of amplitude
RELEASE_LEVELS = (0.1, 0.4, 1.5, 6.0)
QUIET = Acquisition(force_noise=0.0, accel_noise=0.0)


def _project(rig, rec):
    """Modal force and acceleration of mode 1 (least squares on the two accelerometers)."""
    ph = rig.model.sensor_shapes[:, 0]
    A = np.vstack([rec.data[n] for n in rig.model.sensor_names])
    return rig.model.force_shape[0] * rec.data["force"], ph @ A / (ph @ ph)


def _noisy(x, rng, scale=None):
    return x + 0.01 * (np.std(x) if scale is None else scale) * rng.standard_normal(x.size)


@pytest.fixture(scope="module", params=[120, 540])
def rig_data(request):
    rig = seed_rig(request.param)
    rng = np.random.default_rng(request.param)
    signals, levels = [], []
    for F in STEP_LEVELS:
        fr = rig.phase_resonance(F).frequency_hz * (1 + 1.8e-3 * np.linspace(-1.5, 1.5, 7))
        for d in rig.stepped_sine(fr, F, QUIET, settle=False):
            Q, qdd = _project(rig, d.record)
            signals.append(steady_state_signals(d.record.time, _noisy(Q, rng), _noisy(qdd, rng),
                                                frequency_hz=d.frequency_hz))
            levels.append(F)
    stepped = equivalent_linearisation(signals, force_level=levels, label=f"{rig.preload:g} N")
    decays = []
    for rec, s in rig.ringdown(RELEASE_LEVELS, 4.0, QUIET, rng):
        ph = rig.model.sensor_shapes[:, 0]
        a0 = rig.model.sensor_shapes @ s.modal_at(np.linspace(0, 2 * np.pi / s.omega, 64, endpoint=False), 2)
        A = np.vstack([_noisy(rec.data[name], rng, np.sqrt(np.mean(a0[j] ** 2)))  # 1 % of the RMS at the release
                       for j, name in enumerate(rig.model.sensor_names)])
        decays.append(fit_decay(rec.time, ph @ A / (ph @ ph)))
    return rig, stepped, decays


def _check(rig, b, zeta_tol=0.03):
    exact = rig.backbone(b.amplitude)
    dw = np.abs(b.omega / exact.omega - 1)
    dz = np.abs(b.zeta / exact.zeta - 1)
    assert dw.max() < 5e-4, dw.max()
    assert dz.max() < zeta_tol, dz.max()
    return dw.max(), dz.max()


def test_stepped_sine_backbone(rig_data):
    rig, stepped, _ = rig_data
    assert stepped.decades() >= 1.5
    _check(rig, stepped)
    res = phase_resonance_points(stepped)
    assert len(res) == len(STEP_LEVELS)
    _check(rig, res)


def test_ringdown_backbone(rig_data):
    rig, _, decays = rig_data
    from jointid.identify.backbone import Backbone

    parts = [d.backbone() for d in decays]
    amp = np.concatenate([p.amplitude for p in parts])
    assert np.log10(amp.max() / amp.min()) >= 1.5
    for p in parts:
        _check(rig, p)
    assert all(isinstance(p, Backbone) for p in parts)


def _law_check(rig, backbone):
    from jointid.identify.jointlaw import JointModes, fit_cubic_viscous, fit_iwan

    m = rig.model
    law = m.laws[0]
    modes = JointModes(m.omega, m.zeta, m.joint_shapes[0])
    fit = fit_iwan(backbone, modes, K_T=law.linear_stiffness)
    true = law.iwan
    # determined by a micro-slip test: the stuck frequency (joint stiffness through the FE
    # model), the structural damping, chi and the micro-slip dissipation at u_ref
    assert abs(fit.get("chi") - true.chi) < 0.05
    assert abs(fit.get("D_ref") / true.dissipation(fit.u_ref) - 1) < 0.05
    assert abs(fit.get("zeta_0") / m.zeta[0] - 1) < 0.05
    assert abs(fit.get("Omega") / m.omega[0] - 1) < 5e-4
    print(f"\n{rig.preload:g} N, {backbone.source}: chi {fit.get('chi'):.4f} ± {fit.get_stderr('chi'):.2g}, "
          f"D_ref {fit.get('D_ref') / true.dissipation(fit.u_ref) - 1:+.2%}, R {fit.get('R') / true.R - 1:+.2%} "
          f"(± {fit.get_stderr('R') / true.R:.1%}), k3 {fit.get('k3') / law.k3 - 1:+.2%}, "
          f"zeta_0 {fit.get('zeta_0') / m.zeta[0] - 1:+.2%}, Omega {fit.get('Omega') / m.omega[0] - 1:+.1e}, "
          f"chi2_red {fit.adequacy['chi2_red']:.3g}")
    alt = fit_cubic_viscous(backbone, modes)
    assert fit.adequacy["aic"] < alt.adequacy["aic"]  # the Iwan law explains the backbone better
    return fit


def test_joint_law_from_stepped_sine(rig_data):
    rig, stepped, _ = rig_data
    _law_check(rig, stepped)


def test_joint_law_from_ringdowns(rig_data):
    rig, _, decays = rig_data
    from jointid.identify.backbone import Backbone

    parts = [d.backbone() for d in decays]
    cat = Backbone(*(np.concatenate([getattr(p, k) for p in parts]) for k in
                     ("amplitude", "omega", "zeta", "omega_stderr", "zeta_stderr")), "ringdown")
    _law_check(rig, cat)
