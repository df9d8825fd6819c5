"""Forward simulation of a converted model in MuJoCo, many trajectories at once.

A converted model names its coordinate joints and its muscle actuators as OpenSim does, so an
OpenSim initial state and an excitation set carry over by name:

* :func:`initial_state` builds MuJoCo's full physics state (``mjSTATE_FULLPHYSICS``) from
  coordinate values and speeds (rad, m, rad/s, m/s) and muscle activations; joints driven by
  joint equalities (dependent coordinates, coupled axes) are resolved through the model's own
  equalities, positions and speeds alike.
* :func:`controls_from_excitations` lays excitations sampled on OpenSim's time grid out as
  MuJoCo controls, one per step. OpenSim interpolates excitations linearly between samples, so
  step ``k`` (from ``t_k`` to ``t_k + dt``) gets the mean over the step, ``(u_k + u_{k+1}) / 2``.
* :func:`rollout` runs a batch with :mod:`mujoco.rollout` over threads (one model, or one model
  per trajectory, e.g. CMA-ES candidates) and returns :class:`Trajectories` on the sample grid,
  the initial state included; :func:`step_loop` does the same with a plain ``mj_step`` loop (the
  reference the batched path is tested against).
* :func:`force_driven` turns the muscles into force motors and :func:`controls_from_forces` lays
  tendon forces (e.g. OpenSim's recorded ones) out as their controls: the model then moves under
  exactly those forces, which separates what the skeleton, paths and passive forces leave from
  what the muscle model adds (``benchmarks/force_sensitivity.py``).
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import mujoco
import numpy as np
from mujoco import rollout as mj_rollout

from o2m.mj.muscle import integrate_activations
from o2m.mj.posing import joint_equality_plan, joint_qpos_address, pose_mujoco

__all__ = ["STATE_SPEC", "Trajectories", "controls_from_excitations", "initial_state", "muscle_activations",
           "muscle_actuator_ids", "rollout", "state_layout", "step_loop"]

STATE_SPEC = int(mujoco.mjtState.mjSTATE_FULLPHYSICS)


def state_layout(model: mujoco.MjModel, spec: int = STATE_SPEC) -> dict[str, slice]:
    """Where time, qpos, qvel and act sit in a state vector of ``spec``: ``{name: slice}``."""
    out, offset = {}, 0
    for name, bit in (("time", mujoco.mjtState.mjSTATE_TIME), ("qpos", mujoco.mjtState.mjSTATE_QPOS),
                      ("qvel", mujoco.mjtState.mjSTATE_QVEL), ("act", mujoco.mjtState.mjSTATE_ACT)):
        size = mujoco.mj_stateSize(model, int(bit))
        if spec & int(bit):
            out[name] = slice(offset, offset + size)
            offset += size
    return out


def muscle_actuator_ids(model: mujoco.MjModel, muscles: Sequence[str]) -> np.ndarray:
    """Actuator id of each muscle name, shape (len(muscles),); KeyError naming the missing ones."""
    ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, m) for m in muscles]
    missing = [m for m, i in zip(muscles, ids, strict=False) if i < 0]
    if missing:
        raise KeyError(f"MuJoCo model has no actuators named {missing[:5]}{'...' if len(missing) > 5 else ''}")
    return np.asarray(ids, int)


def initial_state(model: mujoco.MjModel, coordinates: Mapping[str, float], *,
                  speeds: Mapping[str, float] | None = None, activations: Mapping[str, float] | None = None,
                  time: float = 0.0, plan: list | None = None) -> np.ndarray:
    """Full physics state, shape (mj_stateSize(FULLPHYSICS),), from OpenSim-named values.

    ``coordinates`` and ``speeds`` map joint names to rad / m and rad/s / m/s; names the model
    has no joint for (e.g. locked coordinates, folded into fixed transforms) are ignored, and
    equality-driven joints take the values their equalities give, speeds by the chain rule.
    ``activations`` maps actuator (muscle) names to activation in [0, 1]. ``plan`` is
    :func:`o2m.validate.joint_equality_plan` of ``model``, computed when None (pass it when
    building many states).
    """
    data = mujoco.MjData(model)
    plan = joint_equality_plan(model) if plan is None else plan
    known = {k: v for k, v in coordinates.items() if _has_joint(model, k)}
    pose_mujoco(model, data, known, plan=plan)
    qvel = np.zeros(model.nv)
    for name, v in (speeds or {}).items():
        if _has_joint(model, name):
            qvel[model.jnt_dofadr[model.joint(name).id]] = float(v)
    for e in plan:  # d(q1)/dt = p'(q2 - ref2) * d(q2)/dt, in dependency order
        d1 = _dofadr_of_qadr(model, e.qadr1)
        if e.qadr2 is None:
            qvel[d1] = 0.0
            continue
        x = float(data.qpos[e.qadr2]) - e.ref2
        c = e.coef
        qvel[d1] = (c[1] + x * (2 * c[2] + x * (3 * c[3] + x * 4 * c[4]))) * qvel[_dofadr_of_qadr(model, e.qadr2)]
    data.qvel[:] = qvel
    for name, a in (activations or {}).items():
        aid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, name)
        if aid >= 0 and model.actuator_actadr[aid] >= 0:
            data.act[model.actuator_actadr[aid]] = float(a)
    data.time = time
    state = np.empty(mujoco.mj_stateSize(model, STATE_SPEC))
    mujoco.mj_getState(model, data, state, STATE_SPEC)
    return state


def welded_at_default_pose(xml: str | os.PathLike[str], body: str) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """``xml``'s model with ``body``'s own joints removed (welded to its parent, e.g. a pelvis to the
    world) and its keyframes dropped, with data at the full model's ``default-pose`` keyframe
    (forward dynamics computed), for tests and benchmarks that hang a model under gravity."""
    full = mujoco.MjModel.from_xml_path(str(xml))
    spec = mujoco.MjSpec.from_file(str(xml))
    for joint in list(spec.body(body).joints):
        spec.delete(joint)
    for key in list(spec.keys):
        spec.delete(key)
    model = spec.compile()
    data = mujoco.MjData(model)
    key = full.key("default-pose").qpos
    for i in range(model.njnt):
        data.qpos[model.jnt_qposadr[i]] = key[full.jnt_qposadr[full.joint(model.joint(i).name).id]]
    mujoco.mj_forward(model, data)
    return model, data


def force_driven(model: str | os.PathLike[str] | mujoco.MjSpec, muscles: Sequence[str]) -> mujoco.MjModel:
    """The model (an MJCF path or an MjSpec, left unchanged) with its ``muscles`` as plain force
    motors on their tendons: no activation state, no force-length-velocity curves, no passive
    force, no control or force limits; the control is the actuator force (N, negative when
    pulling, as MuJoCo's muscle forces are). Tendon springs and damping, joint damping and
    everything else stay. :func:`controls_from_forces` builds the controls."""
    spec = model.copy() if isinstance(model, mujoco.MjSpec) else mujoco.MjSpec.from_file(str(model))
    for name in muscles:
        act = spec.actuator(name)
        if act is None:
            raise KeyError(f"no actuator named {name!r}")
        act.dyntype = mujoco.mjtDyn.mjDYN_NONE
        act.gaintype = mujoco.mjtGain.mjGAIN_FIXED
        act.biastype = mujoco.mjtBias.mjBIAS_NONE
        act.gainprm[:] = 0.0
        act.gainprm[0] = 1.0
        act.biasprm[:] = 0.0
        act.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
        act.forcelimited = mujoco.mjtLimited.mjLIMITED_FALSE
    return spec.compile()


def controls_from_forces(model: mujoco.MjModel, muscles: Sequence[str], forces: np.ndarray, *,
                         hold: bool = False) -> np.ndarray:
    """Controls for a :func:`force_driven` model from pulling forces sampled every step.

    Args:
        forces: shape (..., T, len(muscles)), N, positive when pulling (OpenSim's tendon force).
        hold: step ``k`` gets ``forces[k]`` (the force MuJoCo applied during that step, for
            replaying MuJoCo's own ``actuator_force``) instead of the mean ``(f_k + f_{k+1}) / 2``
            of a force that changes linearly between samples.
    Returns:
        controls, shape (..., T - 1, nu), the other actuators at zero.
    """
    return _step_controls(model, muscles, -np.asarray(forces, float), hold=hold)


def _has_joint(model: mujoco.MjModel, name: str) -> bool:
    try:
        joint_qpos_address(model, name)
        return True
    except KeyError:
        return False


def _dofadr_of_qadr(model: mujoco.MjModel, qadr: int) -> int:
    j = int(np.flatnonzero(model.jnt_qposadr == qadr)[0])
    return int(model.jnt_dofadr[j])


def controls_from_excitations(model: mujoco.MjModel, muscles: Sequence[str], excitations: np.ndarray) -> np.ndarray:
    """MuJoCo controls for excitations sampled every step.

    Args:
        excitations: shape (..., T, len(muscles)), samples at ``t_k = k * timestep``.
    Returns:
        controls, shape (..., T - 1, nu): step ``k`` gets ``(u_k + u_{k+1}) / 2`` (the mean of
        OpenSim's piecewise-linear excitation over the step); actuators not listed get 0.
    """
    return _step_controls(model, muscles, np.asarray(excitations, float), hold=False)


def _step_controls(model: mujoco.MjModel, muscles: Sequence[str], samples: np.ndarray, *, hold: bool) -> np.ndarray:
    """Per-muscle samples (..., T, M) laid out as controls (..., T - 1, nu), the other actuators
    at 0: step ``k`` gets sample ``k`` with ``hold``, else the mean of samples ``k`` and ``k + 1``."""
    ids = muscle_actuator_ids(model, muscles)
    ctrl = np.zeros((*samples.shape[:-2], samples.shape[-2] - 1, model.nu))
    ctrl[..., ids] = samples[..., :-1, :] if hold else 0.5 * (samples[..., :-1, :] + samples[..., 1:, :])
    return ctrl


def muscle_activations(model: mujoco.MjModel, muscles: Sequence[str], excitations: np.ndarray,
                       initial: np.ndarray) -> np.ndarray:
    """The activations MuJoCo's muscle dynamics give for excitations sampled every step.

    Args:
        excitations: shape (..., T, len(muscles)), as for :func:`controls_from_excitations`.
        initial: activations at the first sample, shape (..., len(muscles)).
    Returns:
        shape (..., T, len(muscles)): the activation at every sample, as ``mj_step`` computes it
        (``mju_muscleDynamics``, smoothed where ``tausmooth`` > 0, Euler, then clamped to
        ``actrange`` where the actuator's activation is limited), without simulating the body.
    """
    ids = muscle_actuator_ids(model, muscles)
    exc = np.asarray(excitations, float)
    ctrl = np.clip(0.5 * (exc[..., :-1, :] + exc[..., 1:, :]), 0.0, 1.0)
    limited = model.actuator_actlimited[ids].astype(bool)
    bounds = (np.where(limited, model.actuator_actrange[ids, 0], -np.inf),
              np.where(limited, model.actuator_actrange[ids, 1], np.inf))
    return integrate_activations(ctrl, initial, model.actuator_dynprm[ids, :3], model.opt.timestep, bounds)


@dataclass
class Trajectories:
    """Simulated trajectories on the sample grid (the initial state is sample 0).

    Attributes:
        times: shape (T,), seconds, the sample grid (initial time + k * timestep).
        qpos: shape (B, T, nq); qvel: shape (B, T, nv); act: shape (B, T, na).
        diverged: shape (B,), bool: MuJoCo hit a non-finite or huge acceleration and reset the
            trajectory (its state time jumped back), or a value is not finite. The samples of a
            diverged trajectory are meaningless.
        states: the full physics states, shape (B, T, nstate) (``qpos`` etc. are views into it).
        joint_names: names of the hinge/slide joints in ``coordinates``.
        coordinates: shape (B, T, len(joint_names)), rad or m: the named joints' qpos.
    """

    times: np.ndarray
    qpos: np.ndarray
    qvel: np.ndarray
    act: np.ndarray
    joint_names: list[str]
    coordinates: np.ndarray
    diverged: np.ndarray
    states: np.ndarray


def _as_trajectories(model: mujoco.MjModel, states: np.ndarray, joint_names: Sequence[str] | None) -> Trajectories:
    lay = state_layout(model)
    t = states[..., lay["time"]][..., 0]  # (B, T)
    grid = t[:, :1] + np.arange(t.shape[1]) * model.opt.timestep
    diverged = (np.abs(t - grid) > 0.5 * model.opt.timestep).any(axis=1) | ~np.isfinite(states).all(axis=(1, 2))
    names = list(joint_names) if joint_names is not None else [
        model.joint(j).name for j in range(model.njnt)
        if model.jnt_type[j] in (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE) and model.joint(j).name]
    adr = [joint_qpos_address(model, n) for n in names]
    qpos = states[..., lay["qpos"]]
    return Trajectories(grid[0].copy(), qpos, states[..., lay["qvel"]],
                        states[..., lay["act"]] if "act" in lay else np.zeros((*states.shape[:2], 0)),
                        names, qpos[..., adr], diverged, states)


def rollout(models: mujoco.MjModel | Sequence[mujoco.MjModel], initial_states: np.ndarray, controls: np.ndarray,
            *, joint_names: Sequence[str] | None = None, nthread: int | None = None) -> Trajectories:
    """Simulate a batch with :func:`mujoco.rollout.rollout` on ``nthread`` threads (default: all cores).

    Args:
        models: one MjModel for every trajectory, or a sequence of B models of the same size
            signature (e.g. candidates differing in damping or strength).
        initial_states: shape (B, nstate) or (nstate,), from :func:`initial_state`.
        controls: shape (B, T - 1, nu), from :func:`controls_from_excitations`.
        joint_names: the joints to report in ``coordinates`` (default: every named hinge/slide).
    Returns:
        :class:`Trajectories` with T samples (initial state and one per step); see
        :attr:`Trajectories.diverged` for trajectories MuJoCo had to reset.
    """
    controls = np.asarray(controls, float)
    if controls.ndim == 2:
        controls = controls[None]
    batch, _nstep = controls.shape[0], controls.shape[1]
    model0 = models if isinstance(models, mujoco.MjModel) else models[0]
    init = np.atleast_2d(np.asarray(initial_states, float))
    if init.shape[0] == 1 and batch > 1:
        init = np.repeat(init, batch, axis=0)
    nthread = max(1, min(nthread or os.cpu_count() or 1, batch))
    datas = [mujoco.MjData(model0) for _ in range(nthread)]
    if nthread == 1:
        states, _ = mj_rollout.rollout(models, datas[0], init, controls)
    else:
        with mj_rollout.Rollout(nthread=nthread) as runner:
            states, _ = runner.rollout(models, datas, init, controls)
    full = np.concatenate([init[:, None, :], states], axis=1)
    return _as_trajectories(model0, full, joint_names)


def step_loop(model: mujoco.MjModel, initial_states: np.ndarray, controls: np.ndarray, *,
              joint_names: Sequence[str] | None = None) -> Trajectories:
    """The same as :func:`rollout` for one model, with a plain ``mj_step`` loop (slow; a reference)."""
    controls = np.asarray(controls, float)
    if controls.ndim == 2:
        controls = controls[None]
    init = np.atleast_2d(np.asarray(initial_states, float))
    if init.shape[0] == 1:
        init = np.repeat(init, controls.shape[0], axis=0)
    data = mujoco.MjData(model)
    size = mujoco.mj_stateSize(model, STATE_SPEC)
    out = np.empty((controls.shape[0], controls.shape[1] + 1, size))
    for b in range(controls.shape[0]):
        mujoco.mj_resetData(model, data)
        mujoco.mj_setState(model, data, init[b], STATE_SPEC)
        out[b, 0] = init[b]
        for k in range(controls.shape[1]):
            data.ctrl[:] = controls[b, k]
            mujoco.mj_step(model, data)
            mujoco.mj_getState(model, data, out[b, k + 1], STATE_SPEC)
    return _as_trajectories(model, out, joint_names)
