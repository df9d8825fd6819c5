"""MuJoCo step settings chosen from the converted model's structure: the constraint Jacobian's
layout (``opt.jacobian``) and whether collision detection runs (``<flag contact>``).

Both change what a step costs, never what it computes:

* ``jacobian="sparse"`` when the Newton solver's Hessian (the inertia matrix plus the couplings
  of the joint equalities) would factor into at most :data:`SPARSE_FILL` of a dense factor's
  nonzeros (:func:`factor_fill`). MuJoCo's own choice (``auto``) is sparse from 60 degrees of
  freedom on, whatever the structure; a musculoskeletal model has fewer, most of them leaves
  (path-point carriers) tied to a few coordinates. Measured with MuJoCo 4.0.1 (callgrind, one
  1-s simulation at 2 ms): MoBL-ARMS no-wrap (nv 42, factor fill 0.45) 4.3 % fewer instructions
  sparse, Gait10dof18musc (nv 52, fill 0.37) 11.7 % fewer; Arm26 (nv 5, fill 0.80) 11 % more and
  MoBL-ARMS without carriers (nv 16, fill 0.79) 4.5 % more, so those stay dense. The trajectories
  agree to 2.5e-9 rad over 1 s. Only with MuJoCo 4.0.1 or later: 4.0.0's sparse Cholesky
  factorization can give Newton a wrong Hessian factor (google-deepmind/mujoco#3767).
* ``contact="disable"`` when no two geoms can collide (every geom's ``contype`` and
  ``conaffinity`` zero, or no pair of them matching), there are no explicit contact pairs and no
  flexes: collision detection then finds nothing, and costs its broad phase every step (MoBL-ARMS
  no-wrap: 0.8 % of a step's instructions). A model with contacts keeps it.
"""

from __future__ import annotations

import re

import mujoco
import numpy as np

__all__ = ["SPARSE_FILL", "SPARSE_MIN_MUJOCO", "can_collide", "choose_step_options", "factor_fill", "sparse_pays"]

#: Largest fraction of a dense Cholesky factor's nonzeros (lower triangle) at which o2m asks for
#: MuJoCo's sparse Jacobian and Hessian (the measurements in the module docstring: 0.37-0.45
#: gained, 0.79-0.80 lost).
SPARSE_FILL = 0.5

#: First MuJoCo release whose sparse Cholesky factorization the Newton solver can rely on.
SPARSE_MIN_MUJOCO = (4, 0, 1)


def _coupling_pattern(model: mujoco.MjModel) -> np.ndarray:
    """Structural nonzeros (nv, nv) of the Newton Hessian: each dof with its ancestors (the
    inertia matrix) and the two dofs of every active two-joint equality."""
    pattern = np.eye(model.nv, dtype=bool)
    for dof in range(model.nv):
        parent = model.dof_parentid[dof]
        while parent >= 0:
            pattern[dof, parent] = pattern[parent, dof] = True
            parent = model.dof_parentid[parent]
    for e in np.flatnonzero(model.eq_active0):
        if model.eq_type[e] == mujoco.mjtEq.mjEQ_JOINT and model.eq_obj2id[e] >= 0:
            a, b = model.jnt_dofadr[model.eq_obj1id[e]], model.jnt_dofadr[model.eq_obj2id[e]]
            pattern[a, b] = pattern[b, a] = True
    return pattern


def factor_fill(model: mujoco.MjModel) -> float:
    """Nonzeros of the Hessian's Cholesky factor (:func:`_coupling_pattern`, dofs eliminated from
    the last to the first, leaves before their ancestors as MuJoCo factors the inertia matrix) as a
    fraction of a dense factor's nv (nv + 1) / 2; 1.0 without degrees of freedom."""
    nv = model.nv
    if nv == 0:
        return 1.0
    pattern = _coupling_pattern(model)
    nonzeros = 0
    for k in range(nv - 1, -1, -1):
        earlier = np.flatnonzero(pattern[k, :k])
        nonzeros += len(earlier) + 1
        pattern[np.ix_(earlier, earlier)] = True  # eliminating k couples its remaining neighbours
    return nonzeros / (nv * (nv + 1) / 2)


def sparse_pays(model: mujoco.MjModel) -> bool:
    """Whether the sparse constraint Jacobian should step ``model`` faster: its Hessian factor
    fills at most :data:`SPARSE_FILL` of a dense one."""
    return model.nv > 0 and factor_fill(model) <= SPARSE_FILL


def can_collide(model: mujoco.MjModel) -> bool:
    """Whether collision detection could ever find a contact in ``model``: explicit pairs, flexes,
    or two geoms whose ``contype`` and ``conaffinity`` bits match (one geom with itself counts,
    as two geoms of that kind may exist)."""
    if model.npair or model.nflex:
        return True
    types, affinities = np.unique(model.geom_contype), np.unique(model.geom_conaffinity)
    return bool(np.any((types[:, None] & affinities[None, :]) != 0))


def _version(text: str) -> tuple[int, ...]:
    """``"4.0.1"`` -> (4, 0, 1); a suffix such as ``rc1`` is ignored."""
    return tuple(int(part) for part in re.findall(r"\d+", text)[:3])


def choose_step_options(spec: mujoco.MjSpec, model: mujoco.MjModel, mujoco_version: str) -> list[str]:
    """Set ``spec``'s Jacobian layout and contact flag from its compiled ``model`` (see the module
    docstring) for MuJoCo ``mujoco_version`` (e.g. ``mujoco.__version__``); returns report notes,
    one per setting made."""
    notes = []
    if sparse_pays(model) and _version(mujoco_version) >= SPARSE_MIN_MUJOCO:
        spec.option.jacobian = mujoco.mjtJacobian.mjJAC_SPARSE
        notes.append(f"sparse constraint Jacobian (<option jacobian=\"sparse\">): the Newton Hessian's factor fills "
                     f"{factor_fill(model):.2f} of a dense one (nv {model.nv})")
    if not can_collide(model):
        spec.option.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
        notes.append("collision detection off (<flag contact=\"disable\"/>): no two geoms can collide and there "
                     "are no contact pairs")
    return notes
