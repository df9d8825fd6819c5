"""Corrective controls: small additions to the excitations that make MuJoCo follow OpenSim.

As in Ikkala & Hämäläinen (2020), each muscle's correction is a cubic spline with knots every
0.1 s (10 Hz): here a uniform cubic B-spline, whose coefficient ``j`` only acts on
``[(j - 3) h, (j + 1) h]`` (``h`` the knot spacing), so 13 coefficients per muscle cover 1 s.
The corrected excitation is ``clip(u + correction, 0, 1)``.

The cost of a trajectory's corrections is the paper's: the squared joint error against OpenSim
(averaged over time, summed over DoFs, rad²) plus ``penalty`` (default :data:`PENALTY`) times
the mean squared correction (over time and muscles).

:func:`fit_corrections` minimises it block by block, in time order: for coefficient ``j`` of
every muscle (a 50-dimensional block for MoBL-ARMS) CMA-ES searches while the other blocks stay
fixed, each candidate simulated only from the start of the block's support to ``lookahead``
knots past its end, from the state the current corrections reach there. Each block is accepted
only if it lowers the trajectory's whole cost, so the result is never worse than no correction.
``sweeps`` passes repeat this over all blocks: a later pass refits each block after the blocks
after it have moved (on MoBL-ARMS, 3 passes cut the remaining error by a third against 1).

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

__all__ = ["CorrectionResult", "KNOT_SPACING", "PENALTY", "bspline_basis", "corrected_excitations",
           "fit_corrections", "force_matching_start"]

KNOT_SPACING = 0.1
"""Seconds between spline knots (10 Hz)."""
PENALTY = 0.1
"""Weight of the mean squared correction in the cost (rad² per unit excitation²)."""


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
                    penalty: float = PENALTY, spacing: float = KNOT_SPACING, generations: int = 20,
                    popsize: int | None = None, sigma0: float = 0.05, lookahead: int = 1, sweeps: int = 1,
                    seed: int = 0, nthread: int | None = None, start: np.ndarray | None = None) -> CorrectionResult:
    """Fit corrective excitations for one trajectory (see the module docstring).

    Args:
        model: the (fitted) converted model.
        initial_state: shape (nstate,), :func:`o2m.mujoco_sim.initial_state`.
        excitations: reference excitations, shape (T, len(muscles)), sampled every timestep.
        reference: OpenSim joint values, shape (T, len(dofs)), rad or m.
        generations, popsize, sigma0: CMA-ES budget per block (sigma0 in excitation units).
        lookahead: knot intervals simulated past a block's support.
        sweeps: passes over all blocks.
        start: spline coefficients (n_coef, M) to start from (e.g. :func:`force_matching_start`),
            used when they cost less than no correction.
    """
    import cma

    exc = np.asarray(excitations, float)
    ref = np.asarray(reference, float)
    n_t, n_m = exc.shape
    dt = model.opt.timestep
    times = float(initial_state[0]) + dt * np.arange(n_t)
    basis = bspline_basis(times, spacing)
    n_c = basis.shape[1]
    coef = np.zeros((n_c, n_m))
    evals = 0

    def simulate(coefs: np.ndarray, start: int, stop: int, state0: np.ndarray):
        """Joint values for samples start..stop-1 of candidates coefs (P, C, M), from state0."""
        u = np.clip(exc[None, start:stop] + np.einsum("tc,pcm->ptm", basis[start:stop], coefs), 0.0, 1.0)
        ctrl = controls_from_excitations(model, muscles, u)
        return rollout(model, state0, ctrl, joint_names=dofs, nthread=nthread)

    def full_cost(c: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        tr = simulate(c[None], 0, n_t, initial_state)
        q = tr.coordinates[0]
        err = 1e3 if tr.diverged[0] else float(np.mean((q - ref) ** 2, axis=0).sum())
        return err + penalty * float(np.mean((basis @ c) ** 2)), q, tr.states[0]

    cost0, q0, states = full_cost(coef)
    best_cost = cost0
    if start is not None:
        c, _, st = full_cost(np.clip(np.asarray(start, float), -1.0, 1.0))
        evals += 1
        if c < best_cost:
            coef, best_cost, states = np.clip(np.asarray(start, float), -1.0, 1.0), c, st
    rng = np.random.default_rng(seed)
    for _ in range(sweeps):
        for j in range(n_c):
            support = np.flatnonzero(basis[:, j] > 0)
            if len(support) == 0:
                continue
            start = int(support[0])
            stop = min(n_t, int(support[-1]) + 1 + int(round(lookahead * spacing / dt)))
            if stop - start < 2:
                continue
            state0 = states[start]
            es = cma.CMAEvolutionStrategy(coef[j], sigma0, {"seed": int(rng.integers(1, 2**31 - 1)),
                                                            "bounds": [-1.0, 1.0], "verbose": -9,
                                                            **({"popsize": popsize} if popsize else {})})
            others = penalty * np.mean((basis @ coef) ** 2)  # reference for the penalty change
            for _g in range(generations):
                cand = np.array(es.ask())
                coefs = np.repeat(coef[None], len(cand), axis=0)
                coefs[:, j] = cand
                tr = simulate(coefs, start, stop, state0)
                evals += len(cand)
                err = np.mean((tr.coordinates - ref[None, start:stop]) ** 2, axis=1).sum(axis=1)
                err[tr.diverged] = 1e3
                pen = penalty * np.mean(np.einsum("tc,pcm->ptm", basis, coefs) ** 2, axis=(1, 2))
                es.tell(list(cand), (err + pen - others).tolist())
            trial = coef.copy()
            trial[j] = np.clip(es.result.xbest if es.result.xbest is not None else coef[j], -1.0, 1.0)
            c, q, st = full_cost(trial)
            evals += 1
            if c < best_cost:
                coef, best_cost, states = trial, c, st
    _, q, _ = full_cost(coef)
    corrected = corrected_excitations(exc, basis, coef)
    return CorrectionResult(coef, corrected, corrected - exc, cost0, best_cost, np.mean(np.abs(q0 - ref), axis=0),
                            np.mean(np.abs(q - ref), axis=0), q, evals)
