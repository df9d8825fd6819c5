"""MuJoCo's constraint islands, switched off when a model can only ever have one.

MuJoCo (``mjDSBL_ISLAND`` clear, its default) splits the active constraints every step into
islands of kinematic trees they tie together and solves each island apart. That pays when the
islands are several; when every tree with degrees of freedom is tied to every other by joint
equalities that are always on (a musculoskeletal model: one skeleton tree, and path-point carriers
on a body welded to the world tied to its coordinates), the one island is the whole model and the
search for it is pure cost. Measured, MoBL-ARMS no-wrap (nv 42, 37 equalities, one island): 1-s
simulations take about 7 % less thread CPU time with islands off, and the test-set trajectories
are the same to float32.
"""

from __future__ import annotations

import mujoco
import numpy as np


def always_one_island(model: mujoco.MjModel) -> bool:
    """Whether ``model`` has degrees of freedom in one kinematic tree, or in several each tied to
    the others by active joint equalities: its constraint islands can then never be more than one,
    and that one covers every degree of freedom. Equalities of other kinds are not followed (False
    unless the joint equalities alone tie the trees)."""
    trees = sorted({int(t) for t in model.dof_treeid})
    if not trees:
        return False
    parent = {t: t for t in trees}

    def root(t: int) -> int:
        while parent[t] != t:
            t = parent[t]
        return t

    for e in np.flatnonzero(model.eq_active0):
        if model.eq_type[e] != mujoco.mjtEq.mjEQ_JOINT or model.eq_obj2id[e] < 0:
            continue
        a, b = (int(model.dof_treeid[model.jnt_dofadr[model.eq_obj1id[e]]]),
                int(model.dof_treeid[model.jnt_dofadr[model.eq_obj2id[e]]]))
        parent[root(a)] = root(b)
    return len({root(t) for t in trees}) == 1


def disable_single_island(spec: mujoco.MjSpec, model: mujoco.MjModel) -> bool:
    """Set ``mjDSBL_ISLAND`` on ``spec`` when its compiled ``model`` always has one island
    (:func:`always_one_island`); returns whether it did."""
    if not always_one_island(model):
        return False
    spec.option.disableflags |= mujoco.mjtDisableBit.mjDSBL_ISLAND
    return True
