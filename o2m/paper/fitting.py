"""Fitting a converted model's dynamics to OpenSim trajectories with CMA-ES.

The parameter vector is the paper's (Ikkala & Hämäläinen 2020): for each free degree of freedom
its joint damping and the softness of its limit (the stiffness of its CoordinateLimitForce
tendons), for each tendon its damping and stiffness, and
for each muscle a strength scale (160 parameters for MoBL-ARMS: 5 free DoFs, 50 muscles).

Parameters are searched in log10 space, within the bounds of :data:`BOUNDS`:

=====================  ==========================  =========================================
parameter              MuJoCo field                bounds
=====================  ==========================  =========================================
``damping``            ``dof_damping``             1e-3 .. 10 N·m·s/rad (m: N·s/m)
``limit_scale``        ``tendon_stiffness[poly]``  0.1 .. 10 (x the stiffness of the DoF's
                       of its limit tendons        CoordinateLimitForce tendons; smaller is softer)
``limit_timeconst``    ``jnt_solref[:, 0]``        0.004 .. 0.5 s (a softer limit when larger;
                                                   for a DoF without limit tendons)
``tendon_damping``     ``tendon_damping``          1e-3 .. 1e3 N·s/m
``tendon_stiffness``   ``tendon_stiffness``        1e-2 .. 1e4 N/m (rest length: qpos0 length; for
                                                   a tendon without a spring)
``spring_scale``       ``tendon_stiffness[poly]``  0.1 .. 10 (x the tendon's spring: the passive
                                                   force :mod:`o2m.force_fit` gives the tendon)
``muscle_scale``       ``actuator_gainprm[:, 2]``  0.5 .. 2 (x the model's max force)
=====================  ==========================  =========================================

Damping and stiffness can be zero in a converted model, so for them the searched variable is
``log10(value + lower)``: its lower bound means exactly zero. A parameter starts at the model's
value, so the start point reproduces the model exactly, and is searched within :data:`SPAN`
decades of it (and within the bounds above): on MoBL-ARMS, the whole box let CMA-ES move tendon
damping by two to three decades, which fitted a few training sets and made the test sets worse.
CMA-ES searches that box normalised to [0, 1]^n.

The objective (:class:`TrajectoryObjective`) is the paper's: the squared joint-position error
against OpenSim, averaged over time and summed over the free DoFs and the training
trajectories (rad²), plus ``penalty`` (default :data:`PENALTY`) times the squared log10
distance of every parameter from its start, a small price on large changes. A trajectory
MuJoCo had to reset costs :data:`DIVERGED_COST` per DoF.
"""

from __future__ import annotations

import concurrent.futures
import copy
import json
import os
import pickle
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from o2m.mj.mjcf_text import number_text
from o2m.mj.simulate import rollout

__all__ = ["BOUNDS", "DIVERGED_COST", "FitResult", "PENALTY", "ParameterSpace", "TrajectoryObjective", "fit_cma",
           "free_coordinates", "load_fit", "parameter_space", "save_fit"]

BOUNDS: dict[str, tuple[float, float]] = {
    "damping": (1e-3, 10.0),
    "limit_scale": (0.1, 10.0),
    "limit_timeconst": (0.004, 0.5),
    "tendon_damping": (1e-3, 1e3),
    "tendon_stiffness": (1e-2, 1e4),
    "spring_scale": (0.1, 10.0),
    "muscle_scale": (0.5, 2.0),
}
#: Kinds whose searched variable is log10(value + lower bound), so that zero is reachable.
ZERO_AT_LOWER = frozenset({"damping", "tendon_damping", "tendon_stiffness"})
PENALTY = 1e-3
"""Weight of the squared log10 change of each parameter, rad² per decade²."""
SPAN = 1.0
"""Decades either side of its start value a parameter is searched in."""
DIVERGED_COST = 10.0
"""Cost per DoF of a trajectory MuJoCo had to reset (rad²; about a 3-rad error throughout)."""


def free_coordinates(model: mujoco.MjModel, coordinate_names: Sequence[str]) -> list[str]:
    """The names in ``coordinate_names`` that are hinge/slide joints no joint equality drives."""
    driven = {int(model.eq_obj1id[i]) for i in range(model.neq)
              if int(model.eq_type[i]) == int(mujoco.mjtEq.mjEQ_JOINT) and model.eq_active0[i]}
    out = []
    for name in coordinate_names:
        j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        if j >= 0 and j not in driven and int(model.jnt_type[j]) in (int(mujoco.mjtJoint.mjJNT_HINGE),
                                                                       int(mujoco.mjtJoint.mjJNT_SLIDE)):
            out.append(name)
    return out


def limit_tendons(model: mujoco.MjModel, joint: str) -> list[int]:
    """Fixed tendons on ``joint`` alone with a spring: o2m's CoordinateLimitForce tendons."""
    j = model.joint(joint).id
    out = []
    for t in range(model.ntendon):
        adr, num = model.tendon_adr[t], model.tendon_num[t]
        if num == 1 and int(model.wrap_type[adr]) == int(mujoco.mjtWrap.mjWRAP_JOINT) and model.wrap_objid[adr] == j \
                and (model.tendon_stiffness[t] != 0 or np.any(model.tendon_stiffnesspoly[t] != 0)):
            out.append(t)
    return out


@dataclass
class ParameterSpace:
    """Named parameters of a model, their log10 start values and bounds.

    Attributes:
        names: ``"<kind>:<element>"``, e.g. ``"damping:elbow_flexion"``, length n.
        x0, lower, upper: log10 of the start value and bounds, shape (n,).
    """

    names: list[str]
    x0: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    _targets: list[tuple[str, int | tuple[int, ...]]] = field(default_factory=list, repr=False)
    _shift: np.ndarray | None = field(default=None, repr=False)  # added to a value before its log10
    span: float = SPAN

    def __len__(self) -> int:
        return len(self.names)

    def to_unit(self, x: np.ndarray) -> np.ndarray:
        return (np.asarray(x) - self.lower) / (self.upper - self.lower)

    def from_unit(self, z: np.ndarray) -> np.ndarray:
        return self.lower + np.clip(z, 0.0, 1.0) * (self.upper - self.lower)

    def physical(self, x: np.ndarray) -> np.ndarray:
        """Physical values of the searched variables ``x`` (shape (n,)), in the units of :data:`BOUNDS`."""
        x = np.asarray(x, float)
        shift = self._shift if self._shift is not None else np.zeros(len(self.names))
        return np.maximum(10.0 ** x - shift, 0.0)

    def values(self, x: np.ndarray) -> dict[str, float]:
        """Physical values ``{name: value}``."""
        return dict(zip(self.names, map(float, self.physical(x)), strict=False))

    def apply(self, model: mujoco.MjModel, x: np.ndarray) -> mujoco.MjModel:
        """A copy of ``model`` with the parameters ``x`` (log10, shape (n,)) written in."""
        m = copy.copy(model)
        for (kind, idx), v in zip(self._targets, self.physical(x), strict=False):
            _KINDS[kind].apply(m, model, idx, v)
        return m

    def write_mjcf(self, model: mujoco.MjModel, x: np.ndarray, xml_in: str | os.PathLike[str],
                   xml_out: str | os.PathLike[str]) -> Path:
        """Write ``xml_in`` (the MJCF of ``model``) with the parameters ``x`` to ``xml_out``, at full precision.

        The written model equals :meth:`apply` of ``model`` in every field the parameters touch.
        """
        doc = _Mjcf(xml_in, model)
        for (kind, idx), v in zip(self._targets, self.physical(x), strict=True):
            _KINDS[kind].write(doc, idx, v)
        out = Path(xml_out)
        doc.tree.write(str(out), pretty_print=True)
        mujoco.MjModel.from_xml_path(str(out))  # it must load
        return out


class _Mjcf:
    """The MJCF of a model, to write parameters into: its elements by the model's ids."""

    def __init__(self, xml: str | os.PathLike[str], model: mujoco.MjModel):
        from lxml import etree

        self.xml, self.model = xml, model
        self.tree = etree.parse(str(xml))
        self.root = self.tree.getroot()

    def find(self, tag: str, name: str):
        el = self.root.find(f".//{tag}[@name='{name}']")
        if el is None:
            raise KeyError(f"{self.xml}: no {tag} named {name!r}")
        return el

    def joint_of_dof(self, dof: int):
        return self.find("joint", self.model.joint(int(np.flatnonzero(self.model.jnt_dofadr == dof)[0])).name)

    def tendon(self, t: int):
        name = self.model.tendon(t).name
        return next(el for el in self.root.iterfind(".//tendon/*") if el.get("name") == name)

    def actuator(self, a: int):
        return next(el for el in self.root.iterfind(".//actuator/*") if el.get("name") == self.model.actuator(a).name)


def _scaled(el, attr: str, factor: float, default: str) -> None:
    el.set(attr, number_text(np.array((el.get(attr) or default).split(), float) * factor))


def _scale_spring(m: mujoco.MjModel, model: mujoco.MjModel, t: int, v: float) -> None:
    m.tendon_stiffness[t] = model.tendon_stiffness[t] * v
    m.tendon_stiffnesspoly[t] = model.tendon_stiffnesspoly[t] * v


def _scale_muscle(m: mujoco.MjModel, model: mujoco.MjModel, a: int, v: float) -> None:
    m.actuator_gainprm[a, 2] = model.actuator_gainprm[a, 2] * v
    m.actuator_biasprm[a, 2] = model.actuator_biasprm[a, 2] * v


def _write_muscle_scale(doc: _Mjcf, a: int, v: float) -> None:
    act = doc.actuator(a)
    if act.tag == "muscle":
        _scaled(act, "force", v, "-1")
        return
    for attr in ("gainprm", "biasprm"):
        prm = np.array(act.get(attr).split(), float)
        prm[2] *= v
        act.set(attr, number_text(prm))


def _set_damping(m: mujoco.MjModel, model: mujoco.MjModel, dof: int, v: float) -> None:
    m.dof_damping[dof] = v


def _scale_limits(m: mujoco.MjModel, model: mujoco.MjModel, tendons: tuple[int, ...], v: float) -> None:
    for t in tendons:
        _scale_spring(m, model, t, v)


def _set_limit_timeconst(m: mujoco.MjModel, model: mujoco.MjModel, j: int, v: float) -> None:
    m.jnt_solref[j, 0] = v


def _set_tendon_damping(m: mujoco.MjModel, model: mujoco.MjModel, t: int, v: float) -> None:
    m.tendon_damping[t] = v


def _set_tendon_stiffness(m: mujoco.MjModel, model: mujoco.MjModel, t: int, v: float) -> None:
    m.tendon_stiffness[t] = v


def _write_damping(doc: _Mjcf, dof: int, v: float) -> None:
    doc.joint_of_dof(dof).set("damping", number_text(v))


def _write_limit_scale(doc: _Mjcf, tendons: tuple[int, ...], v: float) -> None:
    for t in tendons:
        _scaled(doc.tendon(t), "stiffness", v, "0")


def _write_limit_timeconst(doc: _Mjcf, j: int, v: float) -> None:
    doc.find("joint", doc.model.joint(j).name).set("solreflimit", number_text([v, doc.model.jnt_solref[j, 1]]))


def _write_tendon_damping(doc: _Mjcf, t: int, v: float) -> None:
    doc.tendon(t).set("damping", number_text(v))


def _write_tendon_stiffness(doc: _Mjcf, t: int, v: float) -> None:
    doc.tendon(t).set("stiffness", number_text(v))


def _write_spring_scale(doc: _Mjcf, t: int, v: float) -> None:
    _scaled(doc.tendon(t), "stiffness", v, "0")


@dataclass(frozen=True)
class _Kind:
    """How one kind of parameter goes into a compiled model (``apply(copy, model, index, value)``)
    and into its MJCF (``write(doc, index, value)``): one entry, so the two cannot drift apart."""

    apply: Callable[[mujoco.MjModel, mujoco.MjModel, Any, float], None]
    write: Callable[[_Mjcf, Any, float], None]


_KINDS: dict[str, _Kind] = {
    "damping": _Kind(_set_damping, _write_damping),
    "limit_scale": _Kind(_scale_limits, _write_limit_scale),
    "limit_timeconst": _Kind(_set_limit_timeconst, _write_limit_timeconst),
    "tendon_damping": _Kind(_set_tendon_damping, _write_tendon_damping),
    "tendon_stiffness": _Kind(_set_tendon_stiffness, _write_tendon_stiffness),
    "spring_scale": _Kind(_scale_spring, _write_spring_scale),
    "muscle_scale": _Kind(_scale_muscle, _write_muscle_scale),
}


def parameter_space(model: mujoco.MjModel, dofs: Sequence[str], muscles: Sequence[str],
                    bounds: dict[str, tuple[float, float]] = BOUNDS, span: float = SPAN) -> ParameterSpace:
    """The paper's parameter vector for ``model``: 2 per free DoF, 2 per muscle tendon, 1 per muscle.

    Each is searched within ``span`` decades of its value in ``model`` and within ``bounds``.
    """
    names, start, lo, hi, targets, shifts = [], [], [], [], [], []

    def add(kind: str, element: str, idx, value: float) -> None:
        b_lo, b_hi = bounds[kind]
        names.append(f"{kind}:{element}")
        shift = b_lo if kind in ZERO_AT_LOWER else 0.0
        x0 = float(np.log10(np.clip(value + shift, b_lo, b_hi + shift)))
        start.append(x0)
        lo.append(max(float(np.log10(b_lo)), x0 - span))
        hi.append(min(float(np.log10(b_hi + shift)), x0 + span))
        shifts.append(shift)
        targets.append((kind, idx))

    for name in dofs:
        j = model.joint(name).id
        add("damping", name, int(model.jnt_dofadr[j]), float(model.dof_damping[model.jnt_dofadr[j]]))
        limits = limit_tendons(model, name)
        if limits:
            add("limit_scale", name, tuple(limits), 1.0)
        else:
            add("limit_timeconst", name, j, float(model.jnt_solref[j, 0]))
    for name in muscles:
        a = model.actuator(name).id
        if model.actuator_trntype[a] != mujoco.mjtTrn.mjTRN_TENDON:
            raise ValueError(f"muscle {name!r} does not act through a tendon")
        t = int(model.actuator_trnid[a, 0])
        add("tendon_damping", name, t, float(model.tendon_damping[t]))
        if model.tendon_stiffness[t] != 0 or np.any(model.tendon_stiffnesspoly[t] != 0):
            add("spring_scale", name, t, 1.0)
        else:
            add("tendon_stiffness", name, t, float(model.tendon_stiffness[t]))
    for name in muscles:
        add("muscle_scale", name, model.actuator(name).id, 1.0)
    return ParameterSpace(names, np.array(start), np.array(lo), np.array(hi), targets, np.array(shifts), span)


class TrajectoryObjective:
    """Squared joint error of candidate models against reference trajectories (see module doc).

    Args:
        model: the converted model.
        space: its :class:`ParameterSpace`.
        initial_states: shape (B, nstate), :func:`o2m.mujoco_sim.initial_state` of each trajectory.
        controls: shape (B, T - 1, nu).
        reference: OpenSim joint values, shape (B, T, len(dofs)), rad or m.
        dofs: the joints compared.
        penalty: weight of the squared log10 change of the parameters.
        nthread: rollout threads (default: all cores).
        executor: a :class:`concurrent.futures.Executor` (e.g. a Dask client's
            ``get_executor()``) that evaluates each candidate as one task (its rollouts on the
            worker's cores); None: every candidate in one batched rollout here.
    """

    def __init__(self, model: mujoco.MjModel, space: ParameterSpace, initial_states: np.ndarray,
                 controls: np.ndarray, reference: np.ndarray, dofs: Sequence[str], *, penalty: float = PENALTY,
                 nthread: int | None = None, executor: concurrent.futures.Executor | None = None):
        self.model, self.space = model, space
        self.initial_states = np.asarray(initial_states, float)
        self.controls = np.asarray(controls, float)
        self.reference = np.asarray(reference, float)
        self.dofs = list(dofs)
        self.penalty = penalty
        self.nthread = nthread
        self.executor = executor
        self.evaluations = 0
        if self.reference.shape[:2] != (self.controls.shape[0], self.controls.shape[1] + 1):
            raise ValueError(f"reference {self.reference.shape} does not match controls {self.controls.shape}")

    def simulate(self, xs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Joint trajectories of candidates ``xs`` (P, n): shape (P, B, T, n_dofs), and diverged (P, B)."""
        xs = np.atleast_2d(xs)
        n_traj = self.controls.shape[0]
        models = [self.space.apply(self.model, x) for x in xs]
        batch_models = [m for m in models for _ in range(n_traj)]
        init = np.tile(self.initial_states, (len(xs), 1))
        ctrl = np.tile(self.controls, (len(xs), 1, 1))
        tr = rollout(batch_models, init, ctrl, joint_names=self.dofs, nthread=self.nthread)
        self.evaluations += len(xs)
        shape = (len(xs), n_traj)
        return tr.coordinates.reshape(*shape, *tr.coordinates.shape[1:]), tr.diverged.reshape(shape)

    def joint_errors(self, xs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Mean squared error per candidate, trajectory and DoF, shape (P, B, n_dofs), and diverged (P, B)."""
        xs = np.atleast_2d(xs)
        if self.executor is not None:
            local = copy.copy(self)
            local.executor = None
            futures = [self.executor.submit(_candidate_errors, local, x) for x in xs]
            parts = [f.result() for f in futures]
            self.evaluations += len(xs)
            return np.stack([p[0] for p in parts]), np.stack([p[1] for p in parts])
        q, diverged = self.simulate(xs)
        with np.errstate(invalid="ignore", over="ignore"):
            mse = np.mean((q - self.reference[None]) ** 2, axis=2)
        mse[diverged] = DIVERGED_COST
        return np.nan_to_num(mse, nan=DIVERGED_COST, posinf=DIVERGED_COST), diverged

    def __call__(self, xs: np.ndarray) -> np.ndarray:
        """Cost of each candidate, shape (P,)."""
        xs = np.atleast_2d(xs)
        mse, _ = self.joint_errors(xs)
        return mse.sum(axis=(1, 2)) + self.penalty * np.sum((xs - self.space.x0) ** 2, axis=1)


def _candidate_errors(objective: TrajectoryObjective, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One candidate's :meth:`TrajectoryObjective.joint_errors`, for an executor's worker."""
    mse, diverged = objective.joint_errors(x[None])
    return mse[0], diverged[0]


@dataclass
class FitResult:
    """The outcome of :func:`fit_cma`.

    Attributes:
        names: parameter names; x: the chosen log10 values, shape (n,); x0: start values.
        cost, cost0: training objective of ``x`` and of the start.
        history: best training cost after each generation, shape (generations,).
        evaluations: objective evaluations (candidates); wall_time: seconds, summed over resumes.
        settings: everything that produced the fit (seed, sigma, popsize, penalty, bounds, data).
        validation_cost, validation_cost0: the validation objective of ``x`` and of the start
            (NaN without validation sets).
    """

    names: list[str]
    x: np.ndarray
    x0: np.ndarray
    cost: float
    cost0: float
    history: np.ndarray
    evaluations: int
    wall_time: float
    settings: dict
    validation_cost: float = float("nan")
    validation_cost0: float = float("nan")

    def values(self, space: ParameterSpace | None = None) -> dict[str, float]:
        """Physical values by name (``10**x`` unless ``space`` says how to map them)."""
        if space is not None:
            return space.values(self.x)
        return {n: float(10.0 ** v) for n, v in zip(self.names, self.x, strict=False)}


def checkpoint_matches(path: str | os.PathLike[str], space: ParameterSpace, seed: int,
                       model: str | None = None) -> bool:
    """Whether the :func:`fit_cma` checkpoint at ``path`` is of a fit over ``space`` (its
    parameters and start) with ``seed`` of the model file ``model`` (``settings["xml"]``), so that
    it can be resumed. Two models can share parameters and start and differ elsewhere (o2m's
    model with and without its passive fibres)."""
    with open(path, "rb") as f:
        state = pickle.load(f)
    same_start = "x0" in state and np.array_equal(state["x0"], space.x0)
    return (state["names"] == space.names and state["seed"] == seed and same_start
            and state.get("model") == model)


def fit_cma(objective: TrajectoryObjective, *, seed: int = 0, sigma0: float = 0.1, popsize: int | None = None,
            generations: int = 100, checkpoint: str | os.PathLike[str] | None = None, progress: bool = True,
            settings: dict | None = None, validation: TrajectoryObjective | None = None,
            early_stopping: bool = True) -> FitResult:
    """Minimise ``objective`` with CMA-ES over the unit box of its parameter space.

    Each generation's candidates are simulated together (:meth:`TrajectoryObjective.__call__`,
    one batched rollout). With ``checkpoint``, the optimiser is pickled there after every
    generation and a later call with the same file resumes from it. The best candidate ever
    seen is returned; it is never worse than the start (which is evaluated first). With
    ``validation`` (the same objective on held-out trajectories), every new best candidate is also
    scored there, and the one with the lowest validation cost is returned instead (the start
    included): early stopping, so that a fit of a few hard training sets cannot make the model
    worse elsewhere. With ``early_stopping=False`` (the paper's way) the best training candidate is
    returned and the validation objective only reports on it.
    """
    import cma
    from tqdm.auto import tqdm

    space = objective.space
    settings = dict(settings or {}, seed=seed, sigma0=sigma0, penalty=objective.penalty, early_stopping=early_stopping,
                    bounds={k: list(v) for k, v in BOUNDS.items()}, span=space.span)
    ckpt = Path(checkpoint) if checkpoint else None
    state = None
    if ckpt is not None and ckpt.exists():
        if not checkpoint_matches(ckpt, space, seed, settings.get("xml")):
            raise ValueError(f"checkpoint {ckpt} belongs to another fit (different parameters, start, seed or model); "
                             "delete it")
        with open(ckpt, "rb") as f:
            state = pickle.load(f)
    t_start = time.perf_counter()
    if state is None:
        cost0 = float(objective(space.x0[None])[0])
        opts = {"seed": seed + 1, "bounds": [0.0, 1.0], "verbose": -9}
        if popsize:
            opts["popsize"] = popsize
        es = cma.CMAEvolutionStrategy(space.to_unit(space.x0), sigma0, opts)
        val0 = float(validation(space.x0[None])[0]) if validation is not None else float("nan")
        state = {"names": space.names, "seed": seed, "x0": space.x0.copy(), "model": settings.get("xml"), "es": es,
                 "best_x": space.x0.copy(), "best": cost0,
                 "cost0": cost0, "history": [], "wall": 0.0, "evals": 1,
                 "val0": val0, "val_best": val0, "val_x": space.x0.copy(), "val_train_cost": cost0}
    if validation is not None and "val_best" not in state:  # a checkpoint written without validation
        val0 = float(validation(space.x0[None])[0])
        state.update(val0=val0, val_best=val0, val_x=space.x0.copy(), val_train_cost=state["cost0"])
    es = state["es"]
    bar = tqdm(total=generations, initial=len(state["history"]), desc="CMA-ES", unit="gen", disable=not progress)
    while len(state["history"]) < generations:
        zs = es.ask()
        xs = np.array([space.from_unit(z) for z in zs])
        costs = objective(xs)
        es.tell(zs, costs.tolist())
        state["evals"] += len(zs)
        k = int(np.argmin(costs))
        if costs[k] < state["best"]:
            state["best"], state["best_x"] = float(costs[k]), xs[k].copy()
            if validation is not None:
                v = float(validation(xs[k][None])[0])
                if v < state["val_best"]:
                    state["val_best"], state["val_x"], state["val_train_cost"] = v, xs[k].copy(), float(costs[k])
        state["history"].append(state["best"])
        state["wall"] += time.perf_counter() - t_start
        t_start = time.perf_counter()
        if ckpt is not None:
            tmp = ckpt.with_suffix(".tmp")
            with open(tmp, "wb") as f:
                pickle.dump(state, f)
            os.replace(tmp, ckpt)
        bar.set_postfix(best=f"{state['best']:.4g}", start=f"{state['cost0']:.4g}",
                        **({"validation": f"{state['val_best']:.4g}"} if validation is not None else {}))
        bar.update()
    bar.close()
    state["wall"] += time.perf_counter() - t_start
    val_cost = state.get("val_best", float("nan"))
    if validation is not None and early_stopping:
        x, cost = state["val_x"], state["val_train_cost"]
    else:
        x, cost = state["best_x"], state["best"]
        if validation is not None:  # scored, not chosen by: what the paper's fit does off its training sets
            val_cost = float(validation(x[None])[0])
    return FitResult(space.names, x, space.x0.copy(), cost, state["cost0"], np.array(state["history"]),
                     state["evals"], state["wall"], dict(settings, generations=generations, popsize=es.popsize,
                                                         best_training_cost=state["best"]),
                     val_cost, state.get("val0", float("nan")))


def save_fit(path: str | os.PathLike[str], result: FitResult, space: ParameterSpace | None = None) -> Path:
    """Write a fit as JSON (names, searched log10 variables, physical values when ``space`` is given,
    costs, history, settings)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    doc = {"names": result.names, "x": result.x.tolist(), "x0": result.x0.tolist(),
           "values": result.values(space) if space is not None else None,
           "cost": result.cost, "cost0": result.cost0, "history": result.history.tolist(),
           "evaluations": result.evaluations, "wall_time_s": result.wall_time, "settings": result.settings,
           "validation_cost": result.validation_cost, "validation_cost0": result.validation_cost0}
    path.write_text(json.dumps(doc, indent=1) + "\n")
    return path


def load_fit(path: str | os.PathLike[str]) -> FitResult:
    """Read a fit written by :func:`save_fit`."""
    d = json.loads(Path(path).read_text())
    return FitResult(d["names"], np.array(d["x"]), np.array(d["x0"]), d["cost"], d["cost0"], np.array(d["history"]),
                     d["evaluations"], d["wall_time_s"], d["settings"], d.get("validation_cost", float("nan")),
                     d.get("validation_cost0", float("nan")))
