"""Mass and armature of the MuJoCo bodies and joints :class:`~o2m.convert.builder.MjcfBuilder` makes.

A body's inertial is OpenSim's (kg, m, kg m², in the body frame), raised where MuJoCo needs more
(a moving massless body, a non-positive or non-physical inertia; each recorded as an
approximation); the extra joints of couplings and complement joints get armatures scaled by the
inertia of the joints they share an axis with (kg or kg m²). Each function takes the builder.
"""

from __future__ import annotations

import mujoco
import numpy as np

from o2m.convert.coupling_plan import extra_armature
from o2m.convert.records import Approximation
from o2m.osim.skeleton import Joint

#: Mass (kg) and principal inertia (kg m²) given to massless moving bodies, which MuJoCo rejects.
MIN_MASS = 1e-8
MIN_INERTIA = 1e-12
#: Mass (kg) and principal inertia (kg m²) of an intermediate body carrying a joint's
#: translations (or an ellipsoid joint's first hinges): just above what MuJoCo accepts, so the
#: model's mass and centre of mass stay OpenSim's. Its joints move the OpenSim body hanging from
#: it, so their inertia is that body's.
COUPLINGS_BODY_MASS = 1e-12
COUPLINGS_BODY_INERTIA = 1e-14
#: A complement joint's armature, as a fraction of its coordinate joint's own inertia: enough to
#: keep the mass matrix regular, small beside what the coordinate moves.
COMPLEMENT_ARMATURE = 0.01


def main_inertias(builder, joints: list[str]) -> dict[str, float]:
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


def _mass_matrix(spec: mujoco.MjSpec) -> tuple[mujoco.MjModel, np.ndarray] | None:
    """The spec compiled and its mass matrix (nv, nv) at the reference pose; None if it does not compile."""
    try:
        m = spec.compile()
    except ValueError:
        return None
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    inertia = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, inertia)
    return m, inertia


def set_complement_armature(builder) -> None:
    """Give each complement joint :data:`COMPLEMENT_ARMATURE` times its coordinate joint's own
    inertia at the reference pose as armature (the two share an axis, so without it the mass
    matrix is singular) and record what that adds to the coordinate's inertia at most
    (armature times the largest (f'(q) - 1)² over the coordinate's range)."""
    if not builder._complements:
        return
    compiled = _mass_matrix(builder.spec)
    if compiled is None:
        return  # the conversion's own compile reports what is wrong
    m, inertia = compiled
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


def set_extra_armature(builder) -> None:
    """Give every extra joint of a coupled axis its armature
    (:func:`~o2m.convert.coupling_plan.extra_armature`: a multiple of the main joint's own
    inertia at the reference pose, the skeleton compiled as built so far) and add to each
    axis's approximation how much its extra joints add to the inertia of its coordinate at
    most."""
    mains = builder._extras_of
    if not mains:
        return
    compiled = _mass_matrix(builder.spec)
    if compiled is None:
        return  # the conversion's own compile reports what is wrong
    m, inertia = compiled
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


def set_inertial(builder, body: mujoco.MjsBody, joint: Joint) -> None:
    """Give MuJoCo body ``body`` the inertial of ``joint``'s child, raised where MuJoCo needs more."""
    b = builder.skel.bodies[joint.child]
    mass, inertia = b.mass, b.inertia.copy()
    if mass == 0.0:  # OpenSim ignores the inertia of a massless body
        inertia[:] = 0.0
    moving = not all(builder.is_fixed(ax) for ax in joint.rotations + joint.translations)
    if moving and mass < MIN_MASS:
        builder.result.approximations.append(Approximation(
            "Body", b.name, f"massless moving body given {MIN_MASS:g} kg (MuJoCo needs mass)", MIN_MASS, "kg"))
        mass = MIN_MASS
    eig = np.linalg.eigvalsh(inertia)
    if eig.min() < MIN_INERTIA:  # MuJoCo needs positive inertia, also on welded bodies
        raised = MIN_INERTIA - min(0.0, eig.min())
        inertia = inertia + np.eye(3) * raised
        builder.result.approximations.append(Approximation(
            "Body", b.name, f"inertia raised by {raised:g} kg m² (MuJoCo needs positive inertia)",
            raised, "kg m^2"))
    inertia = physical_inertia(builder, b.name, inertia)
    body.explicitinertial = True
    body.mass = mass
    body.ipos = b.com
    body.fullinertia = [inertia[0, 0], inertia[1, 1], inertia[2, 2], inertia[0, 1], inertia[0, 2], inertia[1, 2]]
    builder.exact[("inertial", b.name)] = {"pos": b.com, "mass": mass, "fullinertia": np.array(body.fullinertia)}


def physical_inertia(builder, name: str, inertia: np.ndarray) -> np.ndarray:
    """``inertia`` (3, 3), with its largest principal moment lowered to the sum of the other two
    when it breaks the triangle inequality A + B >= C, which MuJoCo enforces."""
    eig, vec = np.linalg.eigh(inertia)
    if eig[0] + eig[1] >= eig[2] * (1 - 1e-12):
        return inertia
    fixed = eig.copy()
    # inside by more than the MJCF's printed precision, and never below the middle moment (with the
    # smallest about 0, lowering the largest below the middle one would break the inequality again)
    fixed[2] = max(eig[1], (eig[0] + eig[1]) * (1 - 1e-5))
    builder.result.approximations.append(Approximation(
        "Body", name, "largest principal inertia lowered to the sum of the other two (A + B >= C)",
        float(eig[2] - fixed[2]), "kg m^2", f"from {eig[2]:.4g} to {fixed[2]:.4g}"))
    return vec @ np.diag(fixed) @ vec.T
