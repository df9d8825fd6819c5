"""Windows of trajectories started from their recorded states (multiple shooting), on a small model."""

from __future__ import annotations

import numpy as np
import pytest

from o2m.mj.simulate import rollout
from o2m.paper.fitting import TrajectoryObjective, parameter_space
from o2m.paper.windows import fit_levenberg_marquardt, window_residuals, window_starts, window_states
from tests.paper.test_fitting import _setup, pendulum


def test_window_starts_are_back_to_back_and_fit():
    assert window_starts(500, 100).tolist() == [0, 100, 200, 300, 400]
    assert window_starts(10, 4, stride=3).tolist() == [0, 3, 6]
    with pytest.raises(ValueError):
        window_starts(10, 11)


def _recorded(true_damping: float):
    """A model's own rollouts, recorded as OpenSim's are: coordinate, speed, activation per sample."""
    truth = pendulum(true_damping)
    _, init, ctrl, _ = _setup(true_damping, true_damping)
    tr = rollout(truth, init, ctrl, joint_names=["swing"])
    return init, ctrl, tr


def test_windows_of_a_models_own_rollouts_replay_them_and_score_another_damping():
    init, ctrl, tr = _recorded(0.3)
    w = window_states(pendulum(0.3), tr.coordinates, tr.qvel[..., :1], ["swing"], tr.act, ["lifter"], ctrl,
                      tr.coordinates, 50, settle=0)
    assert len(w.sets) == 4 * 5 and w.reference.shape == (20, 50, 1) and w.controls.shape == (20, 49, 1)
    first = w.init[(w.sets == 2) & (w.starts == 0)][0]
    assert np.allclose(first, init[2])  # the follower joint and its speed from the equality, as at the start
    errors = {}
    for damping in (0.3, 3.0):
        model = pendulum(damping)
        space = parameter_space(model, ["swing"], ["lifter"])
        objective = TrajectoryObjective(model, space, w.init, w.controls, w.reference, ["swing"])
        errors[damping] = objective(space.x0[None])[0]
    assert errors[0.3] < 1e-4 * errors[3.0]


def test_residuals_sum_to_the_objective_and_levenberg_marquardt_recovers_a_damping():
    init, ctrl, tr = _recorded(0.3)
    model = pendulum(1.0)
    w = window_states(model, tr.coordinates, tr.qvel[..., :1], ["swing"], tr.act, ["lifter"], ctrl, tr.coordinates, 50)
    space = parameter_space(model, ["swing"], ["lifter"])
    objective = TrajectoryObjective(model, space, w.init, w.controls, w.reference, ["swing"], penalty=0.0)
    r = window_residuals(objective, space.x0[None], every=1)[0]
    assert r @ r == pytest.approx(objective(space.x0[None])[0], rel=1e-9)
    full = TrajectoryObjective(model, space, init[:2], ctrl[:2], tr.coordinates[:2], ["swing"], penalty=0.0)
    fit = fit_levenberg_marquardt(objective, validation=full, iterations=6, progress=False)
    assert fit.validation_cost < 0.01 * fit.validation_cost0 and fit.cost < 0.01 * fit.cost0
    assert space.values(fit.x)["damping:swing"] == pytest.approx(0.3, rel=0.05)


def test_a_run_up_gives_the_driven_joint_the_lag_it_has_in_a_rollout():
    init, ctrl, tr = _recorded(0.3)
    args = (pendulum(0.3), tr.coordinates, tr.qvel[..., :1], ["swing"], tr.act, ["lifter"], ctrl, tr.coordinates, 50)
    gaps = {}
    for settle in (0, 50):  # the pendulum's equality has MuJoCo's default time constant, 10 steps
        w = window_states(*args, settle=settle)
        later = w.starts > 0
        own = tr.states[w.sets[later], w.starts[later]]  # the rollout's own states there
        gaps[settle] = np.abs(w.init[later] - own).max()
        assert np.allclose(w.init[~later], init[w.sets[~later]])  # the first window: the recorded start
    assert gaps[50] < 0.2 * gaps[0]
