"""o2m's passive-fibre stage: each set's never-excited muscles pull as OpenSim's passive fibres.

A Schutte1993 muscle that is never excited in a set keeps its fibre as long as it has ever been
there (:mod:`o2m.osim.fibres`, measured in :mod:`o2m.paper.passive`), which a MuJoCo muscle's
memoryless passive force cannot do. :func:`fibre_experiment` writes a model (in the pipeline, the
force-fitted one, before CMA-ES) with an ``o2m.fibre`` plugin instance (:mod:`o2m.mj.fibre_plugin`)
on each muscle that crosses the elbow or pro_sup, and lays out each set's initial state with the
instances of that set's never-excited muscles on, at the fibre lengths OpenSim started from, and
the others off. One model then runs every set, through ``mujoco.rollout`` like any other stage.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

import mujoco
import numpy as np

from o2m import models
from o2m.mj.fibre_plugin import fibre_state, load, with_fibres
from o2m.mj.posing import joint_equality_plan, pose_mujoco
from o2m.osim.fibres import PassiveFibre, passive_fibres
from o2m.osim.simulate import read_initial_state

if TYPE_CHECKING:
    from o2m.paper.pipeline import Experiment

__all__ = ["FIBRE_DOFS", "crossing", "fibre_experiment", "fibre_muscles", "initial_fibre_lengths", "passive_muscles",
           "with_passive_fibres"]

#: The muscles crossing these DoFs get fibres. On all never-excited muscles, OpenSim's curves on
#: MuJoCo's shoulder lengths made the shoulder worse (docs/paper.md, the passive muscles).
FIBRE_DOFS = ("elbow_flexion", "pro_sup")


def passive_muscles(exp: Experiment, i: int, among: Sequence[str] | None = None) -> list[str]:
    """Muscles (of ``among``, default all) never excited in set ``i``."""
    ds = exp.dataset
    cols = [list(ds.activations.muscles).index(m) for m in exp.muscles]
    exc = ds.activations.values[i][:, cols]
    return [m for j, m in enumerate(exp.muscles) if np.all(exc[:, j] == 0) and (among is None or m in among)]


def initial_fibre_lengths(exp: Experiment) -> dict[str, float]:
    """Fibre lengths (m) the dataset's OpenSim runs started from (its initial state file)."""
    state = read_initial_state(models.fetch(exp.dataset.meta["initial_state"]))
    return {m: float(state[f"{m}.fiber_length"]) for m in exp.muscles if f"{m}.fiber_length" in state}


def crossing(exp: Experiment, model: mujoco.MjModel, dof: str, i: int = 0) -> list[str]:
    """The muscles whose length changes with ``dof`` (moment arm above 1 mm) at set ``i``'s initial pose."""
    plan = joint_equality_plan(model)
    data = mujoco.MjData(model)
    pose = {n: v for n, v in zip(exp.dataset.coordinate_names, exp.dataset.coordinates[i, 0], strict=True)
            if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, n) >= 0}
    lengths = []
    for dq in (-1e-4, 1e-4):
        pose_mujoco(model, data, {**pose, dof: pose[dof] + dq}, plan=plan)
        mujoco.mj_tendon(model, data)
        mujoco.mj_transmission(model, data)
        lengths.append(data.actuator_length.copy())
    arm = (lengths[1] - lengths[0]) / 2e-4
    return [m for m in exp.muscles if abs(arm[model.actuator(m).id]) > 1e-3]


def fibre_muscles(exp: Experiment, model: mujoco.MjModel, dofs: Sequence[str] = FIBRE_DOFS) -> list[str]:
    """The muscles that get fibres: those crossing any of ``dofs`` at the first set's initial pose
    (every set of the dataset starts there)."""
    first = int(np.flatnonzero(exp.dataset.ok)[0])
    return sorted(set().union(*(crossing(exp, model, d, first) for d in dofs)))


def fibre_experiment(exp: Experiment, xml: str | Path, plugin_folder: str | Path,
                     muscles: Sequence[str] | None = None) -> Experiment:
    """``exp`` for the model of ``xml`` (in the pipeline, the force-fitted one) with OpenSim's
    passive fibres on ``muscles`` (default :func:`fibre_muscles`), each set starting from
    OpenSim's initial fibre lengths: :func:`with_passive_fibres`. Needs a C compiler for the plugin (built in
    ``plugin_folder``; :class:`o2m.errors.O2MError` without one)."""
    load(plugin_folder)
    muscles = list(muscles) if muscles is not None else fibre_muscles(exp, mujoco.MjModel.from_xml_path(str(xml)))
    fibres = passive_fibres(models.fetch(exp.dataset.meta["model"]), muscles)
    return with_passive_fibres(exp, xml, fibres, initial_fibre_lengths(exp))


def with_passive_fibres(exp: Experiment, xml: str | Path, fibres: dict[str, PassiveFibre],
                        start: dict[str, float]) -> Experiment:
    """``exp`` for the model of ``xml`` with an ``o2m.fibre`` instance on each muscle of ``fibres``
    (the plugin loaded by the caller), written to ``<xml stem>_fibres.xml`` beside ``xml``. Its
    initial states (n_sets, nstate): per set, the instances of the never-excited muscles on at
    their ``start`` fibre lengths (m), the others off."""
    xml = Path(xml)
    out = with_fibres(xml, xml.with_name(xml.stem + "_fibres.xml"), fibres)
    model = mujoco.MjModel.from_xml_path(str(out))
    init = np.full((len(exp.init), mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS)), np.nan)
    for i in np.flatnonzero(np.isfinite(exp.init).all(axis=1)):
        init[i] = fibre_state(model, exp.init[i], {m: start[m] for m in passive_muscles(exp, i, list(fibres))})
    return replace(exp, model=model, xml=out, init=init)
