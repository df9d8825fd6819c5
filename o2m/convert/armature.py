"""Armature of the joints a coupling adds beside a coordinate's joint: extra joints and complements.

An extra joint (:mod:`o2m.convert.coupling_plan`) or a complement joint (a coordinate reaching
its axis through a function, :class:`~o2m.convert.coordinates.CoordinateAxis`) shares its axis
with a main joint, so without armature the mass matrix would be singular. Each gets a multiple of
its main joint's own inertia at the reference pose (kg m² for hinges, kg for slides), and the
report records what that adds to the coordinate's inertia at most.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import mujoco
import numpy as np

from o2m.convert.coupling_plan import extra_armature
from o2m.convert.records import MIN_INERTIA, Approximation

if TYPE_CHECKING:
    from o2m.convert.builder import MjcfBuilder

__all__ = ["COMPLEMENT_ARMATURE", "main_inertias", "set_complement_armature", "set_extra_armature"]

#: A complement joint's armature, as a fraction of its coordinate joint's own inertia: enough to
#: keep the mass matrix regular, small beside what the coordinate moves.
COMPLEMENT_ARMATURE = 0.01


def main_inertias(builder: MjcfBuilder, joints: list[str]) -> dict[str, float]:
    """Each of ``joints``' own inertia (kg or kg m², the diagonal of the mass matrix) at the
    reference pose in the skeleton with plain quartic couplings; {} if it does not compile."""
    plain = type(builder)(builder.skel, plan_couplings=False)
    plain.build()
    try:
        m = plain.spec.compile()
    except ValueError:
        return {}
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    inertia = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, inertia)
    dofs = {j: int(m.jnt_dofadr[m.joint(j).id]) for j in joints}
    return {j: float(inertia[k, k]) for j, k in dofs.items()}

def set_complement_armature(builder: MjcfBuilder) -> None:
    """Give each complement joint :data:`COMPLEMENT_ARMATURE` times its coordinate joint's own
    inertia at the reference pose as armature (the two share an axis, so without it the mass
    matrix is singular) and record what that adds to the coordinate's inertia at most
    (armature times the largest (f'(q) - 1)² over the coordinate's range)."""
    if not builder._complements:
        return
    try:
        m = builder.spec.compile()
    except ValueError:
        return  # the conversion's own compile reports what is wrong
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    inertia = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, inertia)
    for coord, (name, ax) in builder._complements.items():
        dof = int(m.jnt_dofadr[m.joint(coord).id])
        armature = COMPLEMENT_ARMATURE * max(float(inertia[dof, dof] - m.dof_armature[dof]), MIN_INERTIA)
        builder.spec.joint(name).armature = armature
        lo, hi = builder.coupling_range(coord)
        q = np.linspace(lo, hi, 401)
        slope = np.gradient(np.asarray(ax.function(q), dtype=float), q) - 1.0
        unit = "kg m^2" if ax.kind == "rotation" else "kg"
        builder.result.approximations.append(Approximation(
            "Coordinate", coord, f"armature of complement joint '{name}' (shares the coordinate joint's axis)",
            float(armature * np.max(slope**2)), unit, f"armature {armature:.3g} {unit}"))

def set_extra_armature(builder: MjcfBuilder) -> None:
    """Give every extra joint of a coupled axis its armature
    (:func:`~o2m.convert.coupling_plan.extra_armature`: a multiple of the main joint's own
    inertia at the reference pose, the skeleton compiled as built so far) and add to each
    axis's approximation how much its extra joints add to the inertia of its coordinate at
    most."""
    mains = builder._extras_of
    if not mains:
        return
    try:
        m = builder.spec.compile()
    except ValueError:
        return  # the conversion's own compile reports what is wrong
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    inertia = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, inertia)
    own = {}
    for main in mains:
        dof = int(m.jnt_dofadr[m.joint(main).id])
        own[main] = float(inertia[dof, dof] - m.dof_armature[dof])
    armature, added = extra_armature(builder._planned, mains, own)
    for name, value in armature.items():
        builder.spec.joint(name).armature = value
    approx = {a.joint: a for a in builder.result.approximations if a.joint}
    for main, recs in mains.items():
        planned = builder._planned[main]
        a = approx.get(main)
        if a is not None:
            unit = "kg" if m.jnt_type[m.joint(main).id] == mujoco.mjtJoint.mjJNT_SLIDE else "kg m^2"
            base = planned.axes[planned.index].base
            coord_unit = "kg m^2" if builder.coord_joint[base][1].kind == "rotation" else "kg"
            arms = ", ".join(f"{armature[n]:.3g}" for n in recs)
            a.detail += f"; armature {arms} {unit}, adding at most {added[main]:.3g} {coord_unit} to '{base}'"
