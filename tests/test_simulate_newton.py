"""The damped Newton loop shared by both harmonic-balance engines (joint-condensed, its nonlinear modes,
single-mode) and its named policies."""

import numpy as np
import pytest

from jointid.simulate.newton import damped_newton


def _sqrt2(x):
    R = np.array([x[0] ** 2 - 2.0, x[1] - 3.0 * x[0]])
    J = np.array([[2.0 * x[0], 0.0], [-3.0, 1.0]])
    return R, J, float(np.linalg.norm(R)), {"x": x.copy()}


def test_converges_to_the_known_root_and_counts_iterations():
    out = damped_newton(np.array([1.0, 0.0]), _sqrt2, 1e-14, 40)
    assert out.converged and out.reason == ""
    np.testing.assert_allclose(out.x, [np.sqrt(2.0), 3.0 * np.sqrt(2.0)], rtol=1e-15)
    assert 3 <= out.iterations <= 8 and out.error < 1e-14
    assert out.state["x"] is not out.x and np.array_equal(out.state["x"], out.x)


def test_iteration_limit_and_singular_jacobian_are_reported_not_raised():
    out = damped_newton(np.array([1.0, 0.0]), _sqrt2, 1e-14, 1)
    assert not out.converged and out.iterations == 1 and out.reason == "iteration limit reached"

    def flat(x):
        return np.array([1.0]), np.zeros((1, 1)), 1.0, None

    out = damped_newton(np.array([0.0]), flat, 1e-12, 10)
    assert not out.converged and out.reason == "singular Jacobian"


def test_inadmissible_points_are_not_evaluated():
    """Root of x^2 - 4 from x = 1 with x kept below 1.5: the full step (to 2.5) and its halves
    beyond 1.5 are never evaluated; the loop ends with no admissible step."""
    seen = []

    def f(x):
        seen.append(float(x[0]))
        return np.array([x[0] ** 2 - 4.0]), np.array([[2.0 * x[0]]]), abs(x[0] ** 2 - 4.0), None

    out = damped_newton(np.array([1.0]), f, 1e-12, 40, admissible=lambda x: x[0] < 1.5)
    assert max(seen) < 1.5 and not out.converged
    free = damped_newton(np.array([1.0]), f, 1e-12, 40)
    assert free.converged and abs(free.x[0] - 2.0) < 1e-12


def _wrong_sign(calls):
    """R = x with a Jacobian of the wrong sign: every step moves away from the root, so no
    halving decreases |R| (or the error)."""

    def f(x):
        calls.append(float(x[0]))
        return np.array([x[0]]), np.array([[-1.0]]), abs(x[0]), None

    return f


def test_stall_policy_fail_stops_after_the_last_halving():
    calls = []
    out = damped_newton(np.array([1.0]), _wrong_sign(calls), 1e-12, 40, on_stall="fail", halvings=11)
    assert not out.converged and out.reason == "no decrease of the residual along the Newton step"
    assert out.iterations == 1 and out.x[0] == 1.0
    # start, then the trials 1 + 2**-k for k = 0..11
    assert calls == [1.0] + [1.0 + 2.0**-k for k in range(12)]


def test_stall_policy_step_takes_the_shortest_step_anyway():
    calls = []
    out = damped_newton(np.array([1.0]), _wrong_sign(calls), 1e-12, 3, on_stall="step", halvings=10)
    assert not out.converged and out.reason == "iteration limit reached" and out.iterations == 3
    assert len(calls) == 1 + 3 * 11
    assert out.x[0] == (1.0 + 2.0**-10) ** 3 and out.error == out.x[0]


def test_lazy_jacobian_is_built_for_accepted_points_only_and_merit_chooses_them():
    """x^2 - 4 from x = 0.5: the full step lands at 4.25, where |R| grows (14.06 > 3.75) but the
    relative error |R| / x^2 falls (0.78 < 15): the error merit accepts it, the residual merit
    halves to 2.375. The Jacobian is built once per iteration, at the accepted points."""
    for merit, first in (("error", 4.25), ("residual", 2.375)):
        evaluated, built = [], []

        def f(x):
            evaluated.append(float(x[0]))
            R = x[0] ** 2 - 4.0
            return np.array([R]), None, abs(R) / x[0] ** 2, float(x[0])

        def jac(state):
            built.append(state)
            return np.array([[2.0 * state]])

        out = damped_newton(np.array([0.5]), f, 1e-14, 40, jacobian=jac, merit=merit)
        assert out.converged and abs(out.x[0] - 2.0) < 1e-14
        assert built[0] == 0.5 and built[1] == first
        assert len(built) == out.iterations and len(evaluated) > out.iterations
        assert out.state not in built  # the converged point needs no Jacobian


def test_unknown_policy_names_are_refused():
    with pytest.raises(ValueError, match="on_stall"):
        damped_newton(np.array([1.0, 0.0]), _sqrt2, 1e-14, 40, on_stall="retry")
    with pytest.raises(ValueError, match="merit"):
        damped_newton(np.array([1.0, 0.0]), _sqrt2, 1e-14, 40, merit="norm")


def test_single_mode_newton_runs_on_the_shared_loop_with_its_policy():
    """hbm's _Problem.newton: Jacobian built once per iteration (lazily), a converged state
    within tol; stopped by the iteration limit it raises ConvergenceError."""
    from jointid.errors import ConvergenceError
    from jointid.simulate import hbm
    from jointid.simulate.model import SingleModeModel

    m = SingleModeModel("q + -q^3 + q'", (170.0**2, 5e6, 0.5))
    p = hbm._Problem(m, 1.0, 9)
    s = hbm.steady_state(m, 168.0, 1.0)
    z0 = p.reduce(s.coefficients) * 1.05
    built = []
    jacobian = p.jacobian
    p.jacobian = lambda ev, domega=False: built.append(1) or jacobian(ev, domega)
    z, ev, it = p.newton(z0, 168.0, tol=1e-12)
    assert ev["err"] <= 1e-12 and it >= 1 and len(built) == it
    assert np.max(np.abs(z - p.reduce(s.coefficients))) <= 1e-8 * np.max(np.abs(z))
    with pytest.raises(ConvergenceError, match="did not converge at omega=168"):
        p.newton(z0, 168.0, tol=1e-12, max_iter=1)
