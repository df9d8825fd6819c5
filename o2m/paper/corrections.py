"""Corrective controls: small additions to the excitations that make MuJoCo follow OpenSim.

As in Ikkala & Hämäläinen (2020), each muscle's correction is a cubic spline with knots every
0.1 s (10 Hz): here a uniform cubic B-spline, whose coefficient ``j`` only acts on
``[(j - 3) h, (j + 1) h]`` (``h`` the knot spacing), so 13 coefficients per muscle cover 1 s.
The corrected excitation is ``clip(u + correction, 0, 1)``.

The cost of a trajectory's corrections is the paper's: the squared joint error against OpenSim
(averaged over time, summed over DoFs, rad²) plus ``penalty`` (default :data:`PENALTY`) times
the mean squared correction (over time and muscles).

:func:`fit_corrections` minimises it block by block, in time order: coefficient ``j`` of every
muscle (a 50-dimensional block for MoBL-ARMS) is searched while the other blocks stay fixed, each
candidate simulated only from the start of the block's support to ``lookahead`` knots past its
end, from the state the current corrections reach there. Each block is accepted only if it
lowers the trajectory's whole cost, so the result is never worse than no correction. ``sweeps``
passes repeat this over all blocks: a later pass refits each block after the blocks after it have
moved (on MoBL-ARMS, 3 passes cut the remaining error by a third against 1).

A block is searched by CMA-ES (``method="cma"``, the paper's optimiser) or by Levenberg-Marquardt
(``method="lm"``, o2m's addition): the block's window cost is a sum of squares (joint errors and
the penalty), so each iteration takes its Jacobian by forward differences (one simulation per
muscle, all in one batch) and tries a few damped Gauss-Newton steps in another batch, keeping the
best. A block's window is short (0.5 s with the default look-ahead), so the trajectory in it
stays close to linear in the block's corrections.

The search can start from :func:`force_matching_start` (o2m's addition to the paper): the
correction that, along OpenSim's own trajectory, would make every MuJoCo muscle pull with
OpenSim's recorded tendon force (the activation that gives that force, through MuJoCo's
activation dynamics inverted, as a 10 Hz spline). :func:`fit_corrections` starts from whichever
of it and no correction costs less.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np
from scipy.interpolate import BSpline

from o2m.mj.simulate import controls_from_excitations, rollout
from o2m.paper.marquardt import damped_steps

__all__ = ["CorrectionResult", "KNOT_SPACING", "LM_DAMPINGS", "PENALTY", "bspline_basis", "corrected_excitations",
           "fit_corrections", "force_matching_start"]

KNOT_SPACING = 0.1
"""Seconds between spline knots (10 Hz)."""
PENALTY = 0.1
"""Weight of the mean squared correction in the cost (rad² per unit excitation²)."""
LM_DAMPINGS = (1e-4, 1e-3, 1e-2, 1e-1, 1.0)
"""Levenberg-Marquardt dampings tried at each iteration (times the diagonal of JᵀJ), in one batch."""


def bspline_basis(times: np.ndarray, spacing: float = KNOT_SPACING) -> np.ndarray:
    """Uniform cubic B-spline basis on ``times`` (T,), shape (T, n_coef).

    Knots lie every ``spacing`` seconds from ``times[0] - 3 spacing``; ``n_coef`` is
    ``ceil(duration / spacing) + 3``, so every sample sees four basis functions summing to 1.
    """
    times = np.asarray(times, float)
    t0 = times[0]
    n_int = int(np.ceil((times[-1] - t0) / spacing + 1e-9)) or 1
    knots = t0 + spacing * np.arange(-3, n_int + 4)
    n_coef = n_int + 3
    return BSpline.design_matrix(times, knots, 3, extrapolate=False).toarray()[:, :n_coef]


def corrected_excitations(excitations: np.ndarray, basis: np.ndarray, coef: np.ndarray) -> np.ndarray:
    """``clip(excitations + basis @ coef, 0, 1)``: excitations (T, M), basis (T, C), coef (C, M)."""
    return np.clip(excitations + basis @ coef, 0.0, 1.0)


def force_matching_start(model: mujoco.MjModel, excitations: np.ndarray, muscles: Sequence[str],
                         lengths: np.ndarray, velocities: np.ndarray, forces: np.ndarray, *,
                         spacing: float = KNOT_SPACING) -> np.ndarray:
    """Spline coefficients (n_coef, M) of the correction that matches OpenSim's muscle forces.

    Args:
        excitations: reference excitations, shape (T, M), every timestep.
        lengths, velocities: MuJoCo actuator lengths (m) and velocities (m/s) at OpenSim's states
            (:func:`o2m.force_fit.sample_states` with stride 1), shape (T, M), columns as ``muscles``.
        forces: OpenSim's tendon forces (N) at those states, shape (T, M).

    At each sample the activation that makes :func:`o2m.force_fit.pulling_force` equal OpenSim's
    force (clipped to [0, 1]; where activation barely changes the force, the reference
    excitation) is turned into the excitation MuJoCo's muscle dynamics need to follow it,
    ``u = a + tau(a, u) da/dt``; the coefficients are the least-squares spline fit of the
    difference from the reference excitations.
    """
    from o2m.paper.force_fit import pulling_force

    exc = np.asarray(excitations, float)
    n_t, _ = exc.shape
    dt = model.opt.timestep
    need = exc.copy()
    for j, name in enumerate(muscles):
        a_id = model.actuator(name).id
        passive = pulling_force(model, name, lengths[:, j], velocities[:, j], 0.0)
        gain = pulling_force(model, name, lengths[:, j], velocities[:, j], 1.0) - passive
        ok = gain > 1e-3 * model.actuator_gainprm[a_id, 2]
        act = np.clip(np.where(ok, (forces[:, j] - passive) / np.where(ok, gain, 1.0), exc[:, j]), 0.0, 1.0)
        rate = np.diff(act) / dt
        t_act, t_deact = model.actuator_dynprm[a_id, :2]
        tau = np.where(rate > 0, t_act * (0.5 + 1.5 * act[:-1]), t_deact / (0.5 + 1.5 * act[:-1]))
        u = act[:-1] + tau * rate
        need[:, j] = np.clip(np.append(u, u[-1]), 0.0, 1.0)
    times = dt * np.arange(n_t)
    return np.linalg.lstsq(bspline_basis(times, spacing), need - exc, rcond=None)[0]


@dataclass
class CorrectionResult:
    """Corrections for one trajectory.

    Attributes:
        coef: spline coefficients, shape (n_coef, n_muscles).
        excitations: corrected excitations, shape (T, n_muscles).
        correction: ``excitations`` minus the reference excitations, shape (T, n_muscles).
        cost0, cost: the trajectory's cost before and after.
        joint_mae0, joint_mae: mean absolute joint error per DoF before and after, shape (n_dofs,), rad.
        coordinates: the corrected joint trajectory, shape (T, n_dofs).
        evaluations: simulated candidates (each a window of the trajectory).
    """

    coef: np.ndarray
    excitations: np.ndarray
    correction: np.ndarray
    cost0: float
    cost: float
    joint_mae0: np.ndarray
    joint_mae: np.ndarray
    coordinates: np.ndarray
    evaluations: int


def fit_corrections(model: mujoco.MjModel, initial_state: np.ndarray, excitations: np.ndarray,
                    muscles: Sequence[str], reference: np.ndarray, dofs: Sequence[str], *,
                    penalty: float = PENALTY, spacing: float = KNOT_SPACING, method: str = "cma",
                    generations: int = 20, popsize: int | None = None, sigma0: float = 0.05,
                    iterations: int = 6, step: float = 0.01, lookahead: int = 1, sweeps: int = 1,
                    seed: int = 0, nthread: int | None = None, start: np.ndarray | None = None) -> CorrectionResult:
    """Fit corrective excitations for one trajectory (see the module docstring).

    Args:
        model: the (fitted) converted model.
        initial_state: shape (nstate,), :func:`o2m.mujoco_sim.initial_state`.
        excitations: reference excitations, shape (T, len(muscles)), sampled every timestep.
        reference: OpenSim joint values, shape (T, len(dofs)), rad or m.
        method: ``"cma"`` (CMA-ES per block) or ``"lm"`` (Levenberg-Marquardt per block).
        generations, popsize, sigma0: CMA-ES budget per block (sigma0 in excitation units).
        iterations, step: Levenberg-Marquardt iterations per block (it stops earlier when no
            step lowers the window's cost) and forward-difference step (excitation units).
        lookahead: knot intervals simulated past a block's support.
        sweeps: passes over all blocks.
        seed: CMA-ES's seeds (Levenberg-Marquardt is deterministic).
        start: spline coefficients (n_coef, M) to start from (e.g. :func:`force_matching_start`),
            used when they cost less than no correction.
    """
    if method not in ("cma", "lm"):
        raise ValueError(f"method must be 'cma' or 'lm', got {method!r}")
    problem = _Problem(model, initial_state, excitations, muscles, reference, dofs, penalty, spacing, nthread)
    n_t, n_c = problem.basis.shape
    coef = np.zeros((n_c, problem.exc.shape[1]))
    cost0, q0, states = problem.full_cost(coef)
    best_cost = cost0
    if start is not None:
        trial = np.clip(np.asarray(start, float), -1.0, 1.0)
        c, _, st = problem.full_cost(trial)
        if c < best_cost:
            coef, best_cost, states = trial, c, st
    rng = np.random.default_rng(seed)
    dt = model.opt.timestep
    for _ in range(sweeps):
        for j in range(n_c):
            support = np.flatnonzero(problem.basis[:, j] > 0)
            if len(support) == 0:
                continue
            window = (int(support[0]), min(n_t, int(support[-1]) + 1 + int(round(lookahead * spacing / dt))))
            if window[1] - window[0] < 2:
                continue
            if method == "cma":
                x = _search_block_cma(problem, coef, j, window, states[window[0]], generations, popsize, sigma0,
                                      int(rng.integers(1, 2**31 - 1)))
            else:
                x = _search_block_lm(problem, coef, j, window, states[window[0]], iterations, step)
            trial = coef.copy()
            trial[j] = x
            c, _, st = problem.full_cost(trial)
            if c < best_cost:
                coef, best_cost, states = trial, c, st
    _, q, _ = problem.full_cost(coef)
    corrected = corrected_excitations(problem.exc, problem.basis, coef)
    return CorrectionResult(coef, corrected, corrected - problem.exc, cost0, best_cost,
                            np.mean(np.abs(q0 - problem.ref), axis=0), np.mean(np.abs(q - problem.ref), axis=0), q,
                            problem.evaluations)


class _Problem:
    """One trajectory's corrections: its spline basis and simulations (counted in ``evaluations``)."""

    def __init__(self, model, initial_state, excitations, muscles, reference, dofs, penalty, spacing, nthread):
        self.model, self.muscles, self.dofs, self.nthread = model, muscles, dofs, nthread
        self.exc = np.asarray(excitations, float)
        self.ref = np.asarray(reference, float)
        self.initial_state, self.penalty = initial_state, penalty
        times = float(initial_state[0]) + model.opt.timestep * np.arange(len(self.exc))
        self.basis = bspline_basis(times, spacing)
        self.evaluations = 0

    def simulate(self, coefs: np.ndarray, window: tuple[int, int], state0: np.ndarray):
        """Rollout of candidates ``coefs`` (P, C, M) over samples ``window`` (start, stop) from ``state0``."""
        a, b = window
        u = np.clip(self.exc[None, a:b] + np.einsum("tc,pcm->ptm", self.basis[a:b], coefs), 0.0, 1.0)
        self.evaluations += len(coefs)
        return rollout(self.model, state0, controls_from_excitations(self.model, self.muscles, u),
                       joint_names=self.dofs, nthread=self.nthread)

    def full_cost(self, coef: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        """The whole trajectory's cost, its joint values (T, D) and states (T, nstate)."""
        tr = self.simulate(coef[None], (0, len(self.exc)), self.initial_state)
        q = tr.coordinates[0]
        err = 1e3 if tr.diverged[0] else float(np.mean((q - self.ref) ** 2, axis=0).sum())
        return err + self.penalty * float(np.mean((self.basis @ coef) ** 2)), q, tr.states[0]

    def block_residuals(self, coef: np.ndarray, j: int, xs: np.ndarray, window: tuple[int, int],
                        state0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Residuals (P, R) whose sum of squares is the window cost of block ``j`` set to each of
        ``xs`` (P, M): joint errors over the window (their squares averaged over its samples) and
        the penalty over the whole trajectory; and those costs (P,), infinite where a run diverged."""
        a, b = window
        coefs = np.repeat(coef[None], len(xs), axis=0)
        coefs[:, j] = xs
        tr = self.simulate(coefs, window, state0)
        joint = (tr.coordinates - self.ref[None, a:b]) / np.sqrt(b - a)
        size = np.sqrt(self.penalty / self.exc.size) * np.einsum("tc,pcm->ptm", self.basis, coefs)
        r = np.hstack([joint.reshape(len(xs), -1), size.reshape(len(xs), -1)])
        cost = np.sum(r**2, axis=1)
        cost[tr.diverged] = np.inf
        return r, cost


def _search_block_cma(problem: _Problem, coef: np.ndarray, j: int, window: tuple[int, int], state0: np.ndarray,
                      generations: int, popsize: int | None, sigma0: float, seed: int) -> np.ndarray:
    """Block ``j``'s coefficients (M,) after CMA-ES on its window cost."""
    import cma

    es = cma.CMAEvolutionStrategy(coef[j], sigma0, {"seed": seed, "bounds": [-1.0, 1.0], "verbose": -9,
                                                    **({"popsize": popsize} if popsize else {})})
    for _g in range(generations):
        cand = np.array(es.ask())
        _, cost = problem.block_residuals(coef, j, cand, window, state0)
        es.tell(list(cand), np.where(np.isfinite(cost), cost, 1e3).tolist())
    return np.clip(es.result.xbest if es.result.xbest is not None else coef[j], -1.0, 1.0)


def _search_block_lm(problem: _Problem, coef: np.ndarray, j: int, window: tuple[int, int], state0: np.ndarray,
                     iterations: int, step: float) -> np.ndarray:
    """Block ``j``'s coefficients (M,) after Levenberg-Marquardt on its window cost: per iteration
    a forward-difference Jacobian (M simulations) and the steps of :data:`LM_DAMPINGS` (one batch);
    it stops when none lowers the cost."""
    x = coef[j].copy()
    r0, c0 = problem.block_residuals(coef, j, x[None], window, state0)
    r0, c0 = r0[0], c0[0]
    for _ in range(iterations):
        h = np.where(x + step <= 1.0, step, -step)  # stay inside the bounds
        rj, _ = problem.block_residuals(coef, j, x[None] + np.diag(h), window, state0)
        steps = damped_steps((rj - r0[None]).T / h[None], r0, x, LM_DAMPINGS, -1.0, 1.0)
        rs, cs = problem.block_residuals(coef, j, steps, window, state0)
        k = int(np.argmin(cs))
        if not cs[k] < c0:
            break
        x, r0, c0 = steps[k], rs[k], cs[k]
    return x
