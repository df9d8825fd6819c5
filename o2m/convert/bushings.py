"""BushingForce as a linear spring and damper on the one joint between its two frames.

OpenSim's BushingForce deflects frame 2 against frame 1 by X-Y-Z body-fixed angles θ and a
translation p (in frame 1) and applies ``-K θ - D θ̇`` and ``-K p - D ṗ``, diagonal K and D (N m/rad,
N/m; N m s/rad, N s/m), as generalized forces on those six deflections. Where its two frames are
on the two bodies of one joint with one free coordinate q and every stiff or damped deflection is
linear in q (θ_i = θ_i(q_a) + c_i (q - q_a): the joint turns or slides about one of the bushing's
axes), the bushing's generalized force on q is exactly ``-(Σ K_i c_i²)(q - springref) - (Σ D_i c_i²)
q̇``: a MuJoCo joint spring (``stiffness``, ``springref``) and ``damping``, added to the joint's
others (:func:`o2m.convert.limit_forces.set_joint_passive`). Other bushings are skipped (MuJoCo has
no six-axis spring between two frames); the report says so. Angles in radians, lengths in metres.
"""

from __future__ import annotations

import numpy as np
from lxml import etree
from scipy.spatial.transform import Rotation

from o2m.convert.force_context import JointSpring, _Context, _vector
from o2m.convert.limit_forces import set_joint_passive
from o2m.osim.skeleton import Joint, Skipped

__all__ = ["BUSHING_LINEAR_TOLERANCE", "convert_bushing"]

#: A deflection counts as linear in its joint's coordinate when a line fits it within this
#: (rad or m) over the coordinate's range.
BUSHING_LINEAR_TOLERANCE = 1e-9
_SAMPLES = 41


def _one_joint(ctx: _Context, body1: str, body2: str) -> Joint | None:
    """The joint between bodies ``body1`` and ``body2`` (either one the parent), if any."""
    for joint in ctx.builder.skel.joints:
        if {joint.parent, joint.child} == {body1, body2}:
            return joint
    return None


def _free_coordinates(ctx: _Context, joint: Joint) -> list[str]:
    b = ctx.builder
    return [c for c in joint.coordinates if c in b.coord_joint and b.drivers[c].base == c
            and not b.skel.coordinates[c].locked]


def convert_bushing(ctx: _Context, el: etree._Element) -> None:
    """BushingForce -> the spring and damping of the joint between its frames (see the module)."""
    b = ctx.builder
    name = el.get("name")
    if el.find("socket_frame1") is None or el.find("socket_frame2") is None:
        ctx.out.skipped.append(Skipped(el.tag, name, "an OpenSim 3.x bushing (no socket_frame1/2) is not converted; "
                                       "its bodies move without its spring and damping"))
        return
    body1, x1, _ = ctx.reader.socket_frame(el, "socket_frame1")
    body2, x2, _ = ctx.reader.socket_frame(el, "socket_frame2")
    gains = np.concatenate([_vector(el, "rotational_stiffness", (0.0, 0.0, 0.0), ctx),
                            _vector(el, "translational_stiffness", (0.0, 0.0, 0.0), ctx)])
    damps = np.concatenate([_vector(el, "rotational_damping", (0.0, 0.0, 0.0), ctx),
                            _vector(el, "translational_damping", (0.0, 0.0, 0.0), ctx)])
    joint = _one_joint(ctx, body1, body2)
    coords = _free_coordinates(ctx, joint) if joint is not None else []
    if len(coords) != 1:
        where = "not on the two bodies of one joint" if joint is None else \
            f"on joint '{joint.name}' with {len(coords)} free coordinates"
        ctx.out.skipped.append(Skipped(el.tag, name, f"its frames are {where} (MuJoCo has no six-axis spring between "
                                       "two frames); its bodies move without its spring and damping"))
        return
    q = coords[0]
    lo, hi = b.fit_range(q, b.coord_joint[q][1].kind)
    qs = np.linspace(lo, hi, _SAMPLES)
    defl = np.array([_deflection(ctx, {q: float(v)}, (body1, x1), (body2, x2)) for v in qs])  # (n, 6)
    slope, offset = np.polyfit(qs, defl, 1)
    residual = np.max(np.abs(np.outer(qs, slope) + offset - defl), axis=0)
    acting = (gains != 0.0) | (damps != 0.0)
    if np.any(residual[acting] > BUSHING_LINEAR_TOLERANCE):
        ctx.out.skipped.append(Skipped(el.tag, name, f"its deflections are not linear in '{q}' (up to "
                                       f"{float(residual[acting].max()):.3g} rad or m off a line): MuJoCo has no "
                                       "such spring; its bodies move without its spring and damping"))
        return
    k = float(np.sum(gains * slope ** 2))
    ref = float(-np.sum(gains * slope * offset) / k) if k != 0.0 else 0.0
    ctx.out.joint_springs.append(JointSpring(name, q, k, ref, float(np.sum(damps * slope ** 2))))
    set_joint_passive(ctx, ctx.spec.joint(q), q)


def _deflection(ctx: _Context, changes: dict[str, float], end1, end2) -> np.ndarray:
    """(6,): frame 2's X-Y-Z body-fixed angles (rad) and origin (m) in frame 1 at a pose."""
    b = ctx.builder
    frames = b.ground_frames_at(b.coordinate_values(changes))
    f1 = frames[end1[0]] @ end1[1]
    f2 = frames[end2[0]] @ end2[1]
    rot = f1.rot.T @ f2.rot
    angles = Rotation.from_matrix(rot).as_euler("XYZ")
    return np.concatenate([angles, f1.rot.T @ (f2.pos - f1.pos)])
