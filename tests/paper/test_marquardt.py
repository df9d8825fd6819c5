"""The shared Levenberg-Marquardt step."""

from __future__ import annotations

import numpy as np

from o2m.paper.marquardt import damped_steps


def test_undamped_step_solves_a_linear_least_squares_problem_and_damping_shortens_it():
    rng = np.random.default_rng(0)
    a = rng.normal(size=(20, 4))
    truth = np.array([0.3, -0.2, 0.1, 0.05])
    b = a @ truth
    x = np.zeros(4)
    steps = damped_steps(a, a @ x - b, x, [1e-12, 1.0, 100.0], -1.0, 1.0)
    np.testing.assert_allclose(steps[0], truth, atol=1e-9)
    lengths = np.linalg.norm(steps - x, axis=1)
    assert lengths[0] > lengths[1] > lengths[2] > 0


def test_steps_stay_inside_the_bounds():
    a = np.eye(2)
    steps = damped_steps(a, np.array([-5.0, 5.0]), np.zeros(2), [1e-9], np.array([-1.0, 0.0]), np.array([1.0, 2.0]))
    np.testing.assert_array_equal(steps[0], [1.0, 0.0])
