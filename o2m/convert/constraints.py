"""Constraints between bodies: PointOnLineConstraint, WeldConstraint, PointConstraint and
ConstantDistanceConstraint.

(CoordinateCouplerConstraints are joint equalities of the builder, :mod:`o2m.convert.builder`.)

MuJoCo has no point-on-line constraint, but it has the two pieces of one: a body that slides
along the line, hung from the line body (``<constraint>_line``, one slide joint along the
line's direction), and a ``connect`` equality that holds the follower's point at that body's
origin (two sites). Together they leave the follower the motions OpenSim leaves it. The sliding
body is light (:data:`LINE_BODY_MASS`) and its weight cancelled; the report records what its
mass adds. Units: metres; OpenSim ground Y-up, MuJoCo world Z-up.

The other three are MuJoCo equalities between two sites, one at each constraint frame or point:
a ``weld`` (the site frames coincide), a ``connect`` (the site origins coincide), and for a
constant distance a spatial tendon between the sites held at that length by a ``tendon``
equality (MuJoCo has no distance equality). Like the couplers they are soft
(:data:`~o2m.convert.builder.EQUALITY_SOLREF`), and OpenSim's default pose need not satisfy them:
the first steps pull the bodies together.
"""

from __future__ import annotations

import mujoco
import numpy as np

from o2m.convert.builder import EQUALITY_SOLIMP, EQUALITY_SOLREF, MjcfBuilder
from o2m.convert.records import Approximation
from o2m.osim.skeleton import BodyConstraint, PointOnLine
from o2m.transforms import OSIM_TO_MJ, Transform, matrix_to_quat

__all__ = ["LINE_BODY_MASS", "add_body_constraint", "add_constraints", "add_point_on_line"]

#: Mass (kg) and principal inertia (kg m²) of the body that slides along the line, its weight
#: cancelled (gravcomp). MuJoCo takes the softness of the connect equality from this mass, so it
#: cannot be negligible (a near-massless body leaves the equality too soft to act, as with the path
#: carriers), and it moves with the follower, so it must be small beside it.
LINE_BODY_MASS = 1e-3
LINE_BODY_INERTIA = 1e-8


def add_constraints(builder: MjcfBuilder) -> list[str]:
    """Add every body-to-body constraint of the builder's skeleton (after :meth:`MjcfBuilder.build`);
    returns the names of their equalities."""
    for c in builder.skel.point_on_lines:
        add_point_on_line(builder, c)
    names = [c.name for c in builder.skel.point_on_lines]
    for c in builder.skel.body_constraints:
        names.append(add_body_constraint(builder, c))
    return names


def _in_mujoco_frame(body: str, v: np.ndarray) -> np.ndarray:
    """A vector of OpenSim body ``body``'s frame in the MuJoCo body's (ground maps to the world)."""
    return OSIM_TO_MJ @ v if body == "ground" else v


def add_point_on_line(builder: MjcfBuilder, c: PointOnLine) -> None:
    """The sliding body and the connect equality of one PointOnLineConstraint; the slide's zero is
    where the follower's point is at the default pose (projected on the line)."""
    for body in (c.line_body, c.follower_body):
        if body not in builder.bodies:
            raise builder.doc.error(c.element, f"names body '{body}', which the model does not have")
    line_frame, follower_frame = builder.ground_frames[c.line_body], builder.ground_frames[c.follower_body]
    point = line_frame.inverse().apply(follower_frame.apply(c.follower_point))
    anchor = c.line_point + float(np.dot(point - c.line_point, c.direction)) * c.direction
    pos, axis = _in_mujoco_frame(c.line_body, anchor), _in_mujoco_frame(c.line_body, c.direction)
    name = f"{c.name}_line"
    slider = builder.bodies[c.line_body].add_body(name=name, pos=pos, quat=np.array([1.0, 0, 0, 0]),
                                                  gravcomp=1.0)
    slider.explicitinertial = True
    slider.mass = LINE_BODY_MASS
    slider.fullinertia = [LINE_BODY_INERTIA] * 3 + [0.0] * 3
    builder.exact[("inertial", name)] = {"pos": np.zeros(3), "mass": LINE_BODY_MASS,
                                         "fullinertia": np.array(slider.fullinertia)}
    slider.add_joint(name=f"{c.name}_slide", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=axis)
    builder.exact[("body", name)] = {"pos": pos, "quat": np.array([1.0, 0, 0, 0])}
    builder.exact[("joint", f"{c.name}_slide")] = {"axis": axis}
    # two sites, so that the equality holds the point on the line itself (a body connect would
    # keep whatever offset the default pose has: OpenSim's default pose need not satisfy it)
    point = _in_mujoco_frame(c.follower_body, c.follower_point)
    builder.bodies[c.follower_body].add_site(name=f"{c.name}_point", pos=point, group=4)
    slider.add_site(name=f"{c.name}_on_line", pos=np.zeros(3), group=4)
    builder.exact[("site", f"{c.name}_point")] = {"pos": point}
    eq = builder.spec.add_equality(name=c.name, type=mujoco.mjtEq.mjEQ_CONNECT, objtype=mujoco.mjtObj.mjOBJ_SITE,
                                   name1=f"{c.name}_point", name2=f"{c.name}_on_line")
    eq.solref, eq.solimp = list(EQUALITY_SOLREF), list(EQUALITY_SOLIMP)
    builder.result.approximations.append(Approximation(
        "PointOnLineConstraint", c.name, f"body '{name}' slides with the follower along the line",
        LINE_BODY_MASS, "kg", "its mass adds to the follower's inertia along the line; its weight is cancelled"))
    builder.result.notes.append(
        f"PointOnLineConstraint '{c.name}': body '{name}' slides along the line on '{c.line_body}' and a connect "
        f"equality holds '{c.follower_body}''s point at it")


def _site_at(builder: MjcfBuilder, body: str, frame: Transform, name: str) -> None:
    """A site named ``name`` at ``frame`` (in OpenSim body ``body``'s frame), recorded as exact."""
    rot = OSIM_TO_MJ @ frame.rot if body == "ground" else frame.rot
    pos, quat = _in_mujoco_frame(body, frame.pos), matrix_to_quat(rot)
    builder.bodies[body].add_site(name=name, pos=pos, quat=quat, group=4)
    builder.exact[("site", name)] = {"pos": pos, "quat": quat}


def add_body_constraint(builder: MjcfBuilder, c: BodyConstraint) -> str:
    """The two sites and the equality (weld, connect, or tendon length) of one WeldConstraint,
    PointConstraint or ConstantDistanceConstraint (module docstring); returns the equality's name."""
    for body in (c.body1, c.body2):
        if body not in builder.bodies:
            raise builder.doc.error(c.element, f"names body '{body}', which the model does not have")
    name = c.name or c.type.lower()  # an unnamed one: OpenSim's default name, numbered as it numbers them
    taken = {e.name for e in builder.spec.equalities}
    name = next(n for n in (name, *(f"{name}_{i}" for i in range(len(taken) + 1))) if n not in taken)
    s1, s2 = f"{name}_frame1", f"{name}_frame2"
    _site_at(builder, c.body1, c.frame1, s1)
    _site_at(builder, c.body2, c.frame2, s2)
    site = mujoco.mjtObj.mjOBJ_SITE
    if c.type == "ConstantDistanceConstraint":
        tendon = builder.spec.add_tendon(name=f"{name}_distance")
        tendon.wrap_site(s1)
        tendon.wrap_site(s2)
        # MuJoCo's tendon equality holds L - L(qpos0) at polycoef[0]; qpos0 is the default pose
        a, b = (builder.ground_frames[bd].apply(f.pos) for bd, f in ((c.body1, c.frame1), (c.body2, c.frame2)))
        eq = builder.spec.add_equality(name=name, type=mujoco.mjtEq.mjEQ_TENDON, objtype=mujoco.mjtObj.mjOBJ_TENDON,
                                       name1=f"{name}_distance")
        eq.data[0] = c.distance - float(np.linalg.norm(a - b))
        what = f"a tendon equality holds spatial tendon '{name}_distance' at {c.distance:g} m"
    else:
        kind = mujoco.mjtEq.mjEQ_WELD if c.type == "WeldConstraint" else mujoco.mjtEq.mjEQ_CONNECT
        eq = builder.spec.add_equality(name=name, type=kind, objtype=site, name1=s1, name2=s2)
        what = f"a {'weld' if kind == mujoco.mjtEq.mjEQ_WELD else 'connect'} equality between sites '{s1}' and '{s2}'"
    eq.solref, eq.solimp = list(EQUALITY_SOLREF), list(EQUALITY_SOLIMP)
    builder.result.notes.append(f"{c.type} '{name}' ('{c.body1}' to '{c.body2}'): {what}")
    return name
