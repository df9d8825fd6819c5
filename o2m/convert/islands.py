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
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components


def always_one_island(model: mujoco.MjModel) -> bool:
    """Whether ``model`` has degrees of freedom in one kinematic tree, or in several each tied to
    the others by active joint equalities: its constraint islands can then never be more than one,
    and that one covers every degree of freedom. Equalities of other kinds are not followed (False
    unless the joint equalities alone tie the trees)."""
    trees = np.unique(model.dof_treeid)
    if not len(trees):
        return False
    ties = [e for e in np.flatnonzero(model.eq_active0)
            if model.eq_type[e] == mujoco.mjtEq.mjEQ_JOINT and model.eq_obj2id[e] >= 0]
    tree_of = {int(t): i for i, t in enumerate(trees)}  # tree id -> graph node
    ends = [[tree_of[int(model.dof_treeid[model.jnt_dofadr[model.eq_obj1id[e]]])] for e in ties],
            [tree_of[int(model.dof_treeid[model.jnt_dofadr[model.eq_obj2id[e]]])] for e in ties]]
    graph = coo_matrix((np.ones(len(ties)), ends), shape=(len(trees), len(trees)))
    return connected_components(graph, directed=False)[0] == 1


def disable_single_island(spec: mujoco.MjSpec, model: mujoco.MjModel) -> bool:
    """Set ``mjDSBL_ISLAND`` on ``spec`` when its compiled ``model`` always has one island
    (:func:`always_one_island`); returns whether it did."""
    if not always_one_island(model):
        return False
    spec.option.disableflags |= mujoco.mjtDisableBit.mjDSBL_ISLAND
    return True
