"""o2m's Schutte stage: the converted MoBL-ARMS with OpenSim's own muscles inside MuJoCo.

MoBL-ARMS's 50 muscles are Schutte1993Muscle_Deprecated: elastic tendons in series with fibres
whose lengths are states. MuJoCo's muscle (rigid tendon, no fibre state) cannot follow their
tendon force's lag behind activation, nor a passive fibre that stays long after a stretch, and
a 1-s open-loop trajectory of these antagonist-balanced muscles moves by about 0.017 rad per 1 %
of force (docs/paper.md, the floor). :func:`schutte_experiment` replaces every muscle of the
converted model by the ``o2m.schutte`` actuator plugin (:mod:`o2m.mj.schutte_plugin`), each with
the muscle's own parameters and curves read from the ``.osim`` (:mod:`o2m.osim.schutte`), and
starts each set where OpenSim started: its initial activations and fibre lengths. Nothing is
fitted.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

import mujoco
import numpy as np

from o2m import models
from o2m.mj.schutte_plugin import load, schutte_state, with_schutte_muscles
from o2m.osim.schutte import schutte_muscles
from o2m.paper.passive_stage import initial_fibre_lengths

if TYPE_CHECKING:
    from o2m.paper.pipeline import Experiment

__all__ = ["schutte_experiment", "schutte_xml"]


def schutte_xml(exp: Experiment) -> Path:
    """Where :func:`schutte_experiment` writes its model: ``<stem>_schutte.xml`` beside the converted one."""
    return exp.xml.with_name(exp.xml.stem + "_schutte.xml")


def schutte_experiment(exp: Experiment, plugin_folder: str | Path, like: Experiment | None = None) -> Experiment:
    """``exp`` for the converted model with each muscle an ``o2m.schutte`` actuator (the plugin
    built in ``plugin_folder``; :class:`o2m.errors.O2MError` without a C compiler), written to
    :func:`schutte_xml`, or ``like``'s model and file when given (another dataset of the same
    model: nothing is read or written again); each set's initial state (n_sets, nstate) has
    OpenSim's initial activations (those of ``exp.init``) and fibre lengths (the dataset's initial
    state file)."""
    load(plugin_folder)
    if like is None:
        muscles = schutte_muscles(models.fetch(exp.dataset.meta["model"]), exp.muscles)
        xml = with_schutte_muscles(exp.xml, schutte_xml(exp), muscles)
        model = mujoco.MjModel.from_xml_path(str(xml))
    else:
        xml, model = like.xml, like.model
    init = np.full((len(exp.init), mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS)), np.nan)
    ran = np.flatnonzero(np.isfinite(exp.init).all(axis=1))
    init[ran] = schutte_state(model, exp.model, exp.init[ran], initial_fibre_lengths(exp))
    return replace(exp, model=model, xml=xml, init=init)
