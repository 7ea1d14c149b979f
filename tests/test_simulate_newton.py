"""The damped Newton loop shared by the joint-condensed harmonic balance and its nonlinear modes."""

import numpy as np

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
