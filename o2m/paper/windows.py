"""Short windows of OpenSim trajectories, each started from OpenSim's recorded state (multiple shooting).

A 1-s open-loop rollout of MoBL-ARMS amplifies any force difference (docs/paper.md, the floor:
1 % of force moves the joints 0.017 rad), so the full-horizon objective of :mod:`o2m.paper.fitting`
is dominated by a few sets whose trajectories diverge chaotically, and CMA-ES finds nothing
better than the force-fitted start. Here each training trajectory is cut into windows of
``length`` samples; each window starts from OpenSim's recorded state at its first sample
(coordinates, the coupled and carrier joints their equalities give, speeds) and MuJoCo's own
activation there (the excitations integrated by the model's activation dynamics, which the
candidates do not change), and is compared with OpenSim over the window only. The windows are laid
out as trajectories, so :class:`o2m.paper.fitting.TrajectoryObjective` scores them unchanged.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from o2m.mj.posing import joint_equality_plan
from o2m.mj.simulate import STATE_SPEC, initial_state, muscle_activations
from o2m.paper.marquardt import damped_steps

__all__ = ["SETTLE", "HeldJoints", "Windows", "window_objective", "window_starts", "window_states", "windows"]


SETTLE = 10
"""Steps (2 ms) of run-up before a window. Placed exactly on their equalities, MoBL-ARMS's path
carriers lose the lag that transmits part of their tendons' forces in a rollout: at a rebuilt
MuJoCo state pro_sup's acceleration moved by 600 rad/s² on average (RMS 1200, against OpenSim's
RMS 81) and a 0.1-s window ended 0.02 rad off. 10 steps is mid-transient for the biceps' carrier:
on MuJoCo's own rollouts the biceps' velocity is 0.052 m/s RMS off the rollout's after 10 steps,
0.002 after 50 (docs/paper.md, where pro_sup's error comes from); the stored window fits used 10."""


@dataclass
class Windows:
    """Windows of reference trajectories laid out as trajectories of their own.

    Attributes:
        sets, starts: the set and the first sample of each window, shape (W,) each.
        init: MuJoCo state at each window's start, shape (W, nstate).
        controls: shape (W, length - 1, nu); reference: OpenSim's free DoFs, (W, length, n_dofs), rad.
    """

    sets: np.ndarray
    starts: np.ndarray
    init: np.ndarray
    controls: np.ndarray
    reference: np.ndarray


def window_starts(n_samples: int, length: int, stride: int | None = None) -> np.ndarray:
    """First samples of windows of ``length`` samples every ``stride`` samples (default ``length``:
    back to back) that fit in ``n_samples``."""
    if length < 2 or length > n_samples:
        raise ValueError(f"a window needs 2 to {n_samples} samples, not {length}")
    return np.arange(0, n_samples - length + 1, stride or length)


def windows(exp, model: mujoco.MjModel, sets: Sequence[int], length: int, *, stride: int | None = None,
            settle: int = SETTLE) -> Windows:
    """Windows of ``length`` samples (2 ms apart) of the experiment's ``sets`` for ``model``
    (an :class:`o2m.paper.pipeline.Experiment`; ``model`` gives the activation dynamics)."""
    ds = exp.dataset
    sets = list(sets)
    cols = [list(ds.activations.muscles).index(n) for n in exp.muscles]
    first = ds.opensim_activations[sets][:, 0][:, [ds.muscle_names.index(m) for m in exp.muscles]]
    activations = muscle_activations(model, exp.muscles, ds.activations.values[sets][..., cols], first)
    w = window_states(model, ds.coordinates[sets], ds.speeds[sets], ds.coordinate_names, activations, exp.muscles,
                      exp.controls[sets], exp.reference[sets], length, stride=stride, times=ds.times,
                      settle=settle)
    w.sets = np.asarray(sets)[w.sets]
    return w


def window_states(model: mujoco.MjModel, coordinates: np.ndarray, speeds: np.ndarray, coordinate_names: Sequence[str],
                  activations: np.ndarray, muscles: Sequence[str], controls: np.ndarray, reference: np.ndarray,
                  length: int, *, stride: int | None = None, times: np.ndarray | None = None,
                  settle: int = SETTLE) -> Windows:
    """Windows of ``length`` samples of B trajectories, each started from the trajectory's state.

    A window starting at sample k > 0 starts ``settle`` steps earlier from the recorded state
    there and is stepped up to k with the independent joints (those no joint equality drives)
    held on the recording, so that the equality-driven joints (couplings, path carriers) carry
    the lag MuJoCo's soft equalities give them in a rollout (see :data:`SETTLE`).

    Args:
        coordinates, speeds: recorded coordinate values and speeds, (B, T, n_coordinates), rad or m
            (per second); named ``coordinate_names`` (equality-driven joints follow their equalities).
        activations: the ``muscles``' activations at every sample, (B, T, M).
        controls: MuJoCo controls of every step, (B, T - 1, nu); reference: compared joints, (B, T, n_dofs).
        times: sample times (s), (T,) (default: the model's timestep apart).
        settle: steps of that run-up (0: the driven joints exactly on their equalities).
    Returns:
        :class:`Windows`, ``sets`` indexing the B trajectories.
    """
    n_sets, n_samples = coordinates.shape[:2]
    times = np.arange(n_samples) * model.opt.timestep if times is None else times
    starts = window_starts(n_samples, length, stride)
    plan = joint_equality_plan(model)
    drive = HeldJoints(model, coordinate_names)
    rows = []
    for b in range(n_sets):
        for k in starts:
            k0 = max(0, k - settle)
            state = initial_state(model, dict(zip(coordinate_names, coordinates[b, k0], strict=True)),
                                  speeds=dict(zip(coordinate_names, speeds[b, k0], strict=True)),
                                  activations=dict(zip(muscles, activations[b, k0], strict=True)),
                                  time=float(times[k0]), plan=plan)
            if k > k0:
                state = drive.settle(state, coordinates[b, k0 + 1:k + 1], speeds[b, k0 + 1:k + 1], controls[b, k0:k],
                                     dict(zip(muscles, activations[b, k], strict=True)))
            rows.append((b, k, state, controls[b, k:k + length - 1], reference[b, k:k + length]))
    return Windows(np.array([r[0] for r in rows]), np.array([r[1] for r in rows]), np.stack([r[2] for r in rows]),
                   np.stack([r[3] for r in rows]), np.stack([r[4] for r in rows]))


class HeldJoints:
    """Steps a model with its independent joints held on a recorded trajectory (the other joints free)."""

    def __init__(self, model: mujoco.MjModel, coordinate_names: Sequence[str]):
        from o2m.paper.fitting import free_coordinates

        self.model, self.data = model, mujoco.MjData(model)
        held = free_coordinates(model, coordinate_names)
        self.columns = [list(coordinate_names).index(n) for n in held]
        self.qpos = [int(model.joint(n).qposadr[0]) for n in held]
        self.qvel = [int(model.joint(n).dofadr[0]) for n in held]

    def settle(self, state: np.ndarray, coordinates: np.ndarray, speeds: np.ndarray, controls: np.ndarray,
               activations: dict[str, float]) -> np.ndarray:
        """``state`` stepped with ``controls`` (n, nu), the held joints set to ``coordinates`` and
        ``speeds`` (n, n_coordinates) after each step; then the muscles' ``activations`` set."""
        m, d = self.model, self.data
        mujoco.mj_setState(m, d, state, STATE_SPEC)
        for q, v, u in zip(coordinates, speeds, controls, strict=True):
            d.ctrl[:] = u
            mujoco.mj_step(m, d)
            d.qpos[self.qpos], d.qvel[self.qvel] = q[self.columns], v[self.columns]
        for name, a in activations.items():
            d.act[m.actuator_actadr[m.actuator(name).id]] = a
        out = np.empty_like(state)
        mujoco.mj_getState(m, d, out, STATE_SPEC)
        return out


def window_objective(exp, model: mujoco.MjModel, space, sets: Sequence[int], length: int, *,
                     stride: int | None = None, settle: int = SETTLE, penalty: float | None = None, executor=None):
    """:class:`o2m.paper.fitting.TrajectoryObjective` of ``space`` over the :func:`windows` of ``sets``
    (squared joint error averaged over each window's samples, summed over DoFs and windows, rad²)."""
    from o2m.paper.fitting import PENALTY, TrajectoryObjective

    w = windows(exp, model, sets, length, stride=stride, settle=settle)
    return TrajectoryObjective(model, space, w.init, w.controls, w.reference, exp.dofs,
                               penalty=PENALTY if penalty is None else penalty, executor=executor)


def window_residuals(objective, xs: np.ndarray, *, every: int = 5, chunk: int = 4) -> np.ndarray:
    """Joint errors of candidates ``xs`` (P, n) as least-squares residuals, shape (P, R), rad.

    Every ``every``-th sample of every trajectory of ``objective`` (a
    :class:`o2m.paper.fitting.TrajectoryObjective`), scaled so that the sum of squares is the
    objective's joint term (the squared error averaged over samples, summed over DoFs and
    trajectories), then ``sqrt(penalty)`` times each parameter's log10 change. A diverged
    trajectory's residuals are ``sqrt(DIVERGED_COST)`` each. Candidates run ``chunk`` at a time.
    """
    from o2m.paper.fitting import DIVERGED_COST

    xs = np.atleast_2d(xs)
    ref = objective.reference[:, ::every]
    out = []
    for c in range(0, len(xs), chunk):
        q, diverged = objective.simulate(xs[c:c + chunk])
        with np.errstate(invalid="ignore", over="ignore"):
            r = (q[:, :, ::every] - ref[None]) / np.sqrt(ref.shape[1])
        r[diverged] = np.sqrt(DIVERGED_COST / ref.shape[1])
        r = np.nan_to_num(r, nan=np.sqrt(DIVERGED_COST), posinf=np.sqrt(DIVERGED_COST), neginf=-np.sqrt(DIVERGED_COST))
        out.append(r.reshape(len(r), -1))
    penalty = np.sqrt(objective.penalty) * (xs - objective.space.x0)
    return np.concatenate([np.concatenate(out), penalty], axis=1)


def _jacobian(objective, z: np.ndarray, r0: np.ndarray, step: float, every: int) -> np.ndarray:
    """Forward differences of :func:`window_residuals` in the unit box, (R, n); backward at the upper bound."""
    space = objective.space
    h = np.where(z + step <= 1.0, step, -step)
    zs = z[None] + np.diag(h)
    r = window_residuals(objective, np.array([space.from_unit(v) for v in zs]), every=every)
    return ((r - r0[None]) / h[:, None]).T


def fit_levenberg_marquardt(objective, *, validation=None, iterations: int = 10, step: float = 1e-3,
                            every: int = 5, damping: float = 1e-2, progress: bool = True, settings: dict | None = None,
                            callback=None):
    """Minimise ``objective`` (a :class:`o2m.paper.fitting.TrajectoryObjective`, e.g. :func:`window_objective`)
    by Levenberg-Marquardt in the unit box of its parameter space.

    Each iteration differentiates :func:`window_residuals` by forward differences (``step`` in
    the unit box; one candidate per parameter), then tries four Marquardt dampings (``damping``
    x 0.1, 1, 10, 100 times the Gauss-Newton diagonal) in one batch and moves to the best if it
    lowers the cost. With ``validation`` (the full-horizon objective on held-out sets) every
    accepted point is scored there and the lowest validation cost is returned, the start included
    (early stopping); ``callback(x, cost, validation_cost)`` sees every accepted point. Returns an
    :class:`o2m.paper.fitting.FitResult` (its settings hold the validation cost of every accepted point).
    """
    import time

    from tqdm.auto import tqdm

    from o2m.paper.fitting import FitResult

    space = objective.space
    t0 = time.perf_counter()
    z = space.to_unit(space.x0)
    r = window_residuals(objective, space.x0[None], every=every)[0]
    cost0 = cost = float(r @ r)
    val0 = float(validation(space.x0[None])[0]) if validation is not None else float("nan")
    best = (val0, space.x0.copy(), cost0)
    history, val_history, evaluations = [], [], 1
    for _ in tqdm(range(iterations), desc="Levenberg-Marquardt", unit="it", disable=not progress):
        J = _jacobian(objective, z, r, step, every)
        evaluations += len(z)
        zs = damped_steps(J, r, z, damping * np.array([0.1, 1.0, 10.0, 100.0]), 0.0, 1.0)
        rs = window_residuals(objective, np.array([space.from_unit(v) for v in zs]), every=every)
        evaluations += len(zs)
        costs = np.sum(rs * rs, axis=1)
        k = int(np.argmin(costs))
        if costs[k] >= cost:
            damping *= 1e3
            history.append(cost)
            continue
        z, r, cost = zs[k], rs[k], float(costs[k])
        damping = max(damping * [0.1, 1.0, 10.0, 100.0][k] / 3.0, 1e-6)
        history.append(cost)
        x = space.from_unit(z)
        v = float(validation(x[None])[0]) if validation is not None else -np.inf
        val_history.append(v)
        if callback is not None:
            callback(x, cost, v)
        if v < best[0] or validation is None:
            best = (v, x.copy(), cost)
    x = best[1]
    return FitResult(space.names, x, space.x0.copy(), best[2], cost0, np.array(history), evaluations,
                     time.perf_counter() - t0, dict(settings or {}, method="levenberg-marquardt", step=step,
                                                    every=every, iterations=iterations, penalty=objective.penalty,
                                                    best_training_cost=cost, validation_history=val_history),
                     best[0] if validation is not None else float("nan"), val0)
