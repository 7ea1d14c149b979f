"""The single-point and batched paths of the harmonic balance agree to rounding.

``_Problem.evaluate``/``newton``/``peak`` and ``evaluate_batch``/``newton_batch``/
``peak_batch`` are deliberate twins: one point through the batched path costs about twice
the single-point path (which the sweep's lone points and the continuation call thousands of
times), so they stay two functions and this test keeps them equal.
"""

import numpy as np
import pytest

from jointid.simulate import hbm
from jointid.simulate.model import SingleModeModel, seed_model

MODELS = {
    "seed, c(q_max) closure": seed_model(),
    "hardening Duffing": SingleModeModel("q + -q^3 + q'", (170.0**2, 5e6, 0.5)),
    "quadratic, even harmonics": SingleModeModel("q + q^2 + q'", (170.0**2, 2e4, 0.8)),
    "cubic damping": SingleModeModel("q + -q^3 + q' + q'^3", (170.0**2, 5e6, 0.5, 20.0)),
}


def _states(model, rng, omegas=(160.0, 168.0, 172.0, 180.0), spread=0.05):
    """Unknown vectors near the steady states at ``omegas`` (perturbed: residuals not zero)."""
    p = hbm._Problem(model, 1.0, 9)
    Z, W = [], []
    for w in omegas:
        s = hbm.steady_state(model, w, 1.0)
        z = p.reduce(s.coefficients)
        if p.closure:
            z = np.append(z, s.q_max)
        z = z * (1.0 + spread * rng.standard_normal(z.size))
        Z.append(z)
        W.append(w)
    return p, np.array(Z), np.array(W)


@pytest.mark.parametrize("name", sorted(MODELS))
def test_evaluate_and_jacobian_twins_agree(name):
    p, Z, W = _states(MODELS[name], np.random.default_rng(1))
    ev = p.evaluate_batch(Z, W, jacobian=True)
    for k, (z, w) in enumerate(zip(Z, W)):
        one = p.evaluate(z, w, jacobian=True)
        scale = max(abs(p.F), (w * w + p.kq) * np.linalg.norm(z[: p.active.size]))
        assert np.max(np.abs(one["R"] - ev["R"][k])) <= 1e-13 * scale
        assert one["err"] == pytest.approx(ev["err"][k], rel=1e-10)
        assert np.max(np.abs(one["J"] - ev["J"][k])) <= 1e-13 * np.max(np.abs(one["J"]))
        if p.closure:
            assert one["peak"][0] == pytest.approx(ev["peak"][0][k], rel=1e-14, abs=0)


@pytest.mark.parametrize("name", sorted(MODELS))
def test_newton_twins_reach_the_same_state(name):
    p, Z, W = _states(MODELS[name], np.random.default_rng(2), spread=1e-3)
    Zb, err, _, converged, _ = p.newton_batch(Z, W, tol=1e-12, max_iter=8)
    assert converged.all() and (err <= 1e-12).all()
    for k, (z, w) in enumerate(zip(Z, W)):
        zs, ev, _ = p.newton(z, w, tol=1e-12)
        assert ev["err"] <= 1e-12
        assert np.max(np.abs(zs - Zb[k])) <= 1e-10 * np.max(np.abs(zs))


@pytest.mark.parametrize("name", ["seed, c(q_max) closure", "quadratic, even harmonics"])
def test_peak_twins_agree(name):
    """Same value; each phase and sign a maximiser (odd series peak twice, with both signs)."""
    p = hbm._Problem(MODELS[name], 1.0, 9)
    rng = np.random.default_rng(3)
    X = rng.standard_normal((30, p.active.size)) * 1e-3
    vals, taus, signs = p.peak_batch(X)

    def q(x, tau):
        return float((hbm._basis_at(np.atleast_1d(tau), p.H)[:, p.active] @ x)[0])

    for k, x in enumerate(X):
        v, tau, sign = p.peak(x)
        assert v == pytest.approx(vals[k], rel=1e-14, abs=0)
        assert sign * q(x, tau) == pytest.approx(v, rel=1e-13, abs=0)
        assert signs[k] * q(x, taus[k]) == pytest.approx(v, rel=1e-13, abs=0)
