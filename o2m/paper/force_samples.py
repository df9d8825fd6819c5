"""OpenSim's recorded states laid out for a MuJoCo model: the samples the muscle force fit fits.

:func:`sample_states` reads MuJoCo's actuator lengths and velocities (and optionally per-sample
weights) at OpenSim's recorded states, either with every equality-driven joint exactly on its
equality or after a run-up along the recording (``settle``), so that the path carriers lag as they
do in a rollout. :class:`ForceSamples` holds them for :func:`o2m.paper.force_fit.fit_forces`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from o2m.mj.posing import joint_equality_plan
from o2m.mj.simulate import STATE_SPEC, _dofadr_of_qadr, initial_state
from o2m.mj.tendons import tendon_jacobian

__all__ = ["ForceSamples", "sample_states"]


@dataclass
class ForceSamples:
    """Muscle states sampled from OpenSim trajectories, laid out for a MuJoCo model.

    Attributes:
        muscles: muscle (actuator) names, length M.
        length, velocity: MuJoCo actuator length (m) and velocity (m/s) at OpenSim's states, (N, M).
        activation: the muscles' activation at those states, (N, M); force: OpenSim's tendon force (N), (N, M).
        trajectory: which trajectory each sample comes from, (N,).
        step: the sample's time step in its trajectory, (N,); with ``controls`` (the MuJoCo control
            of every step of every trajectory, (B, T - 1, M)), ``initial_activation`` ((B, M)) and
            ``timestep`` (s), the fit can integrate the activations anew for other time constants.
        weight: optional weight of each sample's force residual per muscle, (N, M) (e.g. the
            muscle's moment arm there, so the fit minimises the joint torque error).
    """

    muscles: list[str]
    length: np.ndarray
    velocity: np.ndarray
    activation: np.ndarray
    force: np.ndarray
    trajectory: np.ndarray
    step: np.ndarray | None = None
    controls: np.ndarray | None = None
    initial_activation: np.ndarray | None = None
    timestep: float = 0.002
    weight: np.ndarray | None = None

    def subset(self, rows: np.ndarray) -> ForceSamples:
        return ForceSamples(self.muscles, self.length[rows], self.velocity[rows], self.activation[rows],
                            self.force[rows], self.trajectory[rows], None if self.step is None else self.step[rows],
                            self.controls, self.initial_activation, self.timestep,
                            None if self.weight is None else self.weight[rows])


def sample_states(model: mujoco.MjModel, coordinates: np.ndarray, speeds: np.ndarray, activations: np.ndarray,
                  forces: np.ndarray, coordinate_names: Sequence[str], muscles: Sequence[str], *,
                  stride: int = 2, excitations: np.ndarray | None = None,
                  weight_coordinates: Sequence[str] | None = None, weighting: str = "moment_arm",
                  settle: int = 0) -> ForceSamples:
    """MuJoCo actuator lengths and velocities at every ``stride``-th OpenSim state.

    Args:
        coordinates, speeds: OpenSim coordinate values and speeds, shape (B, T, n_coordinates),
            rad or m (and per second).
        activations: muscle activations at those states (OpenSim's, or MuJoCo's for the same
            excitations), shape (B, T, M); forces: OpenSim's tendon forces (N), shape (B, T, M);
            columns in ``muscles`` order.
        excitations: the excitations of the trajectories, (B, T, M); given, the samples carry
            MuJoCo's controls (the mean of each step's two excitations, clipped to [0, 1], as
            :func:`o2m.mj.simulate.muscle_activations` steps them) and ``activations[:, 0]`` as the
            initial activations, so :func:`fit_forces` can fit the activation time constants.
        weight_coordinates: given (names of joints), each sample's residual weight is the norm of
            the muscle's moment arms about them there (MuJoCo's), scaled to RMS 1 per muscle (1 for
            a muscle with no arm about them): the fit then minimises the torque error.
        weighting: ``"moment_arm"`` (above) or ``"acceleration"``: the norm of the accelerations
            of those joints per newton of the muscle's force, ``M⁻¹ r`` with ``M`` the inertia
            and ``r`` the moment arms of the joints with every equality-driven joint (couplings,
            path carriers) moving along (rad/s² per N), scaled to RMS 1 per muscle: states where
            a force error moves a light joint (pro_sup) count more.
        settle: steps of run-up before each sample (needs ``excitations``): from the recorded state
            ``settle`` steps earlier, MuJoCo steps with the joints no equality drives held on the
            recording (:class:`o2m.paper.windows.HeldJoints`), so the equality-driven joints (path
            carriers) lag as in a rollout and the lengths and velocities are the ones a rollout
            gives the muscles (on MoBL-ARMS BICshort's velocity moves by 0.096 m/s RMS, more than
            its own 0.081). 0: every joint exactly on its equality (as :func:`initial_state` sets it).
    """
    if weighting not in ("moment_arm", "acceleration"):
        raise ValueError(f"weighting must be 'moment_arm' or 'acceleration', not {weighting!r}")
    data = mujoco.MjData(model)
    ids = np.array([model.actuator(m).id for m in muscles])
    tendons = model.actuator_trnid[ids, 0]
    dofs = [int(model.joint(c).dofadr[0]) for c in weight_coordinates or []]
    plan = joint_equality_plan(model)
    exc = None if excitations is None else np.asarray(excitations, float)
    controls = None if exc is None else np.clip(0.5 * (exc[:, :-1] + exc[:, 1:]), 0.0, 1.0)
    if settle and controls is None:
        raise ValueError("a run-up (settle > 0) needs the excitations")
    runup = _RunUp(model, coordinate_names, muscles, plan) if settle else None
    rows = []
    for b in range(coordinates.shape[0]):
        for k in range(0, coordinates.shape[1], stride):
            if not (np.isfinite(coordinates[b, k]).all() and np.isfinite(forces[b, k]).all()):
                continue
            if runup is not None:
                x = runup.state(coordinates[b], speeds[b], activations[b], controls[b], k, settle)
            else:
                x = initial_state(model, dict(zip(coordinate_names, coordinates[b, k], strict=True)),
                                  speeds=dict(zip(coordinate_names, speeds[b, k], strict=True)), plan=plan)
            mujoco.mj_setState(model, data, x, STATE_SPEC)
            mujoco.mj_fwdPosition(model, data)
            mujoco.mj_fwdVelocity(model, data)
            arm = None
            if dofs and weighting == "acceleration":
                arm = _acceleration_per_newton(model, data, plan, dofs, tendons)
            elif dofs:
                arm = np.linalg.norm(tendon_jacobian(model, data)[np.ix_(tendons, dofs)], axis=1)
            rows.append((data.actuator_length[ids].copy(), data.actuator_velocity[ids].copy(),
                         activations[b, k], forces[b, k], b, k, arm))
    if not rows:
        raise ValueError("no finite OpenSim states to sample")
    initial = None if excitations is None else np.asarray(activations, float)[:, 0, :]
    weight = None
    if dofs:
        arms = np.array([r[6] for r in rows])
        rms = np.sqrt(np.mean(arms**2, axis=0))
        weight = np.where(rms > 1e-6, arms / np.maximum(rms, 1e-12), 1.0)
    return ForceSamples(list(muscles), np.array([r[0] for r in rows]), np.array([r[1] for r in rows]),
                        np.array([r[2] for r in rows], float), np.array([r[3] for r in rows], float),
                        np.array([r[4] for r in rows]), np.array([r[5] for r in rows]), controls, initial,
                        float(model.opt.timestep), weight)


class _RunUp:
    """MuJoCo states reached by a run-up along a recorded trajectory (see ``sample_states(settle=...)``)."""

    def __init__(self, model: mujoco.MjModel, coordinate_names: Sequence[str], muscles: Sequence[str], plan: list):
        from o2m.paper.windows import HeldJoints  # windows imports the fitting module, which needs this one

        self.model, self.names, self.muscles, self.plan = model, list(coordinate_names), list(muscles), plan
        self.ids = np.array([model.actuator(m).id for m in muscles])
        self.held = HeldJoints(model, coordinate_names)

    def state(self, coordinates: np.ndarray, speeds: np.ndarray, activations: np.ndarray, controls: np.ndarray,
              k: int, settle: int) -> np.ndarray:
        """The state at sample ``k`` of one trajectory: coordinates, speeds (T, n); the muscles'
        activations (T, M) and controls (T - 1, M)."""
        k0 = max(0, k - settle)
        x = initial_state(self.model, dict(zip(self.names, coordinates[k0], strict=True)),
                          speeds=dict(zip(self.names, speeds[k0], strict=True)),
                          activations=dict(zip(self.muscles, activations[k0], strict=True)), plan=self.plan)
        if k == k0:
            return x
        ctrl = np.zeros((k - k0, self.model.nu))
        ctrl[:, self.ids] = controls[k0:k]
        return self.held.settle(x, coordinates[k0 + 1:k + 1], speeds[k0 + 1:k + 1], ctrl, {})


def _velocity_map(model: mujoco.MjModel, data: mujoco.MjData, plan: list, dofs: Sequence[int]) -> np.ndarray:
    """Joint velocities (nv, len(dofs)) per unit speed of each of ``dofs``, the equality-driven joints
    following by the chain rule at ``data.qpos`` (as :func:`o2m.mj.simulate.initial_state` sets speeds)."""
    P = np.zeros((model.nv, len(dofs)))
    P[list(dofs), np.arange(len(dofs))] = 1.0
    for e in plan:  # in dependency order
        d1 = _dofadr_of_qadr(model, e.qadr1)
        if e.qadr2 is None:
            P[d1] = 0.0
            continue
        x, c = float(data.qpos[e.qadr2]) - e.ref2, e.coef
        P[d1] = (c[1] + x * (2 * c[2] + x * (3 * c[3] + x * 4 * c[4]))) * P[_dofadr_of_qadr(model, e.qadr2)]
    return P


def _acceleration_per_newton(model: mujoco.MjModel, data: mujoco.MjData, plan: list, dofs: Sequence[int],
                             tendons: np.ndarray) -> np.ndarray:
    """Norm of the accelerations of ``dofs`` (rad/s² per N) a unit pull of each tendon gives at rest,
    the driven joints moving along: ``|(Pᵀ M P)⁻¹ Pᵀ Jᵀ|`` per tendon, shape (len(tendons),).
    Needs ``mj_fwdPosition`` done on ``data``."""
    P = _velocity_map(model, data, plan, dofs)
    M = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, M)
    arms = tendon_jacobian(model, data)[tendons] @ P  # (n_tendons, len(dofs)) m per rad
    return np.linalg.norm(np.linalg.solve(P.T @ M @ P, arms.T), axis=0)
